//! What a study gives ([`StudyResult`]): the estimate with its report per
//! experiment and validation run, and the consistent estimate with a prior.

use super::{BlockWeight, ExperimentKind, Loaded, StudyDesign, WeightSource};
use crate::data::{Sampling, TorqueSource};
use crate::ident::consistent::{Active, ConsistentStatus};
use crate::ident::estimate::Errors;
use crate::ident::prior::PriorMetric;
use crate::ident::{EstimateStatus, Filter, Implausible, RowsUsed, TruthRow, VelocitySource};
use crate::robot::Robot;
use serde::Serialize;
use std::path::PathBuf;

/// One experiment in the report.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentReport {
    /// Name.
    pub name: String,
    /// Kind.
    pub kind: ExperimentKind,
    /// Files read.
    pub files: Vec<PathBuf>,
    /// Repetitions.
    pub n_reps: usize,
    /// Samples per joint after processing.
    pub n_samples: usize,
    /// Duration (s).
    pub duration: f64,
    /// Time stamps: uniform, or resampled.
    pub sampling: Sampling,
    /// Filter used.
    pub filter: Filter,
    /// Velocity source.
    pub velocity: VelocitySource,
    /// Torques from torques or currents.
    pub torque_source: TorqueSource,
    /// Rows used per joint.
    pub rows_used: Vec<RowsUsed>,
    /// Per joint: how the rows are weighted.
    pub weights: Vec<BlockWeight>,
    /// Per joint: the torque noise σ the weights stand for (N·m).
    pub sigma: Vec<f64>,
    /// Weighted residual sum of squares of its rows per row.
    pub chi2_per_row: f64,
    /// Errors on its rows used.
    pub errors: Errors,
    /// Errors on every sample.
    pub errors_all: Errors,
    /// Its share of the information, tr((CᵀWC)⁻¹F_e)/k.
    pub information_share: f64,
    /// Per base parameter, its share of that parameter's information.
    pub information_share_per_parameter: Vec<f64>,
    /// Rank of its own weighted design (of k).
    pub rank_alone: usize,
    /// Condition number of its own weighted design (∞ when rank deficient).
    pub cond_alone: f64,
    /// Warnings of its processing.
    pub warnings: Vec<String>,
}

/// One validation run in the report.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationReport {
    /// Name.
    pub name: String,
    /// Kind.
    pub kind: ExperimentKind,
    /// Files read.
    pub files: Vec<PathBuf>,
    /// Samples per joint.
    pub n_samples: usize,
    /// Time stamps.
    pub sampling: Sampling,
    /// Errors of the least-squares estimate on every sample.
    pub errors_all: Errors,
    /// The same on the rows selected like the estimate's.
    pub errors: Errors,
    /// Errors of the consistent estimate on every sample.
    pub consistent_all: Option<Errors>,
}

/// Validation errors summed over the runs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ValidationTotal {
    /// Per joint e_j over every sample of every validation run (N·m).
    pub e: Vec<f64>,
    /// Per joint e*_j = Σ|τ − τ̂| / Σ|τ| over every sample of every run.
    pub e_rel: Vec<f64>,
    /// Per joint RMS over every sample of every run (N·m).
    pub rms: Vec<f64>,
    /// The same for the consistent estimate.
    pub consistent_e_rel: Option<Vec<f64>>,
    /// Mean over runs and joints of the relative RMS error (the criterion of `weight = "validation"`).
    pub mean_relative_rms: f64,
}

/// A link of the consistent estimate beside the prior.
#[derive(Debug, Clone, Serialize)]
pub struct LinkPrior {
    /// Link name.
    pub link: String,
    /// Mass (kg): estimate, prior.
    pub mass: [f64; 2],
    /// Centre of mass (m, link frame): estimate, prior.
    pub com: [[f64; 3]; 2],
    /// Trace of the inertia about the centre of mass (kg·m²): estimate, prior.
    pub inertia_trace: [f64; 2],
    /// Entropic divergence D(J, J₀) of the link's pseudo-inertia from the prior's.
    pub divergence: f64,
}

/// A value physically possible but implausible next to the prior.
#[derive(Debug, Clone, Serialize)]
pub struct Flag {
    /// Link or parameter.
    pub what: String,
    /// Estimate.
    pub value: f64,
    /// Prior.
    pub prior: f64,
    /// Why.
    pub reason: String,
}

/// A direction of the standard parameters the data do not decide.
#[derive(Debug, Clone, Serialize)]
pub struct Direction {
    /// The fit's curvature along it (in prior-scale units; 0: not seen at all).
    pub curvature: f64,
    /// Its largest components (parameter, weight), largest first.
    pub components: Vec<(String, f64)>,
    /// The estimate's coordinate along it, in prior scales (0: the prior's value).
    pub offset: f64,
}

/// A drive parameter without a known value in the consistent estimate.
#[derive(Debug, Clone, Serialize)]
pub struct UnknownParam {
    /// Standard parameter name (`Ia2`).
    pub name: String,
    /// Its consistent estimate.
    pub value: f64,
    /// Its standard deviation seen by the data alone with the other
    /// parameters held (s_j / √H_jj of the fit's curvature); ∞ when no data see it.
    pub std_data: f64,
}

/// The consistent estimate with its prior.
#[derive(Debug, Clone, Serialize)]
pub struct ConsistentReport {
    /// How the fit ended.
    pub status: ConsistentStatus,
    /// `nominal` or the prior robot file.
    pub prior: String,
    /// Metric.
    pub metric: PriorMetric,
    /// Weight used.
    pub weight: f64,
    /// Per candidate weight (weight = "validation"): (weight, mean relative RMS on the validation runs, extra cost).
    pub weight_curve: Vec<(f64, f64, f64)>,
    /// `weight = "validation"`: the tolerance of the one-standard-error rule
    /// (the standard error of the best criterion); the strongest prior within
    /// it of the best was chosen.
    pub weight_tolerance: Option<f64>,
    /// Relative scale of the prior.
    pub scale: f64,
    /// Margin ε.
    pub margin: f64,
    /// Standard parameter names.
    pub standard_names: Vec<String>,
    /// Consistent standard parameters θ.
    pub standard: Vec<f64>,
    /// The prior θ₀.
    pub prior_standard: Vec<f64>,
    /// The prior's scales s.
    pub prior_scale: Vec<f64>,
    /// Base parameters K θ.
    pub base: Vec<f64>,
    /// Increase of the weighted residual sum of squares over WLS.
    pub extra_cost: f64,
    /// Weighted residual sum of squares per degree of freedom.
    pub chi2_dof: f64,
    /// Smallest pseudo-inertia eigenvalue per link (kg·m²).
    pub min_eigenvalue: Vec<f64>,
    /// Constraints at their bound.
    pub active: Vec<Active>,
    /// Per link: the estimate beside the prior.
    pub links: Vec<LinkPrior>,
    /// Implausible values.
    pub flags: Vec<Flag>,
    /// Directions the data do not see at all (decided by the prior alone): their number.
    pub unidentifiable: usize,
    /// Directions the fit sees less than the prior (curvature below the weight), weakest first, at most 12 listed.
    pub prior_decided: Vec<Direction>,
    /// Their number.
    pub n_prior_decided: usize,
    /// The drive parameters without a known value (`unknown`), not pulled toward the prior.
    pub unknown: Vec<UnknownParam>,
    /// Per experiment, the consistent estimate's errors on every sample.
    pub experiments: Vec<Errors>,
    /// Standard parameters per body in Pinocchio's order and convention.
    pub pinocchio: Vec<crate::ident::consistent::PinocchioBody>,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Solver time (s).
    pub solve_time: f64,
}

/// The result of a study (written as `estimate.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    /// Study name.
    pub name: String,
    /// Robot.
    pub robot: String,
    /// How the estimate ended.
    pub status: EstimateStatus,
    /// Estimator.
    pub method: crate::ident::Method,
    /// Weight source.
    pub weights: WeightSource,
    /// The Coulomb dead band (rad/s or m/s) of every experiment and
    /// validation run: |q̇_j| below it is rest for a `sign` Coulomb term.
    pub dead_band: f64,
    /// Base parameter names.
    pub names: Vec<String>,
    /// Their groupings.
    pub groupings: Vec<String>,
    /// Estimates.
    pub theta: Vec<f64>,
    /// Standard deviations.
    pub std: Vec<f64>,
    /// Relative standard deviations.
    pub rel_std: Vec<f64>,
    /// Covariance (rows).
    pub covariance: Vec<Vec<f64>>,
    /// Rank of the weighted design.
    pub rank: usize,
    /// Condition number of the weighted design √W C.
    pub cond: f64,
    /// The same with unit-norm columns.
    pub cond_normalized: f64,
    /// χ²/dof.
    pub chi2_dof: f64,
    /// Reweighting iterations.
    pub iterations: usize,
    /// True when the reweighting converged.
    pub converged: bool,
    /// The experiments.
    pub experiments: Vec<ExperimentReport>,
    /// The validation runs.
    pub validation: Vec<ValidationReport>,
    /// Their totals (None without validation runs).
    pub validation_total: Option<ValidationTotal>,
    /// The consistent estimate with a prior.
    pub consistent: Option<ConsistentReport>,
    /// Base parameters that must be positive but are negative.
    pub implausible: Vec<Implausible>,
    /// Standard parameter names (columns of `base_k`).
    pub standard_names: Vec<String>,
    /// θ_base = K θ_standard.
    pub base_k: Vec<Vec<f64>>,
    /// Comparison with the truth.
    pub truth: Option<Vec<TruthRow>>,
    /// Warnings.
    pub warnings: Vec<String>,
    /// Projection-method details (method `projection`).
    pub projection: Option<crate::ident::closed_loop::ProjectionInfo>,
    /// Maximum-likelihood details (method `ml`).
    pub ml: Option<crate::ident::closed_loop::MlInfo>,
    /// The model reduction (`[reduce]`): its steps and the full model's fit.
    pub reduction: Option<crate::ident::Reduction>,
}

impl Estimate {
    /// True when the estimate stacks the experiments by weighted (or
    /// ordinary) least squares; false for the one-experiment estimators
    /// (projection, maximum likelihood, model reduction), whose condition
    /// numbers are those of the unweighted design C.
    pub fn is_stacked(&self) -> bool {
        matches!(self.method, crate::ident::Method::Wls | crate::ident::Method::Ols) && self.reduction.is_none()
    }
}

/// A study's result with the data behind it (for the plots and files).
#[derive(Debug, Clone)]
pub struct StudyResult {
    /// The resolved design.
    pub design: StudyDesign,
    /// The estimate.
    pub estimate: Estimate,
    /// The experiments.
    pub experiments: Vec<Loaded>,
    /// The validation runs.
    pub validations: Vec<Loaded>,
    /// The robot.
    pub robot: Robot,
    /// The robot file's path.
    pub robot_path: PathBuf,
    /// True when a Ctrl-C stopped it (what exists is written and marked so).
    pub interrupted: bool,
}
