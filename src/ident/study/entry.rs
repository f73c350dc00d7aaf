//! One entry of a study file: an `[[experiment]]` or `[[validation]]` table
//! ([`ExperimentSpec`]): its files, what it is ([`ExperimentKind`]), how it is
//! processed ([`FilterName`], speeds, readers) and, for a dedicated one-joint
//! fit of paper 002 §3.2, its joint and gravity term; validated once here.

use super::design::parse_name;
use crate::data::{Coordinates, TorqueFrom};
use crate::error::{Error, Result};
use crate::ident::{Standstill, VelocityFrom};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Where a dedicated friction fit takes its gravity term from (`gravity`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GravityChoice {
    /// Fitted alongside the friction (`"fit"`, the default).
    Fit,
    /// No gravity term: a vertical axis (`"none"`).
    Zero,
    /// The study's dedicated gravity entry of this name (same joint).
    Entry(String),
    /// A gravity.json written by a gravity fit (a name ending in `.json`,
    /// relative to the study file).
    File(PathBuf),
}

/// What an experiment is; sets the defaults of its processing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ExperimentKind {
    /// A dynamic excitation (Fourier or any trajectory): the standstill rule of the model.
    #[default]
    Excitation,
    /// Slow motions or poses for the gravity terms (low-pass filtered).
    Gravity,
    /// Constant-velocity or bang-bang runs for friction (low-pass filtered).
    Friction,
    /// Poses held at rest (low-pass filtered; joints with smooth friction keep their rows).
    Static,
}

impl ExperimentKind {
    /// The name in files.
    pub fn name(self) -> &'static str {
        match self {
            ExperimentKind::Excitation => "excitation",
            ExperimentKind::Gravity => "gravity",
            ExperimentKind::Friction => "friction",
            ExperimentKind::Static => "static",
        }
    }

    /// The standstill rule used unless the entry gives one: the model's
    /// (`auto`) for every kind but `static`. At rest a `sign` Coulomb term is
    /// undefined (the drive holds anywhere within ±F_c), so the slow rows of
    /// such joints are left out of moving experiments; joints with smooth
    /// friction keep them. A `static` run has no speed rule (`keep`): every
    /// row is a pose held at rest, its logged velocity is noise, and the
    /// study's Coulomb dead band (`dead_band`) sets the Coulomb term to 0
    /// there, in estimation and validation alike.
    pub fn default_standstill(self) -> Standstill {
        match self {
            ExperimentKind::Static => Standstill::Keep,
            _ => Standstill::Auto,
        }
    }
}

/// The position filter of an experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum FilterName {
    /// Fourier filtering when the experiment's Fourier trajectory is known, else low-pass.
    #[default]
    Auto,
    /// Fourier filtering at the trajectory's harmonics (needs the trajectory).
    Fourier,
    /// Zero-phase low-pass at `cutoff`, central differences.
    Lowpass,
    /// Central differences only.
    None,
}

/// One experiment (or validation run) of a study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentSpec {
    /// Name in reports and file names; default: the first file's (or folder's) stem.
    #[serde(default)]
    pub name: String,
    /// Folders of repetition CSVs, or the files (relative to the study file).
    pub files: Vec<PathBuf>,
    /// What the experiment is.
    #[serde(default)]
    pub kind: ExperimentKind,
    /// Position filter.
    #[serde(default)]
    pub filter: FilterName,
    /// Low-pass cut-off (Hz).
    #[serde(default = "ten")]
    pub cutoff: f64,
    /// Fourier trajectory (coefficients.json); default: trajectory.json beside the run.
    #[serde(default)]
    pub trajectory: Option<PathBuf>,
    /// Harmonics kept by Fourier filtering.
    #[serde(default)]
    pub harmonics: Option<usize>,
    /// Keep every k-th sample after filtering.
    #[serde(default = "one")]
    pub decimate: usize,
    /// Uniform rate (Hz) for irregular time stamps; default: the inverse median step.
    #[serde(default)]
    pub resample: Option<f64>,
    /// N_r of an averaged run.
    #[serde(default)]
    pub repetitions: Option<usize>,
    /// Coordinates of the logged positions.
    #[serde(default)]
    pub coordinates: Coordinates,
    /// Joint torques from torques or currents.
    #[serde(default)]
    pub torque_from: TorqueFrom,
    /// Allowed disagreement between logged torques and currents.
    #[serde(default = "current_tolerance")]
    pub current_tolerance: f64,
    /// Velocities from the logged `qd*` columns or the positions.
    #[serde(default)]
    pub velocity_from: VelocityFrom,
    /// Which slow rows are left out (default by kind).
    #[serde(default)]
    pub standstill: Option<Standstill>,
    /// Slow-row fraction of the joint's top speed.
    #[serde(default = "slow_ratio")]
    pub slow_ratio: f64,
    /// Slow-row speed (rad/s or m/s).
    #[serde(default = "min_speed")]
    pub min_speed: f64,
    /// The files are robot logs of this form (RTDE recorder CSV, a CSV with a
    /// column map, a headerless CSV, a ROS 2 bag; [`crate::data::logs::LogSpec`]),
    /// each one repetition; default: idexp's run CSVs.
    #[serde(default)]
    pub log: Option<crate::data::logs::LogSpec>,
    /// A dedicated one-joint fit (paper 002 §3.2, `kind` gravity or
    /// friction): the joint (1-based) that moved alone while the others
    /// rested. The entry is fitted on its own ([`super::dedicated`]), not
    /// stacked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    /// A dedicated friction fit's gravity term ([`GravityChoice`]): `"fit"`
    /// (fitted alongside, the default), `"none"` (a vertical axis), the name
    /// of the study's dedicated gravity entry of the same joint, or a
    /// gravity.json file (relative to the study file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<String>,
}
impl std::str::FromStr for FilterName {
    type Err = Error;
    fn from_str(s: &str) -> Result<FilterName> {
        parse_name("filter", s, "auto, fourier, lowpass or none")
    }
}

fn ten() -> f64 {
    10.0
}
fn one() -> usize {
    1
}
fn current_tolerance() -> f64 {
    crate::data::CURRENT_TOLERANCE
}
fn slow_ratio() -> f64 {
    0.1
}
fn min_speed() -> f64 {
    0.01
}
impl ExperimentSpec {
    /// Checks the entry (`ctx` names it: `experiment 2 (fourier_a)`).
    pub fn validate(&self, ctx: &str) -> Result<()> {
        if self.files.is_empty() {
            return Err(Error::invalid(ctx, "files", "expected at least one folder or CSV file"));
        }
        self.validate_given(ctx)
    }

    /// [`ExperimentSpec::validate`] but `files`: for an entry whose data are given in memory.
    pub fn validate_given(&self, ctx: &str) -> Result<()> {
        let bad = |field: &str, msg: String| Err(Error::invalid(ctx, field, msg));
        if !(self.cutoff.is_finite() && self.cutoff > 0.0) {
            return bad("cutoff", format!("expected a positive frequency in Hz, found {}", self.cutoff));
        }
        if self.decimate == 0 {
            return bad("decimate", "expected ≥ 1".into());
        }
        if let Some(r) = self.resample {
            if !(r.is_finite() && r > 0.0) {
                return bad("resample", format!("expected a positive rate in Hz, found {r}"));
            }
        }
        if let Some(r) = self.repetitions {
            if r < 2 {
                return bad("repetitions", format!("expected N_r ≥ 2 (the sample variance needs two), found {r}"));
            }
        }
        if self.harmonics == Some(0) {
            return bad("harmonics", "expected ≥ 1".into());
        }
        if !(self.current_tolerance.is_finite() && self.current_tolerance > 0.0) {
            return bad(
                "current_tolerance",
                format!("expected a positive relative tolerance, found {}", self.current_tolerance),
            );
        }
        if !(self.slow_ratio.is_finite() && (0.0..1.0).contains(&self.slow_ratio)) {
            return bad("slow_ratio", format!("expected a fraction in [0, 1), found {}", self.slow_ratio));
        }
        if !(self.min_speed.is_finite() && self.min_speed >= 0.0) {
            return bad("min_speed", format!("expected a speed ≥ 0, found {}", self.min_speed));
        }
        if let Some(l) = &self.log {
            l.validate(&format!("{ctx}: log"))?;
            if self.repetitions.is_some() || self.torque_from != TorqueFrom::Auto {
                return bad(
                    "log",
                    "`repetitions` and `torque_from` are for idexp's run CSVs; a log's torques are set in its spec (`torque`, `current`, `tau`)".into(),
                );
            }
        }
        if let Some(j) = self.joint {
            if j == 0 {
                return bad("joint", "expected the joint's number, 1-based (1 is the first joint)".into());
            }
            if !matches!(self.kind, ExperimentKind::Gravity | ExperimentKind::Friction) {
                return bad(
                    "joint",
                    format!(
                        "a dedicated one-joint fit is a `gravity` or `friction` experiment (paper 002 §3.2); this entry is `{}`",
                        self.kind.name()
                    ),
                );
            }
        }
        if self.gravity.is_some() && (self.kind != ExperimentKind::Friction || self.joint.is_none()) {
            return bad(
                "gravity",
                "the gravity term of a dedicated friction fit: give it with `kind = \"friction\"` and `joint`".into(),
            );
        }
        if self.filter == FilterName::Fourier && self.trajectory.is_none() && self.kind != ExperimentKind::Excitation {
            return bad("filter", format!("\"fourier\" for a {} experiment needs `trajectory`", self.kind.name()));
        }
        Ok(())
    }

    /// The gravity term of a dedicated friction fit ([`GravityChoice`]).
    pub fn gravity_choice(&self) -> GravityChoice {
        match self.gravity.as_deref() {
            None | Some("fit") => GravityChoice::Fit,
            Some("none") => GravityChoice::Zero,
            Some(f) if f.ends_with(".json") => GravityChoice::File(PathBuf::from(f)),
            Some(name) => GravityChoice::Entry(name.to_string()),
        }
    }

    /// The name, defaulted to the first file's stem.
    pub fn resolved_name(&self) -> String {
        if !self.name.is_empty() {
            return self.name.clone();
        }
        self.files
            .first()
            .and_then(|f| f.file_stem())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "run".into())
    }
}

/// Characters allowed in experiment names (they name output files).
pub(crate) fn name_ok(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.')) && !s.starts_with('.')
}

impl ExperimentSpec {
    /// An excitation experiment of these files with every default.
    pub fn new(files: Vec<PathBuf>) -> ExperimentSpec {
        ExperimentSpec {
            name: String::new(),
            files,
            kind: ExperimentKind::default(),
            filter: FilterName::default(),
            cutoff: ten(),
            trajectory: None,
            harmonics: None,
            decimate: one(),
            resample: None,
            repetitions: None,
            coordinates: Coordinates::default(),
            torque_from: TorqueFrom::default(),
            current_tolerance: current_tolerance(),
            velocity_from: VelocityFrom::default(),
            standstill: None,
            slow_ratio: slow_ratio(),
            min_speed: min_speed(),
            log: None,
            joint: None,
            gravity: None,
        }
    }

    /// A validation entry processed as this experiment is: the same filter
    /// rule, harmonics, decimation, speed rule and readers, with its own
    /// files and Fourier reference (default: trajectory.json beside it).
    pub fn validation_like(&self, files: Vec<PathBuf>, trajectory: Option<PathBuf>) -> ExperimentSpec {
        ExperimentSpec {
            name: String::new(),
            files,
            trajectory,
            filter: match self.filter {
                FilterName::Fourier => FilterName::Auto,
                f => f,
            },
            ..self.clone()
        }
    }
}
