//! Gray-box fitting of the elastic model to FRF estimates (paper 001 §5):
//! weighted NLS (eq. 4), weighted log-LS (eq. 7) and magnitude-only LLS, with
//! user-defined or optimal (eq. 6, 8) diagonal weights, minimised by
//! Levenberg–Marquardt with the analytic Jacobian; positive parameters in log
//! space; the asymptotic covariance of eq. 5.
//!
//! # Cost
//!
//! V(θ) = Σ_i Σ_k Σ_{a,b} w^{(i)}_{ab}(k) |E^{(i)}_{ab}(k, θ)|², with
//!
//! * NLS: E = Ĝ_ab − G_ab(θ);
//! * LLS: E = log(Ĝ_ab / G_ab(θ)) (principal branch: the phase error lies in
//!   (−π, π] and never wraps across lines);
//! * LLS magnitude: E = log|Ĝ_ab| − log|G_ab(θ)|.
//!
//! # Solver
//!
//! With z the optimisation variables (z_i = ln θ_i for positive parameters,
//! z_i = θ_i/θ_init,i otherwise) and ψ = ∂E/∂z, the Gauss–Newton model is
//! V(z + δ) ≈ V + 2gᵀδ + δᵀHδ with g = Σ w Re(ψ̄ E), H = Σ w Re(ψ̄ ψᵀ).
//! Levenberg–Marquardt solves (H + λ diag H) δ = −g, accepts the step when the
//! actual decrease is positive and updates λ by Nielsen's rule
//! (λ ← λ·max(1/3, 1 − (2ρ − 1)³) on success, λ ← λν, ν ← 2ν on failure).
//! Positive parameters are kept within ±[`BOUND_DECADES`] decades of θ_init
//! by projecting the step (a damper that does not matter would otherwise run
//! off to 0). The `ftol` test counts only for steps with λ < 1 (close to
//! Gauss–Newton), so heavy damping is not taken for convergence.

use super::design::{Design, FitSpec, UserWeights, WeightKind};
use super::estimate::FrfData;
use super::kernel::{FitKernel, LineJac, SolveCache};
use crate::elastic::{ElasticModel, Estimator, OperatingPoint, Output, C64};
use crate::error::{Error, Result};
use crate::optim::lm::{self, LmProblem, LmStatus, LmTolerances};
use crate::optim::Control;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Positive parameters stay within this many decades of θ_init (projected steps).
pub const BOUND_DECADES: f64 = 4.0;

/// One position of a fit problem.
#[derive(Debug, Clone)]
pub struct PosData {
    /// Linearisation point (nominal parameters).
    pub op: OperatingPoint,
    /// Ĝ per line.
    pub g: Vec<DMatrix<C64>>,
    /// Element variances of Ĝ per line.
    pub var: Vec<DMatrix<f64>>,
    /// ln Ĝ per line and element (principal branch: ln|Ĝ| + i arg Ĝ), computed once.
    pub ln_g: Vec<DMatrix<C64>>,
}

/// One weighted element of the estimator's sum, as visited by
/// `FitProblem::for_each_weighted`: position `p`, line `k`, FRF element (a, b),
/// its weight `w`, the model value `g` = G_ab(ω_k, θ) and the derivatives of
/// the model FRF at the line (only when asked for).
struct Element<'a> {
    p: &'a PosData,
    k: usize,
    a: usize,
    b: usize,
    w: f64,
    g: C64,
    jac: &'a LineJac,
}

impl Element<'_> {
    /// ln Ĝ_ab(ω_k).
    fn ln_ghat(&self) -> C64 {
        self.p.ln_g[self.k][(self.a, self.b)]
    }

    /// The measured Ĝ_ab(ω_k).
    fn ghat(&self) -> C64 {
        self.p.g[self.k][(self.a, self.b)]
    }

    /// ∂G_ab/∂θ_j.
    #[inline]
    fn dg(&self, j: usize) -> C64 {
        self.jac.dg(j, self.a, self.b)
    }
}

/// Everything a cost evaluation needs: model, data, estimator and weights.
#[derive(Debug, Clone)]
pub struct FitProblem {
    /// The model.
    pub model: ElasticModel,
    /// FRF output quantity.
    pub output: Output,
    /// Angular frequencies of the lines (rad/s).
    pub omegas: Vec<f64>,
    /// Line frequencies (Hz).
    pub freqs_hz: Vec<f64>,
    /// Per position.
    pub pos: Vec<PosData>,
    /// Estimator.
    pub estimator: Estimator,
    /// Weights w[pos][line] (n×n) of the estimator.
    pub weights: Vec<Vec<DMatrix<f64>>>,
    /// θ_init (nominal values of the unknowns).
    pub theta_nom: Vec<f64>,
    /// Log-space flags.
    pub positive: Vec<bool>,
    kernel: FitKernel,
}

/// A [`FitProblem`] seen by the Levenberg–Marquardt solver, in z, with the
/// line solves of the last point kept: an accepted trial point's cost and
/// the normal equations there share them.
struct InZ<'a>(&'a FitProblem, std::cell::RefCell<SolveCache>);

impl LmProblem for InZ<'_> {
    fn dim(&self) -> usize {
        self.0.n_params()
    }
    fn normal_equations(&self, z: &[f64]) -> Result<(f64, DVector<f64>, DMatrix<f64>)> {
        self.0.normal_equations_cached(&self.0.to_theta(z), true, &mut self.1.borrow_mut())
    }
    fn cost(&self, z: &[f64]) -> f64 {
        self.0.cost_cached(&self.0.to_theta(z), &mut self.1.borrow_mut()).unwrap_or(f64::INFINITY)
    }
    fn clamp(&self, i: usize, zi: f64) -> f64 {
        self.0.clamp(i, zi)
    }
}

/// How a fit ended: the Levenberg–Marquardt status of the seam.
pub use crate::optim::lm::LmStatus as FitStatus;

/// Result of one local fit.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FitOutcome {
    /// Final parameters (physical units).
    pub theta: Vec<f64>,
    /// Final cost V(θ).
    pub cost: f64,
    /// Outcome.
    pub status: FitStatus,
    /// LM iterations (Jacobian evaluations).
    pub iterations: usize,
    /// Cost evaluations (with or without Jacobian).
    pub evaluations: usize,
}

/// Weights of `estimator` for the data: user weights ([`UserWeights`]) or the
/// optimal ones from the variances (NLS: 1/σ̂², LLS: |Ĝ|²/σ̂², eq. 6 and 8 with
/// G(θ0) ≈ Ĝ); the user band applies to both, and a zero variance gives a zero
/// optimal weight.
pub fn weights(d: &Design, data: &FrfData, estimator: Estimator, kind: WeightKind) -> Result<Vec<Vec<DMatrix<f64>>>> {
    let n = data.n;
    let u: &UserWeights = &d.fit.user;
    let mut out = Vec::new();
    let mut any = false;
    for (pi, p) in data.positions.iter().enumerate() {
        let pf = u.positions.get(pi).copied().unwrap_or(1.0);
        let mut wl = Vec::new();
        for (k, f) in data.freqs_hz.iter().enumerate() {
            let inband = u.band.is_none_or(|b| *f >= b[0] && *f <= b[1]);
            let g = p.g[k].to_mat(n);
            let w = DMatrix::from_fn(n, n, |a, b| {
                if !inband {
                    return 0.0;
                }
                let var = p.var[k][a * n + b];
                let mag2 = g[(a, b)].norm_sqr();
                match kind {
                    WeightKind::User => {
                        if u.min_snr > 0.0 && var > 0.0 && mag2 < u.min_snr * u.min_snr * var {
                            return 0.0;
                        }
                        let e = match &u.elements {
                            Some(m) => m[a][b],
                            None if a == b => u.diagonal,
                            None => u.off_diagonal,
                        };
                        e * pf
                    }
                    WeightKind::Optimal => {
                        if var <= 0.0 {
                            return 0.0;
                        }
                        match estimator {
                            Estimator::Nls => 1.0 / var,
                            Estimator::Lls | Estimator::LlsMagnitude => mag2 / var,
                        }
                    }
                }
            });
            any |= w.iter().any(|v| *v > 0.0);
            wl.push(w);
        }
        out.push(wl);
    }
    if !any {
        return Err(Error::invalid(
            "fit weights",
            if kind == WeightKind::Optimal { "fit.weights" } else { "fit.user" },
            "every weight is zero (band outside the data, zero variances for optimal weights, or min_snr too strict)",
        ));
    }
    Ok(out)
}

impl FitProblem {
    /// Builds the problem: operating points at the data's positions (nominal
    /// parameters), measured FRFs and weights.
    pub fn new(model: &ElasticModel, data: &FrfData, estimator: Estimator, weights: Vec<Vec<DMatrix<f64>>>) -> Result<FitProblem> {
        let n = model.n_motors();
        if data.n != n {
            return Err(Error::dim("motors in the FRF data", n, data.n));
        }
        let theta_nom = model.nominal_unknowns();
        let vals = model.full_values(&theta_nom)?;
        let pos = data
            .positions
            .iter()
            .map(|p| {
                let g: Vec<DMatrix<C64>> = p.g.iter().map(|c| c.to_mat(n)).collect();
                Ok(PosData {
                    op: model.operating_point(&p.q0, &vals)?,
                    ln_g: g.iter().map(|m| m.map(|v| v.ln())).collect(),
                    g,
                    var: p.var.iter().map(|v| DMatrix::from_fn(n, n, |a, b| v[a * n + b])).collect(),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(FitProblem {
            kernel: FitKernel::new(model, data.output),
            model: model.clone(),
            output: data.output,
            omegas: data.freqs_hz.iter().map(|f| std::f64::consts::TAU * f).collect(),
            freqs_hz: data.freqs_hz.clone(),
            pos,
            estimator,
            weights,
            positive: model.unknown_positive(),
            theta_nom,
        })
    }

    /// Same data and model, another estimator and weights.
    pub fn with_estimator(&self, estimator: Estimator, weights: Vec<Vec<DMatrix<f64>>>) -> FitProblem {
        let mut p = self.clone();
        p.estimator = estimator;
        p.weights = weights;
        p
    }

    /// Number of unknowns p.
    pub fn n_params(&self) -> usize {
        self.theta_nom.len()
    }

    /// Optimisation variables of θ.
    pub fn to_z(&self, theta: &[f64]) -> Vec<f64> {
        theta
            .iter()
            .enumerate()
            .map(|(i, &t)| if self.positive[i] { t.max(f64::MIN_POSITIVE).ln() } else { t / self.scale(i) })
            .collect()
    }

    /// θ of optimisation variables.
    pub fn to_theta(&self, z: &[f64]) -> Vec<f64> {
        z.iter()
            .enumerate()
            .map(|(i, &v)| if self.positive[i] { v.exp() } else { v * self.scale(i) })
            .collect()
    }

    /// Keeps z_i within ±[`BOUND_DECADES`] decades of θ_init (positive parameters only).
    fn clamp(&self, i: usize, z: f64) -> f64 {
        if self.positive[i] {
            let c = self.theta_nom[i].ln();
            let b = BOUND_DECADES * std::f64::consts::LN_10;
            z.clamp(c - b, c + b)
        } else {
            z
        }
    }

    fn scale(&self, i: usize) -> f64 {
        let s = self.theta_nom[i].abs();
        if s > 0.0 {
            s
        } else {
            1.0
        }
    }

    /// dθ_i/dz_i.
    fn dtheta_dz(&self, theta: &[f64], i: usize) -> f64 {
        if self.positive[i] {
            theta[i]
        } else {
            self.scale(i)
        }
    }

    /// Model FRFs G^{(i)}(ω_k, θ) at every position.
    pub fn model_frfs(&self, theta: &[f64]) -> Result<Vec<Vec<DMatrix<C64>>>> {
        let vals = self.model.full_values(theta)?;
        let n = self.model.n_motors();
        let mut sc = SolveCache::default().scratch;
        let mut g = vec![C64::new(0.0, 0.0); n * n];
        self.pos
            .iter()
            .map(|p| {
                let lin = self.model.linear_model(&p.op, &vals);
                let sys = self.kernel.system(&lin, &p.op)?;
                let mut w = vec![C64::new(0.0, 0.0); self.kernel.w_len(&sys)];
                self.omegas
                    .iter()
                    .map(|&om| {
                        sys.solve(om, &mut sc, &mut w)?;
                        self.kernel.frf(&sys, om, &w, &mut g, None);
                        Ok(DMatrix::from_fn(n, n, |a, b| g[a * n + b]))
                    })
                    .collect()
            })
            .collect()
    }

    /// E of element `el` at the model value `el.g`. For the log estimators
    /// ln(Ĝ/G) = ln Ĝ − ln G with ln Ĝ computed once per problem, ln|G| =
    /// ½ ln |G|² and the phase difference taken to (−π, π] (the principal
    /// branch of ln(Ĝ/G)).
    #[inline]
    fn residual(&self, el: &Element<'_>) -> C64 {
        let g = el.g;
        match self.estimator {
            Estimator::Nls => el.ghat() - g,
            Estimator::Lls => {
                let l = el.ln_ghat();
                let mut ph = l.im - g.im.atan2(g.re);
                if ph > std::f64::consts::PI {
                    ph -= std::f64::consts::TAU;
                } else if ph <= -std::f64::consts::PI {
                    ph += std::f64::consts::TAU;
                }
                C64::new(l.re - 0.5 * g.norm_sqr().ln(), ph)
            }
            Estimator::LlsMagnitude => C64::new(el.ln_ghat().re - 0.5 * g.norm_sqr().ln(), 0.0),
        }
    }

    fn dresidual(&self, g: C64, dg: C64) -> C64 {
        match self.estimator {
            Estimator::Nls => -dg,
            Estimator::Lls => -dg / g,
            Estimator::LlsMagnitude => C64::new(-(dg / g).re, 0.0),
        }
    }

    /// Visits every weighted element of the estimator's sum, in a fixed order:
    /// for each position, each line ω_k whose weight matrix is not all zero,
    /// and each element (a, b) with weight w ≠ 0, calls `f` with the model FRF
    /// G_ab(ω_k, θ) and, when `jac`, its derivatives ∂G_ab/∂θ_j. Serves the
    /// cost and the covariance.
    fn for_each_weighted(&self, theta: &[f64], jac: bool, cache: &mut SolveCache, mut f: impl FnMut(&Element<'_>)) -> Result<()> {
        self.visit(theta, jac, cache, false, |e, _| f(e))
    }

    /// The visitor behind [`Self::for_each_weighted`]. With `pairs`, the
    /// elements (a, b) and (b, a) of a line come together, `f(first, second)`
    /// with the first one of weight ≠ 0 of the two and the other one if its
    /// weight is ≠ 0 too: G(θ) is symmetric (A(s) is complex symmetric and
    /// B = [I; 0]), so both have the same model value and derivatives, and
    /// the normal equations take one Jacobian row for the pair.
    fn visit(&self, theta: &[f64], jac: bool, cache: &mut SolveCache, pairs: bool, mut f: impl FnMut(&Element<'_>, Option<&Element<'_>>)) -> Result<()> {
        let vals = self.model.full_values(theta)?;
        let n = self.model.n_motors();
        let nl = self.omegas.len();
        let hit = !cache.theta.is_empty() && cache.theta.len() == theta.len() && cache.theta.iter().zip(theta).all(|(a, b)| a.to_bits() == b.to_bits());
        cache.theta.clear();
        let mut g = vec![C64::new(0.0, 0.0); n * n];
        let mut lj = LineJac::default();
        for (pi, p) in self.pos.iter().enumerate() {
            let lin = self.model.linear_model(&p.op, &vals);
            let sys = self.kernel.system(&lin, &p.op)?;
            let wl = self.kernel.w_len(&sys);
            if cache.w.len() != self.pos.len() * nl * wl {
                cache.w.resize(self.pos.len() * nl * wl, C64::new(0.0, 0.0));
            }
            for (k, &om) in self.omegas.iter().enumerate() {
                let wk = &self.weights[pi][k];
                if wk.iter().all(|x| *x == 0.0) {
                    continue;
                }
                let w = &mut cache.w[(pi * nl + k) * wl..(pi * nl + k + 1) * wl];
                if !hit {
                    sys.solve(om, &mut cache.scratch, w)?;
                }
                self.kernel.frf(&sys, om, w, &mut g, if jac { Some(&mut lj) } else { None });
                let el = |a: usize, b: usize| Element {
                    p,
                    k,
                    a,
                    b,
                    w: wk[(a, b)],
                    g: g[a * n + b],
                    jac: &lj,
                };
                for a in 0..n {
                    if !pairs {
                        for b in 0..n {
                            if wk[(a, b)] != 0.0 {
                                f(&el(a, b), None);
                            }
                        }
                        continue;
                    }
                    for b in a..n {
                        let (w1, w2) = (wk[(a, b)], if a == b { 0.0 } else { wk[(b, a)] });
                        match (w1 != 0.0, w2 != 0.0) {
                            (true, true) => f(&el(a, b), Some(&el(b, a))),
                            (true, false) => f(&el(a, b), None),
                            (false, true) => f(&el(b, a), None),
                            (false, false) => {}
                        }
                    }
                }
            }
        }
        cache.theta.extend_from_slice(theta);
        Ok(())
    }

    /// V(θ).
    pub fn cost(&self, theta: &[f64]) -> Result<f64> {
        self.cost_cached(theta, &mut SolveCache::default())
    }

    /// V(θ), reusing the line solves in `cache` if they were made at this θ
    /// (bit for bit), and leaving this θ's solves there.
    pub fn cost_cached(&self, theta: &[f64], cache: &mut SolveCache) -> Result<f64> {
        let mut v = 0.0;
        self.for_each_weighted(theta, false, cache, |e| v += e.w * self.residual(e).norm_sqr())?;
        if !v.is_finite() {
            return Err(Error::Numerical("non-finite cost (a model FRF element is zero or infinite)".into()));
        }
        Ok(v)
    }

    /// V, g = Σ w Re(ψ̄E) and H = Σ w Re(ψ̄ψᵀ), derivatives with respect to z
    /// (`in_z`) or to θ.
    pub fn normal_equations(&self, theta: &[f64], in_z: bool) -> Result<(f64, DVector<f64>, DMatrix<f64>)> {
        self.normal_equations_cached(theta, in_z, &mut SolveCache::default())
    }

    /// [`Self::normal_equations`], reusing the line solves in `cache` if they
    /// were made at this θ (as Levenberg–Marquardt does after the cost at an
    /// accepted trial point), and leaving this θ's solves there.
    pub fn normal_equations_cached(&self, theta: &[f64], in_z: bool, cache: &mut SolveCache) -> Result<(f64, DVector<f64>, DMatrix<f64>)> {
        let np = self.n_params();
        let mut v = 0.0;
        let mut grad: DVector<f64> = DVector::zeros(np);
        let mut h: DMatrix<f64> = DMatrix::zeros(np, np);
        let chain: Vec<f64> = (0..np).map(|i| if in_z { self.dtheta_dz(theta, i) } else { 1.0 }).collect();
        let mut psi = vec![C64::new(0.0, 0.0); np];
        // H = Σ w Re(ψ̄ψᵀ) = JᵀJ with two rows √w·Re ψ, √w·Im ψ per element,
        // accumulated block by block as one matrix product (instead of a
        // scalar rank-one update per element, two thirds of the time)
        const BLOCK: usize = 2048;
        let mut rows: Vec<f64> = Vec::with_capacity(BLOCK * np);
        let flush = |rows: &mut Vec<f64>, h: &mut DMatrix<f64>| {
            let nr = rows.len() / np;
            if nr > 0 {
                let jt = nalgebra::DMatrixView::from_slice(rows, np, nr);
                h.gemm(1.0, &jt, &jt.transpose(), 1.0);
                rows.clear();
            }
        };
        self.visit(theta, true, cache, true, |el, mirror| {
            // the pair (a, b), (b, a) shares ψ: one row of weight w_ab + w_ba
            // and the weighted residual w_ab E_ab + w_ba E_ba
            let e = self.residual(el);
            v += el.w * e.norm_sqr();
            let mut ew = e * el.w;
            let mut ww = el.w;
            if let Some(m) = mirror {
                let e2 = self.residual(m);
                v += m.w * e2.norm_sqr();
                ew += e2 * m.w;
                ww += m.w;
            }
            // ∂E/∂θ_i with one reciprocal of G per element instead of a
            // complex division per parameter
            let ginv = C64::new(1.0, 0.0) / el.g;
            for i in 0..np {
                let d = el.dg(i);
                psi[i] = match self.estimator {
                    Estimator::Nls => -d,
                    Estimator::Lls => -(d * ginv),
                    Estimator::LlsMagnitude => C64::new(-(d * ginv).re, 0.0),
                } * chain[i];
            }
            for i in 0..np {
                let pr = psi[i];
                grad[i] += pr.re * ew.re + pr.im * ew.im;
            }
            let sw = ww.sqrt();
            rows.extend(psi.iter().map(|p| sw * p.re));
            if psi.iter().any(|p| p.im != 0.0) {
                rows.extend(psi.iter().map(|p| sw * p.im));
            }
            if rows.len() >= BLOCK * np {
                flush(&mut rows, &mut h);
            }
        })?;
        flush(&mut rows, &mut h);
        h.fill_lower_triangle_with_upper_triangle();
        if !v.is_finite() || grad.iter().any(|x| !x.is_finite()) {
            return Err(Error::Numerical("non-finite cost or gradient".into()));
        }
        Ok((v, grad, h))
    }

    /// Levenberg–Marquardt from `theta0` ([`crate::optim::lm`], run by
    /// argmin's executor, in the log/linear coordinates z of [`Self::to_z`]).
    /// Never errors: a failed start is a status. `ctl` stops it between two
    /// iterations (status `interrupted`).
    pub fn solve(&self, theta0: &[f64], spec: &FitSpec, ctl: &Control) -> FitOutcome {
        let tol = LmTolerances {
            ftol: spec.ftol,
            xtol: spec.xtol,
        };
        let fail = |evals| FitOutcome {
            theta: theta0.to_vec(),
            cost: f64::INFINITY,
            status: FitStatus::Failed,
            iterations: 0,
            evaluations: evals,
        };
        let o = match lm::run(InZ(self, Default::default()), self.to_z(theta0), spec.max_iter, tol, ctl) {
            Ok(o) => o,
            Err(_) => return fail(0),
        };
        if o.status == LmStatus::Failed {
            return fail(o.evaluations);
        }
        FitOutcome {
            theta: self.to_theta(&o.z),
            cost: o.cost,
            status: o.status,
            iterations: o.iterations,
            evaluations: o.evaluations,
        }
    }

    /// Asymptotic covariance of the estimate at `theta` (paper 001 eq. 5):
    /// P = ½ H⁻¹ S H⁻¹, H = Σ Re{Ψ̄ Ξ Ψᵀ}, S = Σ Re{Ψ̄ Ξ Λ̂0 Ξ Ψᵀ}, with Ξ the
    /// estimator's weights, Λ̂0 the data variances in the estimator's domain
    /// (σ̂² for NLS, σ̂²/|G(θ)|² for LLS) and Ψ = ∂E/∂θ (physical units).
    pub fn covariance(&self, theta: &[f64]) -> Result<DMatrix<f64>> {
        let np = self.n_params();
        let mut h: DMatrix<f64> = DMatrix::zeros(np, np);
        let mut s: DMatrix<f64> = DMatrix::zeros(np, np);
        let mut psi = vec![C64::new(0.0, 0.0); np];
        self.for_each_weighted(theta, true, &mut SolveCache::default(), |el| {
            let ww = el.w;
            let var = match self.estimator {
                Estimator::Nls => el.p.var[el.k][(el.a, el.b)],
                _ => el.p.var[el.k][(el.a, el.b)] / el.g.norm_sqr(),
            };
            for i in 0..np {
                psi[i] = self.dresidual(el.g, el.dg(i));
            }
            for i in 0..np {
                for j in i..np {
                    let r = psi[i].re * psi[j].re + psi[i].im * psi[j].im;
                    h[(i, j)] += ww * r;
                    s[(i, j)] += ww * ww * var * r;
                }
            }
        })?;
        h.fill_lower_triangle_with_upper_triangle();
        s.fill_lower_triangle_with_upper_triangle();
        // scale for conditioning: D H D with D = diag(θ)
        let d: DVector<f64> = DVector::from_fn(np, |i, _| theta[i].abs().max(1e-300));
        let hs = DMatrix::from_fn(np, np, |i, j| h[(i, j)] * d[i] * d[j]);
        let ss = DMatrix::from_fn(np, np, |i, j| s[(i, j)] * d[i] * d[j]);
        let hinv: DMatrix<f64> = hs
            .clone()
            .cholesky()
            .map(|c| c.inverse())
            .ok_or_else(|| Error::Numerical("the information matrix is singular: some unknowns do not influence the weighted FRFs".into()))?;
        let ps: DMatrix<f64> = &hinv * ss * &hinv * 0.5;
        Ok(DMatrix::from_fn(np, np, |i, j| ps[(i, j)] * d[i] * d[j]))
    }
}
