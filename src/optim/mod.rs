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
//! This module owns the external solvers' vocabulary: nlopt and Clarabel are
//! named only here (their bridges [`nlopt`] and [`conic`]); the rest of idexp
//! builds [`conic::Cone`]s and reads [`conic::ConicStatus`] and
//! [`GradientStatus`], idexp's own types, which the bridges map to and from
//! the crates' (`tests/module_graph.rs` holds this for `src/`, the command
//! line and the Python bindings).
//!
//! There is no process-wide state: two tasks with two controls run
//! independently, in one process, on any threads.
//!
//! ## Which loops are argmin solvers, and why the others are not
//!
//! argmin's `Solver`/`Executor` is the project's model for an iterative
//! method: the GA ([`ga`]) and Levenberg–Marquardt ([`lm`]) are argmin
//! solvers run by argmin's `Executor`; their `terminate` asks the
//! [`Control`], argmin's `TerminationReason` maps to [`Termination`] (or to
//! the method's own status enum), and [`ga::ArgminProgress`] is an argmin
//! observer that forwards iterations to the control's [`Observer`].
//! argmin's seam does not fit these, which use [`Control`] directly:
//!
//! - **nlopt** (excitation refinement, the ML L-BFGS of closed-loop
//!   identification; [`nlopt`]): `nlopt_optimize` runs its whole loop in C
//!   and returns once, so there is no `next_iter` to hand to an executor; the
//!   objective/constraint callbacks poll the control and end the run. The ML
//!   stage is nlopt's L-BFGS with box bounds (a trust region), not a plain
//!   unconstrained L-BFGS, so argmin's `LBFGS` would change its iterates.
//! - **Clarabel** (the conic phase of position design, the physically
//!   consistent identification; [`conic`]): the interior-point loop is
//!   inside Clarabel; its termination callback returns true when the
//!   control's stop flag is set (status `CallbackTerminated`), and the
//!   control's deadline tightens Clarabel's own time limit.
//! - **Multistart** and **simulation**: many independent runs on rayon's
//!   pool (multistart: one LM executor per start) or one time-stepping loop,
//!   neither an iteration of one optimiser; they poll the control between
//!   starts / every few controller periods.
//! - **First-order design methods and model reduction**: short deterministic
//!   loops whose every step is one closed-form update; they poll the control
//!   at every iteration.

pub mod conic;
mod control;
pub mod ga;
mod gradient;
pub mod lm;
pub mod nlopt;

pub use control::{Control, Observer, Silent, StopFlag, Termination};
pub use gradient::GradientStatus;
