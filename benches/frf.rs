//! FRF fitting kernels on the shipped 6-axis, 26-unknown design
//! (designs/elastic_industrial6.toml: 5 positions × 74 lines, n = 6, N = 19):
//! one FRF + Jacobian evaluation at one line (the elastic module's kernel and
//! the fit's kernel, idexp::frf::kernel), the LLS cost, and the cost with
//! gradient and Gauss–Newton matrix (one LM iteration's Jacobian pass).
//!
//! `cargo bench --bench frf -- --warm-up-time 1 --measurement-time 3`

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::elastic::{Estimator, FrfKernel, Output};
use idexp::frf::{design::WeightKind, fit, simulate, Design};
use std::hint::black_box;
use std::path::Path;

fn bench(c: &mut Criterion) {
    let (d, m) = Design::load(Path::new("designs/elastic_industrial6.toml")).expect("design");
    let tmp = tempfile::tempdir().expect("tempdir");
    let (data, truth) = simulate::simulate(&d, &m, tmp.path(), &idexp::optim::Control::new()).expect("simulate");
    let theta: Vec<f64> = truth.theta.iter().map(|t| t * 1.05).collect();
    let w = fit::weights(&d, &data, Estimator::Lls, WeightKind::User).expect("weights");
    let prob = fit::FitProblem::new(&m, &data, Estimator::Lls, w).expect("problem");
    let vals = m.full_values(&theta).expect("vals");
    let op = m.operating_point(&d.positions[0], &vals).expect("op");
    let lin = m.linear_model(&op, &vals);
    let ker = FrfKernel::new(&m);
    let mut dg = Vec::new();
    let mut g = c.benchmark_group("frf");
    g.bench_function("frf_and_jacobian_one_line_26_params", |b| {
        b.iter(|| {
            black_box(
                ker.eval(&lin, &op, 2.0 * std::f64::consts::PI * 37.0, Output::Acceleration, true, &mut dg)
                    .expect("eval"),
            )
        })
    });
    let fk = idexp::frf::kernel::FitKernel::new(&m, Output::Acceleration);
    let sys = fk.system(&lin, &op).expect("system");
    let mut sc = idexp::frf::kernel::Scratch::default();
    let mut wbuf = vec![idexp::elastic::C64::new(0.0, 0.0); fk.w_len(&sys)];
    let mut gbuf = vec![idexp::elastic::C64::new(0.0, 0.0); 36];
    let mut lj = idexp::frf::kernel::LineJac::default();
    g.bench_function("fit_kernel_solve_frf_jacobian_one_line_26_params", |b| {
        b.iter(|| {
            let w = 2.0 * std::f64::consts::PI * 37.0;
            sys.solve(w, &mut sc, &mut wbuf).expect("solve");
            fk.frf(&sys, w, &wbuf, &mut gbuf, Some(&mut lj));
            black_box(lj.dg(3, 1, 2))
        })
    });
    g.bench_function("lls_cost_5pos_74lines", |b| b.iter(|| black_box(prob.cost(&theta).expect("cost"))));
    g.bench_function("lls_cost_gradient_gn_5pos_74lines", |b| {
        b.iter(|| black_box(prob.normal_equations(&theta, true).expect("ne")))
    });
    // one accepted LM step: the cost at the trial point, then the normal
    // equations there reusing its line solves
    let mut cache = idexp::frf::kernel::SolveCache::default();
    g.bench_function("lls_accepted_step_cost_then_gn_5pos_74lines", |b| {
        b.iter(|| {
            cache = Default::default();
            let v = prob.cost_cached(&theta, &mut cache).expect("cost");
            black_box((v, prob.normal_equations_cached(&theta, true, &mut cache).expect("ne")))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
