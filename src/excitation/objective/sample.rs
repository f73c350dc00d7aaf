//! The per-sample part of the gradient: ∂J/∂(q, q̇, q̈) at one sample from
//! the matrices H = ∂J/∂C, row by row through the inverse-dynamics
//! derivatives or by dual-number regressor passes (module docs of [`super`]).

use super::Objective;
use crate::robot::dynamics::{id_derivative_rows, regressor_dual_directions, regressor_generic, Terms};
use crate::robot::kinematics::joint_transforms;
use crate::robot::kinematics::Kin;
use crate::robot::{Robot, Workspace};
use crate::trajectory::shapes::ShapeScratch;
use num_dual::Dual64;

/// Up to this many matrices H_t, the per-sample gradient goes row by row
/// through the inverse-dynamics derivatives (cost ∝ the number of H_t);
/// beyond, through the 2n dual regressor passes shared by every H_t. On the
/// UR5 (48 columns, 100 samples) one H_t costs 0.74 ms row by row and the
/// dual passes 5.1 ms in all: the crossover is near 7.
pub(super) const ROW_WISE_MAX: usize = 6;

/// Samples per parallel chunk of the gradient's per-sample work.
pub(super) const GRAD_CHUNK: usize = 10;

/// Buffers of one worker of the gradient's per-sample work.
pub(super) struct SampleBuffers {
    kin: Kin<f64>,
    dual: Kin<Dual64>,
    yd: Vec<Dual64>,
    y0: Vec<f64>,
    yk: Vec<f64>,
    q_: Vec<Dual64>,
    qd_: Vec<Dual64>,
    qdd_: Vec<Dual64>,
    pub(super) shape: ShapeScratch,
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
    pub(super) fn new(robot: &Robot) -> Self {
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
    pub(super) fn sample_gradient(&self, i: usize, state: &[Vec<f64>; 3], hs: &[&[f64]], rows: usize, b: &mut SampleBuffers, g: &mut [f64]) {
        if hs.len() <= ROW_WISE_MAX {
            self.sample_gradient_rows(i, state, hs, rows, b, g)
        } else {
            self.sample_gradient_dual(i, state, hs, rows, b, g)
        }
    }

    /// [`Self::sample_gradient`] row by row: τ = Y(q, q̇, q̈) θ for every θ,
    /// so Σ_j H_rj ∂Y_rj/∂x = ∂τ_r(θ_r)/∂x with θ_r the sample's row r of
    /// H_t (weighted) placed on the selected columns, zero elsewhere: the
    /// row kernel [`id_derivative_rows`] on one set of rows per H_t (one
    /// call for all, sharing the motion pass), each set's rows summed.
    fn sample_gradient_rows(&self, i: usize, state: &[Vec<f64>; 3], hs: &[&[f64]], rows: usize, b: &mut SampleBuffers, g: &mut [f64]) {
        let n = self.robot.dof();
        let p = self.robot.n_params();
        let [q, qd, qdd] = state;
        let nt = hs.len();
        b.thetas.resize(nt * n * p, 0.0);
        for (t, h) in hs.iter().enumerate() {
            for r in 0..n {
                let wr = self.row_weight[r];
                let theta = &mut b.thetas[(t * n + r) * p..(t * n + r + 1) * p];
                match &self.mixes {
                    None => {
                        for (j, &c) in self.columns.iter().enumerate() {
                            theta[c] = h[j * rows + i * n + r] * wr;
                        }
                    }
                    // θ_r = Σ_j H_(r,j) a_j over the mixes that reach row r
                    Some(mixes) => {
                        theta.iter_mut().for_each(|v| *v = 0.0);
                        for (j, mx) in mixes.iter().enumerate() {
                            if mx.row.is_some_and(|x| x != r) {
                                continue;
                            }
                            let hv = h[j * rows + i * n + r] * wr;
                            for &(k, a) in &mx.terms {
                                theta[k] += hv * a;
                            }
                        }
                    }
                }
            }
        }
        // every H_t's rows in one call: the motion pass is shared
        for o in [&mut b.rq, &mut b.rqd, &mut b.rqdd] {
            o.resize(nt * n * n, 0.0);
        }
        id_derivative_rows(&self.robot, &mut b.ws, &b.thetas, q, qd, qdd, &mut b.rq, &mut b.rqd, &mut b.rqdd);
        for t in 0..nt {
            let gt = &mut g[t * 3 * n..(t + 1) * 3 * n];
            let o = t * n * n;
            for k in 0..n {
                let col = |x: &[f64]| (0..n).map(|r| x[o + r * n + k]).sum::<f64>();
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
        let m = self.n_cols();
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
        let (hloc, ycol) = (&b.hloc, &mut b.ycol);
        regressor_dual_directions(
            &self.robot,
            &b.kin,
            &mut b.dual,
            [&mut b.q_, &mut b.qd_, &mut b.qdd_],
            &mut b.yd,
            |which, k, yd| {
                self.gather(n, p, |i| yd[i].eps, ycol);
                contract_sample(hloc, ycol, n, which * n + k, g);
            },
        );
        // ∂/∂q̈_k: Y(q,0,e_k) − Y(q,0,0) without gravity (Y is affine in q̈)
        regressor_generic(&self.robot, q, &b.zeros, &b.zeros, no_grav, &mut b.kin, &mut b.y0);
        for k in 0..n {
            b.unit.iter_mut().for_each(|v| *v = 0.0);
            b.unit[k] = 1.0;
            regressor_generic(&self.robot, q, &b.zeros, &b.unit, no_grav, &mut b.kin, &mut b.yk);
            let (yk, y0) = (&b.yk, &b.y0);
            self.gather(n, p, |i| yk[i] - y0[i], &mut b.ycol);
            contract_sample(&b.hloc, &b.ycol, n, 2 * n + k, g);
        }
    }

    /// C's entries of one sample (n × m, row major) from a row-major n × p
    /// regressor given entry by entry (`y(r·p + k)`): the selected columns,
    /// or the mixes' combinations.
    fn gather(&self, n: usize, p: usize, y: impl Fn(usize) -> f64, ycol: &mut [f64]) {
        let m = self.n_cols();
        for r in 0..n {
            match &self.mixes {
                None => {
                    for (j, &c) in self.columns.iter().enumerate() {
                        ycol[r * m + j] = y(r * p + c);
                    }
                }
                Some(mixes) => {
                    for (j, mx) in mixes.iter().enumerate() {
                        ycol[r * m + j] = mx.entry(r, |k| y(r * p + k));
                    }
                }
            }
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
