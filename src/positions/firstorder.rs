//! First-order methods on the simplex and the equivalence-theorem pruning
//! bound: they find the approximate support quickly so that the conic solver
//! only sees a small candidate set.
//!
//! * [`multiplicative_d`]: the multiplicative algorithm w_i ← w_i d_i/δ
//!   (Titterington 1976; with a prior, δ = Σ_j w_j d_j = p − tr(M⁻¹F_0)).
//! * [`multiplicative_a`]: w_i ← w_i (a_i/ā)^{1/2}, renormalised (Yu 2010).
//! * [`fw_away_d`]: Frank–Wolfe (Fedorov–Wynn vertex direction) with away
//!   steps and exact line search (Todd & Yildirim 2007; Ahipasaoglu, Sun &
//!   Todd 2008): linear convergence for D-optimality.
//! * [`d_prune_threshold`]: candidates that cannot carry weight in any
//!   D-optimal design.
//!
//! ## The pruning bound (any rank of F_i, with a prior)
//!
//! Let w be any design with M = M(w), M* an optimal information matrix,
//! H = M^{-1/2} M* M^{-1/2} with eigenvalues λ_1..λ_p, t_0 = tr(M⁻¹F_0) and
//! S = t_0 + max_i d_i(w). Then Σλ = tr(M⁻¹M*) = t_0 + Σ w*_i d_i ≤ S and
//! Πλ = det M*/det M ≥ 1, so λ_min(H) ≥ τ, the smaller root of
//! τ·((S − τ)/(p − 1))^{p−1} = 1 (the other λ's at best equal). A support
//! point i of M* satisfies tr(M*⁻¹F_i) = p − tr(M*⁻¹F_0) (equivalence theorem)
//! while tr(M*⁻¹F_i) ≤ d_i/τ and tr(M*⁻¹F_0) ≤ t_0/τ. Hence every support point
//! has d_i(w) ≥ p·τ − t_0 and candidates below that can be removed. For rank-one
//! F_i without prior, Harman & Pronzato (2007) give the sharper
//! p(1 + ε/2 − √(ε(4 + ε − 4/p))/2), ε = max d − p; this module uses the bound
//! above, which holds for information matrices of any rank (sums over
//! frequencies) and with a prior, at the price of being a little weaker
//! (τ ≈ 1 − √(2ε(1 − 1/p)) instead of 1 − √(ε(1 − 1/p)) for small ε).

use super::problem::{Criterion, Problem};
use crate::error::Result;
use crate::optim::Control;
use nalgebra::DMatrix;

/// The smaller root τ ∈ (0, 1] of ln τ + (p−1) ln((S − τ)/(p−1)) = 0, S ≥ p.
pub fn lambda_min_bound(p: usize, s: f64) -> f64 {
    if p <= 1 {
        return 1.0;
    }
    let pm = (p - 1) as f64;
    let g = |t: f64| t.ln() + pm * ((s - t) / pm).ln();
    if g(1.0) <= 0.0 {
        return 1.0;
    }
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= 0.0 || g(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-15 {
            break;
        }
    }
    lo
}

/// Threshold below which d_i(w) rules candidate i out of every D-optimal
/// design: p·τ(S) − t_0 with S = t_0 + max_i d_i (see the module docs), made
/// slightly conservative (relative 1e-9) against rounding.
pub fn d_prune_threshold(p: usize, max_d: f64, t0: f64) -> f64 {
    let s = (t0 + max_d).max(p as f64);
    let tau = lambda_min_bound(p, s);
    (p as f64 * tau - t0) * (1.0 - 1e-9) - 1e-12
}

/// Result of a first-order run.
#[derive(Debug, Clone, Default)]
pub struct FirstOrderLog {
    /// Iterations done.
    pub iterations: usize,
    /// Final ε = max_i s_i − Σ w_i s_i (the Frank–Wolfe gap).
    pub eps: f64,
}

/// Runs `iters` multiplicative-algorithm steps for D on `pb` from `w`
/// (in place; w must be positive on the candidates that may get weight).
/// Stops early when ε ≤ `eps_target` or the user asked to stop.
pub fn multiplicative_d(pb: &Problem, w: &mut [f64], iters: usize, eps_target: f64, ctl: &Control) -> Result<FirstOrderLog> {
    let p = pb.p() as f64;
    let mut log = FirstOrderLog::default();
    for it in 0..iters {
        let ev = pb.evaluate(Criterion::D, w)?;
        let delta = p - ev.prior_term;
        log.eps = ev.max_sens().1 - delta;
        log.iterations = it;
        if log.eps <= eps_target || ctl.interrupted() {
            return Ok(log);
        }
        for (wi, di) in w.iter_mut().zip(&ev.sens) {
            *wi *= di / delta;
        }
        normalise(w);
    }
    log.iterations = iters;
    Ok(log)
}

/// Multiplicative algorithm for A: w_i ← w_i (a_i / Σ_j w_j a_j)^{1/2}, renormalised.
pub fn multiplicative_a(pb: &Problem, w: &mut [f64], iters: usize, ctl: &Control) -> Result<FirstOrderLog> {
    let mut log = FirstOrderLog::default();
    for it in 0..iters {
        let ev = pb.evaluate(Criterion::A, w)?;
        log.eps = ev.max_sens().1 - ev.mean;
        log.iterations = it;
        if ctl.interrupted() {
            return Ok(log);
        }
        for (wi, ai) in w.iter_mut().zip(&ev.sens) {
            *wi *= (ai / ev.mean).max(0.0).sqrt();
        }
        normalise(w);
    }
    log.iterations = iters;
    Ok(log)
}

/// Normalises w ≥ 0 to unit sum (no-op on an all-zero vector).
pub fn normalise(w: &mut [f64]) {
    let s: f64 = w.iter().map(|v| v.max(0.0)).sum();
    if s > 0.0 {
        for v in w.iter_mut() {
            *v = v.max(0.0) / s;
        }
    }
}

/// Exact line search along M + αE (α ∈ [0, α_max]) after whitening M = LLᵀ,
/// L⁻¹EL⁻ᵀ = V diag(μ) Vᵀ: minimises ψ(α) = −Σ ln(1 + αμ_k) (D) or
/// Σ c_k/(1 + αμ_k), c_k = ‖L⁻ᵀv_k‖² (A: tr (M + αE)⁻¹). ψ is convex; its
/// derivative is bisected.
fn line_search(mu: &[f64], c: Option<&[f64]>, amax: f64) -> f64 {
    let dpsi = |a: f64| -> f64 {
        match c {
            None => -mu.iter().map(|m| m / (1.0 + a * m)).sum::<f64>(),
            Some(c) => -mu.iter().zip(c).map(|(m, c)| c * m / (1.0 + a * m).powi(2)).sum::<f64>(),
        }
    };
    if dpsi(0.0) >= 0.0 {
        return 0.0;
    }
    let mut hi = amax;
    let mneg = mu.iter().cloned().fold(0.0f64, f64::min);
    if mneg < 0.0 {
        hi = hi.min(-1.0 / mneg * (1.0 - 1e-12));
    }
    if dpsi(hi) <= 0.0 {
        return hi;
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if dpsi(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-16 * hi.max(1e-300) {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Frank–Wolfe with away steps for D on `pb` from `w` (in place), until
/// ε = max d − δ ≤ `eps_target`, `max_iter` steps or a stop request.
pub fn fw_away_d(pb: &Problem, w: &mut [f64], max_iter: usize, eps_target: f64, ctl: &Control) -> Result<FirstOrderLog> {
    fw_away(pb, Criterion::D, w, max_iter, eps_target, ctl)
}

/// Frank–Wolfe with away steps and exact line search for D or A (E has no
/// smooth gradient: it falls back to A). ε = max_i s_i − Σ w_i s_i is the
/// Frank–Wolfe gap (an upper bound on the criterion's distance to the optimum).
pub fn fw_away(pb: &Problem, crit: Criterion, w: &mut [f64], max_iter: usize, eps_target: f64, ctl: &Control) -> Result<FirstOrderLog> {
    let crit = if crit == Criterion::E { Criterion::A } else { crit };
    let p = pb.p();
    let mut log = FirstOrderLog::default();
    for it in 0..max_iter {
        let ev = pb.evaluate(crit, w)?;
        let (j, smax) = ev.max_sens();
        let mean = ev.mean;
        log.eps = smax - mean;
        log.iterations = it;
        if log.eps <= eps_target || ctl.interrupted() {
            return Ok(log);
        }
        let (k, smin) = w
            .iter()
            .zip(&ev.sens)
            .enumerate()
            .filter(|(_, (wi, _))| **wi > 0.0)
            .fold((usize::MAX, f64::INFINITY), |b, (i, (_, &d))| if d < b.1 { (i, d) } else { b });
        let chol = match ev.m.clone().cholesky() {
            Some(c) => c,
            None => return Ok(log),
        };
        let linv = match chol.l().solve_lower_triangular(&DMatrix::identity(p, p)) {
            Some(l) => l,
            None => return Ok(log),
        };
        let n_mat = match pb.prior() {
            Some(f0) => &ev.m - f0,
            None => ev.m.clone(),
        };
        let b = &linv * &n_mat * linv.transpose();
        let toward = k == usize::MAX || smax - mean >= mean - smin || w[k] >= 1.0;
        let (e, amax) = if toward {
            let hj = &linv * pb.factor(j);
            (&hj * hj.transpose() - &b, 1.0)
        } else {
            let hk = &linv * pb.factor(k);
            (&b - &hk * hk.transpose(), w[k] / (1.0 - w[k]))
        };
        let mut e = e;
        super::problem::symmetrize(&mut e);
        let eig = e.symmetric_eigen();
        let mu: Vec<f64> = eig.eigenvalues.iter().copied().collect();
        let a = if crit == Criterion::A {
            let lt = linv.transpose();
            let c: Vec<f64> = (0..p).map(|q| (&lt * eig.eigenvectors.column(q)).norm_squared()).collect();
            line_search(&mu, Some(&c), amax)
        } else {
            line_search(&mu, None, amax)
        };
        if a <= 0.0 {
            return Ok(log);
        }
        if toward {
            for v in w.iter_mut() {
                *v *= 1.0 - a;
            }
            w[j] += a;
        } else {
            for v in w.iter_mut() {
                *v *= 1.0 + a;
            }
            w[k] -= a;
            if a >= amax * (1.0 - 1e-12) {
                w[k] = 0.0;
            }
        }
        normalise(w);
    }
    log.iterations = max_iter;
    Ok(log)
}

/// Result of [`d_warm_start`].
#[derive(Debug, Clone)]
pub struct WarmStart {
    /// Candidates not ruled out by the pruning bound (indices into the input problem).
    pub pool: Vec<usize>,
    /// Weights on `pool` (unit sum).
    pub w: Vec<f64>,
    /// First-order iterations (multiplicative + inner Frank–Wolfe).
    pub iterations: usize,
    /// Full passes over the pool (sensitivities of every live candidate).
    pub passes: usize,
    /// ε = max d − δ over the pool at `w`.
    pub eps: f64,
}

fn scatter(n: usize, idx: &[usize], v: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; n];
    for (k, &i) in idx.iter().enumerate() {
        out[i] = v[k];
    }
    out
}

/// D-optimal warm start for large candidate sets: a few multiplicative steps on
/// all candidates, then column generation — Frank–Wolfe with away steps on a
/// small working set (the current support plus the candidates with the largest
/// d_i), one pass over all live candidates per outer round — with the pruning
/// bound applied at every pass (with `prune`). Stops when ε ≤ `eps_target`,
/// after `max_iter` iterations, or on a stop request.
pub fn d_warm_start(pb: &Problem, prune: bool, eps_target: f64, max_iter: usize, ctl: &Control) -> Result<WarmStart> {
    let p = pb.p();
    let pf = p as f64;
    let mut pool: Vec<usize> = (0..pb.n()).collect();
    let mut sub = pb.clone();
    let mut w = vec![1.0 / pb.n() as f64; pb.n()];
    let mut iters = 0usize;
    let mut passes = 0usize;
    let mut eps;
    let mut ma_steps = 0usize;
    loop {
        // full pass on the pool
        let ev = sub.evaluate(Criterion::D, &w)?;
        passes += 1;
        let (_, mx) = ev.max_sens();
        let delta = pf - ev.prior_term;
        eps = mx - delta;
        if prune {
            let thr = d_prune_threshold(p, mx, ev.prior_term);
            let keep: Vec<usize> = (0..pool.len()).filter(|&i| ev.sens[i] >= thr).collect();
            if keep.len() < pool.len() && !keep.is_empty() {
                sub = sub.subset(&keep);
                pool = keep.iter().map(|&i| pool[i]).collect();
                w = keep.iter().map(|&i| w[i]).collect();
                normalise(&mut w);
                if w.iter().sum::<f64>() <= 0.0 {
                    w = vec![1.0 / pool.len() as f64; pool.len()];
                }
                // the design changed: re-evaluate before deciding anything else
                continue;
            }
        }
        if eps <= eps_target || iters >= max_iter || ctl.interrupted() {
            break;
        }
        let n = pool.len();
        if ma_steps < 30 && eps > 0.1 * pf {
            // multiplicative step on all live candidates
            for (wi, di) in w.iter_mut().zip(&ev.sens) {
                *wi *= di / delta;
            }
            normalise(&mut w);
            ma_steps += 1;
            iters += 1;
            continue;
        }
        // working set: current support (sparsified) + the largest d_i
        let wmax = w.iter().cloned().fold(0.0, f64::max);
        let mut set: Vec<usize> = (0..n).filter(|&i| w[i] > 1e-3 * wmax).collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| ev.sens[b].total_cmp(&ev.sens[a]));
        set.extend(order.iter().take((2 * p).min(n)).copied());
        set.sort_unstable();
        set.dedup();
        let inner = sub.subset(&set);
        let mut wi: Vec<f64> = set.iter().map(|&i| if w[i] > 1e-3 * wmax { w[i] } else { 0.0 }).collect();
        normalise(&mut wi);
        let budget = (max_iter - iters).min(60);
        let lg = fw_away_d(&inner, &mut wi, budget, (0.25 * eps).max(0.5 * eps_target), ctl)?;
        iters += lg.iterations.max(1);
        w = scatter(n, &set, &wi);
    }
    Ok(WarmStart {
        pool,
        w,
        iterations: iters,
        passes,
        eps,
    })
}

/// The criterion maximised on the simplex (D: log det M, A: −tr M⁻¹), or
/// `None` when M(w) is not positive definite.
fn simplex_objective(pb: &Problem, crit: Criterion, w: &[f64]) -> Option<f64> {
    let chol = pb.information(w).cholesky()?;
    Some(match crit {
        Criterion::A => -chol.inverse().trace(),
        _ => {
            let l = chol.l();
            2.0 * (0..pb.p()).map(|j| l[(j, j)].ln()).sum::<f64>()
        }
    })
}

/// The Newton direction on the free set `set` of the simplex: with the
/// gradient g (the sensitivities) and the Hessian −Q of the criterion,
/// solves (Q + μI) d + ν1 = g_set, 1ᵀd = 0, μ a small relative
/// regularisation (Q is singular when the free set is larger than the span of
/// its information matrices). `a` holds L⁻¹H and `b` (A only) M⁻¹H.
fn newton_direction(pb: &Problem, set: &[usize], g: &[f64], a: &DMatrix<f64>, b: Option<&DMatrix<f64>>, c: Option<&DMatrix<f64>>) -> Option<Vec<f64>> {
    let p = pb.p();
    let k = set.len();
    let rs: usize = set.iter().map(|&i| pb.rank(i)).sum();
    let q = hessian(pb, set, a, b, c, rs * rs > k * p * p);
    let qmax = (0..k).map(|s| q[(s, s)]).fold(0.0f64, f64::max).max(f64::MIN_POSITIVE);
    let mut mu = 1e-12 * qmax;
    for _ in 0..6 {
        let mut qr = q.clone();
        for s in 0..k {
            qr[(s, s)] += mu;
        }
        if let Some(c) = qr.cholesky() {
            let gs = nalgebra::DVector::from_iterator(k, set.iter().map(|&i| g[i]));
            let x = c.solve(&gs);
            let y = c.solve(&nalgebra::DVector::from_element(k, 1.0));
            let nu = x.sum() / y.sum();
            let d = x - y * nu;
            if d.iter().all(|v| v.is_finite()) {
                return Some(d.iter().copied().collect());
            }
        }
        mu *= 100.0;
    }
    None
}

/// Q = −Hessian of the criterion (D: log det M, A: −tr M⁻¹) with respect to
/// the weights of `set`: D Q_st = tr(M⁻¹F_sM⁻¹F_t), A Q_st = 2 tr(M⁻¹F_sM⁻¹F_tM⁻¹),
/// either from the factor products (`whitened` false) or from the whitened
/// p×p matrices L⁻¹F_sL⁻ᵀ (`whitened` true, cheaper for large ranks).
fn hessian(pb: &Problem, set: &[usize], a: &DMatrix<f64>, b: Option<&DMatrix<f64>>, c: Option<&DMatrix<f64>>, whitened: bool) -> DMatrix<f64> {
    let p = pb.p();
    let k = set.len();
    let cols: Vec<(usize, usize)> = {
        let mut c0 = 0;
        set.iter()
            .map(|&i| {
                let start = c0;
                c0 += pb.rank(i);
                (start, pb.rank(i))
            })
            .collect()
    };
    let rs: usize = cols.iter().map(|c| c.1).sum();
    let off: Vec<usize> = set.iter().map(|&i| pb.offset(i)).collect();
    let gather = |x: &DMatrix<f64>| {
        let mut out = DMatrix::zeros(p, rs);
        for (s, &(c0, r)) in cols.iter().enumerate() {
            out.columns_mut(c0, r).copy_from(&x.columns(off[s], r));
        }
        out
    };
    let mut q = DMatrix::zeros(k, k);
    if whitened {
        // large ranks: X_s = L⁻¹F_sL⁻ᵀ (p×p), D: Q_st = ⟨X_s, X_t⟩; A (with
        // C = L⁻¹L⁻ᵀ): Q_st = 2 tr(X_s X_t C) = ⟨X_s, X_t C + C X_t⟩
        let mut xs = DMatrix::zeros(p * p, k);
        for (s, &(_, r)) in cols.iter().enumerate() {
            let asub = a.columns(off[s], r);
            let x = asub * asub.transpose();
            xs.column_mut(s).copy_from_slice(x.as_slice());
        }
        let ys = match c {
            None => xs.clone(),
            Some(c) => {
                let mut ys = DMatrix::zeros(p * p, k);
                for s in 0..k {
                    let x = DMatrix::from_column_slice(p, p, xs.column(s).as_slice());
                    let y = &x * c + c * &x;
                    ys.column_mut(s).copy_from_slice(y.as_slice());
                }
                ys
            }
        };
        q = xs.transpose() * ys;
        super::problem::symmetrize(&mut q);
    } else {
        let a_s = gather(a);
        let g1 = a_s.transpose() * &a_s;
        let g2 = b.map(|b| {
            let b_s = gather(b);
            b_s.transpose() * &b_s
        });
        for s in 0..k {
            for t in 0..=s {
                let (cs, rs_) = cols[s];
                let (ct, rt) = cols[t];
                let mut v = 0.0;
                for x in 0..rs_ {
                    for y in 0..rt {
                        let e = g1[(cs + x, ct + y)];
                        v += match &g2 {
                            Some(g2) => 2.0 * e * g2[(cs + x, ct + y)],
                            None => e * e,
                        };
                    }
                }
                q[(s, t)] = v;
                q[(t, s)] = v;
            }
        }
    }
    q
}

/// Active-set Newton method for D or A on the simplex of `pb` from `w` (in
/// place): Newton steps on the free set (the positive weights plus the
/// candidate of largest sensitivity when it has none), with a ratio test
/// that drops candidates reaching weight 0 and an Armijo backtracking line
/// search on the criterion; a Frank–Wolfe (toward / away) step when the
/// Newton step cannot improve. Converges quadratically once the support is
/// identified, so it reaches ε = max_i s_i − Σ w_i s_i ≤ `eps_target` far
/// below the first-order methods' reach. E falls back to A (as in [`fw_away`]).
pub fn newton_simplex(pb: &Problem, crit: Criterion, w: &mut [f64], max_iter: usize, eps_target: f64, ctl: &Control) -> Result<FirstOrderLog> {
    let crit = if crit == Criterion::E { Criterion::A } else { crit };
    let n = pb.n();
    let mut log = FirstOrderLog::default();
    // weights that are zero in all but rounding only cost ratio-test steps
    let wmax = w.iter().cloned().fold(0.0, f64::max);
    for v in w.iter_mut() {
        if *v < 1e-12 * wmax {
            *v = 0.0;
        }
    }
    normalise(w);
    let mut f_cur = match simplex_objective(pb, crit, w) {
        Some(f) => f,
        None => {
            pb.evaluate(crit, w)?;
            return Ok(log);
        }
    };
    for it in 0..max_iter {
        log.iterations = it;
        let chol = match pb.information(w).cholesky() {
            Some(c) => c,
            None => return Ok(log),
        };
        let a = match chol.l().solve_lower_triangular(pb.stacked()) {
            Some(a) => a,
            None => return Ok(log),
        };
        let b = if crit == Criterion::A {
            match chol.l().tr_solve_lower_triangular(&a) {
                Some(b) => Some(b),
                None => return Ok(log),
            }
        } else {
            None
        };
        // A: C = L⁻¹L⁻ᵀ for the Hessian of large-rank candidates
        let cmat = match (&b, chol.l().solve_lower_triangular(&DMatrix::identity(pb.p(), pb.p()))) {
            (Some(_), Some(li)) => Some(&li * li.transpose()),
            _ => None,
        };
        let sq = b.as_ref().unwrap_or(&a);
        let g: Vec<f64> = (0..n).map(|i| sq.columns(pb.offset(i), pb.rank(i)).norm_squared()).collect();
        let mean: f64 = w.iter().zip(&g).map(|(a, b)| a * b).sum();
        let (jmax, gmax) = g.iter().enumerate().fold((0, f64::NEG_INFINITY), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
        log.eps = gmax - mean;
        if log.eps <= eps_target || ctl.interrupted() {
            return Ok(log);
        }
        let mut set: Vec<usize> = (0..n).filter(|&i| w[i] > 0.0).collect();
        if w[jmax] == 0.0 {
            set.push(jmax);
        }
        let mut d = newton_direction(pb, &set, &g, &a, b.as_ref(), cmat.as_ref());
        if w[jmax] == 0.0 && d.as_ref().is_some_and(|d| d[set.len() - 1] <= 0.0) {
            // the best outside candidate is not wanted by Newton: step on the support only
            set.pop();
            d = newton_direction(pb, &set, &g, &a, b.as_ref(), cmat.as_ref());
        }
        let mut stepped = false;
        if let Some(d) = d {
            let slope: f64 = set.iter().zip(&d).map(|(&i, di)| g[i] * di).sum();
            let mut amax = 1.0f64;
            for (&i, &di) in set.iter().zip(&d) {
                if di < 0.0 {
                    amax = amax.min(w[i] / -di);
                }
            }
            if slope > 0.0 && amax < 1.0 {
                // projection arc (Bertsekas 1982): w(α) = P(w + αd), negative
                // weights cut to zero, so that many candidates can leave at
                // once; Armijo on the actual change, down to the ratio-test step
                let mut alpha = 1.0f64;
                while alpha > amax {
                    let mut wt = w.to_vec();
                    for (&i, &di) in set.iter().zip(&d) {
                        wt[i] = (wt[i] + alpha * di).max(0.0);
                    }
                    normalise(&mut wt);
                    let gain: f64 = set.iter().map(|&i| g[i] * (wt[i] - w[i])).sum();
                    if gain > 0.0 {
                        if let Some(ft) = simplex_objective(pb, crit, &wt) {
                            if ft >= f_cur + 1e-4 * gain {
                                w.copy_from_slice(&wt);
                                f_cur = ft;
                                stepped = true;
                                break;
                            }
                        }
                    }
                    alpha *= 0.5;
                }
            }
            if !stepped && slope > 0.0 && amax > 0.0 {
                let mut alpha = amax;
                for _ in 0..40 {
                    let mut wt = w.to_vec();
                    for (&i, &di) in set.iter().zip(&d) {
                        wt[i] += alpha * di;
                        // the blocking candidates of the ratio test leave the support exactly
                        let blocks = alpha >= amax && di < 0.0 && w[i] <= -di * amax * (1.0 + 1e-12);
                        if blocks || wt[i] < 0.0 {
                            wt[i] = 0.0;
                        }
                    }
                    normalise(&mut wt);
                    if let Some(ft) = simplex_objective(pb, crit, &wt) {
                        if ft >= f_cur + 1e-4 * alpha * slope {
                            w.copy_from_slice(&wt);
                            f_cur = ft;
                            stepped = true;
                            break;
                        }
                    }
                    alpha *= 0.5;
                }
            }
        }
        if !stepped {
            // Newton cannot improve (rounding level or a degenerate support): one Frank–Wolfe step
            let before = w.to_vec();
            fw_away(pb, crit, w, 1, 0.0, ctl)?;
            match simplex_objective(pb, crit, w) {
                Some(ft) if ft > f_cur => f_cur = ft,
                _ => {
                    w.copy_from_slice(&before);
                    return Ok(log);
                }
            }
        }
    }
    log.iterations = max_iter;
    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// Both Hessian forms equal minus the finite-difference Jacobian of the
    /// sensitivities, for D and A.
    #[test]
    fn newton_hessian_matches_finite_differences() {
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let p = 5;
        let factors: Vec<DMatrix<f64>> = (0..7)
            .map(|i| DMatrix::from_fn(p, 1 + i % 3, |_, _| <StandardNormal as Distribution<f64>>::sample(&StandardNormal, &mut g)))
            .collect();
        let pb = Problem::from_factors(p, &factors, None).unwrap();
        let n = pb.n();
        let w: Vec<f64> = (0..n).map(|i| (1.0 + i as f64) / (n * (n + 1) / 2) as f64).collect();
        let set: Vec<usize> = vec![0, 2, 3, 6];
        for crit in [Criterion::D, Criterion::A] {
            let chol = pb.information(&w).cholesky().unwrap();
            let a = chol.l().solve_lower_triangular(pb.stacked()).unwrap();
            let b = (crit == Criterion::A).then(|| chol.l().tr_solve_lower_triangular(&a).unwrap());
            let li = chol.l().solve_lower_triangular(&DMatrix::identity(p, p)).unwrap();
            let c = b.as_ref().map(|_| &li * li.transpose());
            let q1 = hessian(&pb, &set, &a, b.as_ref(), c.as_ref(), false);
            let q2 = hessian(&pb, &set, &a, b.as_ref(), c.as_ref(), true);
            let h = 1e-6;
            for (t, &j) in set.iter().enumerate() {
                let (mut wp, mut wm) = (w.clone(), w.clone());
                wp[j] += h;
                wm[j] -= h;
                let sp = pb.evaluate(crit, &wp).unwrap().sens;
                let sm = pb.evaluate(crit, &wm).unwrap().sens;
                for (s, &i) in set.iter().enumerate() {
                    let fd = -(sp[i] - sm[i]) / (2.0 * h);
                    let scale = q1[(s, t)].abs().max(1.0);
                    assert!(
                        (q1[(s, t)] - fd).abs() <= 1e-5 * scale,
                        "{crit:?} factor form ({s},{t}): {} vs {fd}",
                        q1[(s, t)]
                    );
                    assert!(
                        (q2[(s, t)] - q1[(s, t)]).abs() <= 1e-10 * scale,
                        "{crit:?} whitened form ({s},{t}): {} vs {}",
                        q2[(s, t)],
                        q1[(s, t)]
                    );
                }
            }
        }
    }
}
