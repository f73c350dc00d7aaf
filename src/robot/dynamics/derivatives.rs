//! Derivatives of inverse dynamics with respect to q and q̇ (the recursive
//! algorithm of Carpentier and Mansard), whole and per row.

use super::crba::{sym_mul, Sym3, Ten};
use super::friction::{friction_slopes, MAX_FRICTION_COLUMNS};
use super::rnea::{check_state, couple};
use super::Workspace;
use crate::robot::kinematics::{joint_transforms, Kin};
use crate::robot::model::Robot;
use nalgebra::{DMatrix, Matrix3, Vector3};

/// Derivatives of inverse dynamics (motor side) with parameters `theta`:
/// returns (∂τ/∂q, ∂τ/∂q̇), each n×n. (∂τ/∂q̈ is [`motor_inertia`](super::motor_inertia).)
/// [`id_derivatives_into`] without the output buffers.
pub fn id_derivatives(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64], qd: &[f64], qdd: &[f64]) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = robot.dof();
    let mut dq = DMatrix::zeros(n, n);
    let mut dqd = DMatrix::zeros(n, n);
    id_derivatives_into(robot, ws, theta, q, qd, qdd, &mut dq, &mut dqd);
    (dq, dqd)
}

/// Motion vector (angular, linear at the world origin).
type Mv = (Vector3<f64>, Vector3<f64>);

/// x ×m y (motion cross product).
#[inline(always)]
fn mcross(x: &Mv, y: &Mv) -> Mv {
    (x.0.cross(&y.0), x.0.cross(&y.1) + x.1.cross(&y.0))
}

/// x ×* f (force cross product), f = (moment, force).
#[inline(always)]
fn fcross(x: &Mv, f: &Mv) -> Mv {
    (x.0.cross(&f.0) + x.1.cross(&f.1), x.0.cross(&f.1))
}

/// ⟨motion, force⟩.
#[inline(always)]
fn mdot(x: &Mv, f: &Mv) -> f64 {
    x.0.dot(&f.0) + x.1.dot(&f.1)
}

/// Per-link quantities of [`id_derivatives_into`], world coordinates, about
/// the world (base) origin.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DerivLink {
    /// World orientation and origin of the link.
    rot: Matrix3<f64>,
    pos: Vector3<f64>,
    /// Joint motion subspace J, velocity v, acceleration a (gravity included).
    j: Mv,
    v: Mv,
    a: Mv,
    /// w = v_λ ×m J and c = −J ×m a_λ − w ×m v_λ (λ the parent).
    w: Mv,
    c: Mv,
    /// Inertia, then composite inertia of the subtree.
    y: Ten,
    /// Force, then the subtree's net force.
    f: Mv,
    /// Momentum Y v, then its sum over the subtree.
    hm: Mv,
    /// The symmetric part of Σ Y [v]×: upper-left block and the vector of the
    /// off-diagonal block (see [`id_derivatives_into`]), summed over the subtree.
    ul: Sym3,
    g: Vector3<f64>,
}

impl DerivLink {
    /// B x = Σ_k [Y_k (x ×m v_k) + x ×* (Y_k v_k) + v_k ×* (Y_k x)] over the
    /// subtree, as −(A + Aᵀ) x + x ×* H (A = Σ Y_k [v_k]×, H = Σ Y_k v_k).
    #[inline(always)]
    pub(super) fn b_mul(&self, x: &Mv) -> Mv {
        let (hn, hf) = &self.hm;
        (-sym_mul(&self.ul, &x.0) + x.0.cross(hn) + x.1.cross(&(hf + self.g)), x.0.cross(&(hf - self.g)))
    }

    /// Bᵀ x.
    #[inline(always)]
    pub(super) fn bt_mul(&self, x: &Mv) -> Mv {
        let (hn, hf) = &self.hm;
        (-sym_mul(&self.ul, &x.0) + hn.cross(&x.0) + (hf - self.g).cross(&x.1), (self.g + hf).cross(&x.0))
    }

    /// Y x (composite inertia).
    #[inline(always)]
    pub(super) fn y_mul(&self, x: &Mv) -> Mv {
        self.y.times(&x.0, &x.1)
    }

    /// What link i (this one, subtree sums in place) gives every strict
    /// ancestor j: ∂τ_j/∂q_i = J_jᵀ g, ∂τ_j/∂q̇_i = J_jᵀ h with
    /// g = J_i ×* F_i + Y^c_i c_i + B_i w_i and h = 2 Y^c_i w_i + B_i J_i.
    #[inline(always)]
    pub(super) fn descendant_terms(&self) -> (Mv, Mv) {
        let jxf = fcross(&self.j, &self.f);
        let yc = self.y_mul(&self.c);
        let bw = self.b_mul(&self.w);
        let yw = self.y_mul(&self.w);
        let bj = self.b_mul(&self.j);
        ((jxf.0 + yc.0 + bw.0, jxf.1 + yc.1 + bw.1), (2.0 * yw.0 + bj.0, 2.0 * yw.1 + bj.1))
    }
}

/// [`id_derivatives`] into `dq` = ∂τ/∂q and `dqd` = ∂τ/∂q̇ (each n×n,
/// overwritten; entry (j, i) = ∂τ_j/∂q_i), allocation-free.
///
/// The recursive derivatives of the RNEA (Carpentier and Mansard, RSS 2018),
/// written in world coordinates about the base origin with the ten-parameter
/// inertias. With J_i the joint's motion subspace, v_i, a_i the link's
/// velocity and acceleration (a_0 = −g), f_k = Y_k a_k + v_k ×* Y_k v_k and
/// τ_j = J_jᵀ Σ_{k in subtree(j)} f_k: moving q_i turns the subtree of i
/// rigidly (the part that leaves τ unchanged) and adds
/// Δv = w_i = v_λ(i) ×m J_i to its velocities and Δa_k = c_i + w_i ×m v_k to its
/// accelerations, c_i = −J_i ×m a_λ(i) − w_i ×m v_λ(i); so, with the composite
/// Y^c_j, F_j = Σ f_k and B_j x = Σ_k [Y_k (x ×m v_k) + x ×* Y_k v_k + v_k ×* Y_k x]
/// over the subtree of j:
///
/// * i an ancestor of j or j itself: ∂τ_j/∂q_i = J_jᵀ (Y^c_j c_i + B_j w_i),
///   ∂τ_j/∂q̇_i = J_jᵀ (2 Y^c_j w_i + B_j J_i);
/// * j a strict ancestor of i: ∂τ_j/∂q_i = J_jᵀ (J_i ×* F_i + Y^c_i c_i + B_i w_i),
///   ∂τ_j/∂q̇_i = J_jᵀ (2 Y^c_i w_i + B_i J_i);
/// * zero otherwise.
///
/// B_j is kept as −(A + Aᵀ) x + x ×* H with A = Σ Y_k (v_k×) and
/// H = Σ Y_k v_k: the symmetric A + Aᵀ has the blocks
/// `[[I [ω]× − [ω]× I + [h]× [u]× + [u]× [h]×, [h × ω − m u]×], [·ᵀ, 0]]` for
/// each body (Y = (m, h, I), v = (ω, u)): nine numbers per body, summed up
/// the tree.
/// Then the motor side: ∂τ/∂q = C⁻ᵀ ∂τ_rb/∂q, ∂τ/∂q̇ = C⁻ᵀ ∂τ_rb/∂q̇ +
/// diag(f′(C q̇)) C (the friction columns' slopes times θ's coefficients;
/// sign-model Coulomb terms have slope 0). Rotor inertias do not depend on
/// q, q̇.
#[allow(clippy::too_many_arguments)] // kernel: robot, workspace, θ, state (q, q̇, q̈), two outputs
pub fn id_derivatives_into(
    robot: &Robot,
    ws: &mut Workspace,
    theta: &[f64],
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    dq: &mut DMatrix<f64>,
    dqd: &mut DMatrix<f64>,
) {
    check_state(robot, q, qd, qdd);
    let n = robot.dof();
    assert_eq!(theta.len(), robot.n_params(), "parameter vector length");
    assert!(
        dq.nrows() == n && dq.ncols() == n && dqd.nrows() == n && dqd.ncols() == n,
        "derivative outputs must be n×n"
    );
    assert_eq!(ws.dl.len(), n, "workspace made for another robot");
    joint_transforms(robot, q, &mut ws.kin);
    deriv_motion(robot, &ws.kin, qd, qdd, &mut ws.dl);
    deriv_inertial(robot, theta, &mut ws.dl, |_| true);
    let dl = &ws.dl;
    let (mq, mqd) = (dq.as_mut_slice(), dqd.as_mut_slice()); // column-major: [col * n + row]
    mq.fill(0.0);
    mqd.fill(0.0);
    for jj in 0..n {
        let d = &dl[jj];
        // i an ancestor of j or j itself
        let pj = d.y_mul(&d.j);
        let qj = d.bt_mul(&d.j);
        let mut i = jj;
        loop {
            let e = &dl[i];
            mq[i * n + jj] = mdot(&e.c, &pj) + mdot(&e.w, &qj);
            mqd[i * n + jj] = 2.0 * mdot(&e.w, &pj) + mdot(&e.j, &qj);
            match robot.joints[i].parent {
                Some(p) => i = p,
                None => break,
            }
        }
        // the strict ancestors j' of jj (in the role of j), jj in the role of i
        if robot.joints[jj].parent.is_some() {
            let (gi, hi) = d.descendant_terms();
            let mut k = jj;
            while let Some(p) = robot.joints[k].parent {
                let jp = &dl[p].j;
                mq[jj * n + p] = mdot(jp, &gi);
                mqd[jj * n + p] = mdot(jp, &hi);
                k = p;
            }
        }
    }
    // motor side: C⁻ᵀ on every column, then the friction slopes
    if robot.coupling.is_some() {
        let col = &mut ws.kin.s1;
        for m in [&mut *dq, &mut *dqd] {
            for c in 0..n {
                let mut v = m.column_mut(c);
                col.copy_from_slice(v.as_slice());
                v.fill(0.0);
                for &(r, k, x) in &robot.cinvt_sparse {
                    v[r] += col[k] * x;
                }
            }
        }
    }
    let w = &mut ws.kin.s2;
    couple(robot, qd, w);
    for jm in 0..n {
        let d = &robot.drives[jm];
        let mut k = robot.drive_param_offset(jm);
        if d.rotor_inertia.is_some() {
            k += 1;
        }
        let mut cols = [0.0; MAX_FRICTION_COLUMNS];
        let mcount = friction_slopes(d, w[jm], &mut cols);
        let slope: f64 = cols[..mcount].iter().enumerate().map(|(c, x)| x * theta[k + c]).sum();
        if slope == 0.0 {
            continue;
        }
        if robot.coupling.is_none() {
            dqd[(jm, jm)] += slope;
        } else {
            for &(r, c, x) in &robot.c_sparse {
                if r == jm {
                    dqd[(jm, c)] += slope * x;
                }
            }
        }
    }
}

/// The θ-independent part of [`id_derivatives_into`]: every link's world
/// placement, J, v, a, w and c (`kin` holds the joint transforms at q).
fn deriv_motion(robot: &Robot, kin: &Kin<f64>, qd: &[f64], qdd: &[f64], dl: &mut [DerivLink]) {
    let z = Vector3::zeros();
    let a0: Mv = (z, -robot.gravity);
    for i in 0..dl.len() {
        let (prot, ppos, pv, pa) = match robot.joints[i].parent {
            None => (Matrix3::identity(), z, (z, z), a0),
            Some(p) => (dl[p].rot, dl[p].pos, dl[p].v, dl[p].a),
        };
        let (rot, pos) = match robot.joints[i].parent {
            None => (kin.rot[i], kin.pos[i]),
            Some(_) => (prot * kin.rot[i], ppos + prot * kin.pos[i]),
        };
        let ja = rot * robot.s_ang[i];
        let j: Mv = (ja, rot * robot.s_lin[i] + pos.cross(&ja));
        let v: Mv = (pv.0 + j.0 * qd[i], pv.1 + j.1 * qd[i]);
        let w = mcross(&pv, &j);
        let a: Mv = (pa.0 + j.0 * qdd[i] + w.0 * qd[i], pa.1 + j.1 * qdd[i] + w.1 * qd[i]);
        let ja_x_pa = mcross(&j, &pa);
        let w_x_pv = mcross(&w, &pv);
        let c: Mv = (-ja_x_pa.0 - w_x_pv.0, -ja_x_pa.1 - w_x_pv.1);
        let d = &mut dl[i];
        (d.rot, d.pos, d.j, d.v, d.a, d.w, d.c) = (rot, pos, j, v, a, w, c);
    }
}

/// The θ-dependent part of [`id_derivatives_into`]: each link's inertia Y,
/// force f, momentum Y v and the pieces of B, then their sums over the
/// subtrees (leaves first). Links for which `used` is false count with zero
/// parameters (they are outside every subtree the caller reads).
fn deriv_inertial(robot: &Robot, theta: &[f64], dl: &mut [DerivLink], used: impl Fn(usize) -> bool) {
    let n = dl.len();
    for i in 0..n {
        let d = &mut dl[i];
        if !used(i) {
            (d.y, d.f, d.hm, d.ul, d.g) = (
                Ten::default(),
                (Vector3::zeros(), Vector3::zeros()),
                (Vector3::zeros(), Vector3::zeros()),
                [0.0; 6],
                Vector3::zeros(),
            );
            continue;
        }
        let o = robot.link_param_offset(i);
        let t = &theta[o..o + 10];
        let local = Ten {
            m: t[9],
            h: Vector3::new(t[6], t[7], t[8]),
            i: [t[0], t[1], t[2], t[3], t[4], t[5]],
        };
        let y = local.in_frame(&d.rot, &d.pos);
        let v = d.v;
        let hm = y.times(&v.0, &v.1);
        let ya = y.times(&d.a.0, &d.a.1);
        let vxh = fcross(&v, &hm);
        let f: Mv = (ya.0 + vxh.0, ya.1 + vxh.1);
        // the symmetric part of Y [v]×: I[ω]× + ([ω]×)ᵀ I + [h]×[u]× + [u]×[h]×, and h × ω − m u
        let (om, u) = &v;
        let ii = &y.i;
        // M = I [ω]×, column c = I (ω × e_c)
        let m0 = sym_mul(ii, &Vector3::new(0.0, om.z, -om.y));
        let m1 = sym_mul(ii, &Vector3::new(-om.z, 0.0, om.x));
        let m2 = sym_mul(ii, &Vector3::new(om.y, -om.x, 0.0));
        let hh = &y.h;
        let hu = 2.0 * hh.dot(u);
        let ul = [
            2.0 * m0.x + 2.0 * u.x * hh.x - hu,
            m1.x + m0.y + u.x * hh.y + hh.x * u.y,
            m2.x + m0.z + u.x * hh.z + hh.x * u.z,
            2.0 * m1.y + 2.0 * u.y * hh.y - hu,
            m2.y + m1.z + u.y * hh.z + hh.y * u.z,
            2.0 * m2.z + 2.0 * u.z * hh.z - hu,
        ];
        let g = hh.cross(om) - u * y.m;
        (d.y, d.f, d.hm, d.ul, d.g) = (y, f, hm, ul, g);
    }
    // subtree sums, leaves first
    for i in (0..n).rev() {
        if let Some(p) = robot.joints[i].parent {
            let d = dl[i];
            let e = &mut dl[p];
            e.y.add(&d.y);
            e.f.0 += d.f.0;
            e.f.1 += d.f.1;
            e.hm.0 += d.hm.0;
            e.hm.1 += d.hm.1;
            for k in 0..6 {
                e.ul[k] += d.ul[k];
            }
            e.g += d.g;
        }
    }
}

/// Row-wise inverse-dynamics derivatives, one parameter vector per row: for
/// every joint r, with θ_r = `thetas[r·p..(r+1)·p]` (any values: the
/// dynamics are linear in θ), row r of ∂τ/∂q, ∂τ/∂q̇ and ∂τ/∂q̈ (motor side,
/// as [`id_derivatives_into`] and [`motor_inertia`](super::motor_inertia)) at the parameters θ_r,
/// into `dq`, `dqd`, `dqdd` (each n×n row-major, entry r·n + k =
/// ∂τ_r(θ_r)/∂x_k). Since τ = Y θ, Σ_r of these rows is the derivative of
/// ⟨H, Y⟩ for the matrix H with rows θ_r: the gradient of a function of
/// the regressor without the regressor's derivatives (the excitation
/// criterion's, `excitation::objective`). Several sets of n parameter
/// vectors at once (`thetas` k·n·p values, the outputs k·n·n each, set after
/// set) share the motion pass.
///
/// The motion pass is shared by every row; per row only the links in the
/// subtrees of the rigid-body rows that τ_r combines (r itself without
/// coupling) get inertias, and only those rows are formed: the ancestors'
/// columns and the descendants' ones of [`id_derivatives_into`], and the
/// mass-matrix row from the same composite inertias (M_si = J_iᵀ Y^c_s J_s
/// for i an ancestor of s or s itself). Allocation-free.
#[allow(clippy::too_many_arguments)] // kernel: robot, workspace, θ rows, state (q, q̇, q̈), three outputs
pub fn id_derivative_rows(
    robot: &Robot,
    ws: &mut Workspace,
    thetas: &[f64],
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    dq: &mut [f64],
    dqd: &mut [f64],
    dqdd: &mut [f64],
) {
    check_state(robot, q, qd, qdd);
    let n = robot.dof();
    let p = robot.n_params();
    assert!(
        n > 0 && p > 0 && !thetas.is_empty() && thetas.len() % (n * p) == 0,
        "one parameter vector per row: n·p values per set"
    );
    let sets = thetas.len() / (n * p);
    assert!(
        dq.len() == sets * n * n && dqd.len() == sets * n * n && dqdd.len() == sets * n * n,
        "row outputs must be n·n per set of parameter vectors"
    );
    assert_eq!(ws.dl.len(), n, "workspace made for another robot");
    joint_transforms(robot, q, &mut ws.kin);
    deriv_motion(robot, &ws.kin, qd, qdd, &mut ws.dl);
    let w = &mut ws.kin.s2;
    couple(robot, qd, w);
    let sub = &robot.topology.sub;
    for sr in 0..sets * n {
        let r = sr % n;
        let theta = &thetas[sr * p..(sr + 1) * p];
        // the rigid-body rows s (with weights x) that τ_r combines
        let coupled = robot.coupling.is_some();
        let rows = || {
            let own = (!coupled).then_some((r, r, 1.0));
            own.into_iter()
                .chain(robot.cinvt_sparse.iter().copied().filter(move |&(rr, _, _)| coupled && rr == r))
        };
        deriv_inertial(robot, theta, &mut ws.dl, |i| rows().any(|(_, s, _)| sub[s * n + i]));
        let dl = &ws.dl;
        let (oq, oqd, oqdd) = (&mut dq[sr * n..(sr + 1) * n], &mut dqd[sr * n..(sr + 1) * n], &mut dqdd[sr * n..(sr + 1) * n]);
        oq.fill(0.0);
        oqd.fill(0.0);
        oqdd.fill(0.0);
        for (_, s, x) in rows() {
            let d = &dl[s];
            let pj = d.y_mul(&d.j);
            let qj = d.bt_mul(&d.j);
            // s and its ancestors i
            let mut i = s;
            loop {
                let e = &dl[i];
                oq[i] += x * (mdot(&e.c, &pj) + mdot(&e.w, &qj));
                oqd[i] += x * (2.0 * mdot(&e.w, &pj) + mdot(&e.j, &qj));
                oqdd[i] += x * mdot(&e.j, &pj);
                match robot.joints[i].parent {
                    Some(a) => i = a,
                    None => break,
                }
            }
            // the strict descendants k of s
            let js = &d.j;
            for k in s + 1..n {
                if !sub[s * n + k] {
                    continue;
                }
                let d = &dl[k];
                let (gi, hi) = d.descendant_terms();
                let pk = d.y_mul(&d.j);
                oq[k] += x * mdot(js, &gi);
                oqd[k] += x * mdot(js, &hi);
                oqdd[k] += x * mdot(js, &pk);
            }
        }
        // the drive of row r: friction slopes on the motor velocity, rotor inertia
        let drive = &robot.drives[r];
        let mut k0 = robot.drive_param_offset(r);
        let ia = drive.rotor_inertia.map(|_| theta[k0]);
        if ia.is_some() {
            k0 += 1;
        }
        let mut cols = [0.0; MAX_FRICTION_COLUMNS];
        let mcount = friction_slopes(drive, w[r], &mut cols);
        let slope: f64 = cols[..mcount].iter().enumerate().map(|(c, v)| v * theta[k0 + c]).sum();
        let ia = ia.unwrap_or(0.0);
        if coupled {
            for &(rr, c, v) in &robot.c_sparse {
                if rr == r {
                    oqd[c] += slope * v;
                    oqdd[c] += ia * v;
                }
            }
        } else {
            oqd[r] += slope;
            oqdd[r] += ia;
        }
    }
}
