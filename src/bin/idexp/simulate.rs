//! `idexp simulate <design.toml>`: run the closed-loop simulation and write the run folder.

use crate::Outcome;
use idexp::optim::Control;
use idexp::sim::{SimDesign, SimSetup};
use std::path::PathBuf;

/// `idexp simulate <design.toml>`
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Simulation design file (TOML).
    pub design: PathBuf,
    /// Output folder (default: out/<design name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override the design's seed (noise and parameter perturbation draws).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Also log the drive's joint velocities qd1..qdn (as `record_velocity = true` in the design; noise `noise.velocity`).
    #[arg(long)]
    pub record_velocity: bool,
    /// Print the run's status summary as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `idexp simulate`.
pub fn run(a: &SimulateArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let mut d = SimDesign::read(&a.design)?;
    if let Some(s) = a.seed {
        d.seed = s;
    }
    if a.record_velocity {
        d.record_velocity = true;
    }
    let base = a.design.parent().map(|p| p.to_path_buf()).unwrap_or_default();
    let ctx = a.design.display().to_string();
    if let Some(o) = &a.out {
        idexp::io::folder::check_out_dir(o)?;
    }
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
    if a.json {
        crate::print_json(st)?;
    } else {
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
    }
    Ok(if st.status == idexp::sim::RunStatus::Interrupted || crate::interrupted(ctl) {
        Outcome::Interrupted
    } else {
        Outcome::Done
    })
}
