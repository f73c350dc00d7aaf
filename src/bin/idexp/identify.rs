//! `idexp identify`: identification from measured (or simulated) runs, and the
//! dedicated gravity and friction experiments (`--experiment`): every form
//! builds (or reads) a study design and runs the library's study engine.

use crate::Outcome;
use anyhow::{anyhow, bail, Context};
use idexp::ident::study::{ConsistentSpec, EssentialRule, EssentialSpec, ExperimentKind, ExperimentSpec, ExportFormat, FilterName, ReduceSpec, StudyDesign};
use idexp::ident::{Method, Weights};
use idexp::io::status::fingerprint_of;
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

/// Runs a study of dedicated one-joint fits (every experiment names its
/// `joint`) into `out`.
fn run_dedicated(a: &IdentifyArgs, design: &StudyDesign, dir: &Path, out: &Path, ctl: &Control, started: SystemTime) -> anyhow::Result<Outcome> {
    idexp::io::folder::check_out_dir(out)?;
    let res = idexp::ident::study::run_dedicated(design, dir, &Default::default(), ctl)?;
    let json = res.json();
    crate::write_folder(
        out,
        "identify",
        &fingerprint_of(design)?,
        || res.write(out, Some(started)),
        a.json.then_some(&json),
        &res.text(),
        None,
    )
}

/// Runs the study engine on `design` (paths relative to `dir`) into `out`.
fn run_design(a: &IdentifyArgs, design: &StudyDesign, dir: &Path, out: &Path, ctl: &Control, started: SystemTime) -> anyhow::Result<Outcome> {
    if design.is_dedicated() {
        return run_dedicated(a, design, dir, out, ctl, started);
    }
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
    if let Some(x) = a.experiment {
        let joint = a
            .joint
            .context("identify --experiment: --joint: name the joint (1-based) of the dedicated experiment")?;
        e.joint = Some(joint);
        e.kind = match x {
            Experiment::Gravity => ExperimentKind::Gravity,
            Experiment::Friction => ExperimentKind::Friction,
        };
        if x == Experiment::Friction {
            // the stiction region of a friction fit (paper 002 §3.2.2)
            e.min_speed = a.min_speed.unwrap_or(0.05);
            e.gravity = match (&a.gravity_fit, a.no_gravity) {
                (Some(_), true) => bail!("identify: --gravity-fit and --no-gravity contradict each other: give one"),
                (Some(p), false) if p.extension().is_some_and(|x| x == "json") => Some(p.display().to_string()),
                (Some(p), false) => bail!("identify --gravity-fit {}: expected the gravity.json of a gravity experiment", p.display()),
                (None, true) => Some("none".into()),
                (None, false) => None,
            };
        } else if a.gravity_fit.is_some() || a.no_gravity {
            bail!("identify: --gravity-fit and --no-gravity are for --experiment friction");
        }
    }
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
    let design = one_run_design(a)?;
    let suffix = a.experiment.map_or_else(String::new, |x| format!("_{x:?}").to_lowercase());
    let out = a.out.clone().unwrap_or_else(|| default_out(&a.run, &suffix));
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
