//! The unscaled random reference instances, shared by
//! `benches/positions.rs` and `examples/positions_reference.rs` (which writes
//! them to files for scripts/cvxpy-reference.sh, so CVXPY solves the very same
//! numbers): candidate i has F_i = J_iᵀJ_i with J_i (3 × p) standard normal
//! entries, drawn from ChaCha8 seeded with `seed`, candidate after candidate,
//! row after row.

use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Relaxed D-optimal reference instance: p = 26, 1,000 candidates.
pub const D_INSTANCE: (&str, u64, usize, usize) = ("d_1000x26", 1, 1000, 26);
/// Relaxed A-optimal reference instance: p = 8, 5,000 candidates.
pub const A_INSTANCE: (&str, u64, usize, usize) = ("a_5000x8", 2, 5000, 8);

/// The Jacobians J_i (3 × p) of `n` candidates.
pub fn jacobians(seed: u64, n: usize, p: usize) -> Vec<DMatrix<f64>> {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let mut j = DMatrix::zeros(3, p);
            for r in 0..3 {
                for c in 0..p {
                    j[(r, c)] = <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut g);
                }
            }
            j
        })
        .collect()
}

/// The problem of those Jacobians (factors H_i = J_iᵀ).
pub fn problem(js: &[DMatrix<f64>]) -> idexp::positions::Problem {
    let p = js[0].ncols();
    let factors: Vec<DMatrix<f64>> = js.iter().map(|j| j.transpose()).collect();
    idexp::positions::Problem::from_factors(p, &factors, None).expect("instance")
}
