//! The linear identification problem y = C θ + e on the base parameters
//! (paper 000 eq. 4) and its least-squares estimators.
//!
//! Rows are stacked joint by joint (y = [τ̄_1(t_1..t_N), …, τ̄_n(t_1..t_N)]),
//! as in the block-diagonal weight matrix W = diag(W_1⁻¹, …, W_n⁻¹) of
//! eq. 8–9. Each row's variance is that of an averaged torque,
//! var(τ̄_{j,p}) = σ²_{j,p}/N_r with σ²_{j,p} the sample variance of eq. 7.
//!
//! * WLS (eq. 5): θ̂ = (CᵀWC)⁻¹CᵀWy with W = diag(1/var(τ̄)); covariance
//!   (eq. 13) var θ̂ = (CᵀWC)⁻¹ = (1/N_r)(CᵀW̃C)⁻¹ with W̃ the inverse sample
//!   variances; relative standard deviations σ*_i = σ_i/|θ̂_i| (eq. 14).
//! * OLS: θ̂ = C⁺y; covariance C⁺ diag(var τ̄) C⁺ᵀ when the variances are known,
//!   else s²(CᵀC)⁻¹ with s² the residual variance.
//!
//! Both are solved by a thin SVD of √W C (faer); directions with singular
//! values below 1e-10·σ_max are reported as rank deficiency (minimum-norm solution).

use crate::error::{Error, Result};
use crate::params::BaseParams;
use crate::robot::{regressor_rows, ParamSign, Robot, Workspace};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

/// The stacked identification problem.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Number of joints n.
    pub n: usize,
    /// Samples per joint N (before rows were left out).
    pub n_samples: usize,
    /// Design matrix C (rows × columns); rows joint-major, row i is joint `joint[i]` at sample `sample[i]`.
    pub c: DMatrix<f64>,
    /// Torques y.
    pub y: DVector<f64>,
    /// Variances of y (of the averaged torques), if known.
    pub var: Option<DVector<f64>>,
    /// Column names.
    pub names: Vec<String>,
    /// Joint of each row.
    pub joint: Vec<usize>,
    /// Sample index of each row.
    pub sample: Vec<usize>,
}

/// Builds the base regressor stack for processed samples (q, q̇, q̈ per sample)
/// and torques; rows joint-major (row j·N + p). Regressor rows are evaluated
/// in parallel, one workspace per thread.
pub fn base_design(robot: &Robot, base: &BaseParams, q: &[Vec<f64>], qd: &[Vec<f64>], qdd: &[Vec<f64>]) -> DMatrix<f64> {
    base_design_dead_band(robot, base, q, qd, qdd, 0.0)
}

/// [`base_design`] with the Coulomb dead band: in the row of a joint whose
/// Coulomb term has the `sign` shape, the Coulomb columns (Fc, Fc±) are 0
/// where |q̇_j| < `dead_band` (at rest); every other term (rigid body,
/// viscous) sees the velocities as they are.
pub fn base_design_dead_band(robot: &Robot, base: &BaseParams, q: &[Vec<f64>], qd: &[Vec<f64>], qdd: &[Vec<f64>], dead_band: f64) -> DMatrix<f64> {
    use crate::robot::ParamKind;
    let coulomb: Vec<(usize, usize)> = if dead_band > 0.0 {
        robot
            .params()
            .iter()
            .enumerate()
            .filter(|(_, i)| matches!(i.kind, ParamKind::Fc | ParamKind::FcPos | ParamKind::FcNeg) && robot.drives[i.joint].discontinuous_at_rest())
            .map(|(c, i)| (c, i.joint))
            .collect()
    } else {
        Vec::new()
    };
    let n = robot.dof();
    let p = robot.n_params();
    let nb = base.n_base();
    let m = q.len();
    let rows: Vec<Vec<f64>> = (0..m)
        .into_par_iter()
        .map_init(
            || (Workspace::new(robot), vec![0.0; n * p]),
            |(ws, y), k| {
                regressor_rows(robot, ws, &q[k], &qd[k], &qdd[k], y);
                for &(c, j) in &coulomb {
                    if qd[k][j].abs() < dead_band {
                        y[j * p + c] = 0.0;
                    }
                }
                let mut out = vec![0.0; n * nb];
                base.select_rows(y, n, &mut out);
                out
            },
        )
        .collect();
    DMatrix::from_fn(n * m, nb, |r, c| {
        let (j, k) = (r / m, r % m);
        rows[k][j * nb + c]
    })
}

/// Default Coulomb dead band (rad/s or m/s, the study's `dead_band`):
/// the speed below which the default speed rule (`min_speed`) already calls
/// the sign of a measured velocity unreliable. A robot at rest logs noise
/// around zero (a 4-decimal log flips sign every sample, ~1e-4 rad/s); a
/// joint crawling slower than 0.01 rad/s carries no usable Coulomb equation.
pub const DEAD_BAND: f64 = 0.01;

impl Dataset {
    /// [`Dataset::every_row`] with the Coulomb dead band
    /// ([`base_design_dead_band`]): the rows of the `sign`-shaped joints at
    /// |q̇_j| < `dead_band` have no Coulomb term. Used alike for estimation
    /// and validation.
    pub fn every_row_dead_band(robot: &Robot, base: &BaseParams, pr: &super::Processed, dead_band: f64) -> Dataset {
        let n = robot.dof();
        let m = pr.len();
        let c = base_design_dead_band(robot, base, &pr.q, &pr.qd, &pr.qdd, dead_band);
        let y = DVector::from_iterator(n * m, (0..n * m).map(|r| pr.tau[r % m][r / m]));
        let var = pr
            .tau_var
            .as_ref()
            .map(|v| DVector::from_iterator(n * m, (0..n * m).map(|r| v[r % m][r / m] / pr.n_reps as f64)));
        Dataset {
            n,
            n_samples: m,
            c,
            y,
            var,
            names: base.names.clone(),
            joint: (0..n * m).map(|r| r / m).collect(),
            sample: (0..n * m).map(|r| r % m).collect(),
        }
    }

    /// Builds the dataset of a processed run. Rows of joint j at samples where
    /// |q̇_j| < max(`slow_ratio` · max_p |q̇_j(p)|, `min_speed`) are left out:
    /// near zero velocity the sign of the estimated velocity is unreliable and
    /// Coulomb friction is undefined at rest (a drive holding still chatters
    /// between ±F_c), which biases the friction estimates; a joint that never
    /// moves faster than `min_speed` contributes no rows (its friction columns
    /// vanish and the rank check of the reduction removes them).
    /// `slow_ratio = min_speed = 0` keeps every row.
    pub fn new(robot: &Robot, base: &BaseParams, pr: &super::Processed, slow_ratio: f64, min_speed: f64) -> Dataset {
        Dataset::every_row(robot, base, pr).moving_rows(pr, slow_ratio, min_speed)
    }

    /// The dataset of every sample of a processed run (no row left out): the
    /// rows paper 000's e_j, e*_j (eq. 11–12) are defined on.
    pub fn every_row(robot: &Robot, base: &BaseParams, pr: &super::Processed) -> Dataset {
        Dataset::every_row_dead_band(robot, base, pr, 0.0)
    }

    /// The rows of a complete dataset ([`Dataset::every_row`] of `pr`) that
    /// [`Dataset::new`] keeps: joint j at samples with |q̇_j| ≥
    /// max(`slow_ratio` · max_p |q̇_j(p)|, `min_speed`).
    pub fn moving_rows(&self, pr: &super::Processed, slow_ratio: f64, min_speed: f64) -> Dataset {
        self.moving_rows_of(pr, slow_ratio, min_speed, &vec![true; self.n])
    }

    /// [`Dataset::moving_rows`] applied only to the joints with `drop[j]`
    /// (the joints whose friction is discontinuous at rest); the other
    /// joints keep every row.
    pub fn moving_rows_of(&self, pr: &super::Processed, slow_ratio: f64, min_speed: f64, drop: &[bool]) -> Dataset {
        let n = self.n;
        let m = self.n_samples;
        let vmax: Vec<f64> = (0..n).map(|j| pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max)).collect();
        let keep: Vec<usize> = (0..n * m)
            .filter(|&r| {
                let thr = (slow_ratio * vmax[r / m]).max(min_speed);
                !drop[r / m] || thr <= 0.0 || pr.qd[r % m][r / m].abs() >= thr
            })
            .collect();
        if keep.len() == n * m {
            return self.clone();
        }
        Dataset {
            n,
            n_samples: m,
            c: self.c.select_rows(keep.iter()),
            y: DVector::from_iterator(keep.len(), keep.iter().map(|&r| self.y[r])),
            var: self.var.as_ref().map(|v| DVector::from_iterator(keep.len(), keep.iter().map(|&r| v[r]))),
            names: self.names.clone(),
            joint: keep.iter().map(|&r| r / m).collect(),
            sample: keep.iter().map(|&r| r % m).collect(),
        }
    }

    /// True when no row was left out (row j·N + p is joint j at sample p).
    pub fn is_complete(&self) -> bool {
        self.c.nrows() == self.n * self.n_samples
    }

    /// The dataset restricted to the given columns.
    pub fn columns(&self, cols: &[usize]) -> Dataset {
        Dataset {
            c: self.c.select_columns(cols.iter()),
            names: cols.iter().map(|&c| self.names[c].clone()).collect(),
            ..self.clone()
        }
    }
}

/// Weights of the WLS estimator (`--weights`: `sample`, `joint`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Weights {
    /// Per joint and time step, the inverse sample variances (paper 000 eq. 7–9).
    #[default]
    Sample,
    /// Per joint, the inverse of the joint's mean sample variance (robust for small N_r).
    Joint,
}

impl Weights {
    /// The name on the command line and in files (`sample`, `joint`).
    pub fn name(self) -> &'static str {
        match self {
            Weights::Sample => "sample",
            Weights::Joint => "joint",
        }
    }
}

/// The name of [`Weights::name`].
impl std::fmt::Display for Weights {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Parses [`Weights::name`]; the error lists the allowed values.
impl std::str::FromStr for Weights {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Weights> {
        match s {
            "sample" => Ok(Weights::Sample),
            "joint" => Ok(Weights::Joint),
            _ => Err(crate::Error::invalid("identify", "weights", format!("expected sample or joint, found `{s}`"))),
        }
    }
}

/// A least-squares fit.
#[derive(Debug, Clone, Serialize)]
pub struct LsFit {
    /// Estimates.
    pub theta: Vec<f64>,
    /// Covariance (row-major, k × k).
    #[serde(skip)]
    pub cov: DMatrix<f64>,
    /// Standard deviations σ_i.
    pub std: Vec<f64>,
    /// Relative standard deviations σ*_i = σ_i/|θ̂_i| (eq. 14).
    pub rel_std: Vec<f64>,
    /// Numerical rank of the (weighted) design matrix.
    pub rank: usize,
    /// Condition number of the design matrix C.
    pub cond: f64,
    /// Condition number of C with unit-norm columns.
    pub cond_normalized: f64,
    /// Weighted residual sum of squares divided by the degrees of freedom
    /// (≈ 1 when the residuals are at the noise floor the variances predict).
    pub chi2_dof: f64,
}

/// Rows per block of [`r_factor`].
const QR_BLOCK: usize = 512;

/// The triangular factor R (k × k, k = columns; fewer rows when `a` has fewer
/// rows than columns) of the QR decomposition of `a`, computed blockwise
/// (TSQR): fixed blocks of `QR_BLOCK` rows are factorised (in parallel),
/// then their factors are stacked and re-factorised one after the other in
/// block order. The floating-point operations do not depend on the number of
/// threads, so neither do the results (RᵀR = aᵀa, and R has the singular
/// values of `a`).
pub fn r_factor(a: &DMatrix<f64>) -> DMatrix<f64> {
    let (m, k) = a.shape();
    let blocks: Vec<DMatrix<f64>> = (0..m.div_ceil(QR_BLOCK).max(1))
        .into_par_iter()
        .map(|b| {
            let r0 = b * QR_BLOCK;
            let r1 = (r0 + QR_BLOCK).min(m);
            let blk = a.rows(r0, r1 - r0).into_owned();
            if blk.nrows() == 0 {
                DMatrix::zeros(0, k)
            } else {
                blk.qr().r()
            }
        })
        .collect();
    let mut r = DMatrix::zeros(0, k);
    for blk in blocks {
        if r.nrows() == 0 {
            r = blk;
            continue;
        }
        let mut st = DMatrix::zeros(r.nrows() + blk.nrows(), k);
        st.rows_mut(0, r.nrows()).copy_from(&r);
        st.rows_mut(r.nrows(), blk.nrows()).copy_from(&blk);
        r = st.qr().r();
    }
    r
}

/// Singular values of a small matrix, decreasing (nalgebra's SVD, sequential).
fn small_singular_values(r: &DMatrix<f64>) -> Result<Vec<f64>> {
    if r.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("matrix has non-finite entries; cannot compute singular values".into()));
    }
    let mut s: Vec<f64> = r.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    Ok(s)
}

/// Condition number (σ_max/σ_min) of a matrix; ∞ if singular.
pub fn cond(c: &DMatrix<f64>) -> Result<f64> {
    if c.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("matrix has non-finite entries; cannot compute singular values".into()));
    }
    let s = small_singular_values(&r_factor(c))?;
    let (mx, mn) = (s[0], s[s.len() - 1]);
    Ok(if s.len() < c.ncols() || mn <= 0.0 { f64::INFINITY } else { mx / mn })
}

/// Condition number of C with columns scaled to unit norm.
pub fn cond_normalized(c: &DMatrix<f64>) -> Result<f64> {
    let mut cn = c.clone();
    for mut col in cn.column_iter_mut() {
        let nrm = col.norm();
        if nrm > 0.0 {
            col /= nrm;
        }
    }
    cond(&cn)
}

/// (θ, (AᵀA)⁺ = V S⁻² Vᵀ, rank) of [`solve_factor`].
pub type SvdSolution = (DVector<f64>, DMatrix<f64>, usize);

/// Solves min ‖√w ⊙ (y − C θ)‖² with A = √W C: the blockwise R factor of
/// [A | √W y] ([`r_factor`], independent of the thread count), then the SVD of
/// its k × k part R = U S Vᵀ; θ = V S⁻¹ Uᵀ (Qᵀ√W y) on the directions with
/// singular values above 1e-10·σ_max (minimum-norm solution otherwise).
/// Returns (θ, (AᵀA)⁺ = V S⁻² Vᵀ, rank).
fn weighted_svd_solve(c: &DMatrix<f64>, y: &DVector<f64>, sw: &DVector<f64>) -> Result<SvdSolution> {
    let k = c.ncols();
    let mut a = DMatrix::zeros(c.nrows(), k + 1);
    a.columns_mut(0, k).copy_from(c);
    a.set_column(k, y);
    for (i, mut row) in a.row_iter_mut().enumerate() {
        row *= sw[i];
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("the weighted design matrix has non-finite entries".into()));
    }
    solve_factor(&r_factor(&a), k)
}

/// The least-squares solution from the triangular factor `ra` of [A | b]
/// (k + 1 columns, any number of rows ≥ 0): the SVD of its k × k part
/// R = U S Vᵀ; θ = V S⁻¹ Uᵀ (Qᵀb) on the directions with singular values
/// above 1e-10·σ_max (minimum-norm otherwise). Returns (θ, (AᵀA)⁺, rank).
pub fn solve_factor(ra: &DMatrix<f64>, k: usize) -> Result<SvdSolution> {
    let kr = ra.nrows().min(k);
    let r = ra.view((0, 0), (kr, k)).into_owned();
    let qtb = ra.view((0, k), (kr, 1)).into_owned();
    let svd = r.svd(true, true);
    let (u, vt) = match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => (u, vt),
        _ => return Err(Error::Numerical("SVD of the triangular factor failed".into())),
    };
    let s = svd.singular_values;
    let smax = s.iter().cloned().fold(0.0, f64::max);
    let rank = s.iter().filter(|&&x| x > 1e-10 * smax).count();
    let mut theta = DVector::zeros(k);
    let mut cov = DMatrix::zeros(k, k);
    for i in 0..s.len() {
        if s[i] > 1e-10 * smax {
            let vi = vt.row(i).transpose();
            let coef = u.column(i).dot(&qtb.column(0)) / s[i];
            theta.axpy(coef, &vi, 1.0);
            cov += &vi * vi.transpose() / (s[i] * s[i]);
        }
    }
    Ok((theta, cov, rank))
}

/// The fit of an estimate with its covariance: σ_i, σ*_i, the condition
/// numbers of `c` (as given and with unit-norm columns) and χ²/dof.
pub fn finish(theta: DVector<f64>, cov: DMatrix<f64>, rank: usize, c: &DMatrix<f64>, chi2_dof: f64) -> Result<LsFit> {
    let std: Vec<f64> = (0..theta.len()).map(|i| cov[(i, i)].max(0.0).sqrt()).collect();
    let rel_std = std
        .iter()
        .zip(theta.iter())
        .map(|(s, t)| if *t != 0.0 { s / t.abs() } else { f64::INFINITY })
        .collect();
    Ok(LsFit {
        theta: theta.as_slice().to_vec(),
        cov,
        std,
        rel_std,
        rank,
        cond: cond(c)?,
        cond_normalized: cond_normalized(c)?,
        chi2_dof,
    })
}

fn check(ds: &Dataset) -> Result<()> {
    if ds.c.ncols() == 0 {
        return Err(Error::Numerical("no parameters left to estimate".into()));
    }
    if ds.c.nrows() <= ds.c.ncols() {
        return Err(Error::Numerical(format!(
            "{} equations for {} parameters: the run is too short",
            ds.c.nrows(),
            ds.c.ncols()
        )));
    }
    Ok(())
}

/// Per-row variances for WLS: the sample variances (eq. 7, divided by N_r), or
/// their per-joint means; without repetitions, the per-joint residual variance of OLS.
pub fn row_variances(ds: &Dataset, weights: Weights) -> Result<DVector<f64>> {
    let per_joint_mean = |v: &DVector<f64>| -> DVector<f64> {
        let mut sum = vec![0.0; ds.n];
        let mut cnt = vec![0usize; ds.n];
        for (i, &j) in ds.joint.iter().enumerate() {
            sum[j] += v[i];
            cnt[j] += 1;
        }
        DVector::from_iterator(v.len(), ds.joint.iter().map(|&j| sum[j] / cnt[j].max(1) as f64))
    };
    let var = match (&ds.var, weights) {
        (Some(v), Weights::Sample) => v.clone(),
        (Some(v), Weights::Joint) => per_joint_mean(v),
        (None, Weights::Sample) => {
            return Err(Error::invalid(
                "identify",
                "repetition_weights",
                "sample weights (paper 000 eq. 7–9) need the per-sample torque variances: a run of N_r ≥ 2 repetitions, or an averaged run with var_tau columns; use repetition_weights = \"joint\" (per-joint residual variance of OLS) or method = \"ols\"",
            ))
        }
        (None, Weights::Joint) => {
            let ones = DVector::from_element(ds.y.len(), 1.0);
            let (th, _, _) = weighted_svd_solve(&ds.c, &ds.y, &ones)?;
            let r = &ds.y - &ds.c * th;
            let dof = (ds.y.len() - ds.c.ncols()).max(1) as f64 / ds.y.len() as f64;
            per_joint_mean(&r.map(|x| x * x / dof))
        }
    };
    // a zero variance (e.g. quantised torques that never changed) would give an infinite weight
    let floor = var.iter().cloned().fold(0.0, f64::max) * 1e-12 + 1e-300;
    Ok(var.map(|v| v.max(floor)))
}

/// Weighted least squares (paper 000 eq. 5, 8–9, 13–14).
pub fn wls(ds: &Dataset, weights: Weights) -> Result<LsFit> {
    check(ds)?;
    let var = row_variances(ds, weights)?;
    let sw = var.map(|v| 1.0 / v.sqrt());
    let (theta, cov, rank) = weighted_svd_solve(&ds.c, &ds.y, &sw)?;
    let r = (&ds.y - &ds.c * &theta).component_mul(&sw);
    let chi2 = r.norm_squared() / (ds.y.len() - rank).max(1) as f64;
    finish(theta, cov, rank, &ds.c, chi2)
}

/// Ordinary least squares with the sandwich covariance C⁺ diag(var) C⁺ᵀ
/// (or s²(CᵀC)⁻¹ without variances).
pub fn ols(ds: &Dataset) -> Result<LsFit> {
    check(ds)?;
    let ones = DVector::from_element(ds.y.len(), 1.0);
    let (theta, cov0, rank) = weighted_svd_solve(&ds.c, &ds.y, &ones)?;
    let r = &ds.y - &ds.c * &theta;
    let (cov, chi2) = match &ds.var {
        Some(v) => {
            // C⁺ diag(v) C⁺ᵀ = (CᵀC)⁺ (Cᵀ diag(v) C) (CᵀC)⁺, with Cᵀ diag(v) C = R_vᵀ R_v
            let mut cv = ds.c.clone();
            for (i, mut row) in cv.row_iter_mut().enumerate() {
                row *= v[i].max(0.0).sqrt();
            }
            let rv = r_factor(&cv);
            let g = rv.transpose() * &rv;
            let chi2 = r.iter().zip(v.iter()).map(|(e, s)| e * e / s).sum::<f64>() / (ds.y.len() - rank).max(1) as f64;
            (&cov0 * g * &cov0, chi2)
        }
        None => {
            let s2 = r.norm_squared() / (ds.y.len() - rank).max(1) as f64;
            (cov0 * s2, 1.0)
        }
    };
    finish(theta, cov, rank, &ds.c, chi2)
}

/// Mean absolute prediction error per joint e_j (eq. 11) and relative error e*_j (eq. 12).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Errors {
    /// e_j (N·m).
    pub e: Vec<f64>,
    /// e*_j (fraction, ×100 for %).
    pub e_rel: Vec<f64>,
    /// RMS residual per joint (N·m).
    pub rms: Vec<f64>,
    /// Noise floor of e_j if the torque variances are known: E|ε| = σ √(2/π) of the averaged torque (N·m).
    pub noise_floor: Option<Vec<f64>>,
}

/// Prediction errors of estimate `theta` on dataset `ds` (columns as in `ds`).
pub fn errors(ds: &Dataset, theta: &[f64]) -> Errors {
    let pred = &ds.c * DVector::from_column_slice(theta);
    let mut e = vec![0.0; ds.n];
    let mut mag = vec![0.0; ds.n];
    let mut rms = vec![0.0; ds.n];
    let mut cnt = vec![0usize; ds.n];
    let mut floor = vec![0.0; ds.n];
    for (i, &j) in ds.joint.iter().enumerate() {
        let d = ds.y[i] - pred[i];
        e[j] += d.abs();
        rms[j] += d * d;
        mag[j] += ds.y[i].abs();
        cnt[j] += 1;
        if let Some(v) = &ds.var {
            floor[j] += v[i].sqrt();
        }
    }
    let c = |j: usize| cnt[j].max(1) as f64;
    let noise_floor = ds
        .var
        .as_ref()
        .map(|_| (0..ds.n).map(|j| floor[j] / c(j) * (2.0 / std::f64::consts::PI).sqrt()).collect());
    Errors {
        e_rel: (0..ds.n).map(|j| if mag[j] > 0.0 { e[j] / mag[j] } else { 0.0 }).collect(),
        e: (0..ds.n).map(|j| e[j] / c(j)).collect(),
        rms: (0..ds.n).map(|j| (rms[j] / c(j)).sqrt()).collect(),
        noise_floor,
    }
}

/// Base parameters that must be positive: every standard parameter in their
/// combination enters with a positive coefficient and is itself non-negative
/// for any physical robot (masses, inertias XX/YY/ZZ about the link origin,
/// rotor inertias, symmetric Coulomb and viscous friction, Fc⁺, Fv⁺, Fv⁻:
/// [`ParamKind::sign`](crate::robot::ParamKind::sign)).
pub fn must_be_positive(robot: &Robot, base: &BaseParams) -> Vec<bool> {
    let info = robot.params();
    (0..base.n_base())
        .map(|i| {
            let row = base.k.row(i);
            let mut any = false;
            for (c, &v) in row.iter().enumerate() {
                if v == 0.0 {
                    continue;
                }
                let nonneg = info[c].kind.sign() == ParamSign::NonNegative;
                if v < 0.0 || !nonneg {
                    return false;
                }
                any = true;
            }
            any
        })
        .collect()
}
