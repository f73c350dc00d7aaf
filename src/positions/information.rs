//! Information matrices per candidate configuration.
//!
//! An [`InformationSource`] maps a configuration q to the information F(q)
//! (p×p, symmetric PSD) that one experiment there gives about p parameters.
//! Implemented here:
//!
//! * [`RigidSource`]: a short local excitation about the pose, with the rigid
//!   base-parameter model (needs only the robot);
//! * [`InformationFile`]: matrices or Jacobians read from a JSON file (any model).
//!
//! The elastic model's FRF information (paper 001 eq. 5) is
//! [`super::elastic::ElasticSource`].
//!
//! ## The rigid local-excitation model
//!
//! At a candidate pose q⁰ one experiment moves every joint j about it,
//! q_j(t) = q⁰_j + A_j sin(h_j ω t), h_j = j (joint j on harmonic j, so the
//! joint velocities are orthogonal over a period), ω = 2π/T, and records the
//! joint torques at N equally spaced instants t_k = kT/N of one period:
//! τ_k = Y_b(q_k, q̇_k, q̈_k) θ_b + e_k, e_k ~ N(0, diag σ²) independent. The
//! Fisher information of the base parameters θ_b is
//!
//! F(q⁰) = Σ_k Y_b(q_k, q̇_k, q̈_k)ᵀ diag(σ)⁻² Y_b(q_k, q̇_k, q̈_k),
//!
//! with factor H = [Y_b,kᵀ diag(σ)⁻¹]_k (p × N n). The base parameters are the
//! ones identifiable from the candidate experiments together (computed from
//! the stacked regressor of up to 100 candidates, `params::BaseParams`).
//!
//! ## Information file (JSON)
//!
//! ```json
//! {
//!   "parameters": ["k1", "k2"],
//!   "prior": [[1.0, 0.0], [0.0, 1.0]],
//!   "candidates": [
//!     { "q": [0.0, 0.5], "information": [[2.0, 0.1], [0.1, 1.0]] },
//!     { "q": [0.3, 0.5], "jacobian": [[1.0, 0.2], [0.0, 1.0], [0.5, 0.5]], "cost": 2.0 }
//!   ]
//! }
//! ```
//!
//! `parameters`: p names (required, distinct). Each candidate gives exactly one
//! of `information` (p×p symmetric PSD, F_i) or `jacobian` (r×p, rows already
//! scaled by the inverse noise standard deviation: F_i = JᵀJ); optional `q`
//! (joint values, the same length for all candidates or absent for all) and
//! `cost` (> 0, default 1). `prior` (optional, p×p PSD) is information already
//! available, in the units of one experiment. Unknown keys, wrong sizes,
//! non-finite numbers, asymmetric or indefinite matrices are errors naming the
//! file, the candidate and the field.

use super::problem::psd_factor;
use crate::error::{Error, Result};
use crate::params::{BaseOptions, BaseParams};
use crate::robot::{regressor_rows, Robot, Workspace};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The information one experiment at configuration q gives about p parameters.
pub trait InformationSource: Sync {
    /// Number of parameters p.
    fn n_params(&self) -> usize;
    /// Parameter names (p).
    fn names(&self) -> Vec<String>;
    /// F(q) (p×p, symmetric PSD).
    fn information(&self, q: &[f64]) -> Result<DMatrix<f64>>;
    /// A factor H with F(q) = H Hᵀ (default: from the eigendecomposition of F).
    fn factor(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        psd_factor(&self.information(q)?, "information matrix")
    }
}

/// Rigid-body local-excitation information (see the module docs).
#[derive(Debug, Clone)]
pub struct RigidSource {
    /// The robot (shared, not copied, with the run).
    pub robot: Arc<Robot>,
    /// Base parameters (columns of the regressor kept).
    pub base: BaseParams,
    /// Amplitude A_j per joint (rad or m).
    pub amplitude: Vec<f64>,
    /// Period T (s).
    pub period: f64,
    /// Samples N per period.
    pub samples: usize,
    /// Torque noise standard deviation σ_j per joint (N·m or N).
    pub noise: Vec<f64>,
}

impl RigidSource {
    /// Joint trajectory sample k of the local motion about q0: (q, q̇, q̈).
    pub fn state(&self, q0: &[f64], k: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = q0.len();
        let w = 2.0 * std::f64::consts::PI / self.period;
        let t = k as f64 * self.period / self.samples as f64;
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for j in 0..n {
            let h = (j + 1) as f64 * w;
            let a = self.amplitude[j];
            q[j] = q0[j] + a * (h * t).sin();
            qd[j] = a * h * (h * t).cos();
            qdd[j] = -a * h * h * (h * t).sin();
        }
        (q, qd, qdd)
    }

    /// Stacked standard regressor of the local motion (N n × p_std), rows scaled by 1/σ.
    pub fn stack(&self, ws: &mut Workspace, q0: &[f64]) -> DMatrix<f64> {
        let n = self.robot.dof();
        let ps = self.robot.n_params();
        let mut y = vec![0.0; n * ps];
        let mut out = DMatrix::zeros(self.samples * n, ps);
        for k in 0..self.samples {
            let (q, qd, qdd) = self.state(q0, k);
            regressor_rows(&self.robot, ws, &q, &qd, &qdd, &mut y);
            for r in 0..n {
                for c in 0..ps {
                    out[(k * n + r, c)] = y[r * ps + c] / self.noise[r];
                }
            }
        }
        out
    }

    /// The factor H = Y_bᵀ diag(σ)⁻¹ stacked over the samples, compressed to rank ≤ p.
    pub fn factor_with(&self, ws: &mut Workspace, q0: &[f64]) -> Result<DMatrix<f64>> {
        self.check(q0)?;
        let w = self.stack(ws, q0);
        let yb = self.base.select(&w);
        let f = yb.transpose() * &yb;
        psd_factor(&f, "rigid information")
    }

    fn check(&self, q0: &[f64]) -> Result<()> {
        if q0.len() != self.robot.dof() {
            return Err(Error::dim("joint values of a candidate", self.robot.dof(), q0.len()));
        }
        Ok(())
    }

    /// Builds the source: the base parameters are computed from the stacked
    /// local-motion regressors of (up to 100 of) the `candidates`.
    pub fn new(
        robot: impl Into<Arc<Robot>>,
        candidates: &[Vec<f64>],
        inertial_only: bool,
        amplitude: Vec<f64>,
        period: f64,
        samples: usize,
        noise: Vec<f64>,
    ) -> Result<RigidSource> {
        let robot: Arc<Robot> = robot.into();
        let n = robot.dof();
        if amplitude.len() != n || noise.len() != n {
            return Err(Error::dim("amplitude/noise per joint", n, amplitude.len().min(noise.len())));
        }
        if candidates.is_empty() {
            return Err(Error::invalid("positions", "candidates", "no candidate configurations"));
        }
        let mut src = RigidSource {
            base: BaseParams::compute(&robot, &BaseOptions::default())?,
            robot,
            amplitude,
            period,
            samples,
            noise,
        };
        let step = candidates.len().div_ceil(100).max(1);
        let mut ws = Workspace::new(&src.robot);
        let picked: Vec<&Vec<f64>> = candidates.iter().step_by(step).collect();
        let ps = src.robot.n_params();
        let mut stack = DMatrix::zeros(picked.len() * samples * n, ps);
        for (k, q0) in picked.iter().enumerate() {
            src.check(q0)?;
            let s = src.stack(&mut ws, q0);
            stack.rows_mut(k * samples * n, samples * n).copy_from(&s);
        }
        src.base = BaseParams::from_stack(
            &src.robot,
            &stack,
            &BaseOptions {
                inertial_only,
                ..Default::default()
            },
        )?;
        Ok(src)
    }
}

impl InformationSource for RigidSource {
    fn n_params(&self) -> usize {
        self.base.n_base()
    }
    fn names(&self) -> Vec<String> {
        self.base.names.clone()
    }
    fn information(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let h = self.factor(q)?;
        Ok(&h * h.transpose())
    }
    fn factor(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let mut ws = Workspace::new(&self.robot);
        self.factor_with(&mut ws, q)
    }
}

/// One candidate of an information file.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileCandidate {
    /// Joint values (optional).
    #[serde(default)]
    pub q: Option<Vec<f64>>,
    /// F_i (p×p).
    #[serde(default)]
    pub information: Option<Vec<Vec<f64>>>,
    /// J_i (r×p), F_i = JᵀJ.
    #[serde(default)]
    pub jacobian: Option<Vec<Vec<f64>>>,
    /// Cost (> 0, default 1).
    #[serde(default)]
    pub cost: Option<f64>,
}

/// The JSON information file (see the module docs).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InformationFileData {
    /// Parameter names.
    pub parameters: Vec<String>,
    /// Prior information (p×p).
    #[serde(default)]
    pub prior: Option<Vec<Vec<f64>>>,
    /// The candidates.
    pub candidates: Vec<FileCandidate>,
}

/// A validated information file.
#[derive(Debug, Clone)]
pub struct InformationFile {
    /// The file.
    pub path: PathBuf,
    /// Parameter names.
    pub names: Vec<String>,
    /// Joint values per candidate (empty vectors when the file has none).
    pub q: Vec<Vec<f64>>,
    /// Factor H_i per candidate (F_i = H_i H_iᵀ).
    pub factors: Vec<DMatrix<f64>>,
    /// Costs (all 1 when absent).
    pub costs: Vec<f64>,
    /// True when any candidate gave a cost.
    pub has_costs: bool,
    /// Prior (p×p), if any.
    pub prior: Option<DMatrix<f64>>,
}

fn matrix_from_rows(rows: &[Vec<f64>], cols: usize, what: &str, path: &Path) -> Result<DMatrix<f64>> {
    let ctx = path.display().to_string();
    if rows.is_empty() {
        return Err(Error::invalid(&ctx, what, "expected a non-empty array of rows"));
    }
    for (r, row) in rows.iter().enumerate() {
        if row.len() != cols {
            return Err(Error::invalid(
                &ctx,
                what,
                format!("row {} has {} entries, expected {cols} (one per parameter)", r + 1, row.len()),
            ));
        }
        if let Some(c) = row.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(&ctx, what, format!("row {}, column {}: expected a finite number", r + 1, c + 1)));
        }
    }
    Ok(DMatrix::from_fn(rows.len(), cols, |i, j| rows[i][j]))
}

impl InformationFile {
    /// Reads and validates an information file.
    pub fn read(path: &Path) -> Result<InformationFile> {
        let text = crate::io::read_to_string(path)?;
        Self::parse(path, &text)
    }

    /// Parses JSON text (from `path`, for messages).
    pub fn parse(path: &Path, text: &str) -> Result<InformationFile> {
        let data: InformationFileData = serde_json::from_str(text).map_err(|e| Error::parse(path, format!("line {}, column {}: {e}", e.line(), e.column())))?;
        let ctx = path.display().to_string();
        let p = data.parameters.len();
        if p == 0 {
            return Err(Error::invalid(&ctx, "parameters", "expected at least one parameter name"));
        }
        for (i, nm) in data.parameters.iter().enumerate() {
            if nm.trim().is_empty() || data.parameters[..i].contains(nm) {
                return Err(Error::invalid(&ctx, "parameters", format!("name {} ({nm:?}) is empty or repeated", i + 1)));
            }
        }
        if data.candidates.is_empty() {
            return Err(Error::invalid(&ctx, "candidates", "expected at least one candidate"));
        }
        let nq = data.candidates[0].q.as_ref().map(|q| q.len());
        let mut qs = Vec::with_capacity(data.candidates.len());
        let mut factors = Vec::with_capacity(data.candidates.len());
        let mut costs = Vec::with_capacity(data.candidates.len());
        let mut has_costs = false;
        for (i, c) in data.candidates.iter().enumerate() {
            let field = |f: &str| format!("candidates[{i}].{f}");
            match (&c.q, nq) {
                (Some(q), Some(n)) if q.len() == n && q.iter().all(|v| v.is_finite()) => qs.push(q.clone()),
                (None, None) => qs.push(Vec::new()),
                _ => {
                    return Err(Error::invalid(
                        &ctx,
                        field("q"),
                        format!(
                            "expected {} finite joint values as in the first candidate",
                            nq.map(|n| n.to_string()).unwrap_or("no".into())
                        ),
                    ))
                }
            }
            let h = match (&c.information, &c.jacobian) {
                (Some(f), None) => {
                    let f = matrix_from_rows(f, p, &field("information"), path)?;
                    if f.nrows() != p {
                        return Err(Error::invalid(
                            &ctx,
                            field("information"),
                            format!("expected {p} rows (p×p), found {}", f.nrows()),
                        ));
                    }
                    psd_factor(&f, &format!("{ctx}: {}", field("information")))?
                }
                (None, Some(j)) => matrix_from_rows(j, p, &field("jacobian"), path)?.transpose(),
                _ => {
                    return Err(Error::invalid(
                        &ctx,
                        field("information"),
                        "give exactly one of `information` (p×p) or `jacobian` (r×p)",
                    ))
                }
            };
            factors.push(h);
            match c.cost {
                Some(v) if v.is_finite() && v > 0.0 => {
                    has_costs = true;
                    costs.push(v)
                }
                Some(v) => return Err(Error::invalid(&ctx, field("cost"), format!("expected a positive cost, found {v}"))),
                None => costs.push(1.0),
            }
        }
        let prior = match &data.prior {
            Some(rows) => {
                let f0 = matrix_from_rows(rows, p, "prior", path)?;
                if f0.nrows() != p {
                    return Err(Error::invalid(&ctx, "prior", format!("expected {p} rows (p×p), found {}", f0.nrows())));
                }
                psd_factor(&f0, &format!("{ctx}: prior"))?;
                Some(f0)
            }
            None => None,
        };
        Ok(InformationFile {
            path: path.to_path_buf(),
            names: data.parameters,
            q: qs,
            factors,
            costs,
            has_costs,
            prior,
        })
    }
}
