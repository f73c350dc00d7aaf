//! Cost of the design's LLS problem at the true parameters and at the nominal ones (diagnostics).
use idexp::frf::cli::setup;
fn main() -> Result<(), idexp::Error> {
    let out = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "out".into()));
    let s = setup(std::path::Path::new("designs/elastic_industrial6.toml"), None, None, None, None, Some(&out))?;
    let t = s.truth.clone().expect("truth");
    println!(
        "cost at truth {:.4e}, at nominal {:.4e}",
        s.problem.cost(&t)?,
        s.problem.cost(&s.problem.theta_nom)?
    );
    let p = s.problem.covariance(&t)?;
    for (i, n) in s.model.unknown_names().iter().enumerate() {
        println!("{n:<10} true {:>12.4e}  rel std_th {:.4}", t[i], p[(i, i)].sqrt() / t[i]);
    }
    Ok(())
}
