//! [`Control`] (stop flag, budget, observer) in, [`Termination`] out.

use serde::{Serialize, Serializer};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A cloneable stop request shared between the caller and a running task.
///
/// Setting it asks every task holding a clone to finish its current step and
/// return what it has (status [`Termination::Interrupted`]).
#[derive(Debug, Clone, Default)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    /// A new flag, not set.
    pub fn new() -> Self {
        Self::default()
    }
    /// Ask the tasks holding this flag to stop.
    pub fn request(&self) {
        self.0.store(true, Ordering::Relaxed)
    }
    /// True once a stop was requested.
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
    /// Clears the request (to reuse the flag for another task).
    pub fn reset(&self) {
        self.0.store(false, Ordering::Relaxed)
    }
}

/// Receives the progress of a long task. Every method has an empty default,
/// so an observer implements only what it shows. Called from worker threads:
/// implementations must be cheap and thread-safe.
pub trait Observer: Send + Sync {
    /// A phase starts (`name`, e.g. "excite GA"), with its number of steps when known.
    fn phase(&self, _name: &str, _total: Option<u64>) {}
    /// `done` steps of the current phase are finished; `msg` is a short status
    /// (best cost so far, current gap...).
    fn progress(&self, _done: u64, _msg: &str) {}
    /// The current phase ended.
    fn phase_done(&self) {}
    /// A line for the user (a warning or a phase summary).
    fn note(&self, _msg: &str) {}
}

/// The observer that shows nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Observer for Silent {}

/// How a task is run: stop flag, budget (deadline, evaluations) and observer.
///
/// Cheap to clone; clones share the stop flag, the evaluation counter and the
/// observer. A phase that needs a tighter budget takes [`Control::sub`].
#[derive(Clone)]
pub struct Control {
    stop: StopFlag,
    deadline: Option<Instant>,
    max_evals: Option<u64>,
    evals: Arc<AtomicU64>,
    observer: Arc<dyn Observer>,
}

impl Default for Control {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for Control {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Control")
            .field("stop", &self.stop.requested())
            .field("deadline", &self.deadline)
            .field("max_evals", &self.max_evals)
            .field("evals", &self.evaluations())
            .finish()
    }
}

impl Control {
    /// No limits, a fresh stop flag, silent.
    pub fn new() -> Self {
        Control {
            stop: StopFlag::new(),
            deadline: None,
            max_evals: None,
            evals: Arc::new(AtomicU64::new(0)),
            observer: Arc::new(Silent),
        }
    }
    /// Uses `stop` as the stop flag (shared with the caller, e.g. a Ctrl-C handler).
    pub fn with_stop(mut self, stop: StopFlag) -> Self {
        self.stop = stop;
        self
    }
    /// Stops the task `seconds` from now (`None`: no time limit). An earlier
    /// deadline already set is kept.
    pub fn with_time_limit(self, seconds: Option<f64>) -> Self {
        let dl = seconds.map(|s| Instant::now() + Duration::from_secs_f64(s.clamp(0.0, 1e9)));
        self.with_deadline(dl)
    }
    /// Stops the task at `deadline` (`None` keeps the current one). The
    /// earlier of the two deadlines wins.
    pub fn with_deadline(mut self, deadline: Option<Instant>) -> Self {
        self.deadline = match (self.deadline, deadline) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self
    }
    /// Stops the task after `n` counted evaluations (`None`: no limit).
    pub fn with_max_evals(mut self, n: Option<u64>) -> Self {
        self.max_evals = n;
        self
    }
    /// Sends progress to `observer`.
    pub fn with_observer(mut self, observer: Arc<dyn Observer>) -> Self {
        self.observer = observer;
        self
    }
    /// A control for a phase of this task: the same stop flag, observer and
    /// evaluation counter, and a deadline no later than this one.
    pub fn sub(&self, time_limit: Option<f64>) -> Control {
        self.clone().with_time_limit(time_limit)
    }
    /// The observer.
    pub fn observer(&self) -> &dyn Observer {
        &*self.observer
    }
    /// The observer, shared (to hand to another seam, e.g. an argmin observer).
    pub fn observer_arc(&self) -> Arc<dyn Observer> {
        self.observer.clone()
    }
    /// The stop flag.
    pub fn stop_flag(&self) -> &StopFlag {
        &self.stop
    }
    /// The deadline, if any.
    pub fn deadline(&self) -> Option<Instant> {
        self.deadline
    }
    /// The evaluation budget, if any.
    pub fn max_evals(&self) -> Option<u64> {
        self.max_evals
    }
    /// Time left before the deadline (`None`: no deadline).
    pub fn remaining(&self) -> Option<Duration> {
        self.deadline.map(|d| d.saturating_duration_since(Instant::now()))
    }
    /// True once the user asked to stop.
    pub fn interrupted(&self) -> bool {
        self.stop.requested()
    }
    /// Counts `n` evaluations toward the budget.
    pub fn count(&self, n: u64) {
        self.evals.fetch_add(n, Ordering::Relaxed);
    }
    /// Evaluations counted so far (by this control and its clones).
    pub fn evaluations(&self) -> u64 {
        self.evals.load(Ordering::Relaxed)
    }
    /// Why the task must stop now, or `None` to go on. Interruption first,
    /// then the deadline, then the evaluation budget.
    pub fn check(&self) -> Option<Termination> {
        if self.stop.requested() {
            Some(Termination::Interrupted)
        } else if self.deadline.is_some_and(|d| Instant::now() >= d) {
            Some(Termination::TimeLimit)
        } else if self.max_evals.is_some_and(|m| self.evaluations() >= m) {
            Some(Termination::MaxEvaluations)
        } else {
            None
        }
    }
    /// True when [`Control::check`] says stop.
    pub fn should_stop(&self) -> bool {
        self.check().is_some()
    }
}

/// Why a task or a solver ended. Serialised as a snake_case word
/// (`"converged"`, `"interrupted"`, ...; `Failed` as its message).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Termination {
    /// The method's own convergence test passed.
    Converged,
    /// The iteration (generation) budget of the method was used up.
    MaxIterations,
    /// The evaluation budget was used up.
    MaxEvaluations,
    /// The deadline was reached.
    TimeLimit,
    /// The user asked to stop.
    Interrupted,
    /// The solver gave up (numerical trouble); the message says how.
    Failed(String),
}

impl Termination {
    /// The word used in files (`status.json`, reports).
    pub fn as_str(&self) -> &str {
        match self {
            Termination::Converged => "converged",
            Termination::MaxIterations => "max_iterations",
            Termination::MaxEvaluations => "max_evaluations",
            Termination::TimeLimit => "time_limit",
            Termination::Interrupted => "interrupted",
            Termination::Failed(m) => m,
        }
    }
    /// Words for people ("time limit reached").
    pub fn describe(&self) -> String {
        match self {
            Termination::Converged => "converged".into(),
            Termination::MaxIterations => "iteration budget used up".into(),
            Termination::MaxEvaluations => "evaluation budget used up".into(),
            Termination::TimeLimit => "time limit reached".into(),
            Termination::Interrupted => "interrupted by the user".into(),
            Termination::Failed(m) => format!("solver failed: {m}"),
        }
    }
    /// True for a user interruption.
    pub fn is_interrupted(&self) -> bool {
        matches!(self, Termination::Interrupted)
    }
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl Serialize for Termination {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_order_and_budget() {
        let c = Control::new().with_max_evals(Some(3));
        assert_eq!(c.check(), None);
        c.sub(None).count(3);
        assert_eq!(c.check(), Some(Termination::MaxEvaluations));
        let c = c.with_time_limit(Some(0.0));
        assert_eq!(c.check(), Some(Termination::TimeLimit));
        c.stop_flag().request();
        assert_eq!(c.check(), Some(Termination::Interrupted));
    }

    #[test]
    fn earlier_deadline_wins() {
        let c = Control::new().with_time_limit(Some(100.0));
        let d = c.deadline().unwrap();
        let s = c.sub(Some(1000.0));
        assert_eq!(s.deadline(), Some(d));
        let s = c.sub(Some(1.0));
        assert!(s.deadline().unwrap() < d);
    }

    #[test]
    fn two_controls_are_independent() {
        let a = Control::new();
        let b = Control::new();
        a.stop_flag().request();
        assert!(a.interrupted() && !b.interrupted());
    }
}
