//! The plan design file (`idexp plan plan.toml`): the robot, the candidate
//! experiments with their costs and noise, the study's prior and the targets.
//!
//! ```toml
//! name = "plan_rpr"                        # output folder out/<name> (default: the file stem)
//! robot = "robots/rpr.toml"                # relative to this file
//! max_repetitions = 100                    # per experiment, unless the experiment says otherwise
//! margin = 0.03                           # plan every target at bound / (1 + margin) (the study's σ has its own sampling error)
//! # budget = 28800                         # optional: total robot time available (s); a cheapest plan above it ends `over_budget` with the best plan within it
//!
//! [[experiment]]                           # candidates: any number (at least one)
//! name = "fourier_a"
//! simulate = "sim_rpr_fourier.toml"        # a simulate design: the motion, its rate, controller and noise
//! cost = 14.0                              # s per repetition: the motion plus lead-in/out and settling
//! # setup = 600                            # s paid once if the experiment is used at all (mounting a payload, recalibration); default 0
//! max_repetitions = 40
//! # noise = 0.05                           # σ per joint of one repetition's torque rows (N·m; one value or a list); default: the study's residual σ on one simulated repetition
//! # noise = { from = "../out/study_rpr/estimate.json", experiment = "fourier" }   # … or a finished study's residual σ per joint (× √its repetitions)
//! identify = { harmonics = 20 }            # how the study will process it: the study's [[experiment]] keys (kind, filter, cutoff, harmonics, decimate, standstill, …) without files
//!
//! [consistent]                             # optional: the study's prior (its [consistent] table); metric euclidean, a numeric weight
//! prior = "nominal"
//! metric = "euclidean"
//! weight = 1.0
//! scale = 0.5
//!
//! [[target]]                               # at least one
//! parameter = "ZZ2"                        # a base parameter's name (as `idexp robot` lists them) or a standard parameter's
//! sigma = 0.002                            # absolute σ in the parameter's SI unit …
//! # relative = 0.05                        # … or relative to |its nominal value|
//!
//! [[target]]
//! task = "sim_rpr_pick_place.toml"         # a simulate design: its motion is the task trajectory
//! rms = 0.05                               # RMS torque-prediction error (N·m) over its joints and samples
//! ```

use crate::error::{Error, Result};
use crate::ident::prior::PriorMetric;
use crate::ident::study::{ConsistentSpec, ExperimentSpec, WeightSpec};
use crate::sim::PerJoint;
use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};

/// A plan design (see the module documentation for the file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanDesign {
    /// Output folder name (default: the file stem).
    #[serde(default)]
    pub name: String,
    /// Robot file (relative to the design file): the model the study will identify.
    pub robot: PathBuf,
    /// Largest repetitions of an experiment that does not set its own.
    #[serde(default = "hundred")]
    pub max_repetitions: usize,
    /// Every target is planned at bound / (1 + margin): the study's own σ
    /// carries the sampling error of its residual weights (≈ 1/√(2·rows per
    /// joint)) and the effective-noise estimate its own; a plan exactly at
    /// a bound meets it in about half of the rehearsal seeds.
    #[serde(default = "three_percent")]
    pub margin: f64,
    /// Total robot time available (s): when the cheapest plan meeting every
    /// target costs more, the plan ends `over_budget` with the best plan
    /// within it (the smallest worst value/bound ratio).
    #[serde(default)]
    pub budget: Option<f64>,
    /// The candidate experiments.
    pub experiment: Vec<CandidateSpec>,
    /// The study's prior (its `[consistent]` table).
    #[serde(default)]
    pub consistent: Option<ConsistentSpec>,
    /// The targets.
    #[serde(default)]
    pub target: Vec<TargetSpec>,
}

/// One candidate experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CandidateSpec {
    /// Its name (names it in the study the plan writes).
    pub name: String,
    /// A simulate design (relative to the plan file): the motion, rate, controller and noise.
    pub simulate: PathBuf,
    /// Seconds of robot time per repetition (lead-in/out and settling included).
    pub cost: f64,
    /// Seconds paid once if the experiment is used at all (mounting a
    /// payload, recalibration, moving the robot to the test rig).
    #[serde(default)]
    pub setup: f64,
    /// Largest repetitions (default: the plan's `max_repetitions`).
    #[serde(default)]
    pub max_repetitions: Option<usize>,
    /// σ per joint of one repetition's torque rows (N·m), given or read
    /// from a finished study; default: the study's residual σ on one
    /// simulated repetition (sensor noise plus the controller's reaction to
    /// position noise).
    #[serde(default, deserialize_with = "noise_keys")]
    pub noise: Option<CandidateNoise>,
    /// How the study processes it: the study's `[[experiment]]` keys without `files`.
    #[serde(default, deserialize_with = "experiment_keys")]
    pub identify: Option<ExperimentSpec>,
}

/// A candidate's noise: σ per joint, or a finished study's estimate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum CandidateNoise {
    /// σ (N·m) for every joint, or one per joint.
    Given(PerJoint),
    /// The residual σ per joint of a finished study.
    From(NoiseFrom),
}

/// `noise = { from = "…/estimate.json", experiment = "…" }`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseFrom {
    /// A study's estimate.json (relative to the plan file).
    pub from: PathBuf,
    /// Which of its experiments (default: the one named as the candidate, else its only one).
    #[serde(default)]
    pub experiment: Option<String>,
}

fn noise_keys<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Option<CandidateNoise>, D::Error> {
    use serde::de::Error as _;
    let v = toml::Value::deserialize(d)?;
    match v {
        toml::Value::Table(t) => t.try_into::<NoiseFrom>().map(|f| Some(CandidateNoise::From(f))).map_err(|e| {
            D::Error::custom(format!(
                "expected {{ from = \"<a study's estimate.json>\", experiment = \"<its name>\" (optional) }}: {e}"
            ))
        }),
        other => other
            .try_into::<PerJoint>()
            .map(|p| Some(CandidateNoise::Given(p)))
            .map_err(|_| D::Error::custom("expected σ (N·m): one number, a list of one per joint, or { from = \"<a study's estimate.json>\" }")),
    }
}

/// One target.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// A base or standard parameter's name.
    #[serde(default)]
    pub parameter: Option<String>,
    /// Its σ (SI unit of the parameter).
    #[serde(default)]
    pub sigma: Option<f64>,
    /// Its σ relative to |its nominal value|.
    #[serde(default)]
    pub relative: Option<f64>,
    /// A simulate design whose motion is the task trajectory.
    #[serde(default)]
    pub task: Option<PathBuf>,
    /// The RMS torque-prediction error on the task (N·m).
    #[serde(default)]
    pub rms: Option<f64>,
}

/// Most candidates when any has a setup cost (2^n subsets are relaxed).
pub const MAX_CANDIDATES_WITH_SETUP: usize = 12;

fn hundred() -> usize {
    100
}
fn three_percent() -> f64 {
    0.03
}

/// The study's experiment keys without `files` (they are filled by the plan).
fn experiment_keys<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Option<ExperimentSpec>, D::Error> {
    let mut t = toml::Table::deserialize(d)?;
    if t.contains_key("files") {
        return Err(serde::de::Error::custom(
            "`files` is not a key of `identify`: the plan simulates the experiment",
        ));
    }
    t.insert("files".into(), toml::Value::Array(vec![]));
    let spec: ExperimentSpec = t.try_into().map_err(serde::de::Error::custom)?;
    Ok(Some(spec))
}

impl PlanDesign {
    /// Reads and validates a plan design file; an empty name becomes the file stem.
    pub fn read(path: &Path) -> Result<PlanDesign> {
        let mut d: PlanDesign = crate::io::read_toml(path)?;
        if d.name.is_empty() {
            d.name = path.file_stem().map_or_else(|| "plan".into(), |s| s.to_string_lossy().into_owned());
        }
        d.validate(&path.display().to_string())?;
        Ok(d)
    }

    /// Checks ranges and combinations; `ctx` names the file in messages.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        if self.experiment.is_empty() {
            return Err(Error::invalid(ctx, "experiment", "expected at least one [[experiment]] (a candidate)"));
        }
        if !(self.margin.is_finite() && (0.0..1.0).contains(&self.margin)) {
            return Err(Error::invalid(ctx, "margin", format!("expected a fraction in [0, 1), got {}", self.margin)));
        }
        if self.max_repetitions == 0 {
            return Err(Error::invalid(ctx, "max_repetitions", "expected at least 1"));
        }
        if let Some(b) = self.budget {
            if !(b.is_finite() && b > 0.0) {
                return Err(Error::invalid(
                    ctx,
                    "budget",
                    format!("expected a positive number of seconds of robot time, got {b}"),
                ));
            }
        }
        if self.experiment.len() > MAX_CANDIDATES_WITH_SETUP && self.experiment.iter().any(|e| e.setup != 0.0) {
            return Err(Error::invalid(
                ctx,
                "setup",
                format!(
                    "setup costs make the plan enumerate the subsets of used experiments: at most {MAX_CANDIDATES_WITH_SETUP} candidates with setup costs, got {}",
                    self.experiment.len()
                ),
            ));
        }
        for (i, e) in self.experiment.iter().enumerate() {
            let at = format!("{ctx}: experiment {} ({})", i + 1, e.name);
            if e.name.is_empty() {
                return Err(Error::invalid(&at, "name", "expected a name"));
            }
            if self.experiment[..i].iter().any(|o| o.name == e.name) {
                return Err(Error::invalid(&at, "name", format!("`{}` names two experiments", e.name)));
            }
            if !(e.cost.is_finite() && e.cost > 0.0) {
                return Err(Error::invalid(
                    &at,
                    "cost",
                    format!("expected a positive number of seconds per repetition, got {}", e.cost),
                ));
            }
            if !(e.setup.is_finite() && e.setup >= 0.0) {
                return Err(Error::invalid(
                    &at,
                    "setup",
                    format!("expected seconds ≥ 0 paid once if the experiment is used, got {}", e.setup),
                ));
            }
            if e.max_repetitions == Some(0) {
                return Err(Error::invalid(&at, "max_repetitions", "expected at least 1"));
            }
            if let Some(CandidateNoise::Given(n)) = &e.noise {
                n.check(&at, "noise")?;
            }
        }
        if self.target.is_empty() {
            return Err(Error::invalid(
                ctx,
                "target",
                "expected at least one [[target]] (a parameter's sigma or relative, or a task's rms)",
            ));
        }
        for (i, t) in self.target.iter().enumerate() {
            let at = format!("{ctx}: target {}", i + 1);
            let pos = |f: &str, v: Option<f64>| -> Result<()> {
                match v {
                    Some(x) if !(x.is_finite() && x > 0.0) => Err(Error::invalid(&at, f, format!("expected a positive number, got {x}"))),
                    _ => Ok(()),
                }
            };
            pos("sigma", t.sigma)?;
            pos("relative", t.relative)?;
            pos("rms", t.rms)?;
            match (&t.parameter, &t.task) {
                (Some(_), None) => {
                    if t.sigma.is_some() == t.relative.is_some() || t.rms.is_some() {
                        return Err(Error::invalid(
                            &at,
                            "sigma",
                            "a parameter target takes exactly one of `sigma` (absolute) or `relative`",
                        ));
                    }
                }
                (None, Some(_)) => {
                    if t.rms.is_none() || t.sigma.is_some() || t.relative.is_some() {
                        return Err(Error::invalid(&at, "rms", "a task target takes `rms` (N·m) only"));
                    }
                }
                _ => {
                    return Err(Error::invalid(
                        &at,
                        "parameter",
                        "expected exactly one of `parameter` (with sigma or relative) or `task` (with rms)",
                    ))
                }
            }
        }
        if let Some(c) = &self.consistent {
            if c.metric != PriorMetric::Euclidean {
                return Err(Error::invalid(
                    format!("{ctx}: [consistent]"),
                    "metric",
                    "the plan predicts with the Euclidean prior only (a Gaussian of σ = scale·|θ₀|): set metric = \"euclidean\" (the study then uses the same prior)",
                ));
            }
            match c.weight {
                WeightSpec::Value(w) if w.is_finite() && w > 0.0 => {}
                _ => {
                    return Err(Error::invalid(
                        format!("{ctx}: [consistent]"),
                        "weight",
                        "expected a positive number: a weight chosen on validation runs or relative to the data is not known before the data",
                    ))
                }
            }
            if !(c.scale.is_finite() && c.scale > 0.0) {
                return Err(Error::invalid(
                    format!("{ctx}: [consistent]"),
                    "scale",
                    format!("expected a positive number, got {}", c.scale),
                ));
            }
        }
        Ok(())
    }
}
