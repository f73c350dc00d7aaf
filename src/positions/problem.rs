//! The relaxed allocation problem in factored form, and the criterion
//! functions with their gradients (the "sensitivities" of the equivalence
//! theorem).
//!
//! Candidate i contributes the information F_i = H_i H_iᵀ (p×p, H_i p×r_i).
//! With weights w on the simplex (w ≥ 0, Σ w_i = 1) and an optional prior F_0,
//!
//! M(w) = F_0 + Σ_i w_i F_i.
//!
//! Criteria (all in the units of the given matrices):
//!
//! | criterion | value Φ(w) | sense | sensitivity s_i(w) = directional derivative towards candidate i |
//! |---|---|---|---|
//! | D | log det M | max | d_i = tr(M⁻¹F_i) |
//! | A | tr M⁻¹ | min | a_i = tr(M⁻²F_i) |
//! | E | λ_min(M) | max | e_i = tr(Z F_i), Z ⪰ 0, tr Z = 1 on the min eigenspace |
//!
//! The factors are stored side by side in one p×R matrix so that M(w) and all
//! sensitivities are two dense products (M = G diag(ŵ) Gᵀ, d = colsum(G ∘ M⁻¹G)).

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Design criterion of the relaxed allocation problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// D-optimal: maximise log det M(w) (minimum volume of the confidence ellipsoid).
    #[default]
    #[serde(alias = "D")]
    D,
    /// A-optimal: minimise tr M(w)⁻¹ (sum of the parameter variances).
    #[serde(alias = "A")]
    A,
    /// E-optimal: maximise λ_min(M(w)) (worst-direction variance).
    #[serde(alias = "E")]
    E,
}

impl Criterion {
    /// Name for reports ("D", "A", "E").
    pub fn label(self) -> &'static str {
        match self {
            Criterion::D => "D",
            Criterion::A => "A",
            Criterion::E => "E",
        }
    }
    /// What the value means, for reports.
    pub fn value_label(self) -> &'static str {
        match self {
            Criterion::D => "log det M(w)",
            Criterion::A => "tr M(w)^-1",
            Criterion::E => "lambda_min M(w)",
        }
    }
}

/// Candidates in factored form, optionally with a prior.
#[derive(Debug, Clone)]
pub struct Problem {
    p: usize,
    /// p × R: the factors H_i side by side.
    g: DMatrix<f64>,
    /// Candidate i owns columns off[i]..off[i+1] of `g`.
    off: Vec<usize>,
    /// Prior information F_0 (p×p) and a factor of it (p×r_0).
    prior: Option<(DMatrix<f64>, DMatrix<f64>)>,
}

/// Relative eigenvalue threshold below which a factor column is dropped.
const RANK_TOL: f64 = 1e-13;

/// Symmetric PSD factor F = H Hᵀ from an eigendecomposition; eigenvalues below
/// `RANK_TOL·λ_max` are dropped. Errors if F is not symmetric PSD (relative
/// tolerance 1e-8) or not finite.
pub fn psd_factor(f: &DMatrix<f64>, what: &str) -> Result<DMatrix<f64>> {
    let p = f.nrows();
    if f.ncols() != p {
        return Err(Error::dim(format!("{what}: columns of a square matrix"), p, f.ncols()));
    }
    if f.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical(format!("{what}: matrix has non-finite entries")));
    }
    let scale = f.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for i in 0..p {
        for j in 0..i {
            if (f[(i, j)] - f[(j, i)]).abs() > 1e-8 * scale.max(f64::MIN_POSITIVE) {
                return Err(Error::Numerical(format!(
                    "{what}: matrix is not symmetric (entry ({}, {}) = {:e} but ({}, {}) = {:e})",
                    i + 1,
                    j + 1,
                    f[(i, j)],
                    j + 1,
                    i + 1,
                    f[(j, i)]
                )));
            }
        }
    }
    if scale == 0.0 {
        return Ok(DMatrix::zeros(p, 0));
    }
    let sym = (f + f.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let lmax = eig.eigenvalues.max();
    let lmin = eig.eigenvalues.min();
    if lmin < -1e-8 * lmax.abs().max(scale) {
        return Err(Error::Numerical(format!(
            "{what}: matrix is not positive semidefinite (smallest eigenvalue {lmin:e}, largest {lmax:e})"
        )));
    }
    let keep: Vec<usize> = (0..p).filter(|&k| eig.eigenvalues[k] > RANK_TOL * lmax).collect();
    Ok(DMatrix::from_fn(p, keep.len(), |i, c| {
        eig.eigenvectors[(i, keep[c])] * eig.eigenvalues[keep[c]].sqrt()
    }))
}

impl Problem {
    /// Builds the problem from factors H_i (each p×r_i, F_i = H_i H_iᵀ) and an
    /// optional prior F_0 (p×p PSD).
    pub fn from_factors(p: usize, factors: &[DMatrix<f64>], prior: Option<&DMatrix<f64>>) -> Result<Problem> {
        if p == 0 {
            return Err(Error::invalid("positions", "parameters", "at least one parameter is needed"));
        }
        if factors.is_empty() {
            return Err(Error::invalid("positions", "candidates", "no candidates"));
        }
        let total: usize = factors.iter().map(|h| h.ncols()).sum();
        let mut g = DMatrix::zeros(p, total);
        let mut off = Vec::with_capacity(factors.len() + 1);
        off.push(0);
        let mut c0 = 0;
        for (i, h) in factors.iter().enumerate() {
            if h.nrows() != p {
                return Err(Error::dim(format!("rows of the factor of candidate {}", i + 1), p, h.nrows()));
            }
            if h.iter().any(|v| !v.is_finite()) {
                return Err(Error::Numerical(format!("candidate {}: information has non-finite entries", i + 1)));
            }
            g.columns_mut(c0, h.ncols()).copy_from(h);
            c0 += h.ncols();
            off.push(c0);
        }
        let prior = match prior {
            Some(f0) => {
                if f0.nrows() != p || f0.ncols() != p {
                    return Err(Error::dim("prior information size", p, f0.nrows()));
                }
                let h0 = psd_factor(f0, "prior information")?;
                Some(((f0 + f0.transpose()) * 0.5, h0))
            }
            None => None,
        };
        Ok(Problem { p, g, off, prior })
    }

    /// Builds the problem from information matrices F_i (each p×p symmetric PSD).
    pub fn from_matrices(mats: &[DMatrix<f64>], prior: Option<&DMatrix<f64>>) -> Result<Problem> {
        let p = mats.first().map(|m| m.nrows()).unwrap_or(0);
        let factors = mats
            .iter()
            .enumerate()
            .map(|(i, f)| {
                if f.nrows() != p {
                    return Err(Error::dim(format!("size of the information matrix of candidate {}", i + 1), p, f.nrows()));
                }
                psd_factor(f, &format!("candidate {}", i + 1))
            })
            .collect::<Result<Vec<_>>>()?;
        Problem::from_factors(p, &factors, prior)
    }

    /// Number of parameters p.
    pub fn p(&self) -> usize {
        self.p
    }
    /// Number of candidates.
    pub fn n(&self) -> usize {
        self.off.len() - 1
    }
    /// Rank r_i of candidate i's information (columns of its factor).
    pub fn rank(&self, i: usize) -> usize {
        self.off[i + 1] - self.off[i]
    }
    /// The first column of H_i in [`Problem::stacked`].
    pub fn offset(&self, i: usize) -> usize {
        self.off[i]
    }
    /// The factor H_i (p × r_i).
    pub fn factor(&self, i: usize) -> nalgebra::DMatrixView<'_, f64> {
        self.g.columns(self.off[i], self.rank(i))
    }
    /// All factors side by side (p × R).
    pub fn stacked(&self) -> &DMatrix<f64> {
        &self.g
    }
    /// F_i = H_i H_iᵀ.
    pub fn matrix(&self, i: usize) -> DMatrix<f64> {
        let h = self.factor(i);
        h * h.transpose()
    }
    /// The prior F_0, if any.
    pub fn prior(&self) -> Option<&DMatrix<f64>> {
        self.prior.as_ref().map(|p| &p.0)
    }
    /// A factor H_0 of the prior (F_0 = H_0 H_0ᵀ), if any.
    pub fn prior_factor(&self) -> Option<&DMatrix<f64>> {
        self.prior.as_ref().map(|p| &p.1)
    }

    /// The sub-problem on candidates `idx` (same prior).
    pub fn subset(&self, idx: &[usize]) -> Problem {
        let total: usize = idx.iter().map(|&i| self.rank(i)).sum();
        let mut g = DMatrix::zeros(self.p, total);
        let mut off = Vec::with_capacity(idx.len() + 1);
        off.push(0);
        let mut c0 = 0;
        for &i in idx {
            let r = self.rank(i);
            g.columns_mut(c0, r).copy_from(&self.factor(i));
            c0 += r;
            off.push(c0);
        }
        Problem {
            p: self.p,
            g,
            off,
            prior: self.prior.clone(),
        }
    }

    /// The congruence-transformed problem: H_i → T H_i, F_0 → T F_0 Tᵀ.
    /// D-optimal weights are invariant under it (log det changes by 2 log|det T|).
    pub fn transformed(&self, t: &DMatrix<f64>) -> Problem {
        Problem {
            p: self.p,
            g: t * &self.g,
            off: self.off.clone(),
            prior: self.prior.as_ref().map(|(f0, h0)| (t * f0 * t.transpose(), t * h0)),
        }
    }

    /// Drops directions of every factor with σ_k² ≤ `tol` (absolute: meant for a
    /// whitened problem, where M ≈ I, so the information left out is at most
    /// `tol` per candidate in every direction). Used to shrink the conic problem;
    /// certificates are always computed with the exact matrices.
    pub fn truncated(&self, tol: f64) -> Problem {
        let factors: Vec<DMatrix<f64>> = (0..self.n())
            .map(|i| {
                let h = self.factor(i).into_owned();
                if h.ncols() <= 1 {
                    return h;
                }
                let f = &h * h.transpose();
                let eig = f.symmetric_eigen();
                let keep: Vec<usize> = (0..self.p).filter(|&k| eig.eigenvalues[k] > tol).collect();
                if keep.len() >= h.ncols() {
                    return h;
                }
                DMatrix::from_fn(self.p, keep.len(), |a, c| eig.eigenvectors[(a, keep[c])] * eig.eigenvalues[keep[c]].sqrt())
            })
            .collect();
        let mut out = Problem::from_factors(self.p, &factors, None).unwrap_or_else(|_| self.clone());
        out.prior = self.prior.clone();
        out
    }

    /// Multiplies every F_i by c_i⁻¹ (costs: weights become fractions of the budget).
    pub fn divided_by(&self, costs: &[f64]) -> Problem {
        let mut g = self.g.clone();
        for (i, c) in costs.iter().enumerate() {
            let s = 1.0 / c.sqrt();
            g.columns_mut(self.off[i], self.rank(i)).scale_mut(s);
        }
        Problem {
            p: self.p,
            g,
            off: self.off.clone(),
            prior: self.prior.clone(),
        }
    }

    /// Multiplies all information (candidates and prior) by the scalar s > 0.
    pub fn scaled(&self, s: f64) -> Problem {
        let r = s.sqrt();
        Problem {
            p: self.p,
            g: &self.g * r,
            off: self.off.clone(),
            prior: self.prior.as_ref().map(|(f0, h0)| (f0 * s, h0 * r)),
        }
    }

    /// M(w) = F_0 + Σ w_i F_i (negative weights are treated as zero).
    pub fn information(&self, w: &[f64]) -> DMatrix<f64> {
        assert_eq!(w.len(), self.n(), "one weight per candidate");
        let mut b = self.g.clone();
        for i in 0..self.n() {
            let s = w[i].max(0.0).sqrt();
            b.columns_mut(self.off[i], self.rank(i)).scale_mut(s);
        }
        let mut m = &b * b.transpose();
        if let Some((f0, _)) = &self.prior {
            m += f0;
        }
        symmetrize(&mut m);
        m
    }

    /// Column sums of G ∘ (X G) grouped per candidate: s_i = tr(X F_i) for a symmetric X.
    pub fn traces(&self, x: &DMatrix<f64>) -> Vec<f64> {
        let xg = x * &self.g;
        let mut colsum = vec![0.0; self.g.ncols()];
        for c in 0..self.g.ncols() {
            colsum[c] = self.g.column(c).dot(&xg.column(c));
        }
        (0..self.n()).map(|i| colsum[self.off[i]..self.off[i + 1]].iter().sum()).collect()
    }

    /// tr(X F_0) (0 without a prior).
    pub fn prior_trace(&self, x: &DMatrix<f64>) -> f64 {
        self.prior.as_ref().map(|(f0, _)| x.component_mul(f0).sum()).unwrap_or(0.0)
    }

    /// Evaluates the criterion and its sensitivities at the design w.
    /// Errors if M(w) is singular (criterion undefined).
    pub fn evaluate(&self, crit: Criterion, w: &[f64]) -> Result<Evaluation> {
        let m = self.information(w);
        eval_at(self, crit, m, w)
    }
}

/// Symmetrises in place: (M + Mᵀ)/2.
pub fn symmetrize(m: &mut DMatrix<f64>) {
    let p = m.nrows();
    for i in 0..p {
        for j in 0..i {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

/// Criterion value, sensitivities and the quantities of the equivalence theorem at one design.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Criterion value Φ(w) (see [`Criterion::value_label`]).
    pub value: f64,
    /// Sensitivity s_i(w) of every candidate (d_i, a_i or e_i).
    pub sens: Vec<f64>,
    /// Σ w_i s_i: the sensitivity of the current design itself.
    pub mean: f64,
    /// tr(X F_0) for the criterion's X (M⁻¹, M⁻², Z): 0 without a prior.
    pub prior_term: f64,
    /// M(w).
    pub m: DMatrix<f64>,
    /// For E: the matrix Z (p×p, PSD, unit trace) used for the sensitivities.
    pub z: Option<DMatrix<f64>>,
}

impl Evaluation {
    /// max_i s_i and its index.
    pub fn max_sens(&self) -> (usize, f64) {
        self.sens
            .iter()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |b, (i, &v)| if v > b.1 { (i, v) } else { b })
    }
}

fn eval_at(pb: &Problem, crit: Criterion, m: DMatrix<f64>, w: &[f64]) -> Result<Evaluation> {
    let p = pb.p();
    match crit {
        Criterion::D | Criterion::A => {
            let chol = m
                .clone()
                .cholesky()
                .ok_or_else(|| Error::Numerical("the information matrix M(w) is singular: the parameters are not identifiable from this design".into()))?;
            let minv = chol.inverse();
            let l = chol.l();
            if crit == Criterion::D {
                let value = 2.0 * (0..p).map(|j| l[(j, j)].ln()).sum::<f64>();
                let sens = pb.traces(&minv);
                let mean = w.iter().zip(&sens).map(|(a, b)| a.max(0.0) * b).sum();
                let prior_term = pb.prior_trace(&minv);
                Ok(Evaluation {
                    value,
                    sens,
                    mean,
                    prior_term,
                    m,
                    z: None,
                })
            } else {
                let value = minv.trace();
                let mut m2 = &minv * &minv;
                symmetrize(&mut m2);
                let sens = pb.traces(&m2);
                let mean = w.iter().zip(&sens).map(|(a, b)| a.max(0.0) * b).sum();
                let prior_term = pb.prior_trace(&m2);
                Ok(Evaluation {
                    value,
                    sens,
                    mean,
                    prior_term,
                    m,
                    z: None,
                })
            }
        }
        Criterion::E => {
            let eig = m.clone().symmetric_eigen();
            let lmin = eig.eigenvalues.min();
            // Z: projector on the (numerically) smallest eigenvector, unit trace
            let k = eig.eigenvalues.imin();
            let v = eig.eigenvectors.column(k).into_owned();
            let z = &v * v.transpose();
            let sens = pb.traces(&z);
            let mean = w.iter().zip(&sens).map(|(a, b)| a.max(0.0) * b).sum();
            let prior_term = pb.prior_trace(&z);
            Ok(Evaluation {
                value: lmin,
                sens,
                mean,
                prior_term,
                m,
                z: Some(z),
            })
        }
    }
}

/// Evaluates the E criterion with a given Z (PSD, unit trace, e.g. an SDP dual):
/// sensitivities e_i = tr(Z F_i), prior term tr(Z F_0).
pub fn evaluate_e_with(pb: &Problem, w: &[f64], z: &DMatrix<f64>) -> Evaluation {
    let m = pb.information(w);
    let lmin = m.clone().symmetric_eigen().eigenvalues.min();
    let sens = pb.traces(z);
    let mean = w.iter().zip(&sens).map(|(a, b)| a.max(0.0) * b).sum();
    let prior_term = pb.prior_trace(z);
    Evaluation {
        value: lmin,
        sens,
        mean,
        prior_term,
        m,
        z: Some(z.clone()),
    }
}

/// Projects a symmetric matrix on the PSD cone and normalises it to unit trace.
pub fn psd_unit_trace(z: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let mut s = z.clone();
    symmetrize(&mut s);
    let eig = s.symmetric_eigen();
    let vals = DVector::from_iterator(eig.eigenvalues.len(), eig.eigenvalues.iter().map(|v| v.max(0.0)));
    let tr = vals.sum();
    if !(tr > 0.0 && tr.is_finite()) {
        return None;
    }
    let v = &eig.eigenvectors;
    let mut out = v * DMatrix::from_diagonal(&vals) * v.transpose() / tr;
    symmetrize(&mut out);
    Some(out)
}
