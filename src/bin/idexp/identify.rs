//! `idexp identify`: identification from measured (or simulated) runs, and the
//! dedicated gravity and friction experiments (`--experiment`).

use crate::Outcome;
use anyhow::{anyhow, bail, Context};
use idexp::ident::experiments::{friction_experiment, gravity_experiment, FrictionFit, GravityFit, GravityTerm};
use idexp::ident::output::{write_friction, write_gravity};
use idexp::ident::study::{ConsistentSpec, EssentialRule, EssentialSpec, ExperimentSpec, ExportFormat, FilterName, ReduceSpec, StudyDesign};
use idexp::ident::{Filter, Method, Run, Weights};
use idexp::io::status::{fingerprint_of, write_status, RunState};
use idexp::optim::Control;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Dedicated experiments of paper 002 §3.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Experiment {
    /// Gravity slopes: fit τ = k sin(q + q_off) + c± (eq. 23).
    Gravity,
    /// Bang-bang acceleration: fit inertia and asymmetric Coulomb + viscous friction (eq. 2).
    Friction,
}

/// `idexp identify <robot> <run>...` or `idexp identify <study.toml>`
#[derive(clap::Args, Debug, Serialize)]
pub struct IdentifyArgs {
    /// A study file (experiments, validation runs, prior: docs/identification.md), or the robot file (.toml or .urdf) of the one-run form.
    pub robot: PathBuf,
    /// The run (one-run form): a folder of repetition CSVs, or the files themselves.
    pub run: Vec<PathBuf>,
    /// Validation run (folder or files).
    #[arg(long, num_args = 1..)]
    pub validate: Vec<PathBuf>,
    /// Estimator: ols, wls, projection or ml.
    #[arg(long, default_value_t = Method::Wls)]
    pub method: Method,
    /// Weights of the least-squares residuals: sample (per sample, paper 000 eq. 7–9) or joint (per joint).
    #[arg(long, default_value_t = Weights::Sample)]
    pub weights: Weights,
    /// Position filter: auto (Fourier filtering when the run's trajectory is known, else low-pass), fourier (needs the trajectory), lowpass (zero-phase, --cutoff), none (central differences only).
    #[arg(long, default_value = "auto")]
    pub filter: FilterName,
    /// Low-pass cut-off (Hz).
    #[arg(long, default_value_t = 10.0)]
    pub cutoff: f64,
    /// Fourier trajectory of the run (coefficients.json); default: trajectory.json in the run folder.
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// Fourier trajectory of the validation run; default: trajectory.json in its folder.
    #[arg(long)]
    pub validate_trajectory: Option<PathBuf>,
    /// Harmonics kept by Fourier filtering (default: the trajectory's n_h).
    #[arg(long)]
    pub harmonics: Option<usize>,
    /// Keep every k-th sample after filtering.
    #[arg(long, default_value_t = 1)]
    pub decimate: usize,
    /// Sensitivity-based model reduction (paper 000 Algorithm 1).
    #[arg(long)]
    pub reduce: bool,
    /// Reduction tolerance e_tol on the relative growth of e*_j (with --reduce).
    #[arg(long, alias = "tol", default_value_t = 0.05)]
    pub reduce_tol: f64,
    /// Essential parameters: auto (friction if every joint moves), none, friction, or a comma-separated list of base names.
    #[arg(long, default_value = "auto")]
    pub essential: String,
    /// Projection method FIR lags "M1,M2" (default: chosen by cross-validation over repetitions).
    #[arg(long)]
    pub fir_lags: Option<String>,
    /// truth.json of a simulated run: compare the estimates with the true base parameters.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Fix the base columns by name, comma separated (e.g. ZZ1,XX2,...): checked to form a base.
    #[arg(long, value_delimiter = ',')]
    pub base_columns: Vec<String>,
    /// Dedicated experiment instead of the full identification.
    #[arg(long, value_enum)]
    pub experiment: Option<Experiment>,
    /// Joint (1-based) of the dedicated experiment.
    #[arg(long)]
    pub joint: Option<usize>,
    /// gravity.json of a gravity experiment on the same joint (friction experiment; else gravity is fitted alongside).
    #[arg(long)]
    pub gravity_fit: Option<PathBuf>,
    /// Friction experiment on a joint without gravity torque (vertical axis): no gravity term.
    #[arg(long)]
    pub no_gravity: bool,
    /// Rows of a joint slower than this fraction of its largest speed are left out of the identification.
    #[arg(long, default_value_t = 0.1)]
    pub slow_ratio: f64,
    /// Speed below which rows are left out: of the identification (default 0.01) and of the friction experiment (default 0.05) (rad/s or m/s).
    #[arg(long)]
    pub min_speed: Option<f64>,
    /// Coulomb dead band (rad/s or m/s): for joints with a `sign` Coulomb term, |q̇| below it is rest (no Coulomb term), in the run and the validation run alike; 0: sign(q̇) everywhere.
    #[arg(long, default_value_t = idexp::ident::DEAD_BAND)]
    pub dead_band: f64,
    /// Which slow rows to leave out: auto (those of joints with a `sign` Coulomb term; smooth tanh/stribeck joints keep their standstill rows), drop (every joint), keep (none).
    #[arg(long, default_value = "auto")]
    pub standstill: idexp::ident::Standstill,
    /// Joint velocities from the drive's logged qd* columns (q̇ unfiltered; q̈ from q̇ through the filter, unless qdd* are logged too) or from the positions; auto: logged when present.
    #[arg(long, default_value_t = idexp::ident::VelocityFrom::Auto)]
    pub velocity_from: idexp::ident::VelocityFrom,
    /// Joint torques from the torque columns tau*, the motor currents cur* (τ = current_sign·k_t·N·i with the robot file's drives), or auto (currents when the run logs no torques).
    #[arg(long, default_value_t = idexp::ident::TorqueFrom::Auto)]
    pub torque_from: idexp::ident::TorqueFrom,
    /// Largest relative RMS difference per file and joint between logged torques and the torques of logged currents.
    #[arg(long, default_value_t = idexp::ident::CURRENT_TOLERANCE)]
    pub current_tolerance: f64,
    /// N_r of an averaged run (one CSV with var_tau1..var_taun columns); default: `repetitions` in run.json next to it.
    #[arg(long)]
    pub repetitions: Option<usize>,
    /// Coordinates of the logged positions: joint, or motor (θ = C q, mapped through the robot's coupling).
    #[arg(long, default_value_t = idexp::ident::Coordinates::Joint)]
    pub coordinates: idexp::ident::Coordinates,
    /// Physically consistent standard parameters after WLS/OLS (semidefinite program, Clarabel).
    #[arg(long)]
    pub consistent: bool,
    /// Margin ε of the consistent fit: every pseudo-inertia ⪰ ε I (kg·m²).
    #[arg(long, default_value_t = 0.0)]
    pub margin: f64,
    /// Weight of the closest-to-nominal (CAD) term of the consistent fit.
    #[arg(long, default_value_t = 1e-6)]
    pub regularization: f64,
    /// Write the identified model: urdf, toml, csv, mjcf (comma-separated; urdf, toml and mjcf imply --consistent).
    #[arg(long, value_delimiter = ',')]
    pub export: Vec<ExportFormat>,
    /// Output folder (default: out/identify_<run folder name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Accept run folders whose status.json is not `complete` (e.g. an interrupted simulate); never one marked `running`.
    #[arg(long)]
    pub allow_incomplete: bool,
    /// The run and validation files are robot logs of this form (rtde, csv, headerless, bag), each one repetition; irregular stamps are resampled.
    #[arg(long, conflicts_with = "log_map")]
    pub log_format: Option<idexp::data::logs::LogFormat>,
    /// A log map file (TOML, `idexp log convert --map`): how the run and validation logs map to the run columns.
    #[arg(long)]
    pub log_map: Option<PathBuf>,
    /// The JointState topic of bag logs (with --log-format bag).
    #[arg(long)]
    pub topic: Option<String>,
    /// Uniform rate (Hz) that irregular logs are resampled to (default: the inverse median step).
    #[arg(long)]
    pub resample: Option<f64>,
    /// Print estimate.json's contents (or the experiment's fit) instead of the text report.
    #[arg(long)]
    #[serde(skip)]
    pub json: bool,
}

fn default_out(run: &[PathBuf], suffix: &str) -> PathBuf {
    let stem = run
        .first()
        .map(|p| {
            let p = if p.is_dir() {
                p.clone()
            } else {
                p.parent().map(Path::to_path_buf).unwrap_or_default()
            };
            p.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "run".into())
        })
        .unwrap_or_else(|| "run".into());
    PathBuf::from("out").join(format!("identify_{stem}{suffix}"))
}

fn parse_lags(s: &str) -> anyhow::Result<[usize; 2]> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || anyhow!("identify: --fir-lags: expected two non-negative integers \"M1,M2\", got {s:?}");
    if parts.len() != 2 {
        return Err(bad());
    }
    Ok([parts[0].parse().map_err(|_| bad())?, parts[1].parse().map_err(|_| bad())?])
}

/// The arguments of the one-run form left at their defaults (a study file
/// takes its options from the file): the flags given anyway, by name.
fn one_run_flags(a: &IdentifyArgs) -> anyhow::Result<Vec<String>> {
    #[derive(clap::Parser)]
    struct Wrap {
        #[command(flatten)]
        a: IdentifyArgs,
    }
    let d = <Wrap as clap::Parser>::try_parse_from(["identify", "x"])?.a;
    let (given, default) = (serde_json::to_value(a)?, serde_json::to_value(&d)?);
    let keep = ["robot", "out"];
    Ok(given
        .as_object()
        .map(|m| {
            m.iter()
                .filter(|(k, v)| !keep.contains(&k.as_str()) && default.get(k.as_str()) != Some(v))
                .map(|(k, _)| format!("--{}", k.replace('_', "-")))
                .collect()
        })
        .unwrap_or_default())
}

/// Runs `idexp identify study.toml`: the library runs the study and writes its folder.
fn run_study(a: &IdentifyArgs, ctl: &Control, started: SystemTime) -> anyhow::Result<Outcome> {
    let flags = one_run_flags(a)?;
    if !flags.is_empty() {
        bail!(
            "identify {}: {} belong to the one-run form (idexp identify ROBOT RUN...); a study takes its options from the study file (docs/identification.md, \"Studies\")",
            a.robot.display(),
            flags.join(", ")
        );
    }
    let design = idexp::ident::study::StudyDesign::read(&a.robot)?;
    let dir = a.robot.parent().map(Path::to_path_buf).unwrap_or_default();
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&design.name));
    run_design(a, &design, &dir, &out, ctl, started)
}

/// Runs the study engine on `design` (paths relative to `dir`) into `out`.
fn run_design(a: &IdentifyArgs, design: &StudyDesign, dir: &Path, out: &Path, ctl: &Control, started: SystemTime) -> anyhow::Result<Outcome> {
    idexp::io::folder::check_out_dir(out)?;
    let res = idexp::ident::study::run_study(design, dir, ctl)?;
    crate::write_folder(
        out,
        "identify",
        &fingerprint_of(design)?,
        || res.write(out, Some(started)),
        a.json.then_some(&res.estimate),
        &res.estimate.text(),
        res.estimate.unusable_reason(),
    )
}

/// The log spec of `--log-format` / `--log-map` (with `--topic`), if any.
fn log_spec(a: &IdentifyArgs) -> anyhow::Result<Option<idexp::data::logs::LogSpec>> {
    use idexp::data::logs::LogSpec;
    if a.log_format.is_none() && a.log_map.is_none() {
        if a.topic.is_some() || a.resample.is_some() {
            bail!("identify: --topic and --resample are for robot logs: give --log-format or --log-map");
        }
        return Ok(None);
    }
    let map = a.log_map.as_deref().map(LogSpec::read).transpose()?;
    let name = a.log_map.as_ref().map_or_else(|| "identify".to_string(), |p| p.display().to_string());
    Ok(Some(LogSpec::resolve(map, &name, a.log_format, a.topic.clone(), None)?))
}

/// The one-run form as a one-experiment study: the run (and validation run)
/// with their processing options, the estimator, the consistent fit and the
/// exports, all as the study file would say them.
fn one_run_design(a: &IdentifyArgs) -> anyhow::Result<StudyDesign> {
    let log = log_spec(a)?;
    let essential = match a.essential.as_str() {
        "auto" => EssentialSpec::Rule(EssentialRule::Auto),
        "none" => EssentialSpec::Rule(EssentialRule::None),
        "friction" => EssentialSpec::Rule(EssentialRule::Friction),
        s => EssentialSpec::Names(s.split(',').map(|x| x.trim().to_string()).filter(|x| !x.is_empty()).collect()),
    };
    let mut e = ExperimentSpec::new(a.run.clone());
    // named by the run's folder (the validation run's too): two CSVs of one name in different folders stay apart
    e.name = default_name(&a.run);
    e.filter = a.filter;
    e.cutoff = a.cutoff;
    e.trajectory = a.trajectory.clone();
    e.harmonics = a.harmonics;
    e.decimate = a.decimate;
    e.resample = a.resample;
    e.repetitions = a.repetitions;
    e.coordinates = a.coordinates;
    e.torque_from = a.torque_from;
    e.current_tolerance = a.current_tolerance;
    e.velocity_from = a.velocity_from;
    e.standstill = Some(a.standstill);
    e.slow_ratio = a.slow_ratio;
    e.min_speed = a.min_speed.unwrap_or(0.01);
    e.log = log;
    let mut d = StudyDesign::one_experiment(&default_name(&a.run), a.robot.clone(), e.clone()).repetition_weighted(a.weights);
    if !a.validate.is_empty() {
        let mut v = e.validation_like(a.validate.clone(), a.validate_trajectory.clone());
        v.name = default_name(&a.validate);
        if v.name == e.name {
            v.name = format!("{}_validation", e.name);
        }
        d.validation.push(v);
    }
    d.method = a.method;
    d.reduce = a.reduce.then(|| ReduceSpec {
        tol: a.reduce_tol,
        essential,
        ..Default::default()
    });
    if let Some(l) = &a.fir_lags {
        d.projection.lags = Some(parse_lags(l)?);
    }
    d.truth = a.truth.clone();
    d.base_columns = a.base_columns.clone();
    d.dead_band = a.dead_band;
    d.allow_incomplete = a.allow_incomplete;
    d.export = a.export.clone();
    if a.consistent || a.export.iter().any(|e| *e != ExportFormat::Csv) {
        d.consistent = Some(ConsistentSpec::closest_to_nominal(a.margin, a.regularization));
    }
    Ok(d)
}

/// The name of the run folder (or of the first file's folder), in the
/// characters a study entry's name allows (letters, digits, `_`, `-`, `.`;
/// no leading `.`).
fn default_name(run: &[PathBuf]) -> String {
    let p = default_out(run, "");
    let s = p.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let s: String = s
        .strip_prefix("identify_")
        .unwrap_or(&s)
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') { c } else { '_' })
        .collect();
    match s.trim_start_matches('.') {
        "" => "run".into(),
        t => t.into(),
    }
}

/// Runs `idexp identify`.
pub fn run(a: &IdentifyArgs, ctl: &Control) -> anyhow::Result<Outcome> {
    let started = SystemTime::now();
    if a.run.is_empty() {
        let text = idexp::io::read_to_string(&a.robot)?;
        if idexp::ident::study::design::is_study_text(&text) {
            return run_study(a, ctl, started);
        }
        bail!(
            "identify {}: no run given. Give the runs after the robot file (idexp identify ROBOT RUN... [--validate RUN...]), or a study file with [[experiment]] entries (idexp identify study.toml)",
            a.robot.display()
        );
    }
    if let Some(exp) = a.experiment {
        a.run.iter().try_for_each(|r| idexp::io::status::require_complete(r, a.allow_incomplete))?;
        let robot = idexp::robot::load(&a.robot)?;
        let (run, _) = Run::read_drives(&a.run, &robot, a.repetitions, a.torque_from, a.current_tolerance)?;
        return run_experiment(a, exp, &run, started);
    }
    let design = one_run_design(a)?;
    let out = a.out.clone().unwrap_or_else(|| default_out(&a.run, ""));
    run_design(a, &design, Path::new(""), &out, ctl, started).map_err(|e| {
        // the engine speaks the study's keys: say the one-run form's way out
        match e.downcast_ref::<idexp::Error>() {
            Some(idexp::Error::Invalid { field, .. }) if field == "weights" => {
                e.context("identify: --weights sample needs repetitions; --weights joint estimates each joint's weight from the residuals")
            }
            _ => e,
        }
    })
}

fn run_experiment(a: &IdentifyArgs, exp: Experiment, run: &Run, started: SystemTime) -> anyhow::Result<Outcome> {
    let joint = a
        .joint
        .context("identify --experiment: --joint: name the joint (1-based) of the dedicated experiment")?;
    let pr = idexp::ident::process_with(run, &Filter::LowPass { cutoff: a.cutoff }, a.velocity_from)?;
    let out = a.out.clone().unwrap_or_else(|| default_out(&a.run, &format!("_{exp:?}").to_lowercase()));
    // the fit first: a refused experiment (wrong run, wrong joint) leaves no
    // output folder behind and an earlier result where it was
    enum Fit {
        Gravity(GravityFit),
        Friction(FrictionFit, f64, &'static str),
    }
    let fit = match exp {
        Experiment::Gravity => Fit::Gravity(gravity_experiment(&pr, joint).with_context(|| {
            let runs: Vec<String> = a.run.iter().map(|p| p.display().to_string()).collect();
            format!("run {}", runs.join(", "))
        })?),
        Experiment::Friction => {
            let grav: Option<GravityFit> = match &a.gravity_fit {
                Some(p) => {
                    let text = idexp::io::read_to_string(p)?;
                    Some(serde_json::from_str(&text).map_err(|e| idexp::Error::parse(p, e.to_string()))?)
                }
                None => None,
            };
            let term = match (&grav, a.no_gravity) {
                (Some(g), _) => GravityTerm::Given(g),
                (None, true) => GravityTerm::Zero,
                (None, false) => GravityTerm::Fit,
            };
            let min_speed = a.min_speed.unwrap_or(0.05);
            let f: FrictionFit = friction_experiment(&pr, joint, term, min_speed)?;
            let source = if f.gravity_given {
                "from the gravity experiment"
            } else if a.no_gravity {
                "none"
            } else {
                "fitted alongside"
            };
            Fit::Friction(f, min_speed, source)
        }
    };
    idexp::io::folder::begin(&out, "identify", "")?;
    let (text, json) = match &fit {
        Fit::Gravity(g) => (write_gravity(&out, joint, &pr, g)?, serde_json::to_value(g)?),
        Fit::Friction(f, min_speed, source) => (write_friction(&out, joint, &pr, f, *min_speed, source)?, serde_json::to_value(f)?),
    };
    idexp::io::write_json(&out.join("options.json"), a)?;
    let detail = format!("{} experiment, joint {joint}", if exp == Experiment::Gravity { "gravity" } else { "friction" });
    write_status(
        &out,
        "identify",
        RunState::Complete,
        detail,
        Some(started),
        fingerprint_of(a)?,
        serde_json::json!({ "experiment": exp, "joint": joint }),
    )?;
    if a.json {
        crate::print_json(&json)?;
    } else {
        print!("{text}");
        println!("written to {}", out.display());
    }
    Ok(Outcome::Done)
}
