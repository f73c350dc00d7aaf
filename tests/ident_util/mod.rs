//! Helpers of the identification and simulation tests: simulated runs from
//! design text, identification with the default base parameters.
#![allow(dead_code)]

use idexp::ident::study::{run_study_with, ExperimentSpec, Given, Inputs, StudyDesign, StudyResult};
use idexp::ident::Run;
use idexp::params::{BaseOptions, BaseParams};
use idexp::sim::{SimDesign, SimResult, SimSetup};
use std::path::{Path, PathBuf};

/// Path relative to the crate root.
pub fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Parses a simulation design given as TOML text (paths relative to the crate root).
pub fn design(text: &str) -> SimDesign {
    let d: SimDesign = idexp::io::parse_toml(Path::new("test.toml"), text).unwrap_or_else(|e| panic!("{e}"));
    d.validate("test.toml").unwrap_or_else(|e| panic!("{e}"));
    d
}

/// Simulates a design.
pub fn simulate(d: &SimDesign) -> SimResult {
    let setup = SimSetup::from_design(d, &root(""), "test.toml").unwrap_or_else(|e| panic!("{e}"));
    setup.run(&idexp::optim::Control::new()).unwrap_or_else(|e| panic!("{e}"))
}

/// The run of a simulation (in memory).
pub fn run_of(res: &SimResult) -> Run {
    Run::new(vec![], res.reps.clone()).unwrap()
}

/// Identifies from a simulation, validated on another, by the study engine:
/// a one-experiment design (sample weights from the repetitions, the run's
/// Fourier reference) that `set` adjusts (method, reduction, the experiment's
/// processing; the validation entry is processed like the experiment), the
/// runs and the truth given in memory.
pub fn ident(res: &SimResult, val: Option<&SimResult>, set: impl FnOnce(&mut StudyDesign)) -> (StudyResult, BaseParams) {
    try_ident(res, val, set).unwrap_or_else(|e| panic!("{e}"))
}

/// [`ident`] that returns the engine's error.
pub fn try_ident(res: &SimResult, val: Option<&SimResult>, set: impl FnOnce(&mut StudyDesign)) -> idexp::Result<(StudyResult, BaseParams)> {
    try_ident_with(res, val, set, &idexp::optim::Control::new())
}

/// [`try_ident`] under the run control `ctl`.
pub fn try_ident_with(
    res: &SimResult,
    val: Option<&SimResult>,
    set: impl FnOnce(&mut StudyDesign),
    ctl: &idexp::optim::Control,
) -> idexp::Result<(StudyResult, BaseParams)> {
    let robot = &res.setup.nominal;
    let base = BaseParams::compute(robot, &BaseOptions::default()).unwrap();
    let given = |r: &SimResult| Given {
        run: run_of(r),
        trajectory: r.setup.reference.fourier().cloned(),
        torque_source: idexp::data::TorqueSource::logged_torques(),
    };
    let mut e = ExperimentSpec::new(vec![]);
    e.name = "run".into();
    let mut d = StudyDesign::one_experiment("test", PathBuf::from("robot.toml"), e).repetition_weighted(idexp::ident::Weights::Sample);
    set(&mut d);
    let mut inputs = Inputs {
        robot: Some(robot.clone()),
        truth: Some(res.truth().unwrap()),
        ..Default::default()
    };
    inputs.entries.insert("run".into(), given(res));
    if let Some(v) = val {
        let mut ve = d.experiment[0].validation_like(vec![], None);
        ve.name = "validate".into();
        d.validation = vec![ve];
        inputs.entries.insert("validate".into(), given(v));
    }
    let r = run_study_with(&d, Path::new(""), &inputs, ctl)?;
    Ok((r, base))
}

/// A Fourier-excitation design on the RPR arm with drives.
/// The true parameters come from `truth_seed`, the noise from `seed`.
pub fn rpr_fourier(truth_seed: u64, seed: u64, traj_seed: u64, reps: usize, position_noise: f64) -> SimDesign {
    rpr_fourier_bw(truth_seed, seed, traj_seed, reps, position_noise, 10.0)
}

/// As [`rpr_fourier`] with a given controller bandwidth (Hz).
pub fn rpr_fourier_bw(truth_seed: u64, seed: u64, traj_seed: u64, reps: usize, position_noise: f64, bandwidth: f64) -> SimDesign {
    design(&format!(
        r#"
robot = "tests/data/ident/rpr_drives.toml"
rate = 1000.0
decimate = 5
repetitions = {reps}
seed = {seed}
[truth]
perturbation = 0.1
seed = {truth_seed}
[controller]
bandwidth = {bandwidth}
[noise]
torque = 0.05
position = {position_noise:e}
[reference]
kind = "random_fourier"
n_h = 5
frequency = 0.1
amplitude = 0.7
seed = {traj_seed}
"#
    ))
}
