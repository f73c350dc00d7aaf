//! Excitation design benchmarks on the UR5 speed case
//! (designs/excite_ur5_bench.toml: UR5, q0 = 0, 5 harmonics of 0.1 Hz, 60
//! coefficients, 48 unit-column base columns sampled at 10 Hz, position and
//! velocity limits).
//!
//! First the whole design is run once with its 10 s wall-clock budget and the
//! condition number reached and the wall time are printed; then the
//! like-for-like variant (designs/excite_ur5_bench_pi.toml: the Python
//! reference's ±π ranges and base set, 10 s) for seeds 1–5, each condition
//! number printed against the reference's 4.47 (skip both with
//! `IDEXP_BENCH_DESIGN=0`, the seeds alone with `IDEXP_BENCH_SEEDS=0`); then
//! criterion measures the kernels (single
//! threaded except the gradient's per-sample work, which uses the rayon pool):
//! the criterion alone, the criterion with its analytic gradient, the
//! constraints with their Jacobian, one GA evaluation (repair + criterion +
//! constraints), and the epigraph refinement's eigenvalue bundle (`bundle =
//! 2`: the 2 largest and 2 smallest eigenvalues) with their gradients and
//! without (SLSQP's line search asks for values alone).
//!
//! Run: `cargo bench --bench excitation -- --warm-up-time 1 --measurement-time 3`.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::{run, Problem};
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use std::path::Path;

fn problem() -> Problem {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    Problem::from_file(&root.join("designs/excite_ur5_bench.toml")).expect("bench design")
}

fn design_run() {
    if std::env::var("IDEXP_BENCH_DESIGN").is_ok_and(|v| v == "0") {
        return;
    }
    let p = problem();
    let r = run(&p, &idexp::optim::Control::new()).expect("bench design run");
    println!(
        "excite_ur5_bench: {:?}, cond {:.4} in {:.2} s wall on {} threads (GA {} generations / {} evaluations in {:.2} s; chosen {})",
        r.status, r.spectrum.cond, r.seconds, r.threads, r.ga.generations, r.ga.evaluations, r.ga.seconds, r.chosen
    );
    for (k, rf) in r.refinements.iter().enumerate() {
        println!(
            "  refine #{}: {:.4} -> {:.4}, {} evaluations, {:.2} s, {}",
            k + 1,
            rf.start,
            rf.end,
            rf.evaluations,
            rf.seconds,
            rf.status
        );
    }
}

/// The reference's condition number (scipy SLSQP, 20 starts, 210 s) on the
/// like-for-like problem.
const PYTHON_REFERENCE_COND: f64 = 4.47;

fn seeds_run() {
    if std::env::var("IDEXP_BENCH_DESIGN").is_ok_and(|v| v == "0") || std::env::var("IDEXP_BENCH_SEEDS").is_ok_and(|v| v == "0") {
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let path = root.join("designs/excite_ur5_bench_pi.toml");
    let mut worst = 0.0f64;
    for seed in 1..=5u64 {
        let mut d = ExciteDesign::load(&path).expect("bench_pi design");
        d.seed = seed;
        let robot = idexp::robot::load(&d.robot).expect("bench_pi robot");
        let p = Problem::new(d, robot, &path.display().to_string()).expect("bench_pi problem");
        let r = run(&p, &idexp::optim::Control::new()).expect("bench_pi run");
        worst = worst.max(r.spectrum.cond);
        println!(
            "excite_ur5_bench_pi seed {seed}: {:?}, cond {:.4} in {:.2} s wall ({} GA evaluations, {} refinement evaluations){}",
            r.status,
            r.spectrum.cond,
            r.seconds,
            r.ga.evaluations,
            r.refinements.iter().map(|rf| rf.evaluations).sum::<u64>(),
            if r.spectrum.cond <= PYTHON_REFERENCE_COND {
                ""
            } else {
                "  ABOVE the reference's 4.47"
            }
        );
    }
    println!("excite_ur5_bench_pi seeds 1-5: worst cond {worst:.4} (reference {PYTHON_REFERENCE_COND})");
}

fn bench(c: &mut Criterion) {
    design_run();
    seeds_run();
    let p = problem();
    let nv = idexp::trajectory::TrajectoryShape::n_vars(&p.shape);
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut x: Vec<f64> = (0..nv).map(|i| g.random_range(p.lower[i]..p.upper[i]) * 0.5).collect();
    p.constraints.repair_joints(&mut x, &p.limits, 1e-6);
    let mut ow = p.objective.workspace();
    let mut cw = p.constraints.workspace();
    let mut grad = vec![0.0; nv];
    let mut cval = vec![0.0; p.constraints.len()];
    let mut jac = vec![0.0; p.constraints.len() * nv];
    let mut grp = c.benchmark_group("excite_ur5_bench");
    grp.bench_function("criterion", |b| b.iter(|| black_box(p.objective.value(black_box(&x), &mut ow))));
    grp.bench_function("criterion_and_gradient", |b| {
        b.iter(|| black_box(p.objective.value_grad(black_box(&x), &mut ow, &mut grad)))
    });
    grp.bench_function("constraints_and_jacobian", |b| {
        b.iter(|| {
            p.constraints.eval(black_box(&x), &mut cw, &mut cval, Some(&mut jac));
            black_box(&jac);
        })
    });
    let mut cbuf = Vec::new();
    grp.bench_function("ga_evaluation", |b| {
        b.iter(|| {
            let mut y = x.clone();
            black_box(p.evaluate(&mut y, &mut ow, &mut cw, &mut cbuf))
        })
    });
    let mut vals = vec![0.0; 4];
    let mut bgrads = vec![0.0; 4 * nv];
    grp.bench_function("eigen_bundle_2_with_gradients", |b| {
        b.iter(|| black_box(p.objective.log_eigen_bundle(black_box(&x), &mut ow, 2, 2, &mut vals, Some(&mut bgrads))))
    });
    grp.bench_function("eigen_bundle_2_values", |b| {
        b.iter(|| black_box(p.objective.log_eigen_bundle(black_box(&x), &mut ow, 2, 2, &mut vals, None)))
    });
    grp.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
