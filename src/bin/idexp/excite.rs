//! `idexp excite <design.toml>` and `idexp assess <robot> <trajectory.csv>`.

use crate::Outcome;
use anyhow::bail;
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::report::{assess_file, ident_figure, violation_lines, write_outputs_with, CriterionRecord};
use idexp::excitation::{run, Problem, Status};
use idexp::optim::{Control, Termination};
use idexp::params::{BaseOptions, BaseParams};
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
    /// Print report.json's contents instead of the one-line summary.
    #[arg(long)]
    pub json: bool,
    /// Also write the delivered trajectory for a controller: ur, ros2, csv (comma separated).
    #[arg(long, value_delimiter = ',')]
    pub export: Vec<String>,
    #[command(flatten)]
    pub export_opts: crate::export::ExportOpts,
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
    /// Only the rows of this segment (column `segment` of idexp excite's trajectory.csv: 0 lead-in, k period k, -1 lead-out); --every then counts those rows.
    #[arg(long, allow_hyphen_values = true)]
    pub segment: Option<i64>,
    /// Rigid-body (inertial) base parameters only, no drive/friction columns.
    #[arg(long)]
    pub inertial: bool,
    /// Fix the base columns by name, comma separated (e.g. ZZ1,XX2,...): checked to form a base.
    #[arg(long, value_delimiter = ',')]
    pub base_columns: Vec<String>,
    /// Also write report.json, report.txt, singular_values.svg and inputs.json into this folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `idexp excite`.
pub fn run_excite(a: &ExciteArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let mut d = ExciteDesign::load(&a.design)?;
    if let Some(s) = a.seed {
        d.seed = s;
    }
    if let Some(t) = a.time_limit {
        if !(t.is_finite() && t > 0.0) {
            bail!("--time-limit: expected a positive number of seconds, got {t}");
        }
        d.time_limit = Some(t);
    }
    let ctx = a.design.display().to_string();
    let robot = idexp::robot::load(&d.robot)?;
    let p = Problem::new(d, robot, &ctx)?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&p.design.name));
    idexp::io::folder::check_out_dir(&out)?;
    eprintln!(
        "excite `{}`: {} ({} joints), {} variables, {} constraints, {} base columns",
        p.design.name,
        p.robot.name,
        p.robot.dof(),
        idexp::trajectory::TrajectoryShape::n_vars(&p.shape),
        p.constraints.len(),
        p.objective.n_cols()
    );
    let formats = if a.export.is_empty() {
        None
    } else {
        Some(crate::export::formats(&a.export)?)
    };
    let r = run(&p, ctl)?;
    ctl.observer().phase("excite write", Some(1));
    ctl.observer()
        .progress(0, &format!("report, trajectories, plots and preview.html into {}", out.display()));
    let written = write_outputs_with(&p, &r, &out, |dir| {
        idexp::preview::write_for_result(&p, &r, dir, &idexp::preview::PreviewOptions::default()).map(|_| ())
    });
    ctl.observer().phase_done();
    let written = written?;
    if a.json {
        print!("{}", idexp::io::read_to_string(&out.join("report.json"))?);
    } else {
        println!(
            "{}: condition number {:.4}, criterion {:.6} ({}), {:.1} s; outputs in {}",
            match r.status {
                Status::Feasible => "feasible",
                Status::Infeasible => "INFEASIBLE",
            },
            r.spectrum.cond,
            r.criterion,
            p.design.objective.criterion.words(),
            r.seconds,
            out.display()
        );
        let grid = &written.record.figures[0].samples;
        println!("  criterion on {}", grid.description);
        println!(
            "  delivered trajectory: condition number {:.4} (unit columns) on {}",
            written.delivered.cond,
            written.delivered.source.as_ref().map_or("", |s| s.description.as_str())
        );
        println!("  base columns, weights, column norms and every figure with its samples: criterion.json");
        for line in violation_lines(&r.violated) {
            println!("  violated: {line}");
        }
        if let Some(b) = &r.stopped_by {
            println!("  stopped early: {b}");
        }
        if let Some(e) = r.unexcited() {
            println!("  {e}");
        }
        if let Some(e) = &r.execution.problem {
            println!("  not playable rest to rest: {e}");
        }
        if r.execution.delivered.is_some() && r.status == Status::Feasible {
            println!("  {}", r.execution.safety.statement);
        }
    }
    if let Some(f) = formats {
        match r.playable() {
            Ok(dl) => {
                let names: Vec<String> = p.robot.joints.iter().map(|j| j.name.clone()).collect();
                let revolute: Vec<bool> = p.robot.joints.iter().map(|j| j.kind == idexp::robot::JointKind::Revolute).collect();
                for path in crate::export::export(
                    &out,
                    &p.design.name,
                    &names,
                    &revolute,
                    dl,
                    f,
                    p.design.trajectory.controller_rate,
                    &a.export_opts,
                )? {
                    eprintln!("  wrote {}", path.display());
                }
            }
            Err(why) => eprintln!("no controller export: {why}"),
        }
    }
    let interrupted = r
        .stopped_by
        .as_ref()
        .is_some_and(|b| b.ga == Some(Termination::Interrupted) || b.refine == Some(Termination::Interrupted))
        || crate::interrupted(ctl);
    Ok(match r.status {
        Status::Infeasible => Outcome::Unusable(match (&r.execution.problem, r.violated.len()) {
            _ if r.unexcited().is_some() => format!("the design is INFEASIBLE: {}", r.unexcited().unwrap_or_default()),
            (Some(e), 0) => format!("the design is INFEASIBLE: not playable rest to rest: {e}"),
            (_, k) => format!("the design is INFEASIBLE ({k} constraint(s) violated)"),
        }),
        Status::Feasible if interrupted => Outcome::Interrupted,
        Status::Feasible => Outcome::Done,
    })
}

/// Runs `idexp assess`.
pub fn run_assess(a: &AssessArgs, _ctl: &Control) -> anyhow::Result<Outcome> {
    let robot = idexp::robot::load(&a.robot)?;
    let n = robot.dof();
    let noise = match a.noise.len() {
        1 => vec![a.noise[0]; n],
        k if k == n => a.noise.clone(),
        k => bail!("idexp assess: --noise: expected 1 or {n} values, got {k}"),
    };
    if let Some(j) = noise.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        bail!("idexp assess: --noise: value {} must be positive", j + 1);
    }
    if a.every == 0 {
        bail!("idexp assess: --every: expected k ≥ 1");
    }
    let started = std::time::SystemTime::now();
    let bopts = BaseOptions {
        inertial_only: a.inertial,
        ..BaseOptions::default()
    };
    let base = if a.base_columns.is_empty() {
        BaseParams::compute(&robot, &bopts)?
    } else {
        BaseParams::with_columns(&robot, &a.base_columns, &bopts)?
    };
    // streamed: memory independent of the trajectory length
    let id = assess_file(&robot, &base, &a.trajectory, a.segment, a.every, &noise)?;
    let title = format!("identifiability of {} on robot `{}`", a.trajectory.display(), robot.name);
    if let Some(dir) = &a.out {
        idexp::io::folder::begin(dir, "assess", "")?;
        id.write(dir, &title)?;
        let inputs = serde_json::json!({
            "command": "assess",
            "robot": a.robot.display().to_string(),
            "trajectory": a.trajectory.display().to_string(),
            "noise": noise,
            "every": a.every,
            "segment": a.segment,
            "inertial": a.inertial,
            "status": if id.unexcited.is_empty() { "every base parameter excited" } else { "some base parameters not excited" },
        });
        idexp::io::write_json(&dir.join("inputs.json"), &inputs)?;
        let mut record = CriterionRecord::new(
            &robot,
            &a.robot.display().to_string(),
            &base,
            &noise,
            "what the condition number of `idexp assess` is computed from: the matrix W½·C·D, C the stacked base regressor \
             (rows: samples × joints; columns: `columns`), W½ = diag(1/noise_j) per joint row, D = diag(scale) (unit columns)"
                .into(),
        );
        if let Some(src) = &id.source {
            record.figures.push(ident_figure("identifiability (report.txt, report.json)", src.clone(), &id));
        }
        idexp::io::write_json(&dir.join("criterion.json"), &record)?;
        let detail = if id.unexcited.is_empty() {
            "every base parameter excited"
        } else {
            "some base parameters not excited"
        };
        let fp = idexp::io::status::fingerprint_of(&inputs)?;
        let summary = serde_json::json!({ "unexcited": id.unexcited.len() });
        idexp::io::status::write_status(dir, "assess", idexp::io::status::RunState::Complete, detail, Some(started), fp, summary)?;
    }
    if a.json {
        crate::print_json(&id)?;
    } else {
        println!("{title}\n");
        print!("{}", id.text());
    }
    Ok(Outcome::Done)
}
