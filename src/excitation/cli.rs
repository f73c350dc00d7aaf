//! `idexp excite <design.toml>` and `idexp assess <robot> <trajectory.csv>`.

use super::report::{assess, read_states, write_outputs};
use super::{run, Problem, Status};
use crate::error::{Error, Result};
use crate::params::{BaseOptions, BaseParams};
use std::path::PathBuf;

/// `idexp excite`: design an excitation trajectory.
#[derive(clap::Args, Debug)]
pub struct ExciteArgs {
    /// Design file (TOML), e.g. designs/excite_ur5.toml.
    pub design: PathBuf,
    /// Output folder (default: out/<design name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override the design's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override the design's wall-clock budget (s).
    #[arg(long)]
    pub time_limit: Option<f64>,
}

/// `idexp assess`: identifiability of a given trajectory.
#[derive(clap::Args, Debug)]
pub struct AssessArgs {
    /// Robot file (.toml or .urdf).
    pub robot: PathBuf,
    /// Trajectory CSV with columns q1..qn, qd1..qdn, qdd1..qddn (t and others ignored).
    pub trajectory: PathBuf,
    /// Torque noise standard deviation (N·m): one value for all joints or one per joint, comma separated.
    #[arg(long, value_delimiter = ',', default_value = "1.0")]
    pub noise: Vec<f64>,
    /// Use every k-th row only.
    #[arg(long, default_value_t = 1)]
    pub every: usize,
    /// Rigid-body (inertial) base parameters only, no drive/friction columns.
    #[arg(long)]
    pub inertial: bool,
    /// Also write report.json, report.txt, singular_values.svg and inputs.json into this folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `idexp excite`.
/// `idexp excite`, stopped by `ctl`.
pub fn run_excite(a: &ExciteArgs, ctl: &crate::optim::Control) -> Result<()> {
    let mut d = super::design::ExciteDesign::load(&a.design)?;
    if let Some(s) = a.seed {
        d.seed = s;
    }
    if let Some(t) = a.time_limit {
        d.time_limit = Some(t);
    }
    let ctx = a.design.display().to_string();
    let robot = crate::robot::load(&d.robot)?;
    let p = Problem::new(d, robot, &ctx)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&p.design.name));
    eprintln!(
        "excite `{}`: {} ({} joints), {} variables, {} constraints, {} base columns",
        p.design.name,
        p.robot.name,
        p.robot.dof(),
        p.layout.n_vars(),
        p.constraints.len(),
        p.objective.n_cols()
    );
    let r = run(&p, ctl)?;
    let _ = write_outputs(&p, &r, &out)?;
    println!(
        "{}: cond {:.4}, criterion {:.6} ({:?}), {:.1} s; outputs in {}",
        match r.status {
            Status::Feasible => "feasible",
            Status::Infeasible => "INFEASIBLE",
        },
        r.spectrum.cond,
        r.criterion,
        p.design.objective.criterion,
        r.seconds,
        out.display()
    );
    for line in super::report::violation_lines(&r.violated) {
        println!("  violated: {line}");
    }
    if let Some(b) = &r.stopped_by {
        println!("  stopped early: {b}");
    }
    Ok(())
}

/// Runs `idexp assess`.
pub fn run_assess(a: &AssessArgs) -> Result<()> {
    let robot = crate::robot::load(&a.robot)?;
    let n = robot.dof();
    let noise = match a.noise.len() {
        1 => vec![a.noise[0]; n],
        k if k == n => a.noise.clone(),
        k => return Err(Error::invalid("idexp assess", "--noise", format!("expected 1 or {n} values, got {k}"))),
    };
    if let Some(j) = noise.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(Error::invalid("idexp assess", "--noise", format!("value {} must be positive", j + 1)));
    }
    if a.every == 0 {
        return Err(Error::invalid("idexp assess", "--every", "expected k ≥ 1"));
    }
    let states = read_states(&a.trajectory, n, a.every)?;
    let base = BaseParams::compute(
        &robot,
        &BaseOptions {
            inertial_only: a.inertial,
            ..BaseOptions::default()
        },
    )?;
    let id = assess(&robot, &base, &states, &noise)?;
    let title = format!("identifiability of {} on robot `{}`", a.trajectory.display(), robot.name);
    if let Some(dir) = &a.out {
        id.write(dir, &title)?;
        let inputs = serde_json::json!({
            "command": "assess",
            "robot": a.robot.display().to_string(),
            "trajectory": a.trajectory.display().to_string(),
            "noise": noise,
            "every": a.every,
            "inertial": a.inertial,
            "status": if id.unexcited.is_empty() { "every base parameter excited" } else { "some base parameters not excited" },
        });
        crate::io::write_json(&dir.join("inputs.json"), &inputs)?;
    }
    if a.json {
        let s = serde_json::to_string_pretty(&id).map_err(|e| Error::Numerical(e.to_string()))?;
        println!("{s}");
    } else {
        println!("{title}\n");
        print!("{}", id.text());
    }
    Ok(())
}
