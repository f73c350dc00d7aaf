//! Relaxed D-optimal design for p = 26 with 1,000 and 20,000 candidates (the
//! whole pipeline: scaling, first-order warm start with pruning, Clarabel on
//! the working set, certificate on all candidates).
//!
//! Instance generator (seed 7): candidate i has F_i = H_i H_iᵀ, H_i (26 × r_i),
//! r_i uniform in 1..=3, standard normal entries, and parameter j scaled by
//! 10^{u_j}, u_j ~ U[−2, 2] (badly scaled on purpose).
//!
//! The group `unscaled_reference` solves the unscaled instances that
//! scripts/cvxpy-reference.sh gives CVXPY + Clarabel (benches/common/instances.rs:
//! D-optimal p = 26 with 1,000 candidates, A-optimal p = 8 with 5,000, F_i =
//! J_iᵀJ_i with J_i 3 × p standard normal, no scaling).
//!
//! Run: `cargo bench --bench positions -- --warm-up-time 1 --measurement-time 3`
//! (only those instances: append `unscaled_reference`).

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::positions::{solve_relaxed, Criterion as Crit, Problem, SolverOptions, Status};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::hint::black_box;

#[path = "common/instances.rs"]
mod instances;

fn instance(n: usize, p: usize) -> Problem {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let scale: Vec<f64> = (0..p).map(|_| 10f64.powf(g.random_range(-2.0..2.0))).collect();
    let factors: Vec<DMatrix<f64>> = (0..n)
        .map(|_| {
            let r = g.random_range(1..=3);
            DMatrix::from_fn(p, r, |i, _| scale[i] * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut g))
        })
        .collect();
    Problem::from_factors(p, &factors, None).expect("instance")
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("positions_d_optimal_p26");
    g.sample_size(10);
    for n in [1000usize, 20000] {
        let pb = instance(n, 26);
        let opts = SolverOptions::default();
        let r = solve_relaxed(&pb, Crit::D, &opts, &idexp::optim::Control::new()).expect("solve");
        assert_eq!(r.status, Status::Optimal, "benchmark instance must certify");
        g.bench_function(format!("{n}_candidates"), |b| {
            b.iter(|| black_box(solve_relaxed(&pb, Crit::D, &opts, &idexp::optim::Control::new()).expect("solve")))
        });
    }
    g.finish();
    let mut g = c.benchmark_group("unscaled_reference");
    g.sample_size(10);
    for ((name, seed, n, p), crit) in [(instances::D_INSTANCE, Crit::D), (instances::A_INSTANCE, Crit::A)] {
        let pb = instances::problem(&instances::jacobians(seed, n, p));
        let opts = SolverOptions::default();
        let r = solve_relaxed(&pb, crit, &opts, &idexp::optim::Control::new()).expect("solve");
        assert_eq!(r.status, Status::Optimal, "benchmark instance must certify");
        g.bench_function(name, |b| {
            b.iter(|| black_box(solve_relaxed(&pb, crit, &opts, &idexp::optim::Control::new()).expect("solve")))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
