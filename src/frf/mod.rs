//! Frequency-domain identification of elastic robots (paper 001 §4–§6):
//! odd random-phase orthogonal multisines ([`multisine`]), nonparametric FRF
//! estimates G = Y U⁻¹ averaged over blocks and periods with their covariance
//! and an even-line nonlinearity flag ([`estimate`]), simulated measurements
//! with known parameters ([`simulate`]), weighted NLS / log-LS fits by
//! Levenberg–Marquardt ([`fit`]), multistart with JSON Lines logs, resume,
//! shards and merge ([`multistart`]), and the report ([`report`]).
//!
//! The commands `idexp multisine`, `idexp frf`, `idexp fit`, `idexp merge`
//! are thin wrappers over [`pipeline::multisine`], [`pipeline::frf`],
//! [`pipeline::fit`], [`pipeline::merge`].

pub mod design;
pub mod estimate;
pub mod fit;
pub mod kernel;
pub mod multisine;
pub mod multistart;
pub mod pipeline;
pub mod report;
pub mod simulate;

pub use design::{Design, FitSpec, MultisineSpec, SimMethod, SimulateSpec, WeightKind};
pub use estimate::{FrfData, FrfPosition};
pub use fit::{FitOutcome, FitProblem, FitStatus};
pub use multistart::{Shard, StartRecord};
