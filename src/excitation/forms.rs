//! What the gradient refinement minimises: the criterion's reformulations.
//!
//! The refinement ([`super::refine`]) runs nlopt stages under the design's
//! constraints and keeps the best feasible point; what each stage minimises
//! is the objective's business, asked through [`Objective::refinement_forms`]:
//!
//! * [`Plain::Direct`]: φ(J(x)) with φ = ln for the condition number and
//!   1/σ_min (a monotone transform with better scaling; the same minimiser)
//!   and φ = identity for −log det;
//! * [`Plain::Smooth`]: the smooth surrogate L_p of 2 ln κ
//!   ([`Objective::soft_log_cond_grad`]), a first stage for the condition
//!   number (`refine.smooth` = p > 0);
//! * [`Epigraph`]: for the condition number and 1/σ_min with
//!   `refine.bundle` = k > 0, over z = (x, u, l), minimise w·(u − l) (for
//!   1/σ_min: −w·l; w = `refine.bundle_weight`) subject to ln λ_i(x) ≤ u for
//!   the k largest and ln λ_i(x) ≥ l for the k smallest eigenvalues
//!   λ_i = σ_i² of C̃ᵀC̃ ([`Objective::log_eigen_bundle`]). At the solution
//!   u − l = ln λ_max − ln λ_min = 2 ln κ, but unlike ln κ the problem stays
//!   smooth where the extreme singular values coalesce (as they do at the
//!   optimum of a min–max criterion): SLSQP sees one linearised constraint
//!   per eigenvalue of the cluster instead of a kink.
//!
//! A new criterion adds its value and gradient in [`super::objective`] and,
//! if it has one, its reformulation here; the refinement does not change.

use super::objective::{Criterion, Objective, ObjectiveWorkspace};

/// Bound of the epigraph variables u, l (ln λ of any finite regressor lies inside).
pub const LN_BOUND: f64 = 700.0;

/// A form of the criterion in the design vector x alone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Plain {
    /// φ(J(x)) (see the module docs).
    Direct,
    /// The smooth surrogate L_p of 2 ln κ with this exponent p.
    Smooth(f64),
}

/// The epigraph form over the eigenvalue bundle (see the module docs): the
/// extra variables (u, l) follow x; `top` upper and `bottom` lower
/// constraints, in that order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Epigraph {
    /// Eigenvalues bounded by u (the largest; 0 for 1/σ_min).
    pub top: usize,
    /// Eigenvalues bounded by l (the smallest).
    pub bottom: usize,
    /// w, the weight of the linear objective.
    pub weight: f64,
}

/// One stage's form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Form {
    /// In x alone.
    Plain(Plain),
    /// Over (x, u, l) with the bundle's constraints.
    Epigraph(Epigraph),
}

/// The forms a refinement minimises in turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Forms {
    /// A first stage (the smooth surrogate), if any.
    pub first: Option<Plain>,
    /// The main stage.
    pub main: Form,
}

impl Objective {
    /// What the refinement minimises for this criterion, given the spec's
    /// `smooth` exponent (≤ 0: none), `bundle` size (0: none) and bundle weight.
    pub fn refinement_forms(&self, smooth: f64, bundle: usize, bundle_weight: f64) -> Forms {
        let first = (smooth > 0.0 && self.criterion == Criterion::Cond).then_some(Plain::Smooth(smooth));
        let main = if bundle > 0 && matches!(self.criterion, Criterion::Cond | Criterion::InvSigmaMin) {
            let m = self.n_cols();
            let with_top = self.criterion == Criterion::Cond;
            let bottom = bundle.min(if with_top { m / 2 } else { m }).max(1);
            Form::Epigraph(Epigraph {
                top: if with_top { bottom } else { 0 },
                bottom,
                weight: bundle_weight,
            })
        } else {
            Form::Plain(Plain::Direct)
        };
        Forms { first, main }
    }

    /// A plain form at x: (the value the stage tracks, the value minimised),
    /// the gradient of the latter into `grad` when asked (zero where the
    /// value is not finite; the minimised value is then 10³⁰⁰). The tracked
    /// value is the criterion J for [`Plain::Direct`], the surrogate for
    /// [`Plain::Smooth`].
    pub fn plain_value(&self, form: Plain, x: &[f64], w: &mut ObjectiveWorkspace, grad: Option<&mut [f64]>) -> (f64, f64) {
        let (j, v) = match (grad, form) {
            (Some(g), Plain::Smooth(p)) => {
                let l = self.soft_log_cond_grad(x, w, g, p);
                if !l.is_finite() {
                    g.iter_mut().for_each(|v| *v = 0.0);
                }
                (l, l)
            }
            (Some(g), Plain::Direct) => {
                let j = self.value_grad(x, w, g);
                if self.criterion != Criterion::LogDet {
                    let jj = j.max(1e-300);
                    g.iter_mut().for_each(|v| *v /= jj);
                }
                if !j.is_finite() {
                    g.iter_mut().for_each(|v| *v = 0.0);
                }
                (j, self.direct_transform(j))
            }
            (None, Plain::Smooth(p)) => {
                let mut g = vec![0.0; x.len()];
                let l = self.soft_log_cond_grad(x, w, &mut g, p);
                (l, l)
            }
            (None, Plain::Direct) => {
                let j = self.value(x, w);
                (j, self.direct_transform(j))
            }
        };
        (j, if v.is_finite() { v } else { 1e300 })
    }

    /// φ(J) of [`Plain::Direct`].
    fn direct_transform(&self, j: f64) -> f64 {
        match self.criterion {
            Criterion::LogDet => j,
            _ => j.max(1e-300).ln(),
        }
    }
}

impl Epigraph {
    /// Number of bundle constraints.
    pub fn n_rows(&self) -> usize {
        self.top + self.bottom
    }

    /// The criterion J at x with the bundle's ln λ_i into `vals` (`n_rows`:
    /// the top ones, then the bottom ones) and their gradients in x into
    /// `grads` (row-major, `n_rows` × n) when asked.
    pub fn bundle(&self, obj: &Objective, x: &[f64], w: &mut ObjectiveWorkspace, vals: &mut [f64], grads: Option<&mut [f64]>) -> f64 {
        obj.log_eigen_bundle(x, w, self.top, self.bottom, vals, grads)
    }

    /// (u, l) at the start from its bundle values: the largest and the
    /// smallest ln λ (u = 0 without top constraints), within ±[`LN_BOUND`].
    pub fn start(&self, vals: &[f64]) -> [f64; 2] {
        let u0 = if self.top > 0 { vals[0] } else { 0.0 };
        [u0.clamp(-LN_BOUND, LN_BOUND), vals[self.n_rows() - 1].clamp(-LN_BOUND, LN_BOUND)]
    }

    /// The box of (u, l).
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        ([-LN_BOUND, -LN_BOUND], [LN_BOUND, LN_BOUND])
    }

    /// The linear objective at (u, l) = `ul`, its gradient in (u, l) into `grad`.
    pub fn value(&self, ul: &[f64], grad: Option<&mut [f64]>) -> f64 {
        let with_top = self.top > 0;
        if let Some(g) = grad {
            g.iter_mut().for_each(|v| *v = 0.0);
            if with_top {
                g[0] = self.weight;
            }
            g[1] = -self.weight;
        }
        if with_top {
            self.weight * (ul[0] - ul[1])
        } else {
            -self.weight * ul[1]
        }
    }

    /// The bundle constraints (≤ 0) at z = (x, u, l) from `j` and `vals` of
    /// [`Epigraph::bundle`]: ln λ_i − u for the top, l − ln λ_i for the bottom
    /// ones ([`LN_BOUND`] each when J is not finite). With `grad` (`n_rows`
    /// rows of len(z), row-major), their gradients from `grads` (zero when J
    /// is not finite).
    pub fn rows(&self, j: f64, vals: &[f64], grads: &[f64], z: &[f64], res: &mut [f64], grad: Option<&mut [f64]>) {
        let (nz, nt, top) = (z.len(), self.n_rows(), self.top);
        let nv = nz - 2;
        let (iu, il) = (nv, nv + 1);
        for t in 0..nt {
            let v = if j.is_finite() { vals[t] } else { LN_BOUND };
            res[t] = if t < top { v - z[iu] } else { z[il] - v };
            if !j.is_finite() {
                res[t] = LN_BOUND;
            }
        }
        if let Some(g) = grad {
            g.iter_mut().for_each(|v| *v = 0.0);
            if j.is_finite() {
                for t in 0..nt {
                    let row = &mut g[t * nz..(t + 1) * nz];
                    let gt = &grads[t * nv..(t + 1) * nv];
                    if t < top {
                        row[..nv].copy_from_slice(gt);
                        row[iu] = -1.0;
                    } else {
                        row[..nv].iter_mut().zip(gt).for_each(|(r, v)| *r = -v);
                        row[il] = 1.0;
                    }
                }
            }
        }
    }
}
