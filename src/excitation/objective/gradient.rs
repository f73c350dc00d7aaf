//! The criterion's analytic gradient (module docs of [`super`]): the matrix
//! M of each criterion, its smooth surrogate and the epigraph bundle, the
//! pull-back through the column scaling, and the sum over the samples
//! through the trajectory shape's Jacobian.

use super::sample::{SampleBuffers, GRAD_CHUNK};
use super::{Criterion, Objective, ObjectiveWorkspace, Scaling, COND_CAP};
use crate::trajectory::{ShapeMotion, TimeGrid, TrajectoryShape};
use faer::{Mat, MatMut, MatRef, Par};
use rayon::prelude::*;

impl Objective {
    /// J(x) and its gradient ∂J/∂x (analytic, see the module docs) into `grad`.
    pub fn value_grad(&self, x: &[f64], w: &mut ObjectiveWorkspace, grad: &mut [f64]) -> f64 {
        self.value_grad_mode(x, w, grad, None)
    }

    /// A smooth surrogate of 2 ln cond(C̃) and its gradient:
    /// L_p = (1/p) ln Σ λ_i^p + (1/p) ln Σ λ_i^{−p}, λ_i = σ_i², which tends to
    /// ln λ_max − ln λ_min = 2 ln κ as p → ∞ (overestimating it by at most
    /// 2 ln(m)/p) and, unlike κ, is differentiable where singular values
    /// coincide. dλ_i = 2 v_iᵀ C̃ᵀ dC̃ v_i. Used by the refinement's first stage.
    pub fn soft_log_cond_grad(&self, x: &[f64], w: &mut ObjectiveWorkspace, grad: &mut [f64], p: f64) -> f64 {
        self.value_grad_mode(x, w, grad, Some(p))
    }

    fn value_grad_mode(&self, x: &[f64], w: &mut ObjectiveWorkspace, grad: &mut [f64], soft: Option<f64>) -> f64 {
        assert_eq!(grad.len(), self.shape.n_vars(), "gradient length");
        w.evaluations += 1;
        w.gradients += 1;
        let tr = self.shape.motion(x);
        self.fill(&tr, w);
        if !self.decompose(w, true) {
            grad.iter_mut().for_each(|g| *g = 0.0);
            return f64::INFINITY;
        }
        let jval = self.criterion_value(w);
        let m = self.n_cols();
        let rows = self.n_rows();
        let s: Vec<f64> = w.s.clone();
        let (s1, sm_raw) = (s[0], s[m - 1]);
        let sm = sm_raw.max(s1 / COND_CAP).max(1e-300);
        // M (m×m, symmetric)
        let mut mm = Mat::<f64>::zeros(m, m);
        let v = &w.v;
        let rank1 = |coef: f64, k: usize, mm: &mut Mat<f64>| {
            for a in 0..m {
                let va = coef * v[(a, k)];
                for b in 0..m {
                    mm[(a, b)] += va * v[(b, k)];
                }
            }
        };
        let mut jval = jval;
        if let Some(pw) = soft {
            let lam: Vec<f64> = s.iter().map(|v| (v * v).max(sm * sm)).collect();
            let (lmax, lmin) = (lam[0], lam[m - 1]);
            let a: Vec<f64> = lam.iter().map(|l| (l / lmax).powf(pw)).collect();
            let b: Vec<f64> = lam.iter().map(|l| (lmin / l).powf(pw)).collect();
            let (sa, sb): (f64, f64) = (a.iter().sum(), b.iter().sum());
            jval = lmax.ln() + sa.ln() / pw - lmin.ln() + sb.ln() / pw;
            for k in 0..m {
                let wk = a[k] / (lam[k] * sa) - b[k] / (lam[k] * sb);
                rank1(2.0 * wk, k, &mut mm);
            }
        } else {
            match self.criterion {
                Criterion::Cond => {
                    rank1(1.0 / (s1 * sm), 0, &mut mm);
                    rank1(-s1 / (sm * sm * sm), m - 1, &mut mm);
                }
                Criterion::InvSigmaMin => rank1(-1.0 / (sm * sm * sm), m - 1, &mut mm),
                Criterion::LogDet => {
                    let floor = s1 / COND_CAP;
                    for k in 0..m {
                        let sk = s[k].max(floor).max(1e-300);
                        rank1(-2.0 / (sk * sk), k, &mut mm);
                    }
                }
            }
        }
        // G = C̃ M, then H (w.r.t. raw C)
        let mut h = std::mem::take(&mut w.h);
        {
            let cs = MatRef::from_column_major_slice(&w.cs, rows, m);
            let hm = MatMut::from_column_major_slice_mut(&mut h, rows, m);
            faer::linalg::matmul::matmul(hm, faer::Accum::Replace, cs, mm.as_ref(), 1.0, Par::Seq);
        }
        self.scale_pullback(&w.col_norm, &w.cs, &mut h);
        self.contract(&tr, &w.states, &[&h], grad);
        w.h = h;
        jval
    }

    /// Pulls G = ∂J/∂C̃ (column-major, rows × m, in place) back through the
    /// column scaling to H = ∂J/∂C (for unit columns
    /// dc̃_j = (dc_j − c̃_j c̃_jᵀ dc_j)/‖c_j‖).
    fn scale_pullback(&self, col_norm: &[f64], cs: &[f64], h: &mut [f64]) {
        let m = self.n_cols();
        let rows = self.n_rows();
        match self.scaling {
            Scaling::UnitColumn => {
                for j in 0..m {
                    let nrm = col_norm[j];
                    let hj = &mut h[j * rows..(j + 1) * rows];
                    if nrm <= 0.0 {
                        hj.iter_mut().for_each(|v| *v = 0.0);
                        continue;
                    }
                    let cj = &cs[j * rows..(j + 1) * rows];
                    let dot: f64 = cj.iter().zip(hj.iter()).map(|(a, b)| a * b).sum();
                    for (hv, cv) in hj.iter_mut().zip(cj) {
                        *hv = (*hv - cv * dot) / nrm;
                    }
                }
            }
            _ => {
                for j in 0..m {
                    let f = self.fixed_scale[j];
                    h[j * rows..(j + 1) * rows].iter_mut().for_each(|v| *v *= f);
                }
            }
        }
    }

    /// The design-vector gradients Σ ⟨H_t, ∂C/∂x⟩ of several matrices H_t
    /// (each = ∂J_t/∂C, column-major) at once, per sample
    /// ([`Self::sample_gradient`]: row by row through the inverse-dynamics
    /// derivatives for up to [`ROW_WISE_MAX`] matrices, else the regressor
    /// derivatives computed once and contracted with every H_t). The
    /// per-sample work runs in fixed chunks of samples in parallel and is
    /// summed in chunk order (the result does not depend on the thread
    /// count). `out` holds one gradient of `n_vars` values per H_t.
    fn contract(&self, tr: &ShapeMotion, states: &[[Vec<f64>; 3]], hs: &[&[f64]], out: &mut [f64]) {
        let n = self.robot.dof();
        let nv = self.shape.n_vars();
        let rows = self.n_rows();
        let len = self.shape.acc_len();
        let nt = hs.len();
        let nchunks = self.grid.len().div_ceil(GRAD_CHUNK);
        let parts: Vec<Vec<f64>> = (0..nchunks)
            .into_par_iter()
            .map_init(
                || SampleBuffers::new(&self.robot),
                |buf, c| {
                    let mut acc = vec![0.0; nt * len];
                    let mut g = vec![0.0; nt * 3 * n];
                    for i in c * GRAD_CHUNK..((c + 1) * GRAD_CHUNK).min(self.grid.len()) {
                        self.sample_gradient(i, &states[i], hs, rows, buf, &mut g);
                        self.shape.grid_accumulate(&self.grid, tr, i, &g, &mut buf.shape, &mut acc);
                    }
                    acc
                },
            )
            .collect();
        let mut sum = vec![0.0; len];
        for t in 0..nt {
            let o = t * len;
            for (k, v) in sum.iter_mut().enumerate() {
                *v = parts.iter().map(|a| a[o + k]).sum();
            }
            self.shape.grid_finish(&sum, &mut out[t * nv..(t + 1) * nv]);
        }
    }

    /// The eigenvalues λ_i = σ_i² of C̃ᵀC̃ at both ends of the spectrum, as
    /// ln λ_i, with their gradients: the `top` largest (i = 1..top) then the
    /// `bottom` smallest (i = m−bottom+1..m), d ln λ_i = (2/λ_i) v_iᵀ C̃ᵀ dC̃ v_i,
    /// exact wherever λ_i is simple. `vals` gets top + bottom values, `grads`
    /// (when given) (top + bottom) × n_vars (one gradient after the other),
    /// through `Objective::contract` (row by row for up to 6 of them,
    /// else the dual passes shared by all); without `grads` only the values
    /// (the same bits: faer's eigenvalues do not depend on whether it also
    /// accumulates the vectors).
    /// Returns the criterion J(x) (+∞, zero gradients and values +∞ when C̃
    /// is not finite). Used by the refinement's epigraph form
    /// (`refine.bundle`). σ_i below σ_1/[`COND_CAP`] count as that floor.
    pub fn log_eigen_bundle(&self, x: &[f64], w: &mut ObjectiveWorkspace, top: usize, bottom: usize, vals: &mut [f64], grads: Option<&mut [f64]>) -> f64 {
        let m = self.n_cols();
        let nv = self.shape.n_vars();
        let nt = top + bottom;
        assert!(top <= m && bottom <= m, "bundle larger than the spectrum");
        assert!(vals.len() == nt && grads.as_ref().is_none_or(|g| g.len() == nt * nv), "bundle buffer lengths");
        w.evaluations += 1;
        let tr = self.shape.motion(x);
        self.fill(&tr, w);
        if !self.decompose(w, grads.is_some()) {
            if let Some(g) = grads {
                g.iter_mut().for_each(|g| *g = 0.0);
            }
            vals.iter_mut().for_each(|v| *v = f64::INFINITY);
            return f64::INFINITY;
        }
        let jval = self.criterion_value(w);
        let floor = (w.s[0] / COND_CAP).max(1e-300);
        let which: Vec<usize> = (0..top).chain(m - bottom..m).collect();
        let lams: Vec<f64> = which
            .iter()
            .map(|&i| {
                let si = w.s[i].max(floor);
                si * si
            })
            .collect();
        vals.iter_mut().zip(&lams).for_each(|(v, l)| *v = l.ln());
        let Some(grads) = grads else {
            return jval;
        };
        w.gradients += 1;
        let rows = self.n_rows();
        w.hb.resize_with(nt, Vec::new);
        // C̃ V_sel (rows × nt), then G_t = (2/λ_i) (C̃ v_i) v_iᵀ
        let mut vsel = Mat::<f64>::zeros(m, nt);
        for (t, &i) in which.iter().enumerate() {
            for a in 0..m {
                vsel[(a, t)] = w.v[(a, i)];
            }
        }
        let mut cv = Mat::<f64>::zeros(rows, nt);
        {
            let cs = MatRef::from_column_major_slice(&w.cs, rows, m);
            faer::linalg::matmul::matmul(cv.as_mut(), faer::Accum::Replace, cs, vsel.as_ref(), 1.0, Par::Seq);
        }
        for (t, &lam) in lams.iter().enumerate() {
            let h = &mut w.hb[t];
            h.resize(rows * m, 0.0);
            for j in 0..m {
                let vj = (2.0 / lam) * vsel[(j, t)];
                for (r, hv) in h[j * rows..(j + 1) * rows].iter_mut().enumerate() {
                    *hv = cv[(r, t)] * vj;
                }
            }
        }
        let mut hb = std::mem::take(&mut w.hb);
        for h in hb.iter_mut() {
            self.scale_pullback(&w.col_norm, &w.cs, h);
        }
        {
            let hs: Vec<&[f64]> = hb.iter().map(|h| h.as_slice()).collect();
            self.contract(&tr, &w.states, &hs, grads);
        }
        w.hb = hb;
        jval
    }
}
