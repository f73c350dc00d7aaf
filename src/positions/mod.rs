//! Optimal measurement positions: convex relaxed experiment design (paper 001
//! §5.2, after Wernholt & Löfberg 2007).
//!
//! From Q_c candidate configurations with information matrices F_i (the
//! information one experiment at configuration i gives about the p
//! parameters), choose how many of M experiments to run at each: m_i ≥ 0
//! integers, Σ m_i = M, maximising an information criterion of
//! F_0 + Σ m_i F_i. Relaxing w_i = m_i/M to real weights on the simplex makes
//! the problem convex ([`relax`]); only a few candidates end with nonzero
//! weight, and the relaxed optimum is rounded back to whole experiments
//! ([`rounding`]).
//!
//! * [`problem`]: the factored problem F_i = H_i H_iᵀ and the criteria D, A, E.
//! * [`firstorder`]: multiplicative and Frank–Wolfe-with-away-steps methods,
//!   and the equivalence-theorem pruning bound.
//! * [`conic`]: the Clarabel formulations (SOCP for D and A, SDP for E and as
//!   a D cross-check).
//! * [`relax`]: the pipeline and the Kiefer–Wolfowitz certificate.
//! * [`rounding`]: efficient rounding and exchange to whole experiments.
//! * [`information`]: information sources (rigid local excitation, JSON file).
//! * [`elastic`]: the elastic gray-box model's FRF information (paper 001 eq. 5).
//! * [`candidates`]: grids, random samples, CSV files, workspace filtering.
//! * [`design`]: the design file and [`design::run_design`]; [`output`]: the
//!   output folder of `idexp positions` (plan, reports, figures).
pub mod candidates;
pub mod conic;
pub mod design;
pub mod elastic;
pub mod firstorder;
pub mod information;
pub mod output;
pub mod problem;
pub mod relax;
pub mod rounding;

pub use conic::Formulation;
pub use design::{run_design, PositionsDesign, PositionsRun};
pub use elastic::{ElasticScale, ElasticSource};
pub use information::{InformationFile, InformationSource, RigidSource};
pub use problem::{Criterion, Problem};
pub use relax::{certify, solve_relaxed, Certificate, Relaxed, SolverOptions, Status};
pub use rounding::{efficient_rounding, round_design, Rounded};
