//! Relaxed D-optimal design on a random instance: `cargo run --release --example positions_random -- [n] [p] [rank] [sdp]`.
//!
//! Instance: candidate i has F_i = H_i H_iᵀ with H_i (p × r_i), r_i uniform in
//! 1..=rank, Gaussian entries, and parameter j scaled by 10^{u_j}, u_j uniform
//! in [−2, 2] (a badly scaled problem, as real parameter units give).
use idexp::positions::{solve_relaxed, Criterion, Formulation, Problem, SolverOptions};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

fn main() -> idexp::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let p: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(26);
    let rank: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(3);
    let crit = match args.get(4).map(|s| s.as_str()) {
        Some("a") => Criterion::A,
        Some("e") => Criterion::E,
        _ => Criterion::D,
    };
    let sdp = args.get(5).is_some_and(|s| s == "sdp");
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let scale: Vec<f64> = (0..p).map(|_| 10f64.powf(g.random_range(-2.0..2.0))).collect();
    let factors: Vec<DMatrix<f64>> = (0..n)
        .map(|_| {
            let r = g.random_range(1..=rank);
            DMatrix::from_fn(p, r, |i, _| scale[i] * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut g))
        })
        .collect();
    let pb = Problem::from_factors(p, &factors, None)?;
    let mut opts = SolverOptions::default();
    if sdp {
        opts.formulation = Formulation::Sdp;
    }
    if let Some(e) = args.get(6).and_then(|s| s.parse().ok()) {
        opts.first_order_eps = e;
    }
    let t = std::time::Instant::now();
    let r = solve_relaxed(&pb, crit, &opts, &idexp::optim::Control::new())?;
    let support = r.weights.iter().filter(|&&w| w > 1e-6).count();
    println!(
        "n={n} p={p} {crit:?}: value {:.10} status {:?} eff>={:.9} max s {:.8} ref {:.8} support {support} pruned {} fo_iters {} eps {:.2e} rounds {:?} fo {:.3}s clarabel {:.3}s total {:.3}s (wall {:.3}s)",
        r.value,
        r.status,
        r.certificate.efficiency_bound,
        r.certificate.max_sensitivity,
        r.certificate.reference,
        r.log.pruned_to,
        r.log.first_order_iterations,
        r.log.first_order_eps,
        r.log.rounds.iter().map(|x| (x.working_set, x.clarabel_status.clone(), x.iterations, x.added)).collect::<Vec<_>>(),
        r.log.first_order_time,
        r.log.clarabel_time,
        r.log.total_time,
        t.elapsed().as_secs_f64()
    );
    Ok(())
}
