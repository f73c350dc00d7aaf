//! Identifiability report of a trajectory and the output files of
//! `idexp excite` / `idexp assess`.
//!
//! For samples (q, q̇, q̈)_i, i = 1..N, of any trajectory, C is the stacked
//! base regressor (N·n × m, unweighted) and C_w = W½ C with W½ = diag(1/σ_j)
//! the torque-noise weights. The report gives
//!
//! * the singular values and the condition number of C_w with unit columns,
//!   and the numerical rank (σ_k > 10⁻⁸ σ_1);
//! * the sensitivity of each parameter, c̄_i = ‖c_i‖₁ / (n N) (paper 000 eq. 10);
//! * the covariance of the WLS estimate from the given data with noise
//!   σ_j on joint j, var(θ̂) = (C_wᵀ C_w)⁻¹ (paper 000 eq. 13 with N_f = 1),
//!   the standard deviations σ_i and the relative ones σ*_i = σ_i / |θ_i|
//!   (eq. 14) at the nominal base-parameter values; when C is rank
//!   deficient, those of the model without the non-excited parameters (which
//!   get ∞);
//! * the parameters that are not excited: zero columns, and those with a
//!   component above 0.1 in a right singular vector of the numerical null space.

mod assess;
mod outputs;
mod plots;
mod text;

pub use assess::{assess, assess_delivered, assess_file, column_parameters, read_states, Identifiability, RANK_TOL};
pub use outputs::{
    criterion_sample_set, ident_figure, unit_scale, write_outputs, write_outputs_with, ColumnRecord, CriterionRecord, Figure, SampleSet, Written,
};
pub use text::{collision_text, excite_report_text, excite_text, violation_lines};
