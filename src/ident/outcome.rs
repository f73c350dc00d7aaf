//! Parts of what an identification gives ([`super::Estimate`], written as
//! `estimate.json`): how it ended ([`EstimateStatus`] and the run state of
//! `status.json`), the rows used per joint, implausible values and the
//! comparison with a known truth.

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
