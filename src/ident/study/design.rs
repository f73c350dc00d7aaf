//! The identification study file (TOML; `idexp identify study.toml`).
//!
//! ```toml
//! name = "cobot"                     # output folder out/<name> (default: the file stem)
//! robot = "robots/cobot.toml"        # relative to this file
//! method = "wls"                     # wls | ols (every experiment stacked) | projection | ml (closed loop, one experiment)
//! weights = "auto"                   # auto (repetitions where they exist, else residuals) | repetitions | residuals
//! repetition_weights = "sample"      # sample (per sample, eq. 7) | joint (per-joint mean); default: sample from 10 repetitions on
//! irls_iterations = 50               # reweighting iterations (residual weights)
//! irls_tol = 1e-6                    # relative change of the block variances that ends them
//! base_columns = []                  # fix the base columns by name (default: computed)
//! truth = "sim/truth.json"           # optional: compare with the true base parameters
//! export = ["urdf", "toml", "csv"]   # the identified model (urdf, toml, mjcf need [consistent])
//! dead_band = 0.01                   # rad/s: |q̇| below it is rest for `sign` Coulomb terms (every experiment and validation run)
//!
//!
//! [reduce]                           # model reduction (paper 000 Algorithm 1; method wls, one experiment)
//! tol = 0.05                         # largest relative growth of any joint's e*_j
//! essential = "auto"                 # auto | none | friction | ["fv1", "fc1"]: never removed
//! moving_speed = 0.05                # a joint moves above this speed (for essential = "auto")
//!
//! [projection]                       # method = "projection" (paper 002 eq. 10–12)
//! lags = [2, 4]                      # FIR lags [M1, M2]; default: chosen by cross-validation
//!
//! [ml]                               # method = "ml" (paper 002 eq. 13–16)
//! max_eval = 400
//! ftol_rel = 1e-12
//! bound = 50.0                       # search box half-width in WLS standard deviations
//!
//! [[experiment]]                     # any number (≥ 1); their rows are stacked
//! name = "fourier_a"                 # default: the first file's (folder's) name
//! files = ["runs/a"]                 # folders of repetition CSVs or the files
//! kind = "excitation"                # excitation | gravity | friction | static (poses at rest: no speed rule)
//! filter = "auto"                    # auto | fourier | lowpass | none
//! cutoff = 10.0                      # low-pass cut-off (Hz)
//! trajectory = "runs/a/coefficients.json"   # Fourier reference (default: trajectory.json beside the run)
//! harmonics = 20
//! decimate = 1
//! resample = 100.0                   # Hz; irregular time stamps are resampled (default rate: 1/median step)
//! repetitions = 50                   # N_r of an averaged run (one CSV with var_tau*)
//! coordinates = "joint"              # joint | motor
//! torque_from = "auto"               # auto | torque | current
//! current_tolerance = 0.05
//! velocity_from = "auto"             # auto | log | positions
//! standstill = "auto"                # auto (the friction model's rule) | drop | keep
//! slow_ratio = 0.1
//! min_speed = 0.01
//! log = { format = "bag", topic = "/joint_states" }   # the files are robot logs (rtde | csv | headerless | bag)
//!
//! # dedicated one-joint fits (paper 002 §3.2; docs/identification.md): a study whose
//! # every [[experiment]] has `joint` fits each on its own (no base parameters)
//! [[experiment]]
//! kind = "gravity"                   # gravity (slopes of opposite sign) | friction (bang-bang)
//! joint = 2                          # the joint that moved alone (1-based)
//! files = ["runs/gravity_2"]
//! [[experiment]]
//! kind = "friction"
//! joint = 2
//! files = ["runs/friction_2"]
//! gravity = "gravity_2"              # fit (default) | none (vertical axis) | a gravity entry of this joint | a gravity.json
//! min_speed = 0.05                   # the stiction region left out (the command line's default for a friction fit)
//!
//! [[validation]]                     # any number; the same keys as an experiment
//! name = "pose_1"
//! files = ["val/pose_1.csv"]
//! kind = "static"
//!
//! [consistent]                       # physically consistent estimate with a prior
//! prior = "nominal"                  # nominal (the robot file) | a robot file (same links and drives)
//! metric = "entropic"                # entropic | euclidean
//! weight = 1.0                       # or "validation": the strongest of `weight_grid` within one standard error of the best validation error
//! weight_grid = [1e-3, 1e-2, 0.1, 1, 10, 100, 1e3]
//! scale = 0.5                        # prior std relative to the nominal value (floored per kind)
//! margin = 0.0                       # pseudo-inertias ⪰ margin · I (kg·m²)
//! plausible = [0.2, 5.0]             # flag masses, inertias and drive parameters outside these ratios to the prior
//! unknown = "zeros"                  # drive parameters without a known value, not pulled: "zeros" (those the prior gives as 0) | "none" | ["Ia1", "Fc2"]
//! ```

use crate::error::{Error, Result};
use crate::ident::estimate::Weights;
use crate::ident::prior::PriorMetric;
use crate::ident::reduce::Essential;
use crate::ident::study::stack::WeightSource;
use crate::ident::{Method, MlOptions};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub(crate) use super::entry::name_ok;
pub use super::entry::{ExperimentKind, ExperimentSpec, FilterName, GravityChoice};

/// Model reduction (`[reduce]`, paper 000 Algorithm 1): weighted least
/// squares on one experiment, parameters removed while every joint's e*_j
/// grows by less than `tol`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReduceSpec {
    /// Tolerance e_tol on the relative growth of e*_j.
    #[serde(default = "reduce_tol")]
    pub tol: f64,
    /// Parameters never removed: `"auto"` (friction when every joint moves),
    /// `"none"`, `"friction"`, or a list of base-parameter names.
    #[serde(default)]
    pub essential: EssentialSpec,
    /// Joint speed above which a joint counts as moving (rad/s or m/s).
    #[serde(default = "moving_speed")]
    pub moving_speed: f64,
    /// Rank tolerance (relative residual of a unit-norm column).
    #[serde(default = "rank_tol")]
    pub rank_tol: f64,
}

impl Default for ReduceSpec {
    fn default() -> Self {
        ReduceSpec {
            tol: reduce_tol(),
            essential: EssentialSpec::default(),
            moving_speed: moving_speed(),
            rank_tol: rank_tol(),
        }
    }
}

/// The consistent fit's prior (`[consistent] prior`): `"nominal"` or the
/// path of a robot file (relative to the study file).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(from = "String", into = "String")]
pub enum Prior {
    /// The identified robot file's own parameters.
    #[default]
    Nominal,
    /// Another robot file with the same links and drives.
    File(PathBuf),
}

impl From<String> for Prior {
    fn from(s: String) -> Prior {
        if s == "nominal" {
            Prior::Nominal
        } else {
            Prior::File(PathBuf::from(s))
        }
    }
}

impl From<Prior> for String {
    fn from(p: Prior) -> String {
        p.to_string()
    }
}

impl std::fmt::Display for Prior {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Prior::Nominal => f.write_str("nominal"),
            Prior::File(p) => write!(f, "{}", p.display()),
        }
    }
}

/// The essential parameters of `[reduce]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum EssentialSpec {
    /// A rule.
    Rule(EssentialRule),
    /// These base parameters by name.
    Names(Vec<String>),
}

impl Default for EssentialSpec {
    fn default() -> Self {
        EssentialSpec::Rule(EssentialRule::Auto)
    }
}

/// Rules of [`EssentialSpec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EssentialRule {
    /// Friction parameters when every joint moves, else none (paper 000 §III-D).
    Auto,
    /// No essential parameters.
    None,
    /// Every friction parameter.
    Friction,
}

impl EssentialSpec {
    /// The reduction's essential set.
    pub fn essential(&self) -> Essential {
        match self {
            EssentialSpec::Rule(EssentialRule::Auto) => Essential::Auto,
            EssentialSpec::Rule(EssentialRule::None) => Essential::None,
            EssentialSpec::Rule(EssentialRule::Friction) => Essential::Friction,
            EssentialSpec::Names(n) => Essential::Names(n.clone()),
        }
    }
}

/// The projection method's options (`[projection]`, paper 002 eq. 10–12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ProjectionSpec {
    /// FIR lags [M1, M2] (non-causal, causal); default: chosen by
    /// cross-validation over the repetitions.
    #[serde(default)]
    pub lags: Option<[usize; 2]>,
}

/// The maximum-likelihood options (`[ml]`, paper 002 eq. 13–16).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MlSpec {
    /// Largest number of cost evaluations.
    #[serde(default = "ml_max_eval")]
    pub max_eval: u32,
    /// Relative tolerance on the cost.
    #[serde(default = "ml_ftol_rel")]
    pub ftol_rel: f64,
    /// Half-width of the search box, in WLS standard deviations around the WLS estimate.
    #[serde(default = "ml_bound")]
    pub bound: f64,
}

impl Default for MlSpec {
    fn default() -> Self {
        MlSpec {
            max_eval: ml_max_eval(),
            ftol_rel: ml_ftol_rel(),
            bound: ml_bound(),
        }
    }
}

impl MlSpec {
    /// The estimator's options.
    pub fn options(&self) -> MlOptions {
        MlOptions {
            max_eval: self.max_eval,
            ftol_rel: self.ftol_rel,
            bound: self.bound,
        }
    }
}

fn reduce_tol() -> f64 {
    0.05
}
fn moving_speed() -> f64 {
    0.05
}
fn rank_tol() -> f64 {
    1e-3
}
fn ml_max_eval() -> u32 {
    MlOptions::default().max_eval
}
fn ml_ftol_rel() -> f64 {
    MlOptions::default().ftol_rel
}
fn ml_bound() -> f64 {
    MlOptions::default().bound
}

/// How the prior's weight is set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum WeightSpec {
    /// This weight.
    Value(f64),
    /// A rule (`"validation"`).
    Rule(WeightRule),
    /// `{ relative = r }`: the weight r · σ²_min, σ_min the smallest singular
    /// value of the weighted design's factor R — a pull that decides only
    /// what the data leave open (the null space of K and nearly so); with
    /// r = 10⁻⁶, the Euclidean metric, `scale = 1` and `unknown = "none"`,
    /// the closest-to-nominal consistent fit of `idexp identify --consistent`.
    Relative {
        /// r.
        relative: f64,
    },
}

/// Rules for the prior's weight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WeightRule {
    /// The largest weight of `weight_grid` (the strongest prior) whose
    /// validation error is within one standard error of the smallest
    /// (one-standard-error rule). The error: the mean over validation runs
    /// and joints of RMS(τ − τ̂) divided by the joint's torque range over all
    /// validation runs; its standard error: sd/√K over those K terms.
    Validation,
}

/// Which drive parameters of the prior have no known value (`[consistent] unknown`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum UnknownSpec {
    /// A rule: `"zeros"` or `"none"`.
    Rule(UnknownRule),
    /// These drive parameters by name (`["Ia1", "Fc2"]`).
    Names(Vec<String>),
}

/// Rules for [`UnknownSpec`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnknownRule {
    /// Every drive parameter (Ia, Fc, Fv, …) that is 0 in the prior is unknown.
    Zeros,
    /// Every drive parameter's prior value is known (0 is pulled toward 0).
    None,
}

impl Default for UnknownSpec {
    fn default() -> Self {
        UnknownSpec::Rule(UnknownRule::Zeros)
    }
}

/// The consistent estimate's prior (`[consistent]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConsistentSpec {
    /// `nominal` (the robot file's parameters) or a robot file with the same layout.
    #[serde(default)]
    pub prior: Prior,
    /// The prior's metric.
    #[serde(default)]
    pub metric: PriorMetric,
    /// The prior's weight.
    #[serde(default = "weight_one")]
    pub weight: WeightSpec,
    /// Candidate weights for `weight = "validation"`.
    #[serde(default = "weight_grid")]
    pub weight_grid: Vec<f64>,
    /// Prior standard deviation relative to the nominal value.
    #[serde(default = "half")]
    pub scale: f64,
    /// J_i ⪰ margin · I (kg·m²).
    #[serde(default)]
    pub margin: f64,
    /// Ratios to the prior outside which masses, inertias and drive parameters are flagged.
    #[serde(default = "plausible")]
    pub plausible: [f64; 2],
    /// Drive parameters without a known value, not pulled toward the prior
    /// (default `"zeros"`: those the prior gives as 0).
    #[serde(default)]
    pub unknown: UnknownSpec,
}

impl Default for ConsistentSpec {
    fn default() -> Self {
        ConsistentSpec {
            prior: Prior::Nominal,
            metric: PriorMetric::default(),
            weight: weight_one(),
            weight_grid: weight_grid(),
            scale: half(),
            margin: 0.0,
            plausible: plausible(),
            unknown: UnknownSpec::default(),
        }
    }
}

/// Files the study writes of the identified model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExportFormat {
    /// `robot.urdf` (the robot's URDF with the consistent inertials).
    Urdf,
    /// `robot.toml` (the robot file with the consistent parameters).
    Toml,
    /// `params.csv` (every base and standard parameter).
    Csv,
    /// `robot.xml` (the consistent model as MJCF for MuJoCo).
    Mjcf,
}

/// Parses a snake_case name of a unit enum (`"lowpass"`, `"mjcf"`): the
/// names the study file uses, for the command line and Python; the error
/// lists the allowed ones.
pub(super) fn parse_name<T: serde::de::DeserializeOwned>(field: &str, s: &str, allowed: &str) -> Result<T> {
    T::deserialize(serde::de::value::StrDeserializer::<serde::de::value::Error>::new(s))
        .map_err(|_| Error::invalid("identify", field, format!("expected {allowed}, found `{s}`")))
}

impl std::str::FromStr for ExportFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<ExportFormat> {
        parse_name("export", s, "urdf, toml, csv or mjcf")
    }
}

impl ExportFormat {
    /// Every format, in the order of the documentation.
    pub const ALL: [ExportFormat; 4] = [ExportFormat::Urdf, ExportFormat::Toml, ExportFormat::Csv, ExportFormat::Mjcf];
}

/// An identification study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyDesign {
    /// Name (output folder); default: the file stem.
    #[serde(default)]
    pub name: String,
    /// Robot file, relative to the study file.
    pub robot: PathBuf,
    /// Estimator: `wls`, `ols` (every experiment stacked), `projection` or
    /// `ml` (closed-loop methods on one experiment).
    #[serde(default)]
    pub method: Method,
    /// Where the weights come from.
    #[serde(default)]
    pub weights: WeightSource,
    /// Per-sample or per-joint weights from repetitions (default: per sample
    /// from 10 repetitions on, per joint below).
    #[serde(default)]
    pub repetition_weights: Option<Weights>,
    /// Largest number of reweighting iterations.
    #[serde(default = "irls_iterations")]
    pub irls_iterations: usize,
    /// Relative change of the block variances that ends the reweighting.
    #[serde(default = "irls_tol")]
    pub irls_tol: f64,
    /// Base columns by name (default: computed).
    #[serde(default)]
    pub base_columns: Vec<String>,
    /// truth.json of a simulated study.
    #[serde(default)]
    pub truth: Option<PathBuf>,
    /// Largest number of samples per repetition (bounds memory before reading).
    #[serde(default = "sample_limit")]
    pub sample_limit: usize,
    /// The experiments whose rows are stacked.
    #[serde(default)]
    pub experiment: Vec<ExperimentSpec>,
    /// The validation runs.
    #[serde(default)]
    pub validation: Vec<ExperimentSpec>,
    /// The consistent estimate with a prior.
    #[serde(default)]
    pub consistent: Option<ConsistentSpec>,
    /// Model files to write.
    #[serde(default)]
    pub export: Vec<ExportFormat>,
    /// Model reduction (method `wls`, one experiment).
    #[serde(default)]
    pub reduce: Option<ReduceSpec>,
    /// Projection-method options (method `projection`).
    #[serde(default)]
    pub projection: ProjectionSpec,
    /// Maximum-likelihood options (method `ml`).
    #[serde(default)]
    pub ml: MlSpec,
    /// Accept run folders whose status.json is not `complete` (an interrupted
    /// simulation); never one marked `running`.
    #[serde(default)]
    pub allow_incomplete: bool,
    /// Coulomb dead band (rad/s or m/s): for the joints with a `sign`
    /// Coulomb term, |q̇_j| below it is rest (Coulomb term 0), in every
    /// experiment and validation run ([`crate::ident::DEAD_BAND`] by default).
    #[serde(default = "dead_band")]
    pub dead_band: f64,
}

fn dead_band() -> f64 {
    crate::ident::DEAD_BAND
}
fn weight_one() -> WeightSpec {
    WeightSpec::Value(1.0)
}
fn weight_grid() -> Vec<f64> {
    vec![1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3]
}
fn half() -> f64 {
    0.5
}
fn plausible() -> [f64; 2] {
    [0.2, 5.0]
}
fn irls_iterations() -> usize {
    50
}
fn irls_tol() -> f64 {
    1e-6
}
fn sample_limit() -> usize {
    5_000_000
}

/// True when a TOML text is a study file (it has `[[experiment]]` entries).
pub fn is_study_text(text: &str) -> bool {
    text.parse::<toml::Table>().is_ok_and(|t| t.contains_key("experiment"))
}

impl ConsistentSpec {
    /// The closest-to-nominal consistent fit: a Euclidean pull toward the
    /// robot file's parameters of weight `relative` × the fit's smallest
    /// curvature ([`WeightSpec::Relative`]) on every standard parameter
    /// (`scale = 1`, `unknown = "none"`), pseudo-inertias ⪰ `margin` · I.
    pub fn closest_to_nominal(margin: f64, relative: f64) -> ConsistentSpec {
        ConsistentSpec {
            metric: PriorMetric::Euclidean,
            weight: WeightSpec::Relative { relative },
            scale: 1.0,
            margin,
            unknown: UnknownSpec::Rule(UnknownRule::None),
            ..Default::default()
        }
    }
}

impl StudyDesign {
    /// A study of `robot` with one experiment and every default: the form
    /// `idexp identify ROBOT RUN…` and Python's `idexp.identify` build.
    pub fn one_experiment(name: &str, robot: PathBuf, experiment: ExperimentSpec) -> StudyDesign {
        StudyDesign {
            name: name.into(),
            robot,
            method: Method::default(),
            weights: WeightSource::default(),
            repetition_weights: None,
            irls_iterations: irls_iterations(),
            irls_tol: irls_tol(),
            base_columns: Vec::new(),
            truth: None,
            sample_limit: sample_limit(),
            experiment: vec![experiment],
            validation: Vec::new(),
            consistent: None,
            export: Vec::new(),
            reduce: None,
            projection: ProjectionSpec::default(),
            ml: MlSpec::default(),
            allow_incomplete: false,
            dead_band: dead_band(),
        }
    }

    /// The least-squares weights of one experiment's repetitions: per
    /// sample (eq. 7–9; the experiment must have repetitions or variances),
    /// or per joint (the repetitions' mean variance, else the residuals').
    pub fn repetition_weighted(mut self, w: Weights) -> StudyDesign {
        self.repetition_weights = Some(w);
        self.weights = match w {
            Weights::Sample => WeightSource::Repetitions,
            Weights::Joint => WeightSource::Auto,
        };
        self
    }

    /// The estimator's rules: the closed-loop methods and the model reduction
    /// work on one experiment; the consistent fit needs every base parameter
    /// of a least-squares fit.
    fn validate_method(&self, ctx: &str) -> Result<()> {
        let one = |field: &str, what: &str| -> Result<()> {
            if self.experiment.len() != 1 {
                return Err(Error::invalid(
                    ctx,
                    field,
                    format!(
                        "{what} works on one experiment (its repetitions and its reference), but the study has {} [[experiment]] entries: give one, or use method \"wls\"",
                        self.experiment.len()
                    ),
                ));
            }
            Ok(())
        };
        if self.consistent.is_some() && (self.reduce.is_some() || !matches!(self.method, Method::Wls | Method::Ols)) {
            return Err(Error::invalid(
                ctx,
                "consistent",
                "the physically consistent fit uses the least-squares fit of every base parameter: use method \"wls\" or \"ols\" and no [reduce]",
            ));
        }
        match self.method {
            Method::Projection => one("method", "the projection method (paper 002 eq. 10–12)")?,
            Method::Ml => one("method", "maximum likelihood (paper 002 eq. 13–16)")?,
            Method::Wls | Method::Ols => {}
        }
        if let Some(r) = &self.reduce {
            let ctx = format!("{ctx}: [reduce]");
            if self.method != Method::Wls {
                return Err(Error::invalid(
                    &ctx,
                    "method",
                    format!(
                        "model reduction (paper 000 Algorithm 1) uses weighted least squares: set method = \"wls\", found \"{}\"",
                        self.method
                    ),
                ));
            }
            one("reduce", "model reduction (paper 000 Algorithm 1)")?;
            if !(r.tol.is_finite() && r.tol > 0.0) {
                return Err(Error::invalid(&ctx, "tol", format!("expected a positive tolerance, found {}", r.tol)));
            }
            if !(r.moving_speed.is_finite() && r.moving_speed >= 0.0) {
                return Err(Error::invalid(&ctx, "moving_speed", format!("expected a speed ≥ 0, found {}", r.moving_speed)));
            }
            if !(r.rank_tol.is_finite() && r.rank_tol > 0.0 && r.rank_tol < 1.0) {
                return Err(Error::invalid(
                    &ctx,
                    "rank_tol",
                    format!("expected a tolerance in (0, 1), found {}", r.rank_tol),
                ));
            }
            if let EssentialSpec::Names(n) = &r.essential {
                if n.is_empty() {
                    return Err(Error::invalid(
                        &ctx,
                        "essential",
                        "expected \"auto\", \"none\", \"friction\" or a non-empty list of base-parameter names",
                    ));
                }
                if let Some((i, x)) = n.iter().enumerate().find(|(i, x)| n[..*i].contains(x)) {
                    return Err(Error::invalid(
                        &ctx,
                        "essential",
                        format!("`{x}` is listed twice (entry {}): expected each name once", i + 1),
                    ));
                }
            }
        }
        if let Some([m1, m2]) = self.projection.lags {
            if m1 + m2 == 0 || m1 + m2 > 10_000 {
                return Err(Error::invalid(
                    format!("{ctx}: [projection]"),
                    "lags",
                    format!("expected [M1, M2] with 1 ≤ M1 + M2 ≤ 10000, found [{m1}, {m2}]"),
                ));
            }
        }
        let ml = &self.ml;
        if ml.max_eval == 0 || !(ml.ftol_rel.is_finite() && ml.ftol_rel > 0.0) || !(ml.bound.is_finite() && ml.bound > 0.0) {
            return Err(Error::invalid(
                format!("{ctx}: [ml]"),
                "max_eval/ftol_rel/bound",
                format!(
                    "expected max_eval ≥ 1, ftol_rel > 0 and bound > 0, found {}, {}, {}",
                    ml.max_eval, ml.ftol_rel, ml.bound
                ),
            ));
        }
        Ok(())
    }

    /// Reads and validates a study file.
    pub fn read(path: &Path) -> Result<StudyDesign> {
        let text = crate::io::read_to_string(path)?;
        let mut d: StudyDesign = toml::from_str(&text).map_err(|e| Error::parse(path, e.to_string()))?;
        if d.name.is_empty() {
            d.name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "study".into());
        }
        crate::io::design_path(path, "robot", &d.robot)?;
        d.validate(&path.display().to_string())?;
        Ok(d)
    }

    /// Checks every field; errors name `ctx` (the file), the entry and the field.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        self.validate_with(ctx, &Default::default())
    }

    /// [`StudyDesign::validate`] for a study whose entries named in `given`
    /// have their data in memory (no `files` needed).
    pub fn validate_with(&self, ctx: &str, given: &std::collections::BTreeMap<String, super::Given>) -> Result<()> {
        if self.experiment.is_empty() {
            return Err(Error::invalid(
                ctx,
                "experiment",
                "expected at least one [[experiment]] entry (files = [...] of its runs)",
            ));
        }
        if self.irls_iterations == 0 {
            return Err(Error::invalid(ctx, "irls_iterations", "expected ≥ 1"));
        }
        if !(self.irls_tol.is_finite() && self.irls_tol > 0.0) {
            return Err(Error::invalid(
                ctx,
                "irls_tol",
                format!("expected a positive tolerance, found {}", self.irls_tol),
            ));
        }
        if !(self.dead_band.is_finite() && self.dead_band >= 0.0) {
            return Err(Error::invalid(
                ctx,
                "dead_band",
                format!("expected a speed ≥ 0 (rad/s; 0: sign(q̇) everywhere), found {}", self.dead_band),
            ));
        }
        if self.sample_limit < 3 {
            return Err(Error::invalid(ctx, "sample_limit", format!("expected ≥ 3, found {}", self.sample_limit)));
        }
        self.validate_method(ctx)?;
        let mut names: Vec<String> = Vec::new();
        for (what, list) in [("experiment", &self.experiment), ("validation", &self.validation)] {
            for (i, e) in list.iter().enumerate() {
                let name = e.resolved_name();
                let entry = format!("{ctx}: {what} {} ({name})", i + 1);
                if given.contains_key(&name) {
                    e.validate_given(&entry)?;
                } else {
                    e.validate(&entry)?;
                }
                if !name_ok(&name) {
                    return Err(Error::invalid(
                        &entry,
                        "name",
                        format!("`{name}`: expected letters, digits, `_`, `-` or `.` (it names output files)"),
                    ));
                }
                if names.contains(&name) {
                    return Err(Error::invalid(
                        &entry,
                        "name",
                        format!("`{name}` is used by another experiment or validation run: give each a name of its own"),
                    ));
                }
                names.push(name);
            }
        }
        if let Some(c) = &self.consistent {
            let ctx = format!("{ctx}: [consistent]");
            match c.weight {
                WeightSpec::Relative { relative: r } if !(r.is_finite() && r > 0.0) => {
                    return Err(Error::invalid(
                        &ctx,
                        "weight",
                        format!("expected {{ relative = r }} with a positive r (the weight relative to the fit's smallest curvature), found {r}"),
                    ));
                }
                WeightSpec::Value(w) if !(w.is_finite() && w > 0.0) => {
                    return Err(Error::invalid(
                        &ctx,
                        "weight",
                        format!("expected a positive weight or \"validation\", found {w}"),
                    ));
                }
                WeightSpec::Rule(WeightRule::Validation) if self.validation.is_empty() => {
                    return Err(Error::invalid(
                        &ctx,
                        "weight",
                        "\"validation\" chooses the weight on the validation runs, but the study has no [[validation]] entry: add one or give a weight",
                    ));
                }
                _ => {}
            }
            if c.weight_grid.is_empty() || c.weight_grid.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
                return Err(Error::invalid(
                    &ctx,
                    "weight_grid",
                    format!("expected positive weights, found {:?}", c.weight_grid),
                ));
            }
            if !(c.scale.is_finite() && c.scale > 0.0) {
                return Err(Error::invalid(&ctx, "scale", format!("expected a positive relative scale, found {}", c.scale)));
            }
            if !(c.margin.is_finite() && c.margin >= 0.0) {
                return Err(Error::invalid(&ctx, "margin", format!("expected a margin ≥ 0 (kg·m²), found {}", c.margin)));
            }
            let [lo, hi] = c.plausible;
            if !(hi.is_finite() && (0.0..1.0).contains(&lo) && hi > 1.0) {
                return Err(Error::invalid(
                    &ctx,
                    "plausible",
                    format!("expected [low, high] with 0 ≤ low < 1 < high, found [{lo}, {hi}]"),
                ));
            }
        }
        if self.export.iter().any(|e| *e != ExportFormat::Csv) && self.consistent.is_none() {
            return Err(Error::invalid(
                ctx,
                "export",
                "\"urdf\" and \"toml\" write the physically consistent model: add a [consistent] table",
            ));
        }
        self.validate_dedicated(ctx)
    }

    /// True when the study's experiments are dedicated one-joint fits
    /// (every `[[experiment]]` has `joint`; [`super::dedicated`]).
    pub fn is_dedicated(&self) -> bool {
        self.experiment.iter().any(|e| e.joint.is_some())
    }

    /// A study is either dedicated one-joint fits or a model identification
    /// from stacked experiments: what the model's keys would mean for the
    /// former is refused, and a friction fit's `gravity` must name a gravity
    /// fit of its joint.
    fn validate_dedicated(&self, ctx: &str) -> Result<()> {
        if !self.is_dedicated() {
            return Ok(());
        }
        let entry = |i: usize| format!("{ctx}: experiment {} ({})", i + 1, self.experiment[i].resolved_name());
        if let Some(i) = self.experiment.iter().position(|e| e.joint.is_none()) {
            return Err(Error::invalid(
                entry(i),
                "joint",
                "missing: a study either fits dedicated one-joint experiments (every [[experiment]] with `joint`, paper 002 §3.2) or identifies the model from stacked experiments; move this entry to a study of its own",
            ));
        }
        for (i, e) in self.experiment.iter().enumerate() {
            let entry = entry(i);
            if let GravityChoice::Entry(g) = e.gravity_choice() {
                let ok = self
                    .experiment
                    .iter()
                    .any(|o| o.resolved_name() == g && o.kind == ExperimentKind::Gravity && o.joint == e.joint);
                if !ok {
                    return Err(Error::invalid(
                        &entry,
                        "gravity",
                        format!(
                            "`{g}`: expected \"fit\", \"none\", a gravity.json file, or the name of this study's dedicated gravity experiment of joint {}",
                            e.joint.unwrap_or(0)
                        ),
                    ));
                }
            }
        }
        let refuse = |field: &str, what: &str| {
            Err(Error::invalid(
                ctx,
                field,
                format!(
                    "{what}: a study of dedicated one-joint fits (`joint`) fits each joint's gravity or friction model on its own, without base parameters"
                ),
            ))
        };
        if !self.validation.is_empty() {
            return refuse("validation", "validation runs predict torques from base parameters");
        }
        if self.consistent.is_some() {
            return refuse("consistent", "the consistent estimate needs base parameters");
        }
        if !self.export.is_empty() {
            return refuse("export", "a model export needs the identified model");
        }
        if self.reduce.is_some() {
            return refuse("reduce", "model reduction removes base parameters");
        }
        if self.method != Method::Wls {
            return refuse("method", "the estimator of base parameters does not apply");
        }
        if self.truth.is_some() || !self.base_columns.is_empty() {
            return refuse(
                if self.truth.is_some() { "truth" } else { "base_columns" },
                "this compares or fixes base parameters",
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimal_file_defaults_and_unknown_keys() {
        let d: StudyDesign = toml::from_str("robot = \"r.toml\"\n[[experiment]]\nfiles = [\"a\"]\n").unwrap();
        assert_eq!(d.experiment[0].kind, ExperimentKind::Excitation);
        assert_eq!(d.experiment[0].resolved_name(), "a");
        d.validate("s.toml").unwrap();
        let e = toml::from_str::<StudyDesign>("robot = \"r.toml\"\n[[experiment]]\nfiles = [\"a\"]\ncutof = 3\n").unwrap_err();
        assert!(e.to_string().contains("cutof"), "{e}");
        let d: StudyDesign = toml::from_str("robot = \"r.toml\"\n[[experiment]]\nfiles = [\"a\"]\n[consistent]\nweight = \"validation\"\n").unwrap();
        let e = d.validate("s.toml").unwrap_err().to_string();
        assert!(e.contains("[consistent]") && e.contains("weight") && e.contains("[[validation]]"), "{e}");
        let d: StudyDesign = toml::from_str("robot = \"r.toml\"\n[[experiment]]\nfiles = [\"a\"]\n[[validation]]\nfiles = [\"x/a\"]\n").unwrap();
        let e = d.validate("s.toml").unwrap_err().to_string();
        assert!(e.contains("`a` is used"), "{e}");
        assert!(is_study_text("robot = \"r\"\n[[experiment]]\nfiles = []\n") && !is_study_text("name = \"x\"\n[[link]]\n"));
    }
}
