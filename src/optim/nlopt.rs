//! The nlopt bridge: nlopt's result as a status word, mapped to [`Termination`].
//!
//! nlopt's algorithms (SLSQP, MMA, L-BFGS) run their own loop inside C, so
//! they cannot be argmin solvers: argmin's `Executor` drives a solver one
//! `next_iter` at a time, while `nlopt_optimize` returns only at the end.
//! The seam is therefore the callbacks: the objective and constraint
//! callbacks of every nlopt stage ask the [`super::Control`] at each
//! evaluation and, when it says stop, return a zero gradient (and the
//! current value), so that nlopt ends at its next step; the deadline of the
//! control is also handed to nlopt as `maxtime`. The nlopt result is kept as
//! [`NloptStatus`] (serialised as nlopt's own word, e.g. `FtolReached`).

use super::Termination;
use serde::{Serialize, Serializer};

/// The result of one nlopt run (nlopt's success and failure codes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NloptStatus {
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

impl NloptStatus {
    /// From nlopt's `optimize` result.
    pub fn of<T>(r: &Result<(nlopt::SuccessState, T), (nlopt::FailState, T)>) -> NloptStatus {
        use nlopt::{FailState as F, SuccessState as S};
        match r {
            Ok((S::Success, _)) => NloptStatus::Success,
            Ok((S::StopValReached, _)) => NloptStatus::StopValReached,
            Ok((S::FtolReached, _)) => NloptStatus::FtolReached,
            Ok((S::XtolReached, _)) => NloptStatus::XtolReached,
            Ok((S::MaxEvalReached, _)) => NloptStatus::MaxEvalReached,
            Ok((S::MaxTimeReached, _)) => NloptStatus::MaxTimeReached,
            Err((F::Failure, _)) => NloptStatus::Failure,
            Err((F::InvalidArgs, _)) => NloptStatus::InvalidArgs,
            Err((F::OutOfMemory, _)) => NloptStatus::OutOfMemory,
            Err((F::RoundoffLimited, _)) => NloptStatus::RoundoffLimited,
            Err((F::ForcedStop, _)) => NloptStatus::ForcedStop,
        }
    }
    /// nlopt's word (`FtolReached`, ...), as written in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            NloptStatus::Success => "Success",
            NloptStatus::StopValReached => "StopValReached",
            NloptStatus::FtolReached => "FtolReached",
            NloptStatus::XtolReached => "XtolReached",
            NloptStatus::MaxEvalReached => "MaxEvalReached",
            NloptStatus::MaxTimeReached => "MaxTimeReached",
            NloptStatus::Failure => "Failure",
            NloptStatus::InvalidArgs => "InvalidArgs",
            NloptStatus::OutOfMemory => "OutOfMemory",
            NloptStatus::RoundoffLimited => "RoundoffLimited",
            NloptStatus::ForcedStop => "ForcedStop",
        }
    }
    /// The run-control word (a stop through the control shows as an early
    /// end of nlopt; the caller knows whether the control asked for it).
    pub fn termination(self) -> Termination {
        match self {
            NloptStatus::Success | NloptStatus::StopValReached | NloptStatus::FtolReached | NloptStatus::XtolReached => Termination::Converged,
            NloptStatus::MaxEvalReached => Termination::MaxEvaluations,
            NloptStatus::MaxTimeReached => Termination::TimeLimit,
            NloptStatus::ForcedStop => Termination::Interrupted,
            s => Termination::Failed(s.as_str().to_string()),
        }
    }
}

impl std::fmt::Display for NloptStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for NloptStatus {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_match_nlopts_debug_names() {
        let r: Result<(nlopt::SuccessState, f64), (nlopt::FailState, f64)> = Ok((nlopt::SuccessState::FtolReached, 0.0));
        assert_eq!(NloptStatus::of(&r).as_str(), format!("{:?}", nlopt::SuccessState::FtolReached));
        let r: Result<(nlopt::SuccessState, f64), (nlopt::FailState, f64)> = Err((nlopt::FailState::RoundoffLimited, 0.0));
        assert_eq!(NloptStatus::of(&r).as_str(), format!("{:?}", nlopt::FailState::RoundoffLimited));
        assert_eq!(serde_json::to_string(&NloptStatus::MaxEvalReached).unwrap(), "\"MaxEvalReached\"");
        assert_eq!(NloptStatus::MaxTimeReached.termination(), Termination::TimeLimit);
    }
}
