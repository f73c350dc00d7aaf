//! `idexp simulate <design.toml>`: run the closed-loop simulation and write the run folder.

use super::{SimDesign, SimSetup};
use crate::error::Result;
use std::path::PathBuf;

/// `idexp simulate <design.toml>`
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Simulation design file (TOML).
    pub design: PathBuf,
    /// Output folder (default: out/<design name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs `idexp simulate`, stopped by `ctl`.
pub fn run(a: &SimulateArgs, ctl: &crate::optim::Control) -> Result<()> {
    let d = SimDesign::read(&a.design)?;
    let base = a.design.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let ctx = a.design.display().to_string();
    let setup = SimSetup::from_design(&d, &base, &ctx)?;
    let res = setup.run(ctl)?;
    let name = d.name.clone().unwrap_or_else(|| {
        a.design
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "simulate".into())
    });
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(name));
    res.write(&out, &d)?;
    let st = &res.status;
    println!(
        "simulated {} repetitions ({}) of {:.3} s at {} Hz on {}; tracking error rms [{}] rad, max [{}] rad",
        st.repetitions,
        st.status,
        setup.reference.duration(),
        setup.rate,
        setup.truth.name,
        st.rms_tracking_error.iter().map(|v| format!("{v:.2e}")).collect::<Vec<_>>().join(", "),
        st.max_tracking_error.iter().map(|v| format!("{v:.2e}")).collect::<Vec<_>>().join(", ")
    );
    println!("written to {}", out.display());
    Ok(())
}
