//! Forward-mode tangents of the regressor written out in f64 (the kernel of
//! [`regressor_derivatives`](super::regressor_derivatives)) and the dual-number
//! directions shared by the excitation objective.

use super::friction::{friction_slopes, MAX_FRICTION_COLUMNS};
use super::regressor::{couple_rows_inv_t, regressor_inner, sym_bilinear};
use super::ALL;
use crate::robot::kinematics::{joint_transform, Kin};
use crate::robot::model::Robot;
use nalgebra::{Matrix3, Vector3};
use num_dual::Dual64;

/// Buffers and shared f64 quantities of [`regressor_derivatives`].
#[derive(Debug, Clone, Default)]
pub(crate) struct Tangents {
    n: usize,
    /// `j * n + i`: link i is in the subtree of joint j (i = j included).
    in_sub: Vec<bool>,
    /// S_j carried to link i (angular, linear), `j * n + i`, i in the subtree of j.
    sub_a: Vec<Vector3<f64>>,
    sub_l: Vec<Vector3<f64>>,
    /// Their tangents in the current q_k direction.
    t_a: Vec<Vector3<f64>>,
    t_l: Vec<Vector3<f64>>,
    /// β_i = v̇_i + ω_i × v_i of every link.
    beta: Vec<Vector3<f64>>,
    /// Tangents of ω, v, ω̇, v̇ of every link in the current direction.
    tw: Vec<Vector3<f64>>,
    tv: Vec<Vector3<f64>>,
    tdw: Vec<Vector3<f64>>,
    tdv: Vec<Vector3<f64>>,
    /// ∂φ/∂w of each drive's friction columns at its motor velocity.
    dphi: Vec<[f64; MAX_FRICTION_COLUMNS]>,
    /// How many friction columns each drive has.
    n_fric: Vec<usize>,
    /// Coupling C (n×n, row-major; identity without coupling).
    c: Vec<f64>,
    /// Column scratch of the coupling.
    col: Vec<f64>,
}

impl Tangents {
    pub(super) fn new(robot: &Robot) -> Self {
        let n = robot.dof();
        let z = Vector3::zeros();
        let mut c = vec![0.0; n * n];
        match &robot.coupling {
            None => (0..n).for_each(|j| c[j * n + j] = 1.0),
            Some(_) => robot.c_sparse.iter().for_each(|&(r, k, v)| c[r * n + k] += v),
        }
        Tangents {
            n,
            in_sub: vec![false; n * n],
            sub_a: vec![z; n * n],
            sub_l: vec![z; n * n],
            t_a: vec![z; n * n],
            t_l: vec![z; n * n],
            beta: vec![z; n],
            tw: vec![z; n],
            tv: vec![z; n],
            tdw: vec![z; n],
            tdv: vec![z; n],
            dphi: vec![[0.0; MAX_FRICTION_COLUMNS]; n],
            n_fric: vec![0; n],
            c,
            col: vec![0.0; n],
        }
    }

    /// The quantities every direction shares, from `kin` filled by the f64
    /// regressor pass at the state.
    pub(super) fn shared(&mut self, robot: &Robot, kin: &Kin<f64>, qd: &[f64]) {
        let n = self.n;
        assert_eq!(n, robot.dof(), "tangent buffers made for another robot");
        for j in 0..n {
            for i in 0..n {
                self.in_sub[j * n + i] = false;
            }
            self.in_sub[j * n + j] = true;
            self.sub_a[j * n + j] = robot.s_ang[j];
            self.sub_l[j * n + j] = robot.s_lin[j];
            for i in j + 1..n {
                if let Some(par) = robot.joints[i].parent {
                    if self.in_sub[j * n + par] {
                        self.in_sub[j * n + i] = true;
                        let rt = kin.rot[i].transpose();
                        let (pa, pl) = (self.sub_a[j * n + par], self.sub_l[j * n + par]);
                        self.sub_a[j * n + i] = rt * pa;
                        self.sub_l[j * n + i] = rt * (pl + pa.cross(&kin.pos[i]));
                    }
                }
            }
            self.beta[j] = kin.dv[j] + kin.w[j].cross(&kin.v[j]);
        }
        // friction slopes at the motor velocities C q̇
        for j in 0..n {
            let w: f64 = (0..n).map(|c| self.c[j * n + c] * qd[c]).sum();
            self.n_fric[j] = friction_slopes(&robot.drives[j], w, &mut self.dphi[j]);
        }
    }

    /// ∂Y/∂q_k (`dq = Some(k)`) or ∂Y/∂q̇_k (`dqd = Some(k)`) into `out`.
    #[allow(clippy::too_many_arguments)] // robot, shared kinematics, state (q, q̇), the direction, output
    pub(super) fn direction(&mut self, robot: &Robot, kin: &Kin<f64>, q: &[f64], qd: &[f64], dq: Option<usize>, dqd: Option<usize>, out: &mut [f64]) {
        let n = self.n;
        let p = robot.n_params();
        let k = dq.or(dqd).expect("one direction");
        let z = Vector3::zeros();
        // the tangent of joint k's transform (q_k direction)
        let (trt, tr) = match dq {
            Some(k) => {
                let (r, pk) = joint_transform(robot, k, Dual64::new(q[k], 1.0));
                (r.map(|d| d.eps).transpose(), pk.map(|d| d.eps))
            }
            None => (Matrix3::zeros(), z),
        };
        let g = -robot.gravity;
        // link tangents over the subtree of k (parents first)
        for i in 0..n {
            if !self.in_sub[k * n + i] {
                self.tw[i] = z;
                self.tv[i] = z;
                self.tdw[i] = z;
                self.tdv[i] = z;
                continue;
            }
            let rt = kin.rot[i].transpose();
            let r = kin.pos[i];
            let (sa, sl) = (robot.s_ang[i], robot.s_lin[i]);
            let (sqa, sql) = (sa * qd[i], sl * qd[i]);
            let (w, v) = (kin.w[i], kin.v[i]);
            let (tw, tv, tdw, tdv);
            if i == k {
                let (wp, vp, dwp, dvp) = match robot.joints[i].parent {
                    None => (z, z, z, g),
                    Some(par) => (kin.w[par], kin.v[par], kin.dw[par], kin.dv[par]),
                };
                if dq.is_some() {
                    tw = trt * wp;
                    tv = trt * (vp + wp.cross(&r)) + rt * wp.cross(&tr);
                    tdw = trt * dwp + tw.cross(&sqa);
                    tdv = trt * (dvp + dwp.cross(&r)) + rt * dwp.cross(&tr) + tw.cross(&sql) + tv.cross(&sqa);
                } else {
                    tw = sa;
                    tv = sl;
                    tdw = tw.cross(&sqa) + w.cross(&sa);
                    tdv = tw.cross(&sql) + w.cross(&sl) + tv.cross(&sqa) + v.cross(&sa);
                }
            } else {
                let par = robot.joints[i].parent.expect("a link below k has a parent");
                let (twp, tvp, tdwp, tdvp) = (self.tw[par], self.tv[par], self.tdw[par], self.tdv[par]);
                tw = rt * twp;
                tv = rt * (tvp + twp.cross(&r));
                tdw = rt * tdwp + tw.cross(&sqa);
                tdv = rt * (tdvp + tdwp.cross(&r)) + tw.cross(&sql) + tv.cross(&sqa);
            }
            self.tw[i] = tw;
            self.tv[i] = tv;
            self.tdw[i] = tdw;
            self.tdv[i] = tdv;
        }
        // tangents of the carried S_j, j strictly above k, at the links below k
        if dq.is_some() {
            for j in 0..k {
                if !self.in_sub[j * n + k] {
                    continue;
                }
                for i in k..n {
                    if !self.in_sub[k * n + i] {
                        continue;
                    }
                    let rt = kin.rot[i].transpose();
                    let r = kin.pos[i];
                    let par = robot.joints[i].parent.expect("a link below j has a parent");
                    let (ta, tl) = if i == k {
                        let (pa, pl) = (self.sub_a[j * n + par], self.sub_l[j * n + par]);
                        (trt * pa, trt * (pl + pa.cross(&r)) + rt * pa.cross(&tr))
                    } else {
                        let (ta, tl) = (self.t_a[j * n + par], self.t_l[j * n + par]);
                        (rt * ta, rt * (tl + ta.cross(&r)))
                    };
                    self.t_a[j * n + i] = ta;
                    self.t_l[j * n + i] = tl;
                }
            }
        }
        out.fill(0.0);
        for i in 0..n {
            if !self.in_sub[k * n + i] {
                continue;
            }
            let (w, v, dw, beta) = (kin.w[i], kin.v[i], kin.dw[i], self.beta[i]);
            let (tw, tdw) = (self.tw[i], self.tdw[i]);
            let tbeta = self.tdv[i] + tw.cross(&v) + w.cross(&self.tv[i]);
            let o = robot.link_param_offset(i);
            for j in 0..=i {
                if !self.in_sub[j * n + i] {
                    continue;
                }
                let (u, s) = (self.sub_a[j * n + i], self.sub_l[j * n + i]);
                let moved = dq.is_some() && j < k && self.in_sub[j * n + k];
                let (tu, ts) = if moved { (self.t_a[j * n + i], self.t_l[j * n + i]) } else { (z, z) };
                let uxw = u.cross(&w);
                let tuxw = tu.cross(&w) + u.cross(&tw);
                let row = &mut out[j * p + o..j * p + o + 10];
                // d/dε of u^T L(ω̇) + (u×ω)^T L(ω), L symmetric-bilinear
                let l = sym_bilinear::<f64>;
                let (l1, l2, l3, l4) = (l(&tu, &dw), l(&u, &tdw), l(&tuxw, &w), l(&uxw, &tw));
                for c in 0..6 {
                    row[c] = l1[c] + l2[c] + l3[c] + l4[c];
                }
                let wxs = w.cross(&s);
                let hc = tbeta.cross(&u) + beta.cross(&tu) + ts.cross(&dw) + s.cross(&tdw) + tw.cross(&wxs) + w.cross(&(tw.cross(&s) + w.cross(&ts)));
                row[6] = hc.x;
                row[7] = hc.y;
                row[8] = hc.z;
                row[9] = ts.dot(&beta) + s.dot(&tbeta);
            }
        }
        if robot.coupling.is_some() {
            couple_rows_inv_t(robot, out, &mut self.col);
        }
        // friction columns: ∂φ_j/∂q̇_k = φ_j'(w_j) C_jk
        if dqd.is_some() {
            for j in 0..n {
                let cjk = self.c[j * n + k];
                if cjk == 0.0 {
                    continue;
                }
                let d = &robot.drives[j];
                let mut col = robot.drive_param_offset(j);
                if d.rotor_inertia.is_some() {
                    col += 1;
                }
                for (c, s) in self.dphi[j][..self.n_fric[j]].iter().enumerate() {
                    out[j * p + col + c] = s * cjk;
                }
            }
        }
    }

    /// ∂Y/∂q̈_k into `out`: the regressor at (q, q̇ = 0, q̈ = e_k) without
    /// gravity. Every link velocity vanishes and link i's acceleration is S_k
    /// carried to i (zero outside the subtree of k), so block (j, i) is
    /// [L(u_ji, u_ki), s_ki × u_ji + s_ji × u_ki, s_ji · s_ki] (u, s the angular
    /// and linear parts of the carried subspaces); plus the rotor-inertia
    /// column (C e_k)_j. The friction columns do not depend on q̈.
    pub(super) fn qdd_direction(&mut self, robot: &Robot, k: usize, out: &mut [f64]) {
        let n = self.n;
        let p = robot.n_params();
        out.fill(0.0);
        for j in 0..n {
            for i in j..n {
                if !(self.in_sub[j * n + i] && self.in_sub[k * n + i]) {
                    continue;
                }
                let (u, sl) = (self.sub_a[j * n + i], self.sub_l[j * n + i]);
                let (dw, dv) = (self.sub_a[k * n + i], self.sub_l[k * n + i]);
                let row = &mut out[j * p + robot.link_param_offset(i)..];
                row[0] = u.x * dw.x;
                row[1] = u.x * dw.y + u.y * dw.x;
                row[2] = u.x * dw.z + u.z * dw.x;
                row[3] = u.y * dw.y;
                row[4] = u.y * dw.z + u.z * dw.y;
                row[5] = u.z * dw.z;
                let hc = dv.cross(&u) + sl.cross(&dw);
                row[6] = hc.x;
                row[7] = hc.y;
                row[8] = hc.z;
                row[9] = sl.dot(&dv);
            }
        }
        if robot.coupling.is_some() {
            couple_rows_inv_t(robot, out, &mut self.col);
        }
        for j in 0..n {
            if robot.drives[j].rotor_inertia.is_some() {
                out[j * p + robot.drive_param_offset(j)] = self.c[j * n + k];
            }
        }
    }
}

/// The dual-number regressor passes of ∂Y/∂q_k (`which` 0) and ∂Y/∂q̇_k
/// (`which` 1), k = 0..n, calling `f(which, k, Y_dual)` after each (the
/// derivative is in the `eps` parts). `kin` must hold the f64 joint
/// transforms at q (any kernel at q fills them); they are shared by every
/// pass: only joint k's transform carries a derivative in a q_k pass, none in
/// a q̇ pass. `state` holds q, q̇, q̈ as duals with zero `eps` (restored on
/// return). Equals 2n independent dual passes bit for bit.
pub(crate) fn regressor_dual_directions(
    robot: &Robot,
    kin: &Kin<f64>,
    dual: &mut Kin<Dual64>,
    state: [&mut [Dual64]; 3],
    yd: &mut [Dual64],
    mut f: impl FnMut(usize, usize, &[Dual64]),
) {
    let n = robot.dof();
    let [q, qd, qdd] = state;
    for i in 0..n {
        dual.rot[i] = kin.rot[i].map(Dual64::from);
        dual.pos[i] = kin.pos[i].map(Dual64::from);
    }
    for k in 0..n {
        q[k].eps = 1.0;
        let (r, pk) = joint_transform(robot, k, q[k]);
        dual.rot[k] = r;
        dual.pos[k] = pk;
        regressor_inner(robot, q, qd, qdd, ALL, false, dual, yd);
        q[k].eps = 0.0;
        dual.rot[k] = kin.rot[k].map(Dual64::from);
        dual.pos[k] = kin.pos[k].map(Dual64::from);
        f(0, k, yd);
    }
    for k in 0..n {
        qd[k].eps = 1.0;
        regressor_inner(robot, q, qd, qdd, ALL, false, dual, yd);
        qd[k].eps = 0.0;
        f(1, k, yd);
    }
}
