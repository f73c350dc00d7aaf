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

mod gains;
mod gradient;
mod sample;

pub use gains::gains_columns;

use crate::error::{Error, Result};
use crate::robot::{regressor_rows, Robot, Workspace};
use crate::trajectory::shapes::ShapeGrid;
use crate::trajectory::{Shape, ShapeMotion, TimeGrid, TrajectoryShape};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{Mat, MatRef, Par};
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

impl Criterion {
    /// The criterion in words, of W½·C·D (report.txt and the command line's summary).
    pub fn words(self) -> &'static str {
        match self {
            Criterion::Cond => "condition number σ_max/σ_min",
            Criterion::LogDet => "−log det((W½CD)ᵀ(W½CD)) (D-optimality)",
            Criterion::InvSigmaMin => "1/σ_min (E-optimality)",
        }
    }
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
    /// A drive-gain calibration with the design's `[payload]` as the known
    /// mass ([`gains_columns`]): per joint j the torque of
    /// the nominal payload on joint j's rows only (the gain's column), and
    /// the payload's nine unknown parameters (first moments and inertia
    /// about its frame's origin), the robot's own parameters known.
    Gains,
}

/// One column of C as a linear combination of regressor columns:
/// c_(i,r) = Σ_(k, a) a·Y_(r,k)(x_i) on the rows r of `row` (every joint
/// when `None`), zero on the others. A plain column k is `{row: None,
/// terms: [(k, 1)]}`; a gain column of joint j is `{row: Some(j), terms:
/// (k, θ_k) over the parameters of a torque}`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnMix {
    /// The only joint whose rows are nonzero (`None`: every joint).
    pub row: Option<usize>,
    /// (standard-parameter index, coefficient) pairs.
    pub terms: Vec<(usize, f64)>,
}

impl ColumnMix {
    /// The column's entry on joint `r`'s row with regressor row `y` (p values).
    #[inline]
    pub(super) fn entry(&self, r: usize, y: impl Fn(usize) -> f64) -> f64 {
        if self.row.is_some_and(|j| j != r) {
            return 0.0;
        }
        self.terms.iter().map(|&(k, a)| a * y(k)).sum()
    }
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
    /// Standard-parameter indices of C's columns (empty when `mixes` describes them).
    pub columns: Vec<usize>,
    /// C's columns as combinations of regressor columns ([`Objective::mixed`]);
    /// `None`: the plain columns of `columns`.
    pub mixes: Option<Vec<ColumnMix>>,
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
            mixes: None,
        })
    }

    /// [`Objective::new`] with columns that are linear combinations of
    /// regressor columns, each possibly restricted to one joint's rows
    /// ([`ColumnMix`]); `names` and `nominal` (the value of each column's
    /// coefficient, for [`Scaling::Nominal`]) one per mix. The gradient is
    /// the same analytic one: the row-wise contraction places
    /// θ_r = Σ_j H_(r,j) a_j on the mixes' parameters.
    pub fn mixed(
        robot: impl Into<Arc<Robot>>,
        shape: impl Into<Shape>,
        mixes: Vec<ColumnMix>,
        names: Vec<String>,
        nominal: Vec<f64>,
        times: Vec<f64>,
        scoring: Scoring,
    ) -> Result<Self> {
        let robot = robot.into();
        let (n, p) = (robot.dof(), robot.n_params());
        for (j, mx) in mixes.iter().enumerate() {
            if mx.terms.is_empty() || mx.terms.iter().any(|&(k, a)| k >= p || !a.is_finite()) || mx.row.is_some_and(|r| r >= n) {
                return Err(Error::invalid(
                    "objective",
                    format!("columns[{j}]"),
                    format!("expected finite coefficients of parameters 0..{p} on joint 0..{n} rows"),
                ));
            }
        }
        // the plain constructor checks sizes and the scaling with one stand-in index per mix
        let stand_in = BaseColumns {
            indices: mixes.iter().map(|mx| mx.terms[0].0).collect(),
            names,
            nominal,
        };
        let mut o = Objective::new(robot, shape, stand_in, times, scoring)?;
        o.columns.clear();
        o.mixes = Some(mixes);
        Ok(o)
    }

    /// Number of columns m of C.
    pub fn n_cols(&self) -> usize {
        self.mixes.as_ref().map_or(self.columns.len(), |m| m.len())
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
            mem_evd: MemBuffer::new(
                self_adjoint_evd_scratch::<f64>(m, ComputeEigenvectors::Yes, Par::Seq, Default::default()).or(self_adjoint_evd_scratch::<f64>(
                    m,
                    ComputeEigenvectors::No,
                    Par::Seq,
                    Default::default(),
                )),
            ),
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
                match &self.mixes {
                    None => {
                        for (j, &c) in self.columns.iter().enumerate() {
                            w.c[j * rows + i * n + r] = wr * yr[c];
                        }
                    }
                    Some(mixes) => {
                        for (j, mx) in mixes.iter().enumerate() {
                            w.c[j * rows + i * n + r] = wr * mx.entry(r, |k| yr[k]);
                        }
                    }
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
            // without vectors the eigenvalues are the same bits (faer's QR
            // iteration does not read the vectors it accumulates), a third faster
            let vs = if vectors { Some(w.vs.as_mut()) } else { None };
            self_adjoint_evd(w.gram.as_ref(), w.sd.as_mut(), vs, Par::Seq, stack, Default::default()).is_ok()
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
