//! The optimisation and run-control seam.
//!
//! Every long task of idexp (excitation search and refinement, multistart
//! fits, the first-order and conic phases of position design, maximum
//! likelihood, model reduction, simulation) takes a [`Control`]: a stop flag
//! that the caller may set at any time (the command line sets it on Ctrl-C),
//! a budget (deadline, maximum number of evaluations) and an [`Observer`]
//! that receives progress (the command line draws progress bars with it; the
//! library itself never prints). The task answers with a [`Termination`]
//! inside its result: why it ended, in words a user reads.
//!
//! There is no process-wide state: two tasks with two controls run
//! independently, in one process, on any threads.

mod control;
pub mod ga;
pub mod lm;
pub mod nlopt;

pub use control::{Control, Observer, Silent, StopFlag, Termination};
