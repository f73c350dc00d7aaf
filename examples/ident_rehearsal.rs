//! Rehearse an identification in a few lines of library code: simulate the
//! RPR test arm (true parameters perturbed by 10 %) tracking a random Fourier
//! excitation in closed loop, identify its base parameters by WLS, and compare
//! them with the truth.
//!
//! `cargo run --release --example ident_rehearsal`

use idexp::ident::study::{run_study_with, ExperimentSpec, Given, Inputs, StudyDesign};
use idexp::ident::Run;
use idexp::sim::{SimDesign, SimSetup};
use std::path::{Path, PathBuf};

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
    // a study of one experiment, its data given in memory
    let mut experiment = ExperimentSpec::new(vec![]);
    experiment.name = "rehearsal".into();
    experiment.harmonics = Some(20);
    let design = StudyDesign::one_experiment("rehearsal", PathBuf::from("tests/data/ident/rpr_drives.toml"), experiment);
    let mut inputs = Inputs {
        robot: Some(setup.nominal.clone()), // identification uses the model structure, not the truth
        truth: Some(sim.truth()?),
        ..Default::default()
    };
    inputs.entries.insert(
        "rehearsal".into(),
        Given {
            run: Run::new(vec![], sim.reps.clone())?,
            trajectory: setup.reference.fourier().cloned(),
            torque_source: idexp::data::TorqueSource::logged_torques(),
        },
    );
    let result = run_study_with(&design, Path::new("."), &inputs, &idexp::optim::Control::new())?;
    print!("{}", result.estimate.text());
    Ok(())
}
