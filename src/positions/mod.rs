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
pub mod conic;
pub mod firstorder;
pub mod problem;
pub mod relax;

pub use conic::Formulation;
pub use problem::{Criterion, Problem};
pub use relax::{certify, solve_relaxed, Certificate, Relaxed, SolverOptions, Status};
