//! Cost of a design's fit problem at the true parameters (from `truth.json`
//! beside the simulated FRF data) and at θ_init, and the relative theoretical
//! standard deviations (eq. 5) at the truth. Run after `idexp frf`:
//! `cargo run --release --example frf_check -- designs/elastic_industrial6.toml out`
use idexp::frf::pipeline::{setup, FitOptions};
use std::path::PathBuf;

fn main() -> Result<(), idexp::Error> {
    let design = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "designs/elastic_industrial6.toml".into()));
    let out = std::env::args().nth(2).map(PathBuf::from);
    let s = setup(
        &design,
        &FitOptions {
            out: out.clone(),
            ..FitOptions::default()
        },
    )?;
    let Some(t) = s.truth.clone() else {
        println!("no truth.json beside the FRF data: the data are not simulated");
        return Ok(());
    };
    println!(
        "cost at truth {:.4e}, at θ_init {:.4e}",
        s.problem.cost(&t)?,
        s.problem.cost(&s.problem.theta_nom)?
    );
    let p = s.problem.covariance(&t)?;
    for (i, n) in s.model.unknown_names().iter().enumerate() {
        println!("{n:<10} true {:>12.4e}  relative std_th {:.2e}", t[i], p[(i, i)].sqrt() / t[i]);
    }
    Ok(())
}
