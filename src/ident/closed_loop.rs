//! Closed-loop estimators of paper 002 §2.2.
//!
//! # Projection method (eq. 10–12)
//!
//! Stage 1 estimates the sensitivity from the reference r to the torque
//! command u by a non-causal FIR filter, u_j(t) = c_j + Σ_i Σ_{k=−M1}^{M2}
//! s_{jik} r_i(t−k) + noise, by least squares, and forms û = Ŝ r (eq. 11): the
//! projection of u on the span of the shifted references (circular shifts when
//! the run is one period of a periodic motion). M1 = M2 = M is given or chosen
//! by the stated rule: the M in {0, 1, 2, 4, 8, 16, 32} with the smallest
//! cross-validated error between the projection of the even repetitions'
//! average and the odd repetitions' average (and vice versa).
//!
//! Stage 2 identifies with û. Because the rigid-body model is nonlinear in q,
//! û (a linear filter of r) lacks the torque harmonics the model predicts; the
//! regressor columns are therefore passed through the same projection P, and
//! θ̂ = argmin ‖W^{1/2} P (u − C θ)‖² (the instrumental-variable form of the
//! projection method, with the shifted references as instruments). Its
//! covariance is the sandwich A Σ Aᵀ, A = (C̃ᵀWC̃)⁻¹C̃ᵀW, C̃ = PC, Σ the
//! variances of the averaged torques.
//!
//! # Maximum likelihood with noisy positions and torques (eq. 13–16)
//!
//! Per sample i, b_i(θ) = τ̄_i − Y(x̄_i) θ with x = (q, q̇, q̈) the filtered
//! states, B_i = ∂b/∂(τ, x) = [I, −J_i(θ)], J_i = ∂(Yθ)/∂x, and S_i² = B_i Σ_i
//! B_iᵀ (eq. 16), Σ_i the sample covariance of (τ, x) over the repetitions
//! divided by N_r (including the τ–x cross-covariance that feedback creates).
//! θ̂_ML = argmin ½ Σ_i b_iᵀ S_i⁻² b_i (eq. 15), solved by L-BFGS (nlopt) from
//! the WLS estimate, in coordinates scaled by the WLS standard deviations,
//! with the analytic gradient
//! ∇ = −Σ_i [Y_iᵀ w_i + Σ_m g_{i,m} D_{i,m}ᵀ w_i], w_i = S_i⁻² b_i,
//! g_i = Σ_xx J_iᵀ w_i − Σ_xτ w_i, D_{i,m} = ∂Y/∂x_m.
//! The covariance reported is the Gauss–Newton inverse (Σ_i Y_iᵀ S_i⁻² Y_i)⁻¹.

use super::estimate::{cond, cond_normalized, Dataset, LsFit, Weights};
use super::{Processed, Run};
use crate::error::{Error, Result};
use crate::optim::nlopt::{Algorithm, Problem};
use crate::optim::{Control, GradientStatus};
use crate::params::BaseParams;
use crate::robot::{regressor_derivatives, Robot, Workspace};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

/// Options of the projection method.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProjectionOptions {
    /// Fixed lags (M1, M2); None: chosen by cross-validation over repetitions.
    pub lags: Option<(usize, usize)>,
    /// Weights of stage 2 (per-joint: the projection mixes samples).
    pub weights: Weights,
}

impl Default for ProjectionOptions {
    fn default() -> Self {
        ProjectionOptions {
            lags: None,
            weights: Weights::Joint,
        }
    }
}

/// Stage-1 and stage-2 details of the projection method.
#[derive(Debug, Clone, Serialize)]
pub struct ProjectionInfo {
    /// Non-causal lags M1.
    pub m1: usize,
    /// Causal lags M2.
    pub m2: usize,
    /// Rule used to pick them.
    pub rule: String,
    /// Cross-validation error per candidate M (if chosen by the rule).
    pub cv: Vec<(usize, f64)>,
    /// Dimension of the instrument space (numerical rank of the shifted references).
    pub instrument_rank: usize,
    /// Correlation coefficient between û and ũ = u − û per joint (≈ 0 by construction).
    pub corr: Vec<f64>,
    /// Fraction of the torque variance (about the mean) explained by û, per joint.
    pub explained: Vec<f64>,
}

fn orthonormal_instruments(r: &[Vec<f64>], m1: usize, m2: usize, periodic: bool) -> Result<DMatrix<f64>> {
    let m = r.len();
    let n = r[0].len();
    let l = m1 + m2 + 1;
    let z = DMatrix::from_fn(m, 1 + n * l, |p, c| {
        if c == 0 {
            return 1.0;
        }
        let i = (c - 1) / l;
        let k = ((c - 1) % l) as isize - m1 as isize;
        let idx = p as isize - k;
        if periodic {
            r[idx.rem_euclid(m as isize) as usize][i]
        } else if idx >= 0 && (idx as usize) < m {
            r[idx as usize][i]
        } else {
            0.0
        }
    });
    // scale columns to unit norm before the SVD
    let mut zs = z;
    for mut col in zs.column_iter_mut() {
        let nrm = col.norm();
        if nrm > 0.0 {
            col /= nrm;
        }
    }
    let (u, s, _) = crate::linalg::thin_svd(&zs)?;
    let rank = s.iter().filter(|&&x| x > 1e-9 * s[0]).count();
    Ok(u.columns(0, rank).into_owned())
}

fn project(u: &DMatrix<f64>, x: &DVector<f64>) -> DVector<f64> {
    u * (u.transpose() * x)
}

/// Joint j's column of a per-sample signal.
fn col(v: &[Vec<f64>], j: usize) -> DVector<f64> {
    DVector::from_iterator(v.len(), v.iter().map(|s| s[j]))
}

/// Projection-method estimate. `ds` is the dataset of the processed run `pr`
/// (its columns: the parameters to estimate); `run` gives the repetitions for the
/// lag rule, `decimate` the step between the run's samples and those of `pr`.
pub fn projection(ds: &Dataset, pr: &Processed, run: &Run, decimate: usize, opts: &ProjectionOptions) -> Result<(LsFit, ProjectionInfo)> {
    let r = pr.r.as_ref().ok_or_else(|| {
        Error::invalid(
            "projection method",
            "r1..rn",
            "the run has no reference columns r1..rn; the projection method needs the reference",
        )
    })?;
    let periodic = pr.fourier.is_some();
    if !ds.is_complete() {
        return Err(Error::invalid(
            "projection method",
            "min_speed",
            "the projection needs every sample: build the dataset with min_speed = 0",
        ));
    }
    let n = ds.n;
    let m = ds.n_samples;
    if r.len() != m {
        return Err(Error::dim("projection: reference samples", m, r.len()));
    }
    let (m1, m2, rule, cv) = match opts.lags {
        Some((a, b)) => (a, b, "given".to_string(), vec![]),
        None if run.reps.len() >= 2 => {
            let dec = decimate.max(1);
            let pick = |even: bool| -> Vec<Vec<f64>> {
                let sel: Vec<&Vec<Vec<f64>>> = run.reps.iter().enumerate().filter(|(i, _)| (i % 2 == 0) == even).map(|(_, r)| &r.tau).collect();
                let k = sel.len() as f64;
                (0..m)
                    .map(|p| (0..n).map(|j| sel.iter().map(|t| t[p * dec][j]).sum::<f64>() / k).collect())
                    .collect()
            };
            let (ue, uo) = (pick(true), pick(false));
            let mut cv = Vec::new();
            for &mm in &[0usize, 1, 2, 4, 8, 16, 32] {
                if n * (2 * mm + 1) + 1 >= m / 2 {
                    break;
                }
                let u = orthonormal_instruments(r, mm, mm, periodic)?;
                let mut err = 0.0;
                for j in 0..n {
                    let (a, b) = (col(&ue, j), col(&uo, j));
                    err += (&b - project(&u, &a)).norm_squared() + (&a - project(&u, &b)).norm_squared();
                }
                cv.push((mm, err));
            }
            let best = cv.iter().min_by(|a, b| a.1.total_cmp(&b.1)).map(|x| x.0).unwrap_or(0);
            (best, best, "cross-validation over even/odd repetitions".to_string(), cv)
        }
        None => (8, 8, "default M1 = M2 = 8 (one repetition: no cross-validation)".to_string(), vec![]),
    };
    // n (M1 + M2 + 1) + 1 instruments must stay below the samples (bounded before allocating)
    let instruments = m1
        .checked_add(m2)
        .and_then(|x| x.checked_add(1))
        .and_then(|x| x.checked_mul(n))
        .and_then(|x| x.checked_add(1));
    if instruments.is_none_or(|k| k >= m) {
        let max_sum = (m.saturating_sub(2) / n.max(1)).saturating_sub(1);
        return Err(Error::invalid(
            "[projection]",
            "lags",
            format!("M1 = {m1}, M2 = {m2} give n·(M1 + M2 + 1) + 1 instruments for {n} joints, but the run has {m} samples: expected M1 + M2 ≤ {max_sum}"),
        ));
    }
    let u = orthonormal_instruments(r, m1, m2, periodic)?;
    let instrument_rank = u.ncols();
    // stage 1: û per joint; stage 2: projected regressor
    let k = ds.c.ncols();
    let mut ct = DMatrix::zeros(n * m, k);
    let mut uh = DVector::zeros(n * m);
    let mut corr = Vec::with_capacity(n);
    let mut explained = Vec::with_capacity(n);
    for j in 0..n {
        let y = ds.y.rows(j * m, m).into_owned();
        let yh = project(&u, &y);
        let res = &y - &yh;
        let mean_h = yh.mean();
        let mean_r = res.mean();
        let cov: f64 = yh.iter().zip(res.iter()).map(|(a, b)| (a - mean_h) * (b - mean_r)).sum();
        let den = (yh.iter().map(|a| (a - mean_h).powi(2)).sum::<f64>() * res.iter().map(|b| (b - mean_r).powi(2)).sum::<f64>()).sqrt();
        corr.push(if den > 0.0 { cov / den } else { 0.0 });
        let ym = y.mean();
        let tot: f64 = y.iter().map(|a| (a - ym).powi(2)).sum();
        explained.push(if tot > 0.0 { 1.0 - res.norm_squared() / tot } else { 1.0 });
        uh.rows_mut(j * m, m).copy_from(&yh);
        for c in 0..k {
            let x = ds.c.view((j * m, c), (m, 1)).into_owned();
            let xp = project(&u, &DVector::from_column_slice(x.as_slice()));
            ct.view_mut((j * m, c), (m, 1)).copy_from(&xp);
        }
    }
    let proj = Dataset {
        n,
        n_samples: m,
        c: ct,
        y: uh,
        var: ds.var.clone(),
        names: ds.names.clone(),
        joint: ds.joint.clone(),
        sample: ds.sample.clone(),
    };
    let var = super::estimate::row_variances(&proj, opts.weights)?;
    let w = var.map(|v| 1.0 / v);
    // A = (C̃ᵀWC̃)⁻¹C̃ᵀW by SVD of W^{1/2}C̃
    let sw = w.map(f64::sqrt);
    let mut a = proj.c.clone();
    for (i, mut row) in a.row_iter_mut().enumerate() {
        row *= sw[i];
    }
    let (uu, s, v) = crate::linalg::thin_svd(&a)?;
    let rank = s.iter().filter(|&&x| x > 1e-10 * s[0]).count();
    let mut vs = v.clone();
    for (j, mut c) in vs.column_iter_mut().enumerate() {
        c *= if j < rank { 1.0 / s[j] } else { 0.0 };
    }
    let mut amat = &vs * uu.transpose(); // k × rows, acting on W^{1/2}-scaled data
    for (i, mut c) in amat.column_iter_mut().enumerate() {
        c *= sw[i];
    }
    let theta = &amat * &proj.y;
    // sandwich with the per-sample variances of the averaged torques (P is absorbed: A P = A)
    let sig = ds.var.clone().unwrap_or_else(|| var.clone());
    let mut asg = amat.clone();
    for (i, mut c) in asg.column_iter_mut().enumerate() {
        c *= sig[i];
    }
    let cov = asg * amat.transpose();
    let res = (&proj.y - &proj.c * &theta).component_mul(&sw);
    let chi2 = res.norm_squared() / (instrument_rank * n).saturating_sub(rank).max(1) as f64;
    let std: Vec<f64> = (0..k).map(|i| cov[(i, i)].max(0.0).sqrt()).collect();
    let fit = LsFit {
        rel_std: std
            .iter()
            .zip(theta.iter())
            .map(|(s, t)| if *t != 0.0 { s / t.abs() } else { f64::INFINITY })
            .collect(),
        theta: theta.as_slice().to_vec(),
        std,
        cov,
        rank,
        cond: cond(&proj.c)?,
        cond_normalized: cond_normalized(&proj.c)?,
        chi2_dof: chi2,
    };
    Ok((
        fit,
        ProjectionInfo {
            m1,
            m2,
            rule,
            cv,
            instrument_rank,
            corr,
            explained,
        },
    ))
}

/// Options of the ML estimator.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MlOptions {
    /// Maximum cost evaluations.
    pub max_eval: u32,
    /// Relative tolerance on the cost.
    pub ftol_rel: f64,
    /// Half-width of the search box, in WLS standard deviations around the WLS estimate.
    pub bound: f64,
}

impl Default for MlOptions {
    fn default() -> Self {
        MlOptions {
            max_eval: 400,
            ftol_rel: 1e-12,
            bound: 50.0,
        }
    }
}

/// Outcome of the ML optimisation.
#[derive(Debug, Clone, Serialize)]
pub struct MlInfo {
    /// Solver status (nlopt's word).
    pub status: GradientStatus,
    /// Cost at the WLS start.
    pub cost_start: f64,
    /// Cost at the end.
    pub cost_end: f64,
    /// Cost evaluations.
    pub evaluations: usize,
}

struct MlData {
    n: usize,
    k: usize,
    /// per sample: Y (n×k) then D_m (3n of n×k), row-major
    mats: Vec<Vec<f64>>,
    tau: Vec<Vec<f64>>,
    /// per sample: Σ (4n × 4n) of the mean
    sig: Vec<Vec<f64>>,
}

/// The terms of one sample of [`MlData`] at θ: Y_i (n×k), J_i (n×3n) with
/// column m = D_m θ (the derivative of Y_i θ with respect to the m-th measured
/// state), the covariance blocks Σ_τx (n×3n) and Σ_xx (3n×3n), and the
/// Cholesky factor of the equation-error covariance
/// Σ_e = Σ_ττ − J Σ_xτ − Σ_τx Jᵀ + J Σ_xx Jᵀ (+ 10⁻¹² tr Σ_e I), None when it is
/// not positive definite.
struct SampleTerms {
    y: DMatrix<f64>,
    jm: DMatrix<f64>,
    stx: DMatrix<f64>,
    sxx: DMatrix<f64>,
    chol: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
}

impl MlData {
    /// D_m of sample i (n×k), m = 0..3n.
    fn d_mat(&self, i: usize, m: usize) -> DMatrix<f64> {
        let nk = self.n * self.k;
        DMatrix::from_row_slice(self.n, self.k, &self.mats[i][(m + 1) * nk..(m + 2) * nk])
    }

    /// The terms of sample i at θ, shared by the cost/gradient and the Fisher information.
    fn sample_terms(&self, i: usize, th: &DVector<f64>) -> SampleTerms {
        let (n, k) = (self.n, self.k);
        let y = DMatrix::from_row_slice(n, k, &self.mats[i][..n * k]);
        let mut jm = DMatrix::zeros(n, 3 * n);
        for m in 0..3 * n {
            jm.set_column(m, &(self.d_mat(i, m) * th));
        }
        let d4 = 4 * n;
        let s = DMatrix::from_row_slice(d4, d4, &self.sig[i.min(self.sig.len() - 1)]);
        let stt = s.view((0, 0), (n, n));
        let stx = s.view((0, n), (n, 3 * n));
        let sxx = s.view((n, n), (3 * n, 3 * n));
        let mut s2 = stt.into_owned() - &jm * stx.transpose() - stx * jm.transpose() + &jm * sxx * jm.transpose();
        let tr = s2.trace().abs().max(1e-300);
        for a in 0..n {
            s2[(a, a)] += 1e-12 * tr;
        }
        SampleTerms {
            y,
            stx: stx.into_owned(),
            sxx: sxx.into_owned(),
            jm,
            chol: s2.cholesky(),
        }
    }

    fn cost_grad(&self, theta: &[f64], grad: Option<&mut [f64]>) -> f64 {
        let (n, k) = (self.n, self.k);
        let want_grad = grad.is_some();
        // Fixed chunks of samples, summed in order: the floating-point
        // order of the sums does not depend on the threads (bit-identical
        // results for any thread count, and from run to run).
        const CHUNK: usize = 64;
        let m = self.mats.len();
        let parts: Vec<(f64, Vec<f64>)> = (0..m.div_ceil(CHUNK))
            .into_par_iter()
            .map(|ch| {
                (ch * CHUNK..((ch + 1) * CHUNK).min(m)).fold((0.0, vec![0.0; k]), |(mut c, mut g), i| {
                    let th = DVector::from_column_slice(theta);
                    let SampleTerms { y, jm, stx, sxx, chol } = self.sample_terms(i, &th);
                    let Some(ch) = chol else {
                        return (f64::INFINITY, g);
                    };
                    let b = DVector::from_column_slice(&self.tau[i]) - &y * &th;
                    let w = ch.solve(&b);
                    c += 0.5 * b.dot(&w);
                    if want_grad {
                        let gg = &sxx * jm.transpose() * &w - stx.transpose() * &w;
                        let yw = y.transpose() * &w;
                        for a in 0..k {
                            g[a] -= yw[a];
                        }
                        for m in 0..3 * n {
                            if gg[m] == 0.0 {
                                continue;
                            }
                            let dw = self.d_mat(i, m).transpose() * &w;
                            for a in 0..k {
                                g[a] -= gg[m] * dw[a];
                            }
                        }
                    }
                    (c, g)
                })
            })
            .collect();
        let mut cost = 0.0;
        let mut g = vec![0.0; k];
        for (c, gp) in &parts {
            cost += c;
            for (a, b) in g.iter_mut().zip(gp) {
                *a += b;
            }
        }
        if let Some(gr) = grad {
            gr.copy_from_slice(&g);
        }
        cost
    }

    fn fisher(&self, theta: &[f64]) -> DMatrix<f64> {
        let mut f = DMatrix::zeros(self.k, self.k);
        let th = DVector::from_column_slice(theta);
        for i in 0..self.mats.len() {
            let t = self.sample_terms(i, &th);
            if let Some(ch) = t.chol {
                let sy = ch.solve(&t.y);
                f += t.y.transpose() * sy;
            }
        }
        f
    }
}

/// Where maximum likelihood starts: the estimated base-parameter columns
/// (indices into the base set), their start values and scales.
#[derive(Debug, Clone, Copy)]
pub struct MlStart<'a> {
    /// Indices of the estimated base parameters.
    pub cols: &'a [usize],
    /// Start values (e.g. the WLS estimate), one per column.
    pub theta: &'a [f64],
    /// Scales (e.g. the WLS standard deviations), one per column.
    pub scale: &'a [f64],
}

/// Maximum-likelihood estimate (paper 002 eq. 13–16) of the base parameters in
/// `cols` (indices into `base`), started from `start` (e.g. WLS) with scales `scale`
/// (e.g. the WLS standard deviations). `ctl` stops it through the nlopt
/// bridge: Ctrl-C, its deadline (nlopt's `maxtime`) and its evaluation
/// budget; every cost evaluation is counted on it.
pub fn ml(robot: &Robot, base: &BaseParams, pr: &Processed, from: MlStart, opts: &MlOptions, ctl: &Control) -> Result<(LsFit, MlInfo)> {
    let MlStart { cols, theta: start, scale } = from;
    let cov = pr.joint_cov.as_ref().ok_or_else(|| {
        Error::invalid(
            "maximum likelihood",
            "repetitions",
            "needs at least 2 repetitions to estimate the noise covariance of positions and torques",
        )
    })?;
    let n = robot.dof();
    let p = robot.n_params();
    let k = cols.len();
    let m = pr.len();
    let nr = pr.n_reps as f64;
    let mats: Vec<Vec<f64>> = (0..m)
        .into_par_iter()
        .map_init(
            || {
                (
                    Workspace::new(robot),
                    vec![0.0; n * p],
                    vec![vec![0.0; n * p]; n],
                    vec![vec![0.0; n * p]; n],
                    vec![vec![0.0; n * p]; n],
                )
            },
            |(ws, y, dq, dqd, dqdd), i| {
                regressor_derivatives(robot, ws, &pr.q[i], &pr.qd[i], &pr.qdd[i], y, dq, dqd, dqdd);
                let mut out = vec![0.0; (1 + 3 * n) * n * k];
                let sel = |src: &[f64], dst: &mut [f64]| {
                    for r in 0..n {
                        for (c, &ci) in cols.iter().enumerate() {
                            dst[r * k + c] = src[r * p + base.independent[ci]];
                        }
                    }
                };
                let nk = n * k;
                sel(y, &mut out[..nk]);
                for (g, set) in [(0usize, &*dq), (1, &*dqd), (2, &*dqdd)] {
                    for kk in 0..n {
                        let m_idx = g * n + kk;
                        sel(&set[kk], &mut out[(m_idx + 1) * nk..(m_idx + 2) * nk]);
                    }
                }
                out
            },
        )
        .collect();
    let data = MlData {
        n,
        k,
        mats,
        tau: pr.tau.clone(),
        sig: {
            // pooled over time: a stationary noise model estimated from all N_r·N deviations
            // (per-sample 4n×4n covariances from a few repetitions are too noisy)
            let d = cov[0].len();
            let mut pooled = vec![0.0; d];
            for c in cov {
                for (a, v) in pooled.iter_mut().zip(c) {
                    *a += v / (m as f64 * nr);
                }
            }
            vec![pooled]
        },
    };
    let sc: Vec<f64> = scale.iter().map(|s| if s.is_finite() && *s > 0.0 { *s } else { 1.0 }).collect();
    let x0 = start.to_vec();
    let to_theta = |z: &[f64]| -> Vec<f64> { (0..k).map(|a| x0[a] + sc[a] * z[a]).collect() };
    let cost_start = data.cost_grad(start, None);
    let obj = |z: &[f64], grad: Option<&mut [f64]>, _: &mut ()| -> f64 {
        let th = to_theta(z);
        match grad {
            Some(g) => {
                let c = data.cost_grad(&th, Some(g));
                for a in 0..k {
                    g[a] *= sc[a];
                }
                c
            }
            None => data.cost_grad(&th, None),
        }
    };
    // a trust region of ±bound WLS standard deviations: without a log-det term the
    // errors-in-variables cost stays bounded as |θ| → ∞ and can drift there on noisy data;
    // the bridge stops it on the control (Ctrl-C, deadline → maxtime, evaluation budget)
    let mut z = vec![0.0; k];
    let run = Problem::new(Algorithm::Lbfgs, vec![-opts.bound; k], vec![opts.bound; k], ctl)
        .max_evals(opts.max_eval)
        .ftol_rel(opts.ftol_rel)
        .xtol_rel(1e-10)
        .minimise(&mut z, obj, ());
    let status = run.status;
    let mut theta = to_theta(&z);
    let mut cost_end = data.cost_grad(&theta, None);
    if cost_end.is_nan() || cost_end > cost_start {
        theta = start.to_vec();
        cost_end = cost_start;
    }
    let f = data.fisher(&theta);
    let (_, s, v) = crate::linalg::thin_svd(&f)?;
    let rank = s.iter().filter(|&&x| x > 1e-12 * s[0]).count();
    let mut vs = v.clone();
    for (j, mut c) in vs.column_iter_mut().enumerate() {
        c *= if j < rank { 1.0 / s[j].sqrt() } else { 0.0 };
    }
    let covm = &vs * vs.transpose();
    let std: Vec<f64> = (0..k).map(|i| covm[(i, i)].max(0.0).sqrt()).collect();
    let chi2 = 2.0 * cost_end / ((n * m).saturating_sub(k)).max(1) as f64;
    // condition numbers of the (unweighted) regressor at the filtered states
    let c = DMatrix::from_fn(n * m, k, |r, cc| {
        let (j, i) = (r / m, r % m);
        data.mats[i][j * k + cc]
    });
    Ok((
        LsFit {
            rel_std: std
                .iter()
                .zip(&theta)
                .map(|(s, t)| if *t != 0.0 { s / t.abs() } else { f64::INFINITY })
                .collect(),
            theta,
            std,
            cov: covm,
            rank,
            cond: cond(&c)?,
            cond_normalized: cond_normalized(&c)?,
            chi2_dof: chi2,
        },
        MlInfo {
            status,
            cost_start,
            cost_end,
            evaluations: run.evaluations as usize,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    #[test]
    fn ml_gradient_matches_finite_differences() {
        let (n, k, m) = (2usize, 3usize, 5usize);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut r = || rng.random_range(-1.0..1.0);
        let mats: Vec<Vec<f64>> = (0..m).map(|_| (0..(1 + 3 * n) * n * k).map(|_| r()).collect()).collect();
        let tau: Vec<Vec<f64>> = (0..m).map(|_| (0..n).map(|_| r()).collect()).collect();
        let d = 4 * n;
        let a = DMatrix::from_fn(d, d, |_, _| r());
        let sig = (&a * a.transpose() * 0.1 + DMatrix::identity(d, d) * 0.05).as_slice().to_vec();
        let data = MlData {
            n,
            k,
            mats,
            tau,
            sig: vec![sig],
        };
        let th = [0.3, -0.7, 0.5];
        let mut g = vec![0.0; k];
        let c0 = data.cost_grad(&th, Some(&mut g));
        for a in 0..k {
            let h = 1e-6;
            let mut tp = th;
            tp[a] += h;
            let mut tm = th;
            tm[a] -= h;
            let fd = (data.cost_grad(&tp, None) - data.cost_grad(&tm, None)) / (2.0 * h);
            assert!((fd - g[a]).abs() < 1e-6 * (1.0 + fd.abs()), "∂/∂θ{a}: analytic {} vs fd {fd} (cost {c0})", g[a]);
        }
    }

    #[test]
    fn projection_of_a_signal_in_the_reference_span_is_exact() {
        // u = 2 r(t−1) + 0.5 r(t+2) + 1 is reproduced by lags M1 = 2, M2 = 1
        let m = 64;
        let r: Vec<Vec<f64>> = (0..m).map(|p| vec![(0.3 * p as f64).sin() + 0.2 * (0.71 * p as f64).cos()]).collect();
        let u = DVector::from_fn(m, |p, _| 2.0 * r[(p + m - 1) % m][0] + 0.5 * r[(p + 2) % m][0] + 1.0);
        let basis = orthonormal_instruments(&r, 2, 1, true).unwrap();
        let uh = project(&basis, &u);
        assert!((uh - &u).amax() < 1e-9);
        // white noise is mostly not in the span
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let e = DVector::from_fn(m, |_, _| rng.random_range(-1.0..1.0));
        assert!(project(&basis, &e).norm() < 0.6 * e.norm());
    }
}
