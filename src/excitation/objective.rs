//! The identifiability criterion of an excitation trajectory and its analytic
//! gradient with respect to the Fourier design vector.
//!
//! # The stacked regressor
//!
//! For the trajectory q(t; x) of design vector x (a [`Shape`]: Fourier series
//! or B-spline) and the sample times t_1..t_N (one period, or the whole
//! rest-to-rest motion, at the design's sample rate), the stacked
//! base regressor is
//!
//! C(x) = [ W½ Y_b(q(t_1), q̇(t_1), q̈(t_1)) ; … ; W½ Y_b(q(t_N), …) ]   (N·n × m),
//!
//! Y_b the columns of the motor-side regressor [`crate::robot::regressor_rows`]
//! selected by `columns` (by default the base parameters, drive and friction
//! columns included: paper 000 eq. 4, paper 002 eq. 20's Φ) and W½ =
//! diag(1/σ_j) the optional per-joint torque-noise weights. The criterion is
//! evaluated on the scaled matrix C̃ = C D:
//!
//! * [`Scaling::UnitColumn`] (default, Sun & Hollerbach / paper 000 ref. \[15\]):
//!   D = diag(1/‖c_j‖), every column of unit norm — D depends on x;
//! * [`Scaling::Nominal`]: D = diag(|θ_b,j|), each column weighted by its
//!   nominal base-parameter value (its torque contribution); values below
//!   10⁻³·max|θ_b| (products of inertia that are nominally zero, say) are
//!   raised to that floor;
//! * [`Scaling::None`]: D = I.
//!
//! # Criteria and gradients
//!
//! With the thin SVD C̃ = U Σ Vᵀ (σ_1 ≥ … ≥ σ_m) and dσ_i = u_iᵀ dC̃ v_i,
//! u_i = C̃ v_i / σ_i, every criterion J has dJ = ⟨C̃ M, dC̃⟩ with a symmetric
//! m × m matrix M:
//!
//! * [`Criterion::Cond`]: J = σ_1/σ_m, M = v_1v_1ᵀ/(σ_1σ_m) − σ_1 v_mv_mᵀ/σ_m³;
//! * [`Criterion::LogDet`]: J = −log det(C̃ᵀC̃) = −2 Σ log σ_i, M = −2 V Σ⁻² Vᵀ;
//! * [`Criterion::InvSigmaMin`]: J = 1/σ_m, M = −v_mv_mᵀ/σ_m³.
//!
//! G = C̃ M is pulled back through the scaling (for unit columns
//! dc̃_j = (dc_j − c̃_j c̃_jᵀ dc_j)/‖c_j‖) to H with dJ = ⟨H, dC⟩, then through
//! the regressor, per sample, ∂J/∂q_k(t_i) = Σ_{r,j} H_(i,r),j ∂Y_b,rj/∂q_k
//! (likewise q̇, q̈), and finally through the trajectory shape's Jacobian of
//! the samples ([`TrajectoryShape::grid_accumulate`]: for the Fourier series
//! its basis at t_i and [`crate::trajectory::FourierLayout::pullback`]).
//!
//! The per-sample contraction never forms ∂Y: since τ = Y θ for every θ,
//! Σ_j H_rj ∂Y_rj/∂q_k = ∂τ_r(θ_r)/∂q_k with θ_r = row r of the sample's
//! H on the selected columns (zero elsewhere), the derivative of one joint
//! torque at a parameter vector of its own: row r of the recursive RNEA
//! derivatives ([`crate::robot::id_derivative_rows`], ∂τ/∂q̈ the mass matrix
//! from the same composite inertias). That costs one RNEA-derivative pass
//! per row instead of 2n dual-number regressor passes (4.4× faster on the
//! UR5). With more than a few matrices H at once (the epigraph bundle) the
//! dual passes, shared by every H, are used instead: ∂Y/∂q, ∂Y/∂q̇ by
//! forward-mode dual numbers, ∂Y/∂q̈ exactly as Y(q, 0, e_k) − Y(q, 0, 0)
//! without gravity (Y is affine in q̈).
//!
//! The decomposition (eigendecomposition of the m×m Gram matrix C̃ᵀC̃ when
//! C̃ is well conditioned, else a thin SVD of C̃) runs sequentially in
//! preallocated faer stacks held by the per-thread [`ObjectiveWorkspace`]; the
//! per-sample gradient work runs in fixed chunks of samples on the rayon pool
//! and is summed in chunk order. An evaluation therefore does not depend on
//! the thread count.

use crate::error::{Error, Result};
use crate::robot::dynamics::{id_derivative_rows, regressor_dual_directions, regressor_generic, Terms};
use crate::robot::kinematics::joint_transforms;
use crate::robot::kinematics::Kin;
use crate::robot::{regressor_rows, Robot, Workspace};
use crate::trajectory::shapes::{ShapeGrid, ShapeScratch};
use crate::trajectory::{Shape, ShapeMotion, TimeGrid, TrajectoryShape};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{Mat, MatMut, MatRef, Par};
use num_dual::Dual64;
use rayon::prelude::*;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

/// Identifiability criterion (minimised).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Condition number σ_max/σ_min of the scaled regressor (default; paper 000 §II-C, paper 002 eq. 20).
    #[default]
    Cond,
    /// −log det(C̃ᵀC̃) (D-optimality).
    LogDet,
    /// 1/σ_min (E-optimality).
    InvSigmaMin,
}

/// Column scaling of the stacked regressor before the criterion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Scaling {
    /// Unit column norms (default).
    #[default]
    UnitColumn,
    /// Columns times the nominal base-parameter values.
    Nominal,
    /// No scaling.
    None,
}

/// Which regressor columns form C.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Columns {
    /// Base parameters including drive columns (Ia, friction) — the default.
    #[default]
    Base,
    /// Base parameters of the rigid-body (inertial) columns only.
    Inertial,
    /// A payload's ten parameters only (the design's `[payload]`), the robot's
    /// own parameters known: the columns of the link carrying the payload.
    Payload,
}

/// Velocities below this (rad/s or m/s) are taken as exactly zero in the
/// regressor samples, so Coulomb columns sign(q̇) do not flip on round-off.
pub const ZERO_VELOCITY: f64 = 1e-12;

/// Largest condition number reported; rank-deficient matrices are clamped to it.
pub const COND_CAP: f64 = 1e12;

/// The criterion J(x) of a design vector, with everything fixed that does not
/// depend on x (robot, columns, sample times, weights, scaling).
#[derive(Debug, Clone)]
pub struct Objective {
    /// The robot (nominal parameters used by [`Scaling::Nominal`]), shared
    /// with the problem's constraints.
    pub robot: Arc<Robot>,
    /// Design vector ↔ trajectory.
    pub shape: Shape,
    /// Standard-parameter indices of C's columns.
    pub columns: Vec<usize>,
    /// Names of the columns (base-parameter names).
    pub column_names: Vec<String>,
    /// Sample times (s) over one period.
    pub times: Vec<f64>,
    /// Criterion.
    pub criterion: Criterion,
    /// Column scaling.
    pub scaling: Scaling,
    /// Row weight per joint, 1/σ_j (σ_j the torque noise standard deviation).
    pub row_weight: Vec<f64>,
    /// Fixed column factors for [`Scaling::Nominal`] (|θ_b,j|, floored), else ones.
    pub fixed_scale: Vec<f64>,
    /// The sample grid, prepared by the shape (the Fourier series' sin/cos table).
    pub grid: ShapeGrid,
}

/// Per-thread buffers of [`Objective`] evaluations.
pub struct ObjectiveWorkspace {
    ws: Workspace,
    y: Vec<f64>,
    /// Raw stacked regressor C (N·n × m), column-major.
    pub c: Vec<f64>,
    /// Scaled regressor C̃, column-major.
    pub cs: Vec<f64>,
    h: Vec<f64>,
    hb: Vec<Vec<f64>>,
    rows: usize,
    col_norm: Vec<f64>,
    sd: faer::diag::Diag<f64>,
    s: Vec<f64>,
    v: Mat<f64>,
    vs: Mat<f64>,
    gram: Mat<f64>,
    mem_novec: MemBuffer,
    mem_vec: MemBuffer,
    mem_evd: MemBuffer,
    states: Vec<[Vec<f64>; 3]>,
    /// Number of criterion evaluations made with this workspace.
    pub evaluations: u64,
    /// Number of gradient evaluations made with this workspace.
    pub gradients: u64,
}

impl std::fmt::Debug for ObjectiveWorkspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectiveWorkspace").field("rows", &self.rows).finish()
    }
}

/// Singular values and the derived identifiability measures of one trajectory.
#[derive(Debug, Clone, Serialize)]
pub struct Spectrum {
    /// Singular values of the scaled stacked regressor, decreasing.
    pub singular_values: Vec<f64>,
    /// Condition number σ_1/σ_m (capped at [`COND_CAP`]).
    pub cond: f64,
    /// Criterion value.
    pub criterion: f64,
}

/// The samples, column scaling and spectrum of one evaluation ([`Objective::record`]).
#[derive(Debug, Clone)]
pub struct GridRecord {
    /// The samples (t, q, q̇, q̈) of the criterion's grid, q̇ below [`ZERO_VELOCITY`] set to 0.
    pub samples: crate::io::States,
    /// ‖c_j‖, the norm of column j of W½C over these samples.
    pub column_norms: Vec<f64>,
    /// The column factors D_jj (C̃ = W½ C D): 1/‖c_j‖ for unit columns (0 for a
    /// zero column), the floored |θ_b,j| for nominal scaling, else 1.
    pub scale: Vec<f64>,
    /// Singular values, condition number and criterion of C̃.
    pub spectrum: Spectrum,
}

/// The m columns of the stacked regressor C: which standard parameters, their
/// names and nominal values.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseColumns {
    /// Standard-parameter indices into the robot's parameter vector.
    pub indices: Vec<usize>,
    /// Labels of the columns (base-parameter names).
    pub names: Vec<String>,
    /// Nominal value of each column's parameter (for [`Scaling::Nominal`]).
    pub nominal: Vec<f64>,
}

/// How C is scored: the criterion, the column scaling and the per-joint torque
/// noise standard deviations σ_j (N·m or N; rows are weighted by 1/σ_j).
#[derive(Debug, Clone, PartialEq)]
pub struct Scoring {
    /// Criterion.
    pub criterion: Criterion,
    /// Column scaling.
    pub scaling: Scaling,
    /// σ_j, one per joint.
    pub noise: Vec<f64>,
}

impl Objective {
    /// Builds the objective for `robot`, the trajectory shape, the columns
    /// of C, the sample times (s) over one period (or the rest-to-rest
    /// motion) and the scoring.
    pub fn new(robot: impl Into<Arc<Robot>>, shape: impl Into<Shape>, columns: BaseColumns, times: Vec<f64>, scoring: Scoring) -> Result<Self> {
        let (robot, shape) = (robot.into(), shape.into());
        let BaseColumns {
            indices: columns,
            names: column_names,
            nominal: base_nominal,
        } = columns;
        let Scoring { criterion, scaling, noise } = scoring;
        let n = robot.dof();
        if shape.n_joints() != n {
            return Err(Error::dim("trajectory joints vs robot joints", n, shape.n_joints()));
        }
        if noise.len() != n {
            return Err(Error::dim("noise levels (one per joint)", n, noise.len()));
        }
        if let Some(j) = noise.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::invalid("objective", format!("noise[{j}]"), "expected a positive torque noise level"));
        }
        if columns.is_empty() || columns.iter().any(|&c| c >= robot.n_params()) {
            return Err(Error::invalid("objective", "columns", "expected a non-empty set of valid parameter indices"));
        }
        if base_nominal.len() != columns.len() || column_names.len() != columns.len() {
            return Err(Error::dim("nominal values / names per column", columns.len(), base_nominal.len()));
        }
        let rows = times.len() * n;
        if rows < columns.len() {
            return Err(Error::invalid(
                "objective",
                "sample_rate",
                format!(
                    "{} samples × {n} joints = {rows} rows cannot determine {} parameters; raise the sample rate",
                    times.len(),
                    columns.len()
                ),
            ));
        }
        let fixed_scale = match scaling {
            Scaling::Nominal => {
                let mx = base_nominal.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let floor = 1e-3 * mx.max(1e-300);
                base_nominal.iter().map(|v| v.abs().max(floor)).collect()
            }
            _ => vec![1.0; columns.len()],
        };
        let grid = shape.grid(times.clone());
        Ok(Objective {
            grid,
            row_weight: noise.iter().map(|s| 1.0 / s).collect(),
            robot,
            shape,
            columns,
            column_names,
            times,
            criterion,
            scaling,
            fixed_scale,
        })
    }

    /// Number of columns m of C.
    pub fn n_cols(&self) -> usize {
        self.columns.len()
    }

    /// Number of rows N·n of C.
    pub fn n_rows(&self) -> usize {
        self.times.len() * self.robot.dof()
    }

    /// A workspace for this objective (one per thread).
    pub fn workspace(&self) -> ObjectiveWorkspace {
        let n = self.robot.dof();
        let p = self.robot.n_params();
        let (r, m) = (self.n_rows(), self.n_cols());
        let req_no = svd_scratch::<f64>(r, m, ComputeSvdVectors::No, ComputeSvdVectors::No, Par::Seq, Default::default());
        let req_v = svd_scratch::<f64>(r, m, ComputeSvdVectors::No, ComputeSvdVectors::Thin, Par::Seq, Default::default());
        ObjectiveWorkspace {
            ws: Workspace::new(&self.robot),
            y: vec![0.0; n * p],
            c: vec![0.0; r * m],
            cs: vec![0.0; r * m],
            h: vec![0.0; r * m],
            hb: Vec::new(),
            rows: r,
            col_norm: vec![0.0; m],
            sd: faer::diag::Diag::zeros(m),
            s: vec![0.0; m],
            v: Mat::zeros(m, m),
            vs: Mat::zeros(m, m),
            gram: Mat::zeros(m, m),
            mem_novec: MemBuffer::new(req_no),
            mem_vec: MemBuffer::new(req_v),
            mem_evd: MemBuffer::new(self_adjoint_evd_scratch::<f64>(m, ComputeEigenvectors::Yes, Par::Seq, Default::default())),
            states: vec![[vec![0.0; n], vec![0.0; n], vec![0.0; n]]; self.times.len()],
            evaluations: 0,
            gradients: 0,
        }
    }

    /// Fills C and C̃ for the trajectory `tr`.
    fn fill(&self, tr: &ShapeMotion, w: &mut ObjectiveWorkspace) {
        let n = self.robot.dof();
        let p = self.robot.n_params();
        let rows = w.rows;
        for i in 0..self.grid.len() {
            let [q, qd, qdd] = &mut w.states[i];
            self.shape.grid_state(&self.grid, tr, i, q, qd, qdd);
            // velocities that are zero up to round-off (t = 0 of an at-rest
            // trajectory) must give sign(q̇) = 0, not a random ±1
            for v in qd.iter_mut() {
                if v.abs() < ZERO_VELOCITY {
                    *v = 0.0;
                }
            }
            regressor_rows(&self.robot, &mut w.ws, q, qd, qdd, &mut w.y);
            for r in 0..n {
                let wr = self.row_weight[r];
                let yr = &w.y[r * p..(r + 1) * p];
                for (j, &c) in self.columns.iter().enumerate() {
                    w.c[j * rows + i * n + r] = wr * yr[c];
                }
            }
        }
        let m = self.n_cols();
        for j in 0..m {
            let col = &w.c[j * rows..(j + 1) * rows];
            let nrm = col.iter().map(|v| v * v).sum::<f64>().sqrt();
            w.col_norm[j] = nrm;
            let f = self.column_factor(j, nrm);
            for r in j * rows..(j + 1) * rows {
                w.cs[r] = w.c[r] * f;
            }
        }
    }

    /// Singular values (into w.s, decreasing) and, with `vectors`, right
    /// singular vectors (w.v) of C̃. Through the eigendecomposition of the
    /// m×m Gram matrix C̃ᵀC̃ when it is well conditioned (σ_1/σ_m < 10⁴, where
    /// its relative accuracy is ≈ ε·κ² ≤ 10⁻⁸), else by a direct SVD of C̃.
    /// Returns false if C̃ is not finite or the decomposition failed.
    fn decompose(&self, w: &mut ObjectiveWorkspace, vectors: bool) -> bool {
        if !w.cs.iter().all(|v| v.is_finite()) {
            return false;
        }
        let m = self.n_cols();
        let cs = MatRef::from_column_major_slice(&w.cs, w.rows, m);
        faer::linalg::matmul::matmul(w.gram.as_mut(), faer::Accum::Replace, cs.transpose(), cs, 1.0, Par::Seq);
        let ok = {
            let stack = MemStack::new(&mut w.mem_evd);
            self_adjoint_evd(w.gram.as_ref(), w.sd.as_mut(), Some(w.vs.as_mut()), Par::Seq, stack, Default::default()).is_ok()
        };
        if ok {
            // ascending eigenvalues λ; σ_i = √λ in decreasing order
            let lam = w.sd.column_vector();
            let mut idx: Vec<usize> = (0..m).collect();
            idx.sort_by(|&a, &b| lam[b].total_cmp(&lam[a]));
            let (lmax, lmin) = (lam[idx[0]], lam[idx[m - 1]]);
            if lmax > 0.0 && lmin > 1e-8 * lmax {
                for (i, &k) in idx.iter().enumerate() {
                    w.s[i] = lam[k].max(0.0).sqrt();
                    if vectors {
                        for a in 0..m {
                            w.v[(a, i)] = w.vs[(a, k)];
                        }
                    }
                }
                return true;
            }
        }
        let res = if vectors {
            let stack = MemStack::new(&mut w.mem_vec);
            svd(cs, w.sd.as_mut(), None, Some(w.v.as_mut()), Par::Seq, stack, Default::default())
        } else {
            let stack = MemStack::new(&mut w.mem_novec);
            svd(cs, w.sd.as_mut(), None, None, Par::Seq, stack, Default::default())
        };
        if res.is_err() {
            return false;
        }
        for i in 0..m {
            w.s[i] = w.sd.column_vector()[i];
        }
        true
    }

    fn sigmas(w: &ObjectiveWorkspace) -> (f64, f64) {
        (w.s[0], w.s[w.s.len() - 1])
    }

    /// Criterion value from the singular values in the workspace.
    fn criterion_value(&self, w: &ObjectiveWorkspace) -> f64 {
        let (s1, sm) = Self::sigmas(w);
        match self.criterion {
            Criterion::Cond => cond_of(s1, sm),
            Criterion::LogDet => {
                let floor = s1 / COND_CAP;
                -2.0 * w.s.iter().map(|v| v.max(floor).max(1e-300).ln()).sum::<f64>()
            }
            Criterion::InvSigmaMin => 1.0 / sm.max(s1 / COND_CAP).max(1e-300),
        }
    }

    /// The criterion J(x). Rank-deficient regressors give the capped value
    /// (cond = [`COND_CAP`]); non-finite regressors give +∞.
    pub fn value(&self, x: &[f64], w: &mut ObjectiveWorkspace) -> f64 {
        let tr = self.shape.motion(x);
        self.value_of(&tr, w)
    }

    /// The criterion of a given trajectory.
    pub fn value_of(&self, tr: &ShapeMotion, w: &mut ObjectiveWorkspace) -> f64 {
        w.evaluations += 1;
        self.fill(tr, w);
        if !self.decompose(w, false) {
            return f64::INFINITY;
        }
        self.criterion_value(w)
    }

    /// Singular values, condition number and criterion of a trajectory.
    pub fn spectrum(&self, tr: &ShapeMotion, w: &mut ObjectiveWorkspace) -> Result<Spectrum> {
        let j = self.value_of(tr, w);
        if !j.is_finite() && j != f64::INFINITY {
            return Err(Error::Numerical("criterion is not a number".into()));
        }
        let s: Vec<f64> = w.s.clone();
        let (s1, sm) = Self::sigmas(w);
        Ok(Spectrum {
            singular_values: s,
            cond: cond_of(s1, sm),
            criterion: j,
        })
    }

    /// The factor D_jj of column j whose norm over the samples is `nrm`:
    /// 1/‖c_j‖ for unit columns (0 for a zero column), else the fixed factor.
    fn column_factor(&self, j: usize, nrm: f64) -> f64 {
        match self.scaling {
            Scaling::UnitColumn if nrm > 0.0 => 1.0 / nrm,
            Scaling::UnitColumn => 0.0,
            _ => self.fixed_scale[j],
        }
    }

    /// Everything one evaluation of trajectory `tr` is made of, for the report
    /// and its replay from the written files: the samples exactly as the
    /// criterion uses them (t_i of [`Objective::times`], q̇ entries below
    /// [`ZERO_VELOCITY`] already set to 0), the column norms ‖c_j‖ of the
    /// weighted matrix W½C over these samples, the column factors D
    /// (C̃ = W½ C D) and the spectrum of C̃.
    pub fn record(&self, tr: &ShapeMotion) -> Result<GridRecord> {
        let mut w = self.workspace();
        let spectrum = self.spectrum(tr, &mut w)?;
        let m = self.n_cols();
        let scale = (0..m).map(|j| self.column_factor(j, w.col_norm[j])).collect();
        let samples = crate::io::States {
            t: Some(self.times.clone()),
            q: w.states.iter().map(|s| s[0].clone()).collect(),
            qd: w.states.iter().map(|s| s[1].clone()).collect(),
            qdd: w.states.iter().map(|s| s[2].clone()).collect(),
        };
        Ok(GridRecord {
            samples,
            column_norms: w.col_norm.clone(),
            scale,
            spectrum,
        })
    }

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
    /// (the same bits: the same decomposition).
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
        if !self.decompose(w, true) {
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

/// Up to this many matrices H_t, the per-sample gradient goes row by row
/// through the inverse-dynamics derivatives (cost ∝ the number of H_t);
/// beyond, through the 2n dual regressor passes shared by every H_t. On the
/// UR5 (48 columns, 100 samples) one H_t costs 0.74 ms row by row and the
/// dual passes 5.1 ms in all: the crossover is near 7.
const ROW_WISE_MAX: usize = 6;

/// Samples per parallel chunk of the gradient's per-sample work.
const GRAD_CHUNK: usize = 10;

/// Buffers of one worker of the gradient's per-sample work.
struct SampleBuffers {
    kin: Kin<f64>,
    dual: Kin<Dual64>,
    yd: Vec<Dual64>,
    y0: Vec<f64>,
    yk: Vec<f64>,
    q_: Vec<Dual64>,
    qd_: Vec<Dual64>,
    qdd_: Vec<Dual64>,
    shape: ShapeScratch,
    hloc: Vec<f64>,
    ycol: Vec<f64>,
    zeros: Vec<f64>,
    unit: Vec<f64>,
    /// The row-wise path: the dynamics workspace, the rows' parameter
    /// vectors θ_r (n·p) and the rows of ∂τ/∂q, ∂τ/∂q̇, ∂τ/∂q̈ (n·n each).
    ws: Workspace,
    thetas: Vec<f64>,
    rq: Vec<f64>,
    rqd: Vec<f64>,
    rqdd: Vec<f64>,
}

impl SampleBuffers {
    fn new(robot: &Robot) -> Self {
        let (n, p) = (robot.dof(), robot.n_params());
        SampleBuffers {
            kin: Kin::new(n),
            dual: Kin::new(n),
            yd: vec![Dual64::from(0.0); n * p],
            y0: vec![0.0; n * p],
            yk: vec![0.0; n * p],
            q_: vec![Dual64::from(0.0); n],
            qd_: vec![Dual64::from(0.0); n],
            qdd_: vec![Dual64::from(0.0); n],
            shape: ShapeScratch::default(),
            hloc: Vec::new(),
            ycol: Vec::new(),
            zeros: vec![0.0; n],
            unit: vec![0.0; n],
            ws: Workspace::new(robot),
            thetas: vec![0.0; n * p],
            rq: vec![0.0; n * n],
            rqd: vec![0.0; n * n],
            rqdd: vec![0.0; n * n],
        }
    }
}

impl Objective {
    /// ∂J_t/∂q, ∂J_t/∂q̇, ∂J_t/∂q̈ at sample i (into g: 3n values per t, one
    /// block after the other) from every H_t of `hs` (column-major, `rows` rows).
    fn sample_gradient(&self, i: usize, state: &[Vec<f64>; 3], hs: &[&[f64]], rows: usize, b: &mut SampleBuffers, g: &mut [f64]) {
        if hs.len() <= ROW_WISE_MAX {
            self.sample_gradient_rows(i, state, hs, rows, b, g)
        } else {
            self.sample_gradient_dual(i, state, hs, rows, b, g)
        }
    }

    /// [`Self::sample_gradient`] row by row: τ = Y(q, q̇, q̈) θ for every θ,
    /// so Σ_j H_rj ∂Y_rj/∂x = ∂τ_r(θ_r)/∂x with θ_r the sample's row r of
    /// H_t (weighted) placed on the selected columns, zero elsewhere: one
    /// call of the row kernel [`id_derivative_rows`] per H_t, whose rows
    /// are summed.
    fn sample_gradient_rows(&self, i: usize, state: &[Vec<f64>; 3], hs: &[&[f64]], rows: usize, b: &mut SampleBuffers, g: &mut [f64]) {
        let n = self.robot.dof();
        let p = self.robot.n_params();
        let [q, qd, qdd] = state;
        for (t, h) in hs.iter().enumerate() {
            for r in 0..n {
                let wr = self.row_weight[r];
                let theta = &mut b.thetas[r * p..(r + 1) * p];
                for (j, &c) in self.columns.iter().enumerate() {
                    theta[c] = h[j * rows + i * n + r] * wr;
                }
            }
            id_derivative_rows(&self.robot, &mut b.ws, &b.thetas, q, qd, qdd, &mut b.rq, &mut b.rqd, &mut b.rqdd);
            let gt = &mut g[t * 3 * n..(t + 1) * 3 * n];
            for k in 0..n {
                let col = |o: &[f64]| (0..n).map(|r| o[r * n + k]).sum::<f64>();
                gt[k] = col(&b.rq);
                gt[n + k] = col(&b.rqd);
                gt[2 * n + k] = col(&b.rqdd);
            }
        }
    }

    /// [`Self::sample_gradient`] by 2n dual regressor passes (∂Y/∂q_k, ∂Y/∂q̇_k)
    /// and n + 1 f64 ones (∂Y/∂q̈_k), each contracted with every H_t.
    fn sample_gradient_dual(&self, i: usize, state: &[Vec<f64>; 3], hs: &[&[f64]], rows: usize, b: &mut SampleBuffers, g: &mut [f64]) {
        let n = self.robot.dof();
        let p = self.robot.n_params();
        let [q, qd, qdd] = state;
        let m = self.columns.len();
        // this sample's rows of every W½-weighted H_t, gathered contiguously
        // (r major, j minor: the order of the sums below)
        let nt = hs.len();
        b.hloc.resize(nt * n * m, 0.0);
        for (t, h) in hs.iter().enumerate() {
            for r in 0..n {
                for j in 0..m {
                    b.hloc[(t * n + r) * m + j] = h[j * rows + i * n + r] * self.row_weight[r];
                }
            }
        }
        b.ycol.resize(n * m, 0.0);
        let no_grav = Terms { gravity: false, drive: true };
        // ∂/∂q_k and ∂/∂q̇_k with duals, sharing the joint transforms at q
        // (filled into b.kin by the f64 pass)
        joint_transforms(&self.robot, q, &mut b.kin);
        for a in 0..n {
            b.q_[a] = Dual64::from(q[a]);
            b.qd_[a] = Dual64::from(qd[a]);
            b.qdd_[a] = Dual64::from(qdd[a]);
        }
        let columns = &self.columns;
        let (hloc, ycol) = (&b.hloc, &mut b.ycol);
        regressor_dual_directions(
            &self.robot,
            &b.kin,
            &mut b.dual,
            [&mut b.q_, &mut b.qd_, &mut b.qdd_],
            &mut b.yd,
            |which, k, yd| {
                for r in 0..n {
                    for (j, &c) in columns.iter().enumerate() {
                        ycol[r * m + j] = yd[r * p + c].eps;
                    }
                }
                contract_sample(hloc, ycol, n, which * n + k, g);
            },
        );
        // ∂/∂q̈_k: Y(q,0,e_k) − Y(q,0,0) without gravity (Y is affine in q̈)
        regressor_generic(&self.robot, q, &b.zeros, &b.zeros, no_grav, &mut b.kin, &mut b.y0);
        for k in 0..n {
            b.unit.iter_mut().for_each(|v| *v = 0.0);
            b.unit[k] = 1.0;
            regressor_generic(&self.robot, q, &b.zeros, &b.unit, no_grav, &mut b.kin, &mut b.yk);
            for r in 0..n {
                for (j, &c) in self.columns.iter().enumerate() {
                    b.ycol[r * m + j] = b.yk[r * p + c] - b.y0[r * p + c];
                }
            }
            contract_sample(&b.hloc, &b.ycol, n, 2 * n + k, g);
        }
    }
}

/// One derivative direction of one sample against every H_t: entry `idx`
/// of each H_t's 3n block of `g` gets ⟨H_t's rows of the sample (`hloc`, n·m
/// per H_t), ∂Y/∂(direction) on the columns (`ycol`)⟩.
fn contract_sample(hloc: &[f64], ycol: &[f64], n: usize, idx: usize, g: &mut [f64]) {
    let block = ycol.len();
    for (t, h) in hloc.chunks_exact(block).enumerate() {
        let mut acc = 0.0;
        for (hv, yv) in h.iter().zip(ycol) {
            acc += hv * yv;
        }
        g[t * 3 * n + idx] = acc;
    }
}

/// σ_1/σ_m clamped to [`COND_CAP`] (and to the cap for σ_m ≤ 0).
pub fn cond_of(s1: f64, sm: f64) -> f64 {
    if !(s1.is_finite() && sm.is_finite()) {
        return f64::INFINITY;
    }
    if sm <= s1 / COND_CAP {
        COND_CAP
    } else {
        s1 / sm
    }
}
