//! Identification from measured runs (paper 000 §II-B, §III-C, §III-D, §IV;
//! paper 002 §2.2, §3.2–3.5).
//!
//! Pipeline ([`identify`]): read the repetitions ([`Run`]), average them and
//! filter the positions ([`process()`]: Fourier filtering with analytic
//! derivatives for Fourier references, else zero-phase low-pass and central
//! differences), stack the base-parameter regressor ([`estimate::Dataset`]),
//! estimate by OLS, WLS (paper 000 eq. 5, 8–9), the projection method or
//! maximum likelihood ([`closed_loop`], paper 002 eq. 10–16), with covariances
//! and relative standard deviations (eq. 13–14), prediction errors e_j, e*_j
//! on the identification and a validation run (eq. 11–12), the condition
//! number, physical-plausibility flags, and optionally the sensitivity-based
//! model reduction ([`reduce`], Algorithm 1). The dedicated gravity and
//! friction experiments of paper 002 §3.2 are in [`experiments`].
//!
//! Files: `options.rs` (what is asked: [`Method`], [`IdentOptions`]),
//! `prepare.rs` (one run made ready for estimation, shared with the
//! [`study`]), `pipeline.rs` (the one-run pipeline [`identify`]),
//! `outcome.rs` (what it gives: [`Estimate`], [`EstimateStatus`],
//! [`Identification`] and its run state), `text.rs` (`report.txt`),
//! [`output`] (the writers); the estimators and their parts in [`estimate`],
//! [`closed_loop`], [`reduce`], [`consistent`], [`prior`]. Their items are
//! re-exported here: `idexp::ident::X` is the path to use.

pub mod closed_loop;
pub mod consistent;
pub mod estimate;
pub mod experiments;
mod options;
mod outcome;
pub mod output;
mod prepare;
pub mod prior;
pub mod process;
pub mod reduce;
pub mod study;
mod text;

pub use crate::data::{Coordinates, Repetition, Run, TorqueFrom, TorqueSource, CURRENT_TOLERANCE};
pub use closed_loop::{MlOptions, ProjectionOptions};
pub use consistent::{ConsistentOptions, ConsistentStatus};
pub use estimate::{Dataset, Errors, LsFit, Weights, DEAD_BAND};
pub use process::{process, process_with, Filter, Processed, VelocityFrom, VelocitySource};
pub use reduce::{Essential, ReduceOptions, Reduction};

pub use options::{FilterChoice, IdentOptions, Method, Standstill};
pub use outcome::{EstimateStatus, Implausible, RowsUsed, TruthRow};
pub(crate) use prepare::filter_warnings;
pub use prepare::{in_joint_coordinates, prepare, resolve_filter, run_trajectory, Prepared};
pub use study::Estimate;
pub(crate) use text::{parameter_table, plausibility_and_truth_text};
