//! Rehearse an identification in a few lines of library code: simulate the
//! RPR test arm (true parameters perturbed by 10 %) tracking a random Fourier
//! excitation in closed loop, identify its base parameters by WLS, and compare
//! them with the truth.
//!
//! `cargo run --release --example ident_rehearsal`

use idexp::ident::{identify, IdentOptions, Run};
use idexp::params::{BaseOptions, BaseParams};
use idexp::sim::{SimDesign, SimSetup};
use std::path::Path;

fn main() -> idexp::Result<()> {
    let design: SimDesign = idexp::io::parse_toml(
        Path::new("rehearsal.toml"),
        r#"
robot = "tests/data/ident/rpr_drives.toml"
rate = 1000.0
decimate = 5
repetitions = 50
seed = 1
[truth]
perturbation = 0.1
[noise]
torque = 0.05
position = 1e-5
[reference]
kind = "random_fourier"
amplitude = 0.7
seed = 3
"#,
    )?;
    design.validate("rehearsal.toml")?;
    let setup = SimSetup::from_design(&design, Path::new("."), "rehearsal.toml")?;
    let sim = setup.run(&idexp::optim::Control::new())?;
    let run = Run::new(vec![], sim.reps.clone())?;
    let robot = &setup.nominal; // identification uses the model structure, not the truth
    let base = BaseParams::compute(robot, &BaseOptions::default())?;
    let opts = IdentOptions {
        harmonics: Some(20),
        ..Default::default()
    };
    let mut id = identify(robot, &base, &run, setup.reference.fourier(), None, &opts, &idexp::optim::Control::new())?;
    let truth = sim.truth()?;
    id.estimate.compare_truth(&truth.base_names, &truth.base)?;
    print!("{}", id.estimate.text());
    Ok(())
}
