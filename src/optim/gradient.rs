//! idexp's word for how a gradient-based local optimisation ended.

use super::Termination;
use serde::{Serialize, Serializer};

/// How a gradient-based local optimisation ended (the excitation
/// refinement's SLSQP/MMA stages, the L-BFGS of maximum likelihood).
/// The variants and their words are nlopt's result codes (`FtolReached`,
/// `MaxEvalReached`, `ForcedStop`, ...), as written in estimate.json and
/// the excitation reports; the bridge [`super::nlopt`] maps nlopt's result
/// to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GradientStatus {
    /// Generic success.
    Success,
    /// The objective reached `stopval`.
    StopValReached,
    /// Relative or absolute objective tolerance reached.
    FtolReached,
    /// Relative or absolute x tolerance reached.
    XtolReached,
    /// Evaluation budget used up.
    MaxEvalReached,
    /// Time budget used up.
    MaxTimeReached,
    /// Generic failure.
    Failure,
    /// Invalid arguments.
    InvalidArgs,
    /// Out of memory.
    OutOfMemory,
    /// Round-off errors stopped progress.
    RoundoffLimited,
    /// A callback forced the stop.
    ForcedStop,
}

impl GradientStatus {
    /// The word written in reports (`FtolReached`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            GradientStatus::Success => "Success",
            GradientStatus::StopValReached => "StopValReached",
            GradientStatus::FtolReached => "FtolReached",
            GradientStatus::XtolReached => "XtolReached",
            GradientStatus::MaxEvalReached => "MaxEvalReached",
            GradientStatus::MaxTimeReached => "MaxTimeReached",
            GradientStatus::Failure => "Failure",
            GradientStatus::InvalidArgs => "InvalidArgs",
            GradientStatus::OutOfMemory => "OutOfMemory",
            GradientStatus::RoundoffLimited => "RoundoffLimited",
            GradientStatus::ForcedStop => "ForcedStop",
        }
    }
    /// The run-control word (a stop through the control shows as an early
    /// end of the optimiser; the caller knows whether the control asked for it).
    pub fn termination(self) -> Termination {
        match self {
            GradientStatus::Success | GradientStatus::StopValReached | GradientStatus::FtolReached | GradientStatus::XtolReached => Termination::Converged,
            GradientStatus::MaxEvalReached => Termination::MaxEvaluations,
            GradientStatus::MaxTimeReached => Termination::TimeLimit,
            GradientStatus::ForcedStop => Termination::Interrupted,
            s => Termination::Failed(s.as_str().to_string()),
        }
    }
}

impl std::fmt::Display for GradientStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for GradientStatus {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}
