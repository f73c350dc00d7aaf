//! What an identification gives: the estimate with its statistics and
//! errors ([`Estimate`], written as `estimate.json`), how it ended
//! ([`EstimateStatus`] and the run state of `status.json`), and the data
//! behind it ([`Identification`]). The text report is in `text.rs`, the
//! output folder's writer in [`super::output`].

use super::closed_loop;
use super::{Consistent, Coordinates, Dataset, Errors, Filter, Method, Processed, Reduction, VelocitySource};
use crate::error::{Error, Result};
use crate::io::status::RunState;
use serde::Serialize;

/// The rows of one joint used for the estimate and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RowsUsed {
    /// Joint name.
    pub joint: String,
    /// Rows of this joint in the estimate.
    pub used: usize,
    /// Rows of this joint in the run (after decimation).
    pub total: usize,
    /// True when slow rows were left out.
    pub slow_dropped: bool,
    /// The rule in words.
    pub reason: String,
}

/// How an estimate ended (`status` in estimate.json: `ok`, `rank_deficient`,
/// or nlopt's word for the maximum-likelihood stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimateStatus {
    /// Full rank, estimated.
    Ok,
    /// The design matrix is rank deficient: the minimum-norm solution is not an estimate.
    RankDeficient,
    /// The maximum-likelihood stage ended with this status (nlopt's word).
    Ml(crate::optim::GradientStatus),
}

impl EstimateStatus {
    /// The word written in estimate.json and reports.
    pub fn as_str(self) -> &'static str {
        match self {
            EstimateStatus::Ok => "ok",
            EstimateStatus::RankDeficient => "rank_deficient",
            EstimateStatus::Ml(s) => s.as_str(),
        }
    }

    /// What status.json says of a run that ended so: a rank-deficient design
    /// or an ML failure is not usable, a forced stop is an interruption.
    pub fn state(self) -> RunState {
        use crate::optim::GradientStatus as N;
        match self {
            EstimateStatus::RankDeficient => RunState::Failed,
            EstimateStatus::Ml(N::Failure | N::InvalidArgs | N::OutOfMemory | N::RoundoffLimited) => RunState::Failed,
            EstimateStatus::Ml(N::ForcedStop) => RunState::Interrupted,
            _ => RunState::Complete,
        }
    }
}

impl std::fmt::Display for EstimateStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for EstimateStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

/// A base parameter that must be positive but was estimated negative.
#[derive(Debug, Clone, Serialize)]
pub struct Implausible {
    /// Base parameter name.
    pub name: String,
    /// Its combination of standard parameters.
    pub grouping: String,
    /// Estimate.
    pub value: f64,
    /// Standard deviation.
    pub std: f64,
}

/// Comparison with known true parameters (simulated runs).
#[derive(Debug, Clone, Serialize)]
pub struct TruthRow {
    /// Name.
    pub name: String,
    /// True base value.
    pub truth: f64,
    /// Estimate.
    pub estimate: f64,
    /// (estimate − truth)/σ.
    pub z: f64,
}

/// The result of an identification (written as `estimate.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    /// How the estimate ended.
    pub status: EstimateStatus,
    /// Estimator.
    pub method: Method,
    /// Names of the estimated base parameters.
    pub names: Vec<String>,
    /// Their combinations of standard parameters.
    pub groupings: Vec<String>,
    /// Estimates θ̂.
    pub theta: Vec<f64>,
    /// Standard deviations σ_i.
    pub std: Vec<f64>,
    /// Relative standard deviations σ*_i (eq. 14).
    pub rel_std: Vec<f64>,
    /// Covariance matrix (rows).
    pub covariance: Vec<Vec<f64>>,
    /// Rank of the design matrix.
    pub rank: usize,
    /// Condition number of C.
    pub cond: f64,
    /// Condition number of C with unit-norm columns.
    pub cond_normalized: f64,
    /// Weighted residual sum of squares per degree of freedom.
    pub chi2_dof: f64,
    /// Errors (eq. 11–12) on the rows of the identification run used for the
    /// estimate (fast enough for friction: `slow_ratio`, `min_speed`).
    pub errors: Errors,
    /// Errors on the same kind of rows of the validation run.
    pub validation: Option<Errors>,
    /// Errors on every sample of the identification run (paper 000's
    /// definition), with the same model (friction shape) as the estimate.
    pub errors_all: Errors,
    /// Per joint: the rows used for the estimate and the standstill rule applied.
    pub rows_used: Vec<RowsUsed>,
    /// How the joint torques were obtained when the run logged motor
    /// currents ([`crate::data::Run::read_drives`]); set by the caller.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torque_source: Option<crate::data::TorqueSource>,
    /// Errors on every sample of the validation run.
    pub validation_all: Option<Errors>,
    /// Names of the standard parameters (columns of `base_k`).
    pub standard_names: Vec<String>,
    /// K restricted to the estimated base parameters: θ_base = K θ_standard (rows: `names`).
    pub base_k: Vec<Vec<f64>>,
    /// Coordinates the run's positions were logged in.
    pub coordinates: Coordinates,
    /// True when the run was one averaged file with variance columns.
    pub averaged: bool,
    /// The physically consistent estimate, if asked for.
    pub consistent: Option<Consistent>,
    /// Base parameters that must be positive but are negative.
    pub implausible: Vec<Implausible>,
    /// Repetitions averaged.
    pub n_reps: usize,
    /// Samples per joint used.
    pub n_samples: usize,
    /// Filter used.
    pub filter: Filter,
    /// Where q̇ and q̈ came from (logged `qd*`/`qdd*` or the positions).
    pub velocity: VelocitySource,
    /// Per joint: RMS of (averaged − filtered) positions and the noise RMS of
    /// the averaged positions ([`Processed::filter_residual`]).
    pub filter_residual: Vec<(f64, Option<f64>)>,
    /// Warnings about the data processing (e.g. motion removed by the filter).
    pub warnings: Vec<String>,
    /// Projection-method details.
    pub projection: Option<closed_loop::ProjectionInfo>,
    /// ML details.
    pub ml: Option<closed_loop::MlInfo>,
    /// Model reduction.
    pub reduction: Option<Reduction>,
    /// Comparison with the truth.
    pub truth: Option<Vec<TruthRow>>,
}

/// An identification with the data behind it (for plots).
#[derive(Debug, Clone)]
pub struct Identification {
    /// The estimate.
    pub estimate: Estimate,
    /// Processed identification data.
    pub processed: Processed,
    /// Its dataset (columns of the estimated parameters).
    pub dataset: Dataset,
    /// Validation dataset, if any.
    pub validation: Option<Dataset>,
}

impl Estimate {
    /// Adds the comparison with true base parameters (names must match the base parameters).
    pub fn compare_truth(&mut self, base_names: &[String], base_truth: &[f64]) -> Result<()> {
        let mut rows = Vec::new();
        for (i, nm) in self.names.iter().enumerate() {
            let k = base_names.iter().position(|x| x == nm).ok_or_else(|| {
                Error::invalid(
                    "truth",
                    "base_names",
                    format!("the truth file has no base parameter {nm:?} (different robot or base-parameter options?)"),
                )
            })?;
            rows.push(TruthRow {
                name: nm.clone(),
                truth: base_truth[k],
                estimate: self.theta[i],
                z: (self.theta[i] - base_truth[k]) / self.std[i],
            });
        }
        self.truth = Some(rows);
        Ok(())
    }
}

impl Identification {
    /// What status.json says of this identification: the estimate's state,
    /// failed when the consistent fit failed, interrupted when `interrupted`.
    pub fn state(&self, interrupted: bool) -> RunState {
        let e = &self.estimate;
        if interrupted {
            RunState::Interrupted
        } else if e.consistent.as_ref().is_some_and(|c| !c.status.is_ok()) {
            RunState::Failed
        } else {
            e.status.state()
        }
    }

    /// Why the result is not usable (None when it is): the words of the
    /// command line's exit-3 message.
    pub fn unusable_reason(&self) -> Option<String> {
        let e = &self.estimate;
        match e.consistent.as_ref().map(|c| &c.status) {
            Some(s) if !s.is_ok() => Some(format!("the consistent fit ended with status `{s}`")),
            _ if e.status.state() == RunState::Failed => Some(format!("the {} estimate ended with status `{}`", e.method.words(), e.status)),
            _ => None,
        }
    }

    /// Writes `status.json` into `dir` (command `identify`) with the state of
    /// [`Identification::state`]; `options` is what the run was asked
    /// (fingerprinted). Returns the state written.
    pub fn write_status(
        &self,
        dir: &std::path::Path,
        started: Option<std::time::SystemTime>,
        options: &serde_json::Value,
        interrupted: bool,
    ) -> Result<RunState> {
        let e = &self.estimate;
        let state = self.state(interrupted);
        let detail = format!("{}: {}", e.method.words(), e.status);
        let summary = serde_json::json!({ "method": e.method, "estimate_status": e.status });
        crate::io::status::write_status(dir, "identify", state, detail, started, crate::io::status::fingerprint_of(options)?, summary)?;
        Ok(state)
    }
}
