//! Identification from measured runs (paper 000 §II-B, §III-C, §III-D, §IV;
//! paper 002 §2.2, §3.2–3.5).
//!
//! One engine: the [`study`] ([`study::run_study`]). A study design names the
//! experiments and validation runs (files, or data given in memory), how each
//! is processed and the estimator; the one-run command line and Python's
//! keyword `identify` build a design of one experiment. Each entry is read
//! ([`Run`]), averaged and filtered ([`process()`]: Fourier filtering with
//! analytic derivatives for Fourier references, else zero-phase low-pass and
//! central differences) and stacked into the base-parameter regressor
//! ([`estimate::Dataset`], `prepare.rs`); the estimate is the weighted (or
//! ordinary) least squares of every experiment stacked ([`study::stack`],
//! paper 000 eq. 5, 8–9), or on one experiment the projection method or
//! maximum likelihood ([`closed_loop`], paper 002 eq. 10–16) or the
//! sensitivity-based model reduction ([`reduce`], Algorithm 1); with
//! covariances and relative standard deviations (eq. 13–14), prediction
//! errors e_j, e*_j (eq. 11–12), condition numbers, plausibility flags and
//! the physically consistent estimate with a prior ([`consistent`],
//! [`prior`]). The dedicated gravity and friction fits of paper 002 §3.2
//! ([`experiments`]) are a study too: one whose every experiment names its
//! joint ([`study::run_dedicated`]).
//!
//! Files: `options.rs` ([`Method`], [`Standstill`]), `prepare.rs` (one
//! entry made ready for estimation as its study entry says), `outcome.rs`
//! ([`EstimateStatus`], rows used, flags), [`output`] (plots and tables);
//! the estimators in [`estimate`], [`closed_loop`], [`reduce`],
//! [`consistent`], [`prior`], [`study`]. The signal processing they start
//! from is the data layer's ([`process()`], `src/data/process.rs`). Their
//! items are re-exported here: `idexp::ident::X` is the path to use.

pub mod closed_loop;
pub mod consistent;
pub mod estimate;
pub mod experiments;
mod options;
mod outcome;
pub mod output;
mod prepare;
pub mod prior;
pub mod reduce;
pub mod study;

pub use crate::data::process::{self, process, process_with, Filter, Processed, VelocityFrom, VelocitySource};
pub use crate::data::{Coordinates, Repetition, Run, TorqueFrom, TorqueSource, CURRENT_TOLERANCE};
pub use closed_loop::{MlOptions, ProjectionOptions};
pub use consistent::ConsistentStatus;
pub use estimate::{Dataset, Errors, LsFit, Weights, DEAD_BAND};
pub use reduce::{Essential, ReduceOptions, Reduction};

pub use options::{Method, Standstill};
pub use outcome::{EstimateStatus, Implausible, RowsUsed, TruthRow};
pub(crate) use prepare::filter_warnings;
pub use prepare::{fourier_filter, in_joint_coordinates, prepare, run_trajectory, Prepared};
pub use study::Estimate;
