//! Relaxed designs on random instances against an independent reference.
//!
//! Instances: candidate i has F_i = H_i H_iᵀ with H_i (p × r_i), r_i uniform in
//! 1..=rank, standard normal entries, and parameter j scaled by 10^{u_j},
//! u_j ~ U[−s, s] (badly scaled on purpose). The reference is written here from
//! scratch on the dense matrices: Frank–Wolfe with away steps and a bisection
//! line search (D: on tr((M + αE)⁻¹E), A: on −tr(M_α⁻¹ E M_α⁻¹)), run until its
//! own Frank–Wolfe gap certifies 1e-9 relative accuracy. E is checked by weak
//! duality with the returned Z: λ_min(M(w)) ≤ λ* ≤ max_i tr(Z F_i) + tr(Z F_0).

use approx::assert_relative_eq;
use idexp::positions::{solve_relaxed, Criterion, Formulation, Problem, SolverOptions, Status};
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

fn instance(n: usize, p: usize, rank: usize, spread: f64, seed: u64) -> (Vec<DMatrix<f64>>, Vec<DMatrix<f64>>) {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let scale: Vec<f64> = (0..p).map(|_| 10f64.powf(g.random_range(-spread..=spread))).collect();
    let h: Vec<DMatrix<f64>> = (0..n)
        .map(|_| {
            let r = g.random_range(1..=rank);
            DMatrix::from_fn(p, r, |i, _| scale[i] * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut g))
        })
        .collect();
    let f = h.iter().map(|h| h * h.transpose()).collect();
    (h, f)
}

fn info(f: &[DMatrix<f64>], f0: Option<&DMatrix<f64>>, w: &[f64]) -> DMatrix<f64> {
    let p = f[0].nrows();
    let mut m = f0.cloned().unwrap_or_else(|| DMatrix::zeros(p, p));
    for (fi, wi) in f.iter().zip(w) {
        m += fi * *wi;
    }
    m
}

fn logdet(m: &DMatrix<f64>) -> Option<f64> {
    m.clone().cholesky().map(|c| 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>())
}

/// Reference D or A solver: Frank–Wolfe with away steps on dense F_i.
/// Returns the criterion value (D: log det, A: tr M⁻¹) and the final FW gap.
fn reference(f: &[DMatrix<f64>], f0: Option<&DMatrix<f64>>, a_opt: bool, rel_gap: f64, max_iter: usize) -> (f64, f64) {
    let (v, gap, _) = reference_w(f, f0, a_opt, rel_gap, max_iter);
    (v, gap)
}

fn reference_w(f: &[DMatrix<f64>], f0: Option<&DMatrix<f64>>, a_opt: bool, rel_gap: f64, max_iter: usize) -> (f64, f64, Vec<f64>) {
    let n = f.len();
    let mut w = vec![1.0 / n as f64; n];
    let mut gap = f64::INFINITY;
    for _ in 0..max_iter {
        let m = info(f, f0, &w);
        let minv = m.clone().cholesky().expect("reference: singular").inverse();
        // sensitivities: gradient of log det (D) or of −tr M⁻¹ (A)
        let x = if a_opt { &minv * &minv } else { minv.clone() };
        let s: Vec<f64> = f.iter().map(|fi| x.component_mul(fi).sum()).collect();
        let mean: f64 = w.iter().zip(&s).map(|(a, b)| a * b).sum();
        let (j, smax) = s.iter().enumerate().fold((0, f64::NEG_INFINITY), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
        let (k, smin) = s
            .iter()
            .enumerate()
            .filter(|(i, _)| w[*i] > 0.0)
            .fold((usize::MAX, f64::INFINITY), |b, (i, &v)| if v < b.1 { (i, v) } else { b });
        gap = smax - mean;
        let value = if a_opt { minv.trace() } else { logdet(&m).unwrap() };
        if gap <= rel_gap * value.abs().max(1.0) {
            break;
        }
        let nmat = match f0 {
            Some(f0) => &m - f0,
            None => m.clone(),
        };
        let toward = smax - mean >= mean - smin || k == usize::MAX;
        let (e, amax) = if toward { (&f[j] - &nmat, 1.0) } else { (&nmat - &f[k], w[k] / (1.0 - w[k])) };
        let dphi = |a: f64| -> Option<f64> {
            let ma = &m + &e * a;
            let inv = ma.cholesky()?.inverse();
            Some(if a_opt { (&inv * &e * &inv).trace() } else { inv.component_mul(&e).sum() })
        };
        let (mut lo, mut hi) = (0.0, amax);
        if dphi(hi).is_some_and(|d| d >= 0.0) {
            lo = hi;
        } else {
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                match dphi(mid) {
                    Some(d) if d > 0.0 => lo = mid,
                    _ => hi = mid,
                }
            }
        }
        let a = lo;
        if toward {
            w.iter_mut().for_each(|v| *v *= 1.0 - a);
            w[j] += a;
        } else {
            w.iter_mut().for_each(|v| *v *= 1.0 + a);
            w[k] -= a;
            if a >= amax * (1.0 - 1e-12) {
                w[k] = 0.0;
            }
        }
    }
    let m = info(f, f0, &w);
    let v = if a_opt {
        m.cholesky().unwrap().inverse().trace()
    } else {
        logdet(&m).unwrap()
    };
    (v, gap, w)
}

fn check_d(n: usize, p: usize, rank: usize, seed: u64, with_prior: bool) {
    let (h, f) = instance(n, p, rank, 1.5, seed);
    let f0 = with_prior.then(|| {
        let (_, g) = instance(1, p, 3, 1.5, seed + 100);
        g[0].clone() * 0.2
    });
    let pb = Problem::from_factors(p, &h, f0.as_ref()).unwrap();
    let r = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    assert_eq!(r.status, Status::Optimal, "n={n} p={p}: {:?}", r.certificate);
    // the value reported is log det M(w) of the reported weights
    let w = &r.weights;
    assert!(w.iter().all(|&v| v >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let m = info(&f, f0.as_ref(), w);
    let v = logdet(&m).unwrap();
    assert_relative_eq!(r.value, v, epsilon = 1e-9, max_relative = 1e-9);
    // Kiefer–Wolfowitz on every candidate, recomputed here
    let minv = m.clone().cholesky().unwrap().inverse();
    let t0 = f0.as_ref().map(|f0| minv.component_mul(f0).sum()).unwrap_or(0.0);
    let dmax = f.iter().map(|fi| minv.component_mul(fi).sum()).fold(f64::NEG_INFINITY, f64::max);
    let eff = p as f64 / (t0 + dmax);
    assert!(eff >= 1.0 - 1e-6, "efficiency bound {eff}");
    assert!((eff - r.certificate.efficiency_bound).abs() < 1e-9);
    if !with_prior {
        assert!((r.certificate.reference - p as f64).abs() < 1e-12);
        assert!(dmax <= p as f64 * (1.0 + 1e-6), "max d = {dmax} vs p = {p}");
    }
    let (vref, gap) = reference(&f, f0.as_ref(), false, 1e-10, 200_000);
    assert!(gap <= 1e-9 * vref.abs().max(1.0), "reference did not converge: gap {gap}");
    // idexp's optimum against the independent first-order reference
    assert_relative_eq!(r.value, vref, epsilon = 1e-6, max_relative = 1e-6);
}

#[test]
fn d_optimal_50_candidates() {
    check_d(50, 8, 1, 1, false);
    check_d(50, 12, 3, 2, false);
}

#[test]
fn d_optimal_500_candidates() {
    check_d(500, 16, 2, 3, false);
    check_d(500, 26, 3, 4, false);
}

#[test]
fn d_optimal_with_prior() {
    check_d(200, 10, 2, 5, true);
}

/// cargo test --release --test positions_relaxed -- --ignored
#[test]
#[ignore]
fn d_optimal_5000_candidates() {
    check_d(5000, 26, 2, 6, false);
    check_d(5000, 8, 1, 7, false);
}

#[test]
fn socp_and_sdp_formulations_agree() {
    let (h, _) = instance(60, 8, 2, 1.0, 8);
    let pb = Problem::from_factors(8, &h, None).unwrap();
    let a = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    let b = solve_relaxed(
        &pb,
        Criterion::D,
        &SolverOptions {
            formulation: Formulation::Sdp,
            prune: false,
            ..Default::default()
        },
        &idexp::optim::Control::new(),
    )
    .unwrap();
    assert_eq!(a.status, Status::Optimal);
    assert_eq!(b.status, Status::Optimal);
    assert_relative_eq!(a.value, b.value, epsilon = 1e-6, max_relative = 1e-6);
}

#[test]
fn a_optimal_matches_reference() {
    for (n, p, rank, seed) in [(50, 8, 2, 11), (300, 12, 3, 12)] {
        let (h, f) = instance(n, p, rank, 1.0, seed);
        let pb = Problem::from_factors(p, &h, None).unwrap();
        let r = solve_relaxed(&pb, Criterion::A, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
        assert_eq!(r.status, Status::Optimal, "{:?}", r.certificate);
        let (vref, _) = reference(&f, None, true, 1e-10, 200_000);
        assert!((r.value - vref).abs() <= 1e-6 * vref, "A: idexp {} vs reference {vref}", r.value);
        // idexp's value is feasible: it cannot beat the optimum by more than the reference's gap
        assert!(r.value >= vref * (1.0 - 1e-8));
    }
}

#[test]
fn e_optimal_weak_duality_certificate() {
    for (n, p, rank, seed) in [(50, 6, 2, 21), (400, 10, 3, 22)] {
        let (h, f) = instance(n, p, rank, 0.5, seed);
        let pb = Problem::from_factors(p, &h, None).unwrap();
        let r = solve_relaxed(&pb, Criterion::E, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
        let z = r.dual.clone().expect("E returns its dual matrix");
        let ez = z.clone().symmetric_eigen();
        assert!(
            ez.eigenvalues.min() >= -1e-10 && (z.trace() - 1.0).abs() < 1e-9,
            "Z must be PSD with unit trace"
        );
        let lmin = info(&f, None, &r.weights).symmetric_eigen().eigenvalues.min();
        let upper = f.iter().map(|fi| z.component_mul(fi).sum()).fold(f64::NEG_INFINITY, f64::max);
        assert!(lmin <= upper * (1.0 + 1e-12));
        assert!((upper - lmin) / lmin <= 1e-6, "E gap {} (λ_min {lmin}, upper {upper})", (upper - lmin) / lmin);
        assert!((r.value - lmin).abs() <= 1e-9 * lmin);
        assert_eq!(r.status, Status::Optimal);
    }
}

#[test]
fn weights_invariant_to_parameter_scaling_for_d() {
    let (h, _) = instance(120, 8, 2, 0.0, 31);
    let pb = Problem::from_factors(8, &h, None).unwrap();
    let t = DMatrix::from_diagonal(&nalgebra::DVector::from_fn(8, |i, _| 10f64.powi(i as i32 - 4)));
    let pb2 = pb.transformed(&t);
    let a = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    let b = solve_relaxed(&pb2, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap();
    let logdet_t = 2.0 * (0..8).map(|i| t[(i, i)].ln()).sum::<f64>();
    assert!((b.value - a.value - logdet_t).abs() < 1e-6 * a.value.abs().max(1.0));
    assert_eq!(a.status, Status::Optimal);
    assert_eq!(b.status, Status::Optimal);
}

#[test]
fn unidentifiable_candidate_set_is_an_error() {
    // all candidates see only the first 3 of 5 parameters
    let h: Vec<DMatrix<f64>> = (0..20)
        .map(|i| DMatrix::from_fn(5, 1, |r, _| if r < 3 { (i + r) as f64 + 1.0 } else { 0.0 }))
        .collect();
    let pb = Problem::from_factors(5, &h, None).unwrap();
    let e = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &idexp::optim::Control::new()).unwrap_err();
    assert!(e.to_string().contains("not identifiable"), "{e}");
}

/// The pruning bound (any rank, with a prior) never removes a support point of
/// the optimum: checked at many designs along the way to the optimum.
#[test]
fn pruning_bound_keeps_the_optimal_support() {
    use idexp::positions::firstorder::d_prune_threshold;
    for (n, p, rank, seed, prior) in [(80, 6, 3, 41, false), (120, 10, 2, 42, true), (60, 4, 4, 43, false)] {
        let (_, f) = instance(n, p, rank, 1.0, seed);
        let f0 = prior.then(|| instance(1, p, 2, 1.0, seed + 1).1[0].clone() * 0.3);
        let (_, _, wopt) = reference_w(&f, f0.as_ref(), false, 1e-11, 200_000);
        let support: Vec<usize> = (0..n).filter(|&i| wopt[i] > 1e-7).collect();
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for trial in 0..200 {
            // designs from uniform to nearly optimal
            let t = trial as f64 / 200.0;
            let w: Vec<f64> = (0..n).map(|i| (1.0 - t) * g.random_range(0.1..1.0) / n as f64 + t * wopt[i]).collect();
            let s: f64 = w.iter().sum();
            let w: Vec<f64> = w.iter().map(|v| v / s).collect();
            let m = info(&f, f0.as_ref(), &w);
            let minv = m.cholesky().unwrap().inverse();
            let d: Vec<f64> = f.iter().map(|fi| minv.component_mul(fi).sum()).collect();
            let t0 = f0.as_ref().map(|f0| minv.component_mul(f0).sum()).unwrap_or(0.0);
            let thr = d_prune_threshold(p, d.iter().cloned().fold(f64::NEG_INFINITY, f64::max), t0);
            for &i in &support {
                assert!(d[i] >= thr, "support point {i} would be pruned: d = {} < {thr} (trial {trial})", d[i]);
            }
        }
    }
}

/// The Newton path (default) and the Clarabel path (`newton = false`) reach
/// the same certified optimum on random instances: D and A, with and without
/// a prior, ranks 1..=3, badly scaled parameters; and the Newton path
/// certifies without any conic solve.
#[test]
fn newton_path_matches_the_conic_path() {
    let cases = [
        (Criterion::D, 200, 10, 3, 71, false),
        (Criterion::D, 400, 16, 2, 72, true),
        (Criterion::D, 150, 6, 1, 73, false),
        (Criterion::A, 300, 8, 3, 74, false),
        (Criterion::A, 200, 10, 2, 75, true),
        (Criterion::A, 120, 5, 1, 76, false),
    ];
    for (crit, n, p, rank, seed, prior) in cases {
        let (h, f) = instance(n, p, rank, 1.0, seed);
        let f0 = prior.then(|| instance(1, p, 2, 1.0, seed + 1).1[0].clone() * 0.3);
        let pb = Problem::from_factors(p, &h, f0.as_ref()).unwrap();
        let ctl = idexp::optim::Control::new();
        let newton = solve_relaxed(&pb, crit, &SolverOptions::default(), &ctl).unwrap();
        let conic_opts = SolverOptions {
            newton: false,
            ..Default::default()
        };
        let conic = solve_relaxed(&pb, crit, &conic_opts, &ctl).unwrap();
        let tag = format!("{crit:?} n={n} p={p} seed={seed}");
        assert_eq!(newton.status, Status::Optimal, "{tag}: {:?}", newton.certificate);
        assert_eq!(conic.status, Status::Optimal, "{tag}: {:?}", conic.certificate);
        assert!(newton.log.newton_certified && newton.log.rounds.is_empty(), "{tag}: Clarabel was needed");
        assert!(!conic.log.newton_certified && !conic.log.rounds.is_empty());
        assert!(newton.certificate.efficiency_bound >= 1.0 - 1e-6, "{tag}");
        // the certified efficiency, recomputed here on the dense matrices
        let m = info(&f, f0.as_ref(), &newton.weights);
        let minv = m.clone().cholesky().unwrap().inverse();
        let x = if crit == Criterion::A { &minv * &minv } else { minv.clone() };
        let s: Vec<f64> = f.iter().map(|fi| x.component_mul(fi).sum()).collect();
        let t0 = f0.as_ref().map(|f0| x.component_mul(f0).sum()).unwrap_or(0.0);
        let smax = s.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        let eff = if crit == Criterion::D {
            p as f64 / (t0 + smax)
        } else {
            let mean: f64 = newton.weights.iter().zip(&s).map(|(a, b)| a * b).sum();
            1.0 - (smax - mean) / minv.trace()
        };
        assert!(eff >= 1.0 - 1e-6, "{tag}: recomputed efficiency {eff}");
        assert!((eff - newton.certificate.efficiency_bound).abs() < 1e-9, "{tag}");
        // both are certified within 1e-6: the values agree to that
        let rel = (newton.value - conic.value).abs() / conic.value.abs().max(1.0);
        assert!(rel <= 1e-6, "{tag}: Newton {} vs Clarabel {}", newton.value, conic.value);
        // and the Newton value is no worse than Clarabel's beyond Clarabel's own accuracy
        let better = if crit == Criterion::D {
            newton.value >= conic.value - 1e-7 * conic.value.abs().max(1.0)
        } else {
            newton.value <= conic.value * (1.0 + 1e-7)
        };
        assert!(better, "{tag}: Newton {} vs Clarabel {}", newton.value, conic.value);
    }
}

/// Pruning by the equivalence-theorem bound (D) never drops a support point:
/// the pipeline with pruning finds the same weights as without it.
#[test]
fn pruned_and_unpruned_solves_agree() {
    for (n, p, rank, seed) in [(600, 12, 3, 81), (300, 20, 1, 82)] {
        let (h, _) = instance(n, p, rank, 1.0, seed);
        let pb = Problem::from_factors(p, &h, None).unwrap();
        let ctl = idexp::optim::Control::new();
        let pruned = solve_relaxed(&pb, Criterion::D, &SolverOptions::default(), &ctl).unwrap();
        let full_opts = SolverOptions {
            prune: false,
            ..Default::default()
        };
        let full = solve_relaxed(&pb, Criterion::D, &full_opts, &ctl).unwrap();
        assert_eq!(pruned.status, Status::Optimal);
        assert_eq!(full.status, Status::Optimal);
        assert!((pruned.value - full.value).abs() <= 1e-9 * full.value.abs().max(1.0));
        // the D-optimal information matrix is unique; with weights above 1e-4 both find the same support
        let sup = |w: &[f64]| (0..n).filter(|&i| w[i] > 1e-4).collect::<Vec<_>>();
        assert_eq!(sup(&pruned.weights), sup(&full.weights), "n={n} p={p}");
        // the first-order phase run to a tight gap prunes most candidates, and
        // never one that carries weight in the unpruned optimum
        let ws = idexp::positions::firstorder::d_warm_start(&pb, true, 1e-6 * p as f64, 5000, &ctl).unwrap();
        assert!(ws.pool.len() < n / 2, "n={n}: only pruned to {}", ws.pool.len());
        for i in (0..n).filter(|&i| full.weights[i] > 1e-9) {
            assert!(ws.pool.contains(&i), "n={n} p={p}: support point {i} (weight {}) was pruned", full.weights[i]);
        }
    }
}
