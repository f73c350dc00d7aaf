//! Rigid-body dynamics: recursive Newton–Euler inverse dynamics (RNEA), the
//! joint-torque regressor, the composite-rigid-body mass matrix (CRBA),
//! forward dynamics, the derivatives of inverse dynamics (the recursive
//! algorithm of Carpentier and Mansard, [`id_derivatives_into`]) and of the
//! regressor with respect to q, q̇, q̈ (forward-mode tangents written out in
//! f64, [`regressor_derivatives`]).
//!
//! # Model
//!
//! Motor-side torques, referred to the joint side, with coupling matrix C
//! (motor positions θ = C q):
//!
//! τ = C⁻ᵀ τ_rb(q, q̇, q̈) + Ia ⊙ (C q̈) + f(C q̇),
//!
//! τ_rb the rigid-body joint torques, Ia the reflected rotor inertias and f
//! the friction model of each drive ([`friction_columns`]: the Coulomb term
//! switches by sign, tanh or tanh with a Stribeck column, [`Coulomb`]). The regressor Y (n × p) satisfies
//! τ = Y(q, q̇, q̈) θ for the standard parameter vector θ in the layout of
//! [`Robot::params`].
//!
//! Link quantities are expressed in link coordinates about the link origin
//! (Khalil–Gautier parameters XX…ZZ about the origin, first moments MX, MY, MZ,
//! mass M). Gravity enters as a base acceleration −g.

use super::kinematics::{joint_transform, joint_transforms, lift3, Kin, Real};
use super::model::{Coulomb, Drive, Friction, Inertial, Robot};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use num_dual::Dual64;

/// Per-thread buffers for every kernel. Create one per thread
/// (e.g. rayon `map_init`) and reuse it: the kernels do not allocate.
#[derive(Debug, Clone)]
pub struct Workspace {
    pub(crate) kin: Kin<f64>,
    pub(crate) y: Vec<f64>,
    /// Shared quantities and tangents of [`regressor_derivatives`].
    tan: Tangents,
    /// Scratch for the kernels that take a parameter vector θ (the link
    /// inertials of θ); the nominal kernels read `robot.links` instead.
    theta_inertials: Vec<Inertial>,
    /// Composite inertias of the CRBA (ten parameters each).
    crb: Vec<Ten>,
    /// The joints' motion subspaces, classified once ([`Axis`]).
    axes: Vec<Axis>,
    /// The joints' rotations, classified once ([`Placed`]).
    placed: Vec<Placed>,
    /// Most non-root joints are [`Placed::RxZ`]: the CRBA dispatches on them.
    rxz_crba: bool,
    /// What the Rx(α) Rz(θ) CRBA needs of each joint's transform ([`Need`]).
    need: Vec<Need>,
    /// (cos θ, sin θ) of the [`Need::Turn`] joints (the CRBA's scratch).
    cs: Vec<(f64, f64)>,
    /// A serial chain: joint i's parent is i − 1 (the CRBA's index walk).
    chain: bool,
    /// Per-link quantities of [`id_derivatives_into`].
    dl: Vec<DerivLink>,
    /// `s * n + i`: link i is in the subtree of joint s (s itself included).
    sub: Vec<bool>,
    /// Mass matrix / Cholesky factor of forward dynamics.
    fd_m: DMatrix<f64>,
    /// Right-hand side and scratch of forward dynamics.
    fd_rhs: Vec<f64>,
    fd_tmp: Vec<f64>,
    fd_zero: Vec<f64>,
    /// Stages of [`rk4_step`]: a1..a4, q2..q4, v2..v4.
    rk: [Vec<f64>; 10],
}

impl Workspace {
    /// Buffers sized for `robot`.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.dof();
        let p = robot.n_params();
        let placed: Vec<Placed> = (0..n).map(|i| Placed::of(robot, i)).collect();
        // the dispatch on `placed` pays when most non-root joints take the shortcut
        let non_root: Vec<usize> = (0..n).filter(|&i| robot.joints[i].parent.is_some()).collect();
        let rxz = non_root.iter().filter(|&&i| matches!(placed[i], Placed::RxZ(_))).count();
        let need = (0..n).map(|i| Need::of(robot, &placed, i)).collect();
        Workspace {
            kin: Kin::new(n),
            y: vec![0.0; n * p],
            tan: Tangents::new(robot),
            theta_inertials: robot.links.iter().map(|l| l.inertial).collect(),
            crb: vec![Ten::default(); n],
            axes: (0..n).map(|i| Axis::of(robot, i)).collect(),
            placed,
            chain: (0..n).all(|i| robot.joints[i].parent == i.checked_sub(1)),
            rxz_crba: 2 * rxz > non_root.len(),
            need,
            cs: vec![(1.0, 0.0); n],
            dl: vec![DerivLink::default(); n],
            sub: (0..n * n)
                .map(|si| {
                    let (s, mut i) = (si / n, si % n);
                    loop {
                        if i == s {
                            break true;
                        }
                        match robot.joints[i].parent {
                            Some(a) => i = a,
                            None => break false,
                        }
                    }
                })
                .collect(),
            fd_m: DMatrix::zeros(n, n),
            fd_rhs: vec![0.0; n],
            fd_tmp: vec![0.0; n],
            fd_zero: vec![0.0; n],
            rk: std::array::from_fn(|_| vec![0.0; n]),
        }
    }
}

/// Which terms of the dynamics to include.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Terms {
    pub gravity: bool,
    pub drive: bool,
}

const ALL: Terms = Terms { gravity: true, drive: true };

/// Forward pass: link velocities and accelerations.
fn forward_pass<T: Real>(robot: &Robot, q: &[T], qd: &[T], qdd: &[T], gravity: bool, kin: &mut Kin<T>) {
    joint_transforms(robot, q, kin);
    forward_pass_given_transforms(robot, qd, qdd, gravity, kin);
}

/// [`forward_pass`] with `kin.rot`, `kin.pos` already set.
fn forward_pass_given_transforms<T: Real>(robot: &Robot, qd: &[T], qdd: &[T], gravity: bool, kin: &mut Kin<T>) {
    let g = if gravity { -lift3::<T>(&robot.gravity) } else { Vector3::zeros() };
    for i in 0..robot.dof() {
        let rt = kin.rot[i].transpose();
        let r = kin.pos[i];
        let (wp, vp, dwp, dvp) = match robot.joints[i].parent {
            None => (Vector3::zeros(), Vector3::zeros(), Vector3::zeros(), g),
            Some(p) => (kin.w[p], kin.v[p], kin.dw[p], kin.dv[p]),
        };
        let sa = lift3::<T>(&robot.s_ang[i]);
        let sl = lift3::<T>(&robot.s_lin[i]);
        let w = rt * wp + sa * qd[i];
        let v = rt * (vp + wp.cross(&r)) + sl * qd[i];
        // a_i = X a_p + S q̈ + v_i ×m (S q̇)
        let sqa = sa * qd[i];
        let sql = sl * qd[i];
        kin.dw[i] = rt * dwp + sa * qdd[i] + w.cross(&sqa);
        kin.dv[i] = rt * (dvp + dwp.cross(&r)) + sl * qdd[i] + w.cross(&sql) + v.cross(&sqa);
        kin.w[i] = w;
        kin.v[i] = v;
    }
}

/// Link inertials of the rigid-body pass: the robot's nominal ones or those of
/// a parameter vector θ.
#[derive(Clone, Copy)]
enum Inertials<'a> {
    /// `robot.links[i].inertial`.
    Nominal,
    /// One per link, from θ.
    Of(&'a [Inertial]),
}

/// Rigid-body link-side torques for inertials `inert` (generic), into `out`.
#[allow(clippy::too_many_arguments)] // kernel: robot, inertials, state (q, q̇, q̈), flag, buffers, output
fn rnea_rigid<T: Real>(robot: &Robot, inert: Inertials<'_>, q: &[T], qd: &[T], qdd: &[T], gravity: bool, kin: &mut Kin<T>, out: &mut [T]) {
    forward_pass(robot, q, qd, qdd, gravity, kin);
    let n = robot.dof();
    for i in 0..n {
        let ine = match inert {
            Inertials::Nominal => &robot.links[i].inertial,
            Inertials::Of(v) => &v[i],
        };
        let io: Matrix3<T> = ine.inertia.map(T::c);
        let h = lift3::<T>(&ine.first_moment);
        let m = T::c(ine.mass);
        let (w, v, dw, dv) = (kin.w[i], kin.v[i], kin.dw[i], kin.dv[i]);
        let beta = dv + w.cross(&v);
        kin.n[i] = io * dw + w.cross(&(io * w)) + h.cross(&beta);
        kin.f[i] = beta * m + dw.cross(&h) + w.cross(&w.cross(&h));
    }
    for i in (0..n).rev() {
        out[i] = lift3::<T>(&robot.s_ang[i]).dot(&kin.n[i]) + lift3::<T>(&robot.s_lin[i]).dot(&kin.f[i]);
        if let Some(p) = robot.joints[i].parent {
            let rf = kin.rot[i] * kin.f[i];
            let rn = kin.rot[i] * kin.n[i] + kin.pos[i].cross(&rf);
            kin.f[p] += rf;
            kin.n[p] += rn;
        }
    }
}

#[inline]
fn sgn<T: Real>(x: T) -> T {
    let r = x.re_();
    if r > 0.0 {
        T::one()
    } else if r < 0.0 {
        -T::one()
    } else {
        T::zero()
    }
}

/// Motor positions-like product C·x (identity when no coupling), into `out`.
fn couple<T: Real>(robot: &Robot, x: &[T], out: &mut [T]) {
    if robot.coupling.is_none() {
        out.copy_from_slice(x);
        return;
    }
    out.iter_mut().for_each(|v| *v = T::zero());
    for &(r, c, v) in &robot.c_sparse {
        out[r] += x[c] * T::c(v);
    }
}

/// In place: tau ← C⁻ᵀ tau (no-op without coupling). `scratch` has length n.
fn couple_inv_t<T: Real>(robot: &Robot, tau: &mut [T], scratch: &mut [T]) {
    if robot.coupling.is_none() {
        return;
    }
    scratch.copy_from_slice(tau);
    tau.iter_mut().for_each(|v| *v = T::zero());
    for &(r, c, v) in &robot.cinvt_sparse {
        tau[r] += scratch[c] * T::c(v);
    }
}

/// Generic inverse dynamics (motor side) with arbitrary standard parameters
/// `theta` (f64 constants) at a generic-scalar state.
#[allow(clippy::too_many_arguments)] // kernel: robot, inertials, θ, state (q, q̇, q̈), terms, buffers, output
pub(crate) fn inverse_dynamics_generic<T: Real>(
    robot: &Robot,
    inert: &mut [Inertial],
    theta: &[f64],
    q: &[T],
    qd: &[T],
    qdd: &[T],
    terms: Terms,
    kin: &mut Kin<T>,
    out: &mut [T],
) {
    let n = robot.dof();
    for (i, slot) in inert.iter_mut().enumerate().take(n) {
        let o = robot.link_param_offset(i);
        *slot = Inertial::from_params(&theta[o..o + 10]);
    }
    rnea_rigid(robot, Inertials::Of(inert), q, qd, qdd, terms.gravity, kin, out);
    let mut s1 = std::mem::take(&mut kin.s1);
    let mut s2 = std::mem::take(&mut kin.s2);
    couple_inv_t(robot, out, &mut s1);
    if terms.drive {
        couple(robot, qdd, &mut s1); // motor accelerations
        couple(robot, qd, &mut s2); // motor velocities
        for j in 0..n {
            let mut k = robot.drive_param_offset(j);
            let d = &robot.drives[j];
            if d.rotor_inertia.is_some() {
                out[j] += s1[j] * T::c(theta[k]);
                k += 1;
            }
            let mut cols = [T::zero(); MAX_FRICTION_COLUMNS];
            let m = friction_columns(d, s2[j], &mut cols);
            // the Coulomb + viscous group is summed first, then added (then
            // offset and Stribeck terms one by one): the rounding of the
            // kernel before the smooth shapes, so sign-model results stay bit-identical
            let group = match d.friction {
                Friction::None => 0,
                Friction::Symmetric { .. } => 2,
                Friction::Asymmetric { .. } => 4,
            };
            if group > 0 {
                let mut f = cols[0] * T::c(theta[k]);
                for i in 1..group {
                    f += cols[i] * T::c(theta[k + i]);
                }
                out[j] += f;
            }
            for i in group..m {
                out[j] += cols[i] * T::c(theta[k + i]);
            }
        }
    }
    kin.s1 = s1;
    kin.s2 = s2;
}

fn check_state(robot: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) {
    let n = robot.dof();
    assert!(q.len() == n && qd.len() == n && qdd.len() == n, "state vectors must have length n = {n}");
}

/// Inverse dynamics τ (motor side, n) for standard parameters `theta` (p).
/// Equals `regressor(q, q̇, q̈) · theta` for any `theta`.
///
/// # Panics
/// If slice lengths differ from n and p (a programming error, not user input:
/// loaders and CSV readers check dimensions first).
pub fn inverse_dynamics(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64], qd: &[f64], qdd: &[f64], tau: &mut [f64]) {
    check_state(robot, q, qd, qdd);
    assert_eq!(theta.len(), robot.n_params(), "parameter vector length");
    let mut inert = std::mem::take(&mut ws.theta_inertials);
    inverse_dynamics_generic(robot, &mut inert, theta, q, qd, qdd, ALL, &mut ws.kin, tau);
    ws.theta_inertials = inert;
}

/// Inverse dynamics with the robot's nominal parameters (no parameter vector
/// needed): rigid body + drives + friction, motor side.
pub fn rnea(robot: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64], tau: &mut [f64]) {
    check_state(robot, q, qd, qdd);
    rnea_rigid(robot, Inertials::Nominal, q, qd, qdd, true, &mut ws.kin, tau);
    let n = robot.dof();
    let mut s1 = std::mem::take(&mut ws.kin.s1);
    let mut s2 = std::mem::take(&mut ws.kin.s2);
    couple_inv_t(robot, tau, &mut s1);
    couple(robot, qdd, &mut s1);
    couple(robot, qd, &mut s2);
    for j in 0..n {
        let d = &robot.drives[j];
        if let Some(ia) = d.rotor_inertia {
            tau[j] += ia * s1[j];
        }
        tau[j] += friction_torque(d, s2[j]);
    }
    ws.kin.s1 = s1;
    ws.kin.s2 = s2;
}

/// Friction torque of a drive at motor velocity `w` (joint-side units), with
/// its nominal coefficients: Σ_k θ_k φ_k(w) over [`friction_columns`].
pub fn friction_torque(d: &Drive, w: f64) -> f64 {
    let mut cols = [0.0; MAX_FRICTION_COLUMNS];
    let m = friction_columns(d, w, &mut cols);
    let mut coef = [0.0; MAX_FRICTION_COLUMNS];
    let mut k = 0;
    let mut push = |v: f64| {
        coef[k] = v;
        k += 1;
    };
    match d.friction {
        Friction::None => {}
        Friction::Symmetric { fc, fv, offset } => {
            push(fc);
            push(fv);
            if let Some(o) = offset {
                push(o);
            }
            if let Coulomb::Stribeck { fs, .. } = d.coulomb {
                push(fs[0]);
            }
        }
        Friction::Asymmetric {
            fc_pos,
            fc_neg,
            fv_pos,
            fv_neg,
            offset,
        } => {
            for v in [fc_pos, fc_neg, fv_pos, fv_neg] {
                push(v);
            }
            if let Some(o) = offset {
                push(o);
            }
            if let Coulomb::Stribeck { fs, .. } = d.coulomb {
                push(fs[0]);
                push(fs[1]);
            }
        }
    }
    debug_assert_eq!(k, m);
    cols[..m].iter().zip(&coef[..m]).map(|(c, v)| c * v).sum()
}

/// Most friction columns of one drive (asymmetric: Fc±, Fv±, F0, Fs±).
pub const MAX_FRICTION_COLUMNS: usize = 7;

/// The friction regressor columns φ(w) of drive `d` at motor velocity `w`
/// (joint-side units), in the parameter layout order after Ia; returns
/// how many were written into `out`. τ_f = Σ_k θ_k φ_k(w).
///
/// With s(w) the Coulomb switch of [`Coulomb`] (sign(w), or tanh(w/v_s)) and
/// e(w) = exp(−(w/v_st)²) for the Stribeck shape:
///
/// * symmetric: [s, w, (1 if F0), (s·e if Stribeck)] for [Fc, Fv, F0, Fs];
/// * asymmetric: [σ⁺, σ⁻, σ⁺w, σ⁻w, (1), (σ⁺e, σ⁻e)] for
///   [Fc⁺, Fc⁻, Fv⁺, Fv⁻, F0, Fs⁺, Fs⁻], σ± the indicators of ±w > 0 for the
///   sign shape (paper 002 eq. 2) and (1 ± tanh(w/v_s))/2 for the smooth ones.
///
/// Generic in the scalar so that dual numbers carry ∂φ/∂w (zero for sign
/// away from 0, (1 − tanh²)/v_s for tanh).
pub fn friction_columns<T: Real>(d: &Drive, w: T, out: &mut [T]) -> usize {
    let (s, e) = match d.coulomb {
        Coulomb::Sign => (sgn(w), T::zero()),
        Coulomb::Tanh { velocity_scale } => ((w / T::c(velocity_scale)).tanh(), T::zero()),
        Coulomb::Stribeck {
            velocity_scale,
            stribeck_velocity,
            ..
        } => {
            let x = w / T::c(stribeck_velocity);
            ((w / T::c(velocity_scale)).tanh(), (-(x * x)).exp())
        }
    };
    let stribeck = matches!(d.coulomb, Coulomb::Stribeck { .. });
    let mut k = 0;
    let mut push = |v: T| {
        out[k] = v;
        k += 1;
    };
    match d.friction {
        Friction::None => {}
        Friction::Symmetric { offset, .. } => {
            push(s);
            push(w);
            if offset.is_some() {
                push(T::one());
            }
            if stribeck {
                push(s * e);
            }
        }
        Friction::Asymmetric { offset, .. } => {
            let (sp, sn) = if d.coulomb.is_sign() {
                let r = w.re_();
                (if r > 0.0 { T::one() } else { T::zero() }, if r < 0.0 { T::one() } else { T::zero() })
            } else {
                let h = T::c(0.5);
                (h * (T::one() + s), h * (T::one() - s))
            };
            push(sp);
            push(sn);
            push(sp * w);
            push(sn * w);
            if offset.is_some() {
                push(T::one());
            }
            if stribeck {
                push(sp * e);
                push(sn * e);
            }
        }
    }
    k
}

/// The slopes ∂φ_k/∂w of the friction columns of [`friction_columns`] at
/// motor velocity `w`, in the same order; returns how many were written.
/// Closed form: sign switches have slope 0 (away from w = 0, where the
/// columns jump), tanh(w/v_s) has (1 − tanh²)/v_s (finite and → 0 for large
/// |w/v_s|), the Stribeck shape e = exp(−(w/v_st)²) has −2 w e / v_st².
pub fn friction_slopes(d: &Drive, w: f64, out: &mut [f64]) -> usize {
    let (s, ds, e, de) = match d.coulomb {
        Coulomb::Sign => (sgn(w), 0.0, 0.0, 0.0),
        Coulomb::Tanh { velocity_scale } => {
            let s = (w / velocity_scale).tanh();
            (s, (1.0 - s * s) / velocity_scale, 0.0, 0.0)
        }
        Coulomb::Stribeck {
            velocity_scale,
            stribeck_velocity,
            ..
        } => {
            let s = (w / velocity_scale).tanh();
            let x = w / stribeck_velocity;
            let e = (-(x * x)).exp();
            (s, (1.0 - s * s) / velocity_scale, e, -2.0 * x / stribeck_velocity * e)
        }
    };
    let stribeck = matches!(d.coulomb, Coulomb::Stribeck { .. });
    let mut k = 0;
    let mut push = |v: f64| {
        out[k] = v;
        k += 1;
    };
    match d.friction {
        Friction::None => {}
        Friction::Symmetric { offset, .. } => {
            push(ds);
            push(1.0);
            if offset.is_some() {
                push(0.0);
            }
            if stribeck {
                push(ds * e + s * de);
            }
        }
        Friction::Asymmetric { offset, .. } => {
            let (sp, sn, dsp, dsn) = if d.coulomb.is_sign() {
                (if w > 0.0 { 1.0 } else { 0.0 }, if w < 0.0 { 1.0 } else { 0.0 }, 0.0, 0.0)
            } else {
                (0.5 * (1.0 + s), 0.5 * (1.0 - s), 0.5 * ds, -0.5 * ds)
            };
            push(dsp);
            push(dsn);
            push(dsp * w + sp);
            push(dsn * w + sn);
            if offset.is_some() {
                push(0.0);
            }
            if stribeck {
                push(dsp * e + sp * de);
                push(dsn * e + sn * de);
            }
        }
    }
    k
}

/// Rigid-body regressor (link side, inertial columns only) into the row-major
/// n×p buffer `y` (drive columns left untouched), generic scalar.
#[allow(clippy::too_many_arguments)] // kernel: robot, state (q, q̇, q̈), flags, buffers, output
fn rigid_regressor<T: Real>(robot: &Robot, q: &[T], qd: &[T], qdd: &[T], gravity: bool, transforms: bool, kin: &mut Kin<T>, y: &mut [T]) {
    if transforms {
        joint_transforms(robot, q, kin);
    }
    forward_pass_given_transforms(robot, qd, qdd, gravity, kin);
    let n = robot.dof();
    let p = robot.n_params();
    for j in 0..n {
        // propagate S_j down the subtree of j (parents come first)
        kin.sa[j] = lift3::<T>(&robot.s_ang[j]);
        kin.sl[j] = lift3::<T>(&robot.s_lin[j]);
        // mark: s1[i] = 1 if i in subtree(j)
        for i in 0..n {
            kin.s1[i] = T::zero();
        }
        kin.s1[j] = T::one();
        for i in j..n {
            if i > j {
                match robot.joints[i].parent {
                    Some(par) if kin.s1[par].re_() == 1.0 => {
                        kin.s1[i] = T::one();
                        let rt = kin.rot[i].transpose();
                        let (pa, pl) = (kin.sa[par], kin.sl[par]);
                        kin.sa[i] = rt * pa;
                        kin.sl[i] = rt * (pl + pa.cross(&kin.pos[i]));
                    }
                    _ => continue,
                }
            }
            let (u, sl) = (kin.sa[i], kin.sl[i]);
            let (w, v, dw, dv) = (kin.w[i], kin.v[i], kin.dw[i], kin.dv[i]);
            let beta = dv + w.cross(&v);
            let uxw = u.cross(&w);
            let row = &mut y[j * p + robot.link_param_offset(i)..];
            // u^T (L(α) + S(ω)L(ω)) = u^T L(α) + (u×ω)^T L(ω)
            let l1 = sym_bilinear(&u, &dw);
            let l2 = sym_bilinear(&uxw, &w);
            for k in 0..6 {
                row[k] = l1[k] + l2[k];
            }
            let hc = beta.cross(&u) + sl.cross(&dw) + w.cross(&w.cross(&sl));
            row[6] = hc.x;
            row[7] = hc.y;
            row[8] = hc.z;
            row[9] = sl.dot(&beta);
        }
    }
}

/// Rows of the inertial columns of a row-major n×p regressor ← C⁻ᵀ rows
/// (column by column; `col` is scratch of length n).
fn couple_rows_inv_t<T: Real>(robot: &Robot, y: &mut [T], col: &mut [T]) {
    let (n, p) = (robot.dof(), robot.n_params());
    for i in 0..n {
        let o = robot.link_param_offset(i);
        for c in o..o + 10 {
            for r in 0..n {
                col[r] = y[r * p + c];
                y[r * p + c] = T::zero();
            }
            for &(r, k, v) in &robot.cinvt_sparse {
                y[r * p + c] += col[k] * T::c(v);
            }
        }
    }
}

/// aᵀL(b) for the inertia columns (XX, XY, XZ, YY, YZ, ZZ): the products of
/// a and b that multiply each second moment in u·(I b), symmetric in the
/// off-diagonal pairs.
fn sym_bilinear<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> [T; 6] {
    [
        a.x * b.x,
        a.x * b.y + a.y * b.x,
        a.x * b.z + a.z * b.x,
        a.y * b.y,
        a.y * b.z + a.z * b.y,
        a.z * b.z,
    ]
}

/// Full regressor (motor side, coupling and drive columns) into row-major `y` (n×p).
pub(crate) fn regressor_generic<T: Real>(robot: &Robot, q: &[T], qd: &[T], qdd: &[T], terms: Terms, kin: &mut Kin<T>, y: &mut [T]) {
    regressor_inner(robot, q, qd, qdd, terms, true, kin, y);
}

/// [`regressor_generic`]; with `transforms` false, `kin.rot` and `kin.pos`
/// must already hold the joint transforms at `q` (`q` is then not read).
#[allow(clippy::too_many_arguments)] // kernel: robot, state (q, q̇, q̈), flags, buffers, output
fn regressor_inner<T: Real>(robot: &Robot, q: &[T], qd: &[T], qdd: &[T], terms: Terms, transforms: bool, kin: &mut Kin<T>, y: &mut [T]) {
    let n = robot.dof();
    let p = robot.n_params();
    for v in y.iter_mut() {
        *v = T::zero();
    }
    rigid_regressor(robot, q, qd, qdd, terms.gravity, transforms, kin, y);
    if robot.coupling.is_some() {
        let mut col = std::mem::take(&mut kin.s1);
        couple_rows_inv_t(robot, y, &mut col);
        kin.s1 = col;
    }
    if terms.drive {
        let mut s1 = std::mem::take(&mut kin.s1);
        let mut s2 = std::mem::take(&mut kin.s2);
        couple(robot, qdd, &mut s1);
        couple(robot, qd, &mut s2);
        for j in 0..n {
            let mut k = robot.drive_param_offset(j);
            let d = &robot.drives[j];
            let row = j * p;
            if d.rotor_inertia.is_some() {
                y[row + k] = s1[j];
                k += 1;
            }
            let mut cols = [T::zero(); MAX_FRICTION_COLUMNS];
            let m = friction_columns(d, s2[j], &mut cols);
            y[row + k..row + k + m].copy_from_slice(&cols[..m]);
        }
        kin.s1 = s1;
        kin.s2 = s2;
    }
}

/// The regressor Y(q, q̇, q̈) (n × p, motor side): τ = Y θ for every standard
/// parameter vector θ. `out` must be n × p.
pub fn regressor(robot: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut DMatrix<f64>) {
    check_state(robot, q, qd, qdd);
    let (n, p) = (robot.dof(), robot.n_params());
    assert!(out.nrows() == n && out.ncols() == p, "regressor output must be n×p");
    let mut y = std::mem::take(&mut ws.y);
    regressor_generic(robot, q, qd, qdd, ALL, &mut ws.kin, &mut y);
    for r in 0..n {
        for c in 0..p {
            out[(r, c)] = y[r * p + c];
        }
    }
    ws.y = y;
}

/// Regressor into a row-major slice of length n·p (no copy into a matrix):
/// the kernel for stacking millions of rows.
pub fn regressor_rows(robot: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
    check_state(robot, q, qd, qdd);
    assert_eq!(out.len(), robot.dof() * robot.n_params(), "output length n·p");
    regressor_generic(robot, q, qd, qdd, ALL, &mut ws.kin, out);
}

/// Derivatives of the regressor: `dq[k]`, `dqd[k]`, `dqdd[k]` receive
/// ∂Y/∂q_k, ∂Y/∂q̇_k, ∂Y/∂q̈_k (each row-major n×p, in slices of length n·p),
/// and `y` receives Y itself. Sign-function columns have zero derivative.
///
/// Forward-mode derivatives written out in f64 (`Tangents`): one f64 pass
/// for Y and the quantities every direction shares (joint transforms, link
/// velocities and accelerations, the motion subspaces S_j carried down the
/// tree), then per direction only the tangents, only where they are not zero
/// (a q_k or q̇_k direction moves the links of the subtree of k, and the
/// carried S_j only for j above k); ∂Y/∂q̈_k in closed form (Y is affine in
/// q̈). Allocation-free. Equals the scalar dual passes to rounding
/// (`regressor_derivatives_equal_independent_dual_passes`).
#[allow(clippy::too_many_arguments)] // kernel: robot, workspace, state (q, q̇, q̈), outputs (Y, ∂Y/∂q, ∂Y/∂q̇, ∂Y/∂q̈)
pub fn regressor_derivatives(
    robot: &Robot,
    ws: &mut Workspace,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    y: &mut [f64],
    dq: &mut [Vec<f64>],
    dqd: &mut [Vec<f64>],
    dqdd: &mut [Vec<f64>],
) {
    check_state(robot, q, qd, qdd);
    let n = robot.dof();
    let np = n * robot.n_params();
    assert!(
        y.len() == np && dq.len() == n && dqd.len() == n && dqdd.len() == n && dq.iter().chain(dqd.iter()).chain(dqdd.iter()).all(|o| o.len() == np),
        "regressor derivative outputs: Y and n slices per variable, each of length n·p"
    );
    // Y itself, and the f64 joint transforms, velocities, accelerations at the state
    regressor_generic(robot, q, qd, qdd, ALL, &mut ws.kin, y);
    let mut t = std::mem::take(&mut ws.tan);
    t.shared(robot, &ws.kin, qd);
    for k in 0..n {
        t.direction(robot, &ws.kin, q, qd, Some(k), None, &mut dq[k]);
        t.direction(robot, &ws.kin, q, qd, None, Some(k), &mut dqd[k]);
        t.qdd_direction(robot, k, &mut dqdd[k]);
    }
    ws.tan = t;
}

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
    fn new(robot: &Robot) -> Self {
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
    fn shared(&mut self, robot: &Robot, kin: &Kin<f64>, qd: &[f64]) {
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
    fn direction(&mut self, robot: &Robot, kin: &Kin<f64>, q: &[f64], qd: &[f64], dq: Option<usize>, dqd: Option<usize>, out: &mut [f64]) {
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
    fn qdd_direction(&mut self, robot: &Robot, k: usize, out: &mut [f64]) {
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

/// Derivatives of inverse dynamics (motor side) with parameters `theta`:
/// returns (∂τ/∂q, ∂τ/∂q̇), each n×n. (∂τ/∂q̈ is [`motor_inertia`].)
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
    fn b_mul(&self, x: &Mv) -> Mv {
        let (hn, hf) = &self.hm;
        (-sym_mul(&self.ul, &x.0) + x.0.cross(hn) + x.1.cross(&(hf + self.g)), x.0.cross(&(hf - self.g)))
    }

    /// Bᵀ x.
    #[inline(always)]
    fn bt_mul(&self, x: &Mv) -> Mv {
        let (hn, hf) = &self.hm;
        (-sym_mul(&self.ul, &x.0) + hn.cross(&x.0) + (hf - self.g).cross(&x.1), (self.g + hf).cross(&x.0))
    }

    /// Y x (composite inertia).
    #[inline(always)]
    fn y_mul(&self, x: &Mv) -> Mv {
        self.y.times(&x.0, &x.1)
    }

    /// What link i (this one, subtree sums in place) gives every strict
    /// ancestor j: ∂τ_j/∂q_i = J_jᵀ g, ∂τ_j/∂q̇_i = J_jᵀ h with
    /// g = J_i ×* F_i + Y^c_i c_i + B_i w_i and h = 2 Y^c_i w_i + B_i J_i.
    #[inline(always)]
    fn descendant_terms(&self) -> (Mv, Mv) {
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
/// as [`id_derivatives_into`] and [`motor_inertia`]) at the parameters θ_r,
/// into `dq`, `dqd`, `dqdd` (each n×n row-major, entry r·n + k =
/// ∂τ_r(θ_r)/∂x_k). Since τ = Y θ, Σ_r of these rows is the derivative of
/// ⟨H, Y⟩ for the matrix H with rows θ_r: the gradient of a function of
/// the regressor without the regressor's derivatives (the excitation
/// criterion's, `excitation::objective`).
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
    assert_eq!(thetas.len(), n * p, "one parameter vector per row: n·p values");
    assert!(dq.len() == n * n && dqd.len() == n * n && dqdd.len() == n * n, "row outputs must be n·n");
    assert_eq!(ws.dl.len(), n, "workspace made for another robot");
    joint_transforms(robot, q, &mut ws.kin);
    deriv_motion(robot, &ws.kin, qd, qdd, &mut ws.dl);
    let w = &mut ws.kin.s2;
    couple(robot, qd, w);
    let sub = &ws.sub;
    for r in 0..n {
        let theta = &thetas[r * p..(r + 1) * p];
        // the rigid-body rows s (with weights x) that τ_r combines
        let coupled = robot.coupling.is_some();
        let rows = || {
            let own = (!coupled).then_some((r, r, 1.0));
            own.into_iter()
                .chain(robot.cinvt_sparse.iter().copied().filter(move |&(rr, _, _)| coupled && rr == r))
        };
        deriv_inertial(robot, theta, &mut ws.dl, |i| rows().any(|(_, s, _)| sub[s * n + i]));
        let dl = &ws.dl;
        let (oq, oqd, oqdd) = (&mut dq[r * n..(r + 1) * n], &mut dqd[r * n..(r + 1) * n], &mut dqdd[r * n..(r + 1) * n]);
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

/// A symmetric 3×3 matrix as its upper triangle [xx, xy, xz, yy, yz, zz].
type Sym3 = [f64; 6];

/// s·x for a [`Sym3`] s.
#[inline(always)]
fn sym_mul(s: &Sym3, x: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        s[0] * x.x + s[1] * x.y + s[2] * x.z,
        s[1] * x.x + s[3] * x.y + s[4] * x.z,
        s[2] * x.x + s[4] * x.y + s[5] * x.z,
    )
}

/// The ten inertial parameters of a body about a frame's origin, in that
/// frame's coordinates: mass m, first moment h = m·c, rotational inertia I
/// about the origin.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Ten {
    m: f64,
    h: Vector3<f64>,
    i: Sym3,
}

impl Ten {
    #[inline(always)]
    fn of(ine: &Inertial) -> Self {
        let i = &ine.inertia;
        Ten {
            m: ine.mass,
            h: ine.first_moment,
            i: [i[(0, 0)], i[(0, 1)], i[(0, 2)], i[(1, 1)], i[(1, 2)], i[(2, 2)]],
        }
    }

    #[inline(always)]
    fn add(&mut self, o: &Ten) {
        self.m += o.m;
        self.h += o.h;
        for k in 0..6 {
            self.i[k] += o.i[k];
        }
    }

    /// The same body's parameters about the origin of a frame A, in A's
    /// coordinates, given the orientation `r` and position `p` of this
    /// frame in A: h' = R h + m p and, with u = R h and g = u + (m/2) p,
    /// I' = R I Rᵀ − [p]×[u]× − [u]×[p]× − m [p]×² = R I Rᵀ + 2 (p·g) 1 − g pᵀ − p gᵀ
    /// (parallel axes).
    #[inline(always)]
    fn in_frame(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> Ten {
        // rows r_x of R; row x of A = R I is (I r_x)ᵀ (I symmetric); then
        // (R I Rᵀ)_xy = (I r_x) · r_y, upper triangle only
        let rows = [
            Vector3::new(r[(0, 0)], r[(0, 1)], r[(0, 2)]),
            Vector3::new(r[(1, 0)], r[(1, 1)], r[(1, 2)]),
            Vector3::new(r[(2, 0)], r[(2, 1)], r[(2, 2)]),
        ];
        let a = [sym_mul(&self.i, &rows[0]), sym_mul(&self.i, &rows[1]), sym_mul(&self.i, &rows[2])];
        let rir = |x: usize, y: usize| a[x].dot(&rows[y]);
        let ri = [rir(0, 0), rir(0, 1), rir(0, 2), rir(1, 1), rir(1, 2), rir(2, 2)];
        self.shifted(&ri, &(r * self.h), p)
    }

    /// [`Ten::in_frame`] for a joint rotation R = Rx(α) Rz(θ) of
    /// [`Placed::RxZ`]: I and h turned about z (c = cos θ, s = sin θ), then
    /// the exact quarter or half turn about x, a permutation with signs.
    #[inline(always)]
    fn in_frame_rxz(&self, alpha: i8, (c, s): (f64, f64), p: &Vector3<f64>) -> Ten {
        let [xx, xy, xz, yy, yz, zz] = self.i;
        // Rz I Rzᵀ
        let (cc, ss, cs) = (c * c, s * s, c * s);
        let cs2 = 2.0 * cs * xy;
        let z = [
            cc * xx - cs2 + ss * yy,
            cs * (xx - yy) + (cc - ss) * xy,
            c * xz - s * yz,
            ss * xx + cs2 + cc * yy,
            s * xz + c * yz,
            zz,
        ];
        let u = Vector3::new(c * self.h.x - s * self.h.y, s * self.h.x + c * self.h.y, self.h.z);
        let (ri, u) = match alpha {
            0 => (z, u),
            // (x, y, z) → (x, −z, y)
            1 => ([z[0], -z[2], z[1], z[5], -z[4], z[3]], Vector3::new(u.x, -u.z, u.y)),
            // (x, y, z) → (x, z, −y)
            -1 => ([z[0], z[2], -z[1], z[5], -z[4], z[3]], Vector3::new(u.x, u.z, -u.y)),
            // (x, y, z) → (x, −y, −z)
            _ => ([z[0], -z[1], -z[2], z[3], z[4], z[5]], Vector3::new(u.x, -u.y, -u.z)),
        };
        self.shifted(&ri, &u, p)
    }

    /// The parallel-axis part of [`Ten::in_frame`], given the turned
    /// inertia `ri` = R I Rᵀ and first moment `u` = R h: h' = u + m p and,
    /// with g = u + (m/2) p, I' = R I Rᵀ + 2 (p·g) 1 − g pᵀ − p gᵀ.
    #[inline(always)]
    fn shifted(&self, ri: &Sym3, u: &Vector3<f64>, p: &Vector3<f64>) -> Ten {
        let g = u + p * (0.5 * self.m);
        let d = 2.0 * p.dot(&g);
        Ten {
            m: self.m,
            h: u + p * self.m,
            i: [
                ri[0] + d - 2.0 * g.x * p.x,
                ri[1] - (g.x * p.y + p.x * g.y),
                ri[2] - (g.x * p.z + p.x * g.z),
                ri[3] + d - 2.0 * g.y * p.y,
                ri[4] - (g.y * p.z + p.y * g.z),
                ri[5] + d - 2.0 * g.z * p.z,
            ],
        }
    }

    /// The spatial force (moment about the origin n, force f) of the motion
    /// (angular a, linear l at the origin) on this body: n = I a + h × l,
    /// f = m l + a × h.
    #[inline(always)]
    fn times(&self, a: &Vector3<f64>, l: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (sym_mul(&self.i, a) + self.h.cross(l), l * self.m + a.cross(&self.h))
    }
}

/// A joint's rotation R(q) in its parent, for the CRBA's transforms. A
/// revolute joint about +e_z, without post-rotation, whose placement
/// rotation is Rx(α) with α ∈ {0, π/2, −π/2, π} to 1e-15 (the modified-DH
/// placements of most arms) has R = Rx(α) Rz(θ): a turn about z, then a
/// permutation with signs (`RxZ`, α coded 0, 1, −1, 2; cos θ and sin θ
/// read back from the joint transform). Any other joint is `General`.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Placed {
    RxZ(i8),
    General,
}

impl Placed {
    fn of(robot: &Robot, i: usize) -> Self {
        let g = &robot.geo[i];
        if robot.joints[i].kind != super::model::JointKind::Revolute || g.coord != Some((2, 1.0)) || !g.post_identity {
            return Placed::General;
        }
        let rx = |c: f64, s: f64| Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c);
        [(0, rx(1.0, 0.0)), (1, rx(0.0, 1.0)), (-1, rx(0.0, -1.0)), (2, rx(-1.0, 0.0))]
            .into_iter()
            .find(|(_, m)| (m - g.pl_r).amax() <= 1e-15)
            .map_or(Placed::General, |(a, _)| Placed::RxZ(a))
    }

    /// (cos θ, sin θ) of R = Rx(α) Rz(θ) from its first column `r0`:
    /// c = R₀₀, and s = R₁₀, R₂₀, −R₂₀, −R₁₀ for α = 0, π/2, −π/2, π.
    #[inline(always)]
    fn cs(alpha: i8, r0: &Vector3<f64>) -> (f64, f64) {
        let s = match alpha {
            0 => r0.y,
            1 => r0.z,
            -1 => -r0.z,
            _ => -r0.y,
        };
        (r0.x, s)
    }

    /// R v, from `r` (General) or from (c, s) = (cos θ, sin θ) (RxZ).
    #[inline(always)]
    fn apply(self, r: &Matrix3<f64>, (c, s): (f64, f64), v: &Vector3<f64>) -> Vector3<f64> {
        match self {
            Placed::General => r * v,
            Placed::RxZ(alpha) => {
                let (x, y, z) = (c * v.x - s * v.y, s * v.x + c * v.y, v.z);
                match alpha {
                    0 => Vector3::new(x, y, z),
                    1 => Vector3::new(x, -z, y),
                    -1 => Vector3::new(x, z, -y),
                    _ => Vector3::new(x, -y, -z),
                }
            }
        }
    }
}

/// What the CRBA with the [`Placed::RxZ`] shortcut reads of joint i's
/// transform: nothing for a root (its column ends at itself); the whole
/// rotation for a child of a root (the root's entry reads rows of it) and
/// for a [`Placed::General`] joint; otherwise only cos θ and sin θ (the turn
/// about z; the position is the constant placement of a revolute joint).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Need {
    Nothing,
    Full,
    Turn,
}

impl Need {
    fn of(robot: &Robot, placed: &[Placed], i: usize) -> Self {
        match (robot.joints[i].parent, placed[i]) {
            (None, _) => Need::Nothing,
            (Some(par), Placed::RxZ(_)) if robot.joints[par].parent.is_some() => Need::Turn,
            _ => Need::Full,
        }
    }
}

/// A joint's motion subspace S = (angular a, linear l), in link
/// coordinates, for the kernels that specialise to it: a revolute joint
/// about a coordinate axis (a = e_k exactly, l = 0), or any other.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Axis {
    /// Revolute about e_k (k = 0, 1, 2) through the link origin.
    Coord(usize),
    /// Any other (a, l).
    General(Vector3<f64>, Vector3<f64>),
}

impl Axis {
    fn of(robot: &Robot, i: usize) -> Self {
        let (a, l) = (robot.s_ang[i], robot.s_lin[i]);
        if l == Vector3::zeros() {
            for k in 0..3 {
                if (0..3).all(|c| a[c] == if c == k { 1.0 } else { 0.0 }) {
                    return Axis::Coord(k);
                }
            }
        }
        Axis::General(a, l)
    }

    /// Sᵀ (n, f).
    #[inline(always)]
    fn dot(&self, n: &Vector3<f64>, f: &Vector3<f64>) -> f64 {
        // literal components: a runtime index would send the vector
        // through memory (a store-forwarding stall on every call)
        match self {
            Axis::Coord(0) => n.x,
            Axis::Coord(1) => n.y,
            Axis::Coord(_) => n.z,
            Axis::General(a, l) => a.dot(n) + l.dot(f),
        }
    }

    /// The force (n, f) = I S of the motion S on the body `t`.
    #[inline(always)]
    fn force(&self, t: &Ten) -> (Vector3<f64>, Vector3<f64>) {
        match self {
            // the k-th column of I and e_k × h, written out per k
            Axis::Coord(0) => (Vector3::new(t.i[0], t.i[1], t.i[2]), Vector3::new(0.0, -t.h.z, t.h.y)),
            Axis::Coord(1) => (Vector3::new(t.i[1], t.i[3], t.i[4]), Vector3::new(t.h.z, 0.0, -t.h.x)),
            Axis::Coord(_) => (Vector3::new(t.i[2], t.i[4], t.i[5]), Vector3::new(-t.h.y, t.h.x, 0.0)),
            Axis::General(a, l) => t.times(a, l),
        }
    }
}

/// Composite rigid-body algorithm into `m` (n×n, overwritten): M_rb(q) for
/// the inertials `inert` plus Cᵀ diag(Ia) C for the rotor inertias `ia(j)`.
/// Allocation-free (buffers in `ws`).
///
/// The composite inertias are kept in their ten parameters ([`Ten`]: mass,
/// first moment, rotational inertia about the link origin, link
/// coordinates), carried from each link to its parent with the rotation and
/// parallel-axis transform of [`Ten::in_frame`] (leaves first). Column i:
/// the force F = I^c_i S_i ([`Axis::force`]; for a revolute joint about e_k
/// the k-th column of I and e_k × h), M_ii = S_iᵀ F, then F carried up the
/// path to the root (n ← R n + p × R f, f ← R f) and projected on each
/// ancestor's S_j (the k-th moment component for a joint about e_k; at the
/// root only that component is computed). A root joint about e_k reads only
/// the (k, k) entry of its composite, so only that entry is accumulated.
/// Column i holds the upper triangle M_ji (j ≤ i), mirrored at the end.
/// Rotations R = Rx(α) Rz(θ) ([`Placed::RxZ`], most arms' modified-DH
/// placements) are applied as a turn about z and a signed permutation when
/// most joints have one; on a serial chain the path is walked by index.
fn crba_into(robot: &Robot, ws: &mut Workspace, inert: Inertials<'_>, ia: impl Fn(usize) -> Option<f64>, q: &[f64], m: &mut DMatrix<f64>) {
    // the per-joint dispatch on [`Placed`] pays only when most joints take
    // the Rx(α) Rz(θ) shortcut; otherwise every transform is general
    match (ws.rxz_crba, ws.chain) {
        (true, true) => crba_placed::<true, true>(robot, ws, inert, ia, q, m),
        (true, false) => crba_placed::<true, false>(robot, ws, inert, ia, q, m),
        (false, true) => crba_placed::<false, true>(robot, ws, inert, ia, q, m),
        (false, false) => crba_placed::<false, false>(robot, ws, inert, ia, q, m),
    }
}

/// [`crba_into`], with ([`Placed`]) or without (`RXZ` false) the joint
/// rotations' shortcut, for a serial chain (`CHAIN`: joint i's parent is
/// i − 1) or any tree.
fn crba_placed<const RXZ: bool, const CHAIN: bool>(
    robot: &Robot,
    ws: &mut Workspace,
    inert: Inertials<'_>,
    ia: impl Fn(usize) -> Option<f64>,
    q: &[f64],
    m: &mut DMatrix<f64>,
) {
    let n = robot.dof();
    assert!(m.nrows() == n && m.ncols() == n, "mass matrix output must be n×n");
    assert!(q.len() == n && ws.need.len() == n, "workspace made for another robot");
    if RXZ {
        // only what the passes below read ([`Need`]): a turn's (cos θ, sin θ)
        // are the bits `joint_transform` would have put in R₀₀ and R₁₀/R₂₀
        for i in 0..n {
            match (ws.need[i], ws.placed[i]) {
                (Need::Nothing, _) => {}
                (Need::Turn, Placed::RxZ(alpha)) => {
                    let (s, c) = (q[i] + robot.joints[i].offset).sincos();
                    // R's first column is P e_x c + P e_y s (`joint_transform`
                    // about +e_z): the same products, signed zeros included
                    let pl = &robot.geo[i].pl_r;
                    let r0 = |x: usize| pl[(x, 0)] * c + pl[(x, 1)] * s;
                    ws.cs[i] = Placed::cs(alpha, &Vector3::new(r0(0), r0(1), r0(2)));
                    ws.kin.pos[i] = robot.geo[i].pl_p;
                }
                (_, placed) => {
                    let (r, p) = joint_transform(robot, i, q[i]);
                    if let Placed::RxZ(alpha) = placed {
                        ws.cs[i] = Placed::cs(alpha, &r.column(0).into_owned());
                    }
                    ws.kin.rot[i] = r;
                    ws.kin.pos[i] = p;
                }
            }
        }
    } else {
        joint_transforms(robot, q, &mut ws.kin);
    }
    for i in 0..n {
        let ine = match inert {
            Inertials::Nominal => &robot.links[i].inertial,
            Inertials::Of(v) => &v[i],
        };
        ws.crb[i] = Ten::of(ine);
    }
    let kin = &ws.kin;
    let axes = &ws.axes;
    assert_eq!(axes.len(), n, "workspace made for another robot");
    // The composite of link i's chain child (parent i) is handed over in
    // `carry`, not through ws.crb: reading back a Ten just written field by
    // field stalls on store forwarding. Other children (branches) add into
    // ws.crb[par] as before.
    let mut carry: Option<Ten> = None;
    for i in (0..n).rev() {
        let mut t = ws.crb[i];
        if let Some(c) = carry.take() {
            t.add(&c);
            ws.crb[i] = t;
        }
        if let Some(par) = robot.joints[i].parent {
            let (r, p) = (&kin.rot[i], &kin.pos[i]);
            match (robot.joints[par].parent, axes[par]) {
                // a root joint about e_k reads only I^c_kk of its composite
                // (M_par,par; its column's force n = I^c e_k is read only at k):
                // (R I Rᵀ)_kk + 2 p·g − 2 g_k p_k, g = R h + (m/2) p
                (None, Axis::Coord(k)) => {
                    let rk = Vector3::new(r[(k, 0)], r[(k, 1)], r[(k, 2)]);
                    let g = r * t.h + p * (0.5 * t.m);
                    let v = rk.dot(&sym_mul(&t.i, &rk)) + 2.0 * p.dot(&g) - 2.0 * g[k] * p[k];
                    ws.crb[par].i[[0, 3, 5][k]] += v;
                }
                _ => {
                    let c = match if RXZ { ws.placed[i] } else { Placed::General } {
                        Placed::RxZ(alpha) => t.in_frame_rxz(alpha, ws.cs[i], p),
                        Placed::General => t.in_frame(r, p),
                    };
                    if par + 1 == i {
                        carry = Some(c);
                    } else {
                        ws.crb[par].add(&c);
                    }
                }
            }
        }
    }
    let ms = m.as_mut_slice(); // column-major: ms[col * n + row]
    ms.fill(0.0);
    let (crb, rot, pos, placed, cs) = (&ws.crb[..n], &kin.rot[..n], &kin.pos[..n], &ws.placed[..n], &ws.cs[..n]);
    // column i's force carried up its path; the upper triangle M[j, i]
    // (j ≤ i) goes into column i, mirrored below at the end. On a chain the
    // path is i, i − 1, …, 0 (indices the compiler can bound).
    for i in 0..n {
        let col = &mut ms[i * n..(i + 1) * n];
        let (mut nn, mut ff) = axes[i].force(&crb[i]);
        col[i] = axes[i].dot(&nn, &ff);
        let mut j = i;
        loop {
            let par = if CHAIN {
                if j == 0 {
                    break;
                }
                j - 1
            } else {
                match robot.joints[j].parent {
                    Some(p) => p,
                    None => break,
                }
            };
            let root = if CHAIN { par == 0 } else { robot.joints[par].parent.is_none() };
            let (r, p) = (&rot[j], &pos[j]);
            let (turn, cj) = if RXZ { (placed[j], cs[j]) } else { (Placed::General, (1.0, 0.0)) };
            let rf = turn.apply(r, cj, &ff);
            if let (true, Axis::Coord(k)) = (root, axes[par]) {
                // only the k-th moment component: (R n)_k + (p × R f)_k
                let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
                let rn = r[(k, 0)] * nn.x + r[(k, 1)] * nn.y + r[(k, 2)] * nn.z;
                col[par] = rn + (p[k1] * rf[k2] - p[k2] * rf[k1]);
                break;
            }
            nn = turn.apply(r, cj, &nn) + p.cross(&rf);
            ff = rf;
            col[par] = axes[par].dot(&nn, &ff);
            j = par;
        }
    }
    for i in 0..n {
        for j in 0..i {
            ms[j * n + i] = ms[i * n + j];
        }
    }
    // rotor inertias: Cᵀ diag(Ia) C
    if robot.coupling.is_none() {
        for j in 0..n {
            if let Some(v) = ia(j) {
                m[(j, j)] += v;
            }
        }
    } else {
        for &(j, a, ca) in &robot.c_sparse {
            if let Some(v) = ia(j) {
                for &(jj, b, cb) in &robot.c_sparse {
                    if jj == j {
                        m[(a, b)] += ca * v * cb;
                    }
                }
            }
        }
    }
}

/// Link-side mass matrix for parameters `theta` into `out` (n×n):
/// M_rb(q) + Cᵀ diag(Ia) C. Allocation-free.
pub fn mass_matrix_with_into(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64], out: &mut DMatrix<f64>) {
    let n = robot.dof();
    assert_eq!(theta.len(), robot.n_params(), "parameter vector length");
    assert_eq!(q.len(), n, "q length");
    let mut inert = std::mem::take(&mut ws.theta_inertials);
    for (i, slot) in inert.iter_mut().enumerate().take(n) {
        let o = robot.link_param_offset(i);
        *slot = Inertial::from_params(&theta[o..o + 10]);
    }
    let ia = |j: usize| robot.drives[j].rotor_inertia.map(|_| theta[robot.drive_param_offset(j)]);
    crba_into(robot, ws, Inertials::Of(&inert), ia, q, out);
    ws.theta_inertials = inert;
}

/// Link-side mass matrix with the nominal parameters into `out` (n×n).
/// Allocation-free.
pub fn mass_matrix_into(robot: &Robot, ws: &mut Workspace, q: &[f64], out: &mut DMatrix<f64>) {
    assert_eq!(q.len(), robot.dof(), "q length");
    crba_into(robot, ws, Inertials::Nominal, |j| robot.drives[j].rotor_inertia, q, out);
}

/// Link-side mass matrix for parameters `theta`: M_rb(q) + Cᵀ diag(Ia) C
/// (n×n, symmetric, positive definite for physical parameters). Composite
/// rigid-body algorithm ([`mass_matrix_with_into`] without the output buffer).
pub fn mass_matrix_with(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64]) -> DMatrix<f64> {
    let n = robot.dof();
    let mut m = DMatrix::zeros(n, n);
    mass_matrix_with_into(robot, ws, theta, q, &mut m);
    m
}

/// Link-side mass matrix with the nominal parameters.
pub fn mass_matrix(robot: &Robot, ws: &mut Workspace, q: &[f64]) -> DMatrix<f64> {
    let n = robot.dof();
    let mut m = DMatrix::zeros(n, n);
    mass_matrix_into(robot, ws, q, &mut m);
    m
}

/// ∂τ/∂q̈ of the motor-side torque: C⁻ᵀ M_rb + diag(Ia) C (n×n; equals the
/// mass matrix when there is no coupling).
pub fn motor_inertia(robot: &Robot, ws: &mut Workspace, theta: &[f64], q: &[f64]) -> DMatrix<f64> {
    match &robot.coupling_inv_t {
        None => mass_matrix_with(robot, ws, theta, q),
        // M_total = M_rb + Cᵀ D C  ⇒  C⁻ᵀ M_total = C⁻ᵀ M_rb + D C
        Some(ct) => ct * mass_matrix_with(robot, ws, theta, q),
    }
}

/// Link-side gravity torques g(q) (nominal parameters).
pub fn gravity(robot: &Robot, ws: &mut Workspace, q: &[f64]) -> DVector<f64> {
    let n = robot.dof();
    let z = vec![0.0; n];
    let mut out = vec![0.0; n];
    rnea_rigid(robot, Inertials::Nominal, q, &z, &z, true, &mut ws.kin, &mut out);
    DVector::from_vec(out)
}

/// Link-side Coriolis, centrifugal and gravity torques c(q, q̇) + g(q) (nominal parameters, no friction).
pub fn bias_forces(robot: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64]) -> DVector<f64> {
    let n = robot.dof();
    let z = vec![0.0; n];
    let mut out = vec![0.0; n];
    rnea_rigid(robot, Inertials::Nominal, q, qd, &z, true, &mut ws.kin, &mut out);
    DVector::from_vec(out)
}

/// Forward dynamics: joint accelerations q̈ for motor torques `tau_motor`
/// (nominal parameters, friction included):
/// (M_rb + CᵀIaC) q̈ = Cᵀ(τ_m − f(C q̇)) − c(q, q̇) − g(q).
/// Returns an error if the mass matrix is not positive definite.
pub fn forward_dynamics(robot: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64], tau_motor: &[f64]) -> crate::Result<DVector<f64>> {
    let mut out = DVector::zeros(robot.dof());
    forward_dynamics_into(robot, ws, q, qd, tau_motor, out.as_mut_slice())?;
    Ok(out)
}

/// [`forward_dynamics`] into `qdd` (length n), allocation-free: the
/// simulator's inner loop.
pub fn forward_dynamics_into(robot: &Robot, ws: &mut Workspace, q: &[f64], qd: &[f64], tau_motor: &[f64], qdd: &mut [f64]) -> crate::Result<()> {
    let n = robot.dof();
    assert!(
        q.len() == n && qd.len() == n && tau_motor.len() == n && qdd.len() == n,
        "state vectors must have length n = {n}"
    );
    let mut m = std::mem::take(&mut ws.fd_m);
    mass_matrix_into(robot, ws, q, &mut m);
    let mut rhs = std::mem::take(&mut ws.fd_rhs);
    let mut tmp = std::mem::take(&mut ws.fd_tmp);
    // motor velocities w = C q̇ (tmp), then tmp ← τ_m − f(w)
    couple(robot, qd, &mut tmp);
    for j in 0..n {
        tmp[j] = tau_motor[j] - friction_torque(&robot.drives[j], tmp[j]);
    }
    // rhs = Cᵀ tmp
    if robot.coupling.is_none() {
        rhs.copy_from_slice(&tmp);
    } else {
        rhs.iter_mut().for_each(|v| *v = 0.0);
        for &(r, c, v) in &robot.c_sparse {
            rhs[c] += v * tmp[r];
        }
    }
    // − c(q, q̇) − g(q)
    rnea_rigid(robot, Inertials::Nominal, q, qd, &ws.fd_zero, true, &mut ws.kin, &mut tmp);
    for j in 0..n {
        rhs[j] -= tmp[j];
    }
    // nalgebra's Cholesky on the moved buffer (no allocation, the same
    // arithmetic as before the buffers were kept)
    let ok = match nalgebra::Cholesky::new(m) {
        Some(chol) => {
            chol.solve_mut(&mut nalgebra::DVectorViewMut::from_slice(&mut rhs, n));
            ws.fd_m = chol.unpack_dirty();
            true
        }
        None => {
            ws.fd_m = DMatrix::zeros(n, n);
            false
        }
    };
    qdd.copy_from_slice(&rhs);
    ws.fd_rhs = rhs;
    ws.fd_tmp = tmp;
    if ok {
        Ok(())
    } else {
        Err(crate::Error::Numerical("mass matrix is not positive definite".into()))
    }
}

/// One classical Runge–Kutta step of q̈ = FD(q, q̇, τ) (nominal parameters,
/// `tau` held over the step) of length `h`, in place, allocation-free (stage
/// buffers in `ws`). `check` sees every stage's accelerations and may reject
/// them (divergence); errors of forward dynamics are mapped by `on_fd_error`.
#[allow(clippy::too_many_arguments)] // kernel: robot, buffers, state in/out, input, step, two callbacks
pub fn rk4_step(
    robot: &Robot,
    ws: &mut Workspace,
    q: &mut [f64],
    qd: &mut [f64],
    tau: &[f64],
    h: f64,
    check: impl Fn(&[f64]) -> crate::Result<()>,
    on_fd_error: impl Fn(crate::Error) -> crate::Error,
) -> crate::Result<()> {
    let n = q.len();
    let [mut a1, mut a2, mut a3, mut a4, mut q2, mut q3, mut q4, mut v2, mut v3, mut v4] = std::mem::take(&mut ws.rk);
    let res = (|| {
        let f = |ws: &mut Workspace, q: &[f64], qd: &[f64], a: &mut [f64]| -> crate::Result<()> {
            forward_dynamics_into(robot, ws, q, qd, tau, a).map_err(&on_fd_error)?;
            check(a)
        };
        f(ws, q, qd, &mut a1)?;
        for j in 0..n {
            q2[j] = q[j] + 0.5 * h * qd[j];
            v2[j] = qd[j] + 0.5 * h * a1[j];
        }
        f(ws, &q2, &v2, &mut a2)?;
        for j in 0..n {
            q3[j] = q[j] + 0.5 * h * v2[j];
            v3[j] = qd[j] + 0.5 * h * a2[j];
        }
        f(ws, &q3, &v3, &mut a3)?;
        for j in 0..n {
            q4[j] = q[j] + h * v3[j];
            v4[j] = qd[j] + h * a3[j];
        }
        f(ws, &q4, &v4, &mut a4)?;
        for j in 0..n {
            q[j] += h / 6.0 * (qd[j] + 2.0 * v2[j] + 2.0 * v3[j] + v4[j]);
            qd[j] += h / 6.0 * (a1[j] + 2.0 * a2[j] + 2.0 * a3[j] + a4[j]);
        }
        Ok(())
    })();
    ws.rk = [a1, a2, a3, a4, q2, q3, q4, v2, v3, v4];
    res
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix6;

    /// The straightforward kernel: 3n independent scalar dual passes, transforms recomputed.
    fn reference(robot: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<Vec<f64>> {
        let n = robot.dof();
        let mut out = Vec::new();
        let mut yd = vec![Dual64::from(0.0); n * robot.n_params()];
        let mut dual = Kin::new(n);
        let (mut qv, mut qdv, mut qddv) = (vec![Dual64::from(0.0); n], vec![Dual64::from(0.0); n], vec![Dual64::from(0.0); n]);
        for which in 0..3 {
            for k in 0..n {
                for i in 0..n {
                    let seed = |x: f64, on: bool| Dual64::new(x, if on { 1.0 } else { 0.0 });
                    qv[i] = seed(q[i], which == 0 && i == k);
                    qdv[i] = seed(qd[i], which == 1 && i == k);
                    qddv[i] = seed(qdd[i], which == 2 && i == k);
                }
                regressor_generic(robot, &qv, &qdv, &qddv, ALL, &mut dual, &mut yd);
                out.push(yd.iter().map(|d| d.eps).collect());
            }
        }
        out
    }

    /// The f64 tangents of `regressor_derivatives` equal 3n independent scalar
    /// dual passes to 1e-12 of each direction's largest entry, and the
    /// shared-transform dual passes of the excitation gradient equal them to
    /// the last bit (up to the sign of zeros), on robots with and without
    /// coupling, rotor inertia and friction.
    #[test]
    fn regressor_derivatives_equal_independent_dual_passes() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        for name in ["ur5", "industrial6", "puma560", "panda"] {
            let r = crate::robot::load(&root.join(format!("designs/robots/{name}.toml"))).unwrap();
            let (n, p) = (r.dof(), r.n_params());
            let mut ws = Workspace::new(&r);
            let mut t = 0.0_f64;
            for _ in 0..5 {
                let mut st = || {
                    (0..n)
                        .map(|_| {
                            t += 0.731;
                            2.0 * (3.7 * t).sin()
                        })
                        .collect::<Vec<f64>>()
                };
                let (q, qd, qdd) = (st(), st(), st());
                let mut y = vec![0.0; n * p];
                let mut d = vec![vec![0.0; n * p]; 3 * n];
                let (a, rest) = d.split_at_mut(n);
                let (b, c) = rest.split_at_mut(n);
                regressor_derivatives(&r, &mut ws, &q, &qd, &qdd, &mut y, a, b, c);
                let want = reference(&r, &q, &qd, &qdd);
                for (k, (got, exp)) in d.iter().zip(&want).enumerate() {
                    let scale = exp.iter().fold(0.0_f64, |a, e| a.max(e.abs()));
                    for (i, (g, e)) in got.iter().zip(exp).enumerate() {
                        assert!(
                            (g - e).abs() <= 1e-12 * scale,
                            "{name}: direction {k}, entry {i}: {g:e} vs {e:e} (scale {scale:e})"
                        );
                    }
                }
                // and the excitation gradient's shared-transform dual passes, bit for bit
                let mut qv: Vec<Dual64> = q.iter().map(|&x| Dual64::from(x)).collect();
                let mut qdv: Vec<Dual64> = qd.iter().map(|&x| Dual64::from(x)).collect();
                let mut qddv: Vec<Dual64> = qdd.iter().map(|&x| Dual64::from(x)).collect();
                let mut yd = vec![Dual64::from(0.0); n * p];
                joint_transforms(&r, &q, &mut ws.kin);
                let mut dual = Kin::new(n);
                regressor_dual_directions(&r, &ws.kin, &mut dual, [&mut qv, &mut qdv, &mut qddv], &mut yd, |which, k, yd| {
                    for (i, (g, e)) in yd.iter().zip(&want[which * n + k]).enumerate() {
                        assert!(g.eps == *e, "{name}: dual direction {which}/{k}, entry {i}: {:e} vs {e:e}", g.eps);
                    }
                });
            }
        }
    }

    /// The spatial inertia as the dense CRBA built it.
    fn dense_spatial_inertia(ine: &Inertial) -> Matrix6<f64> {
        let sh = ine.first_moment.cross_matrix();
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&ine.inertia);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&sh);
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&sh.transpose());
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Matrix3::identity() * ine.mass));
        m
    }

    /// Motion transform parent → child (6×6) from child orientation `r` and
    /// position `p` in parent: the dense form the CRBA had before its block
    /// products.
    fn dense_motion_x(r: &Matrix3<f64>, p: &Vector3<f64>) -> Matrix6<f64> {
        let rt = r.transpose();
        let mut x = Matrix6::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&rt);
        x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-rt * p.cross_matrix()));
        x
    }

    /// The CRBA with dense 6×6 products (Xᵀ I X, Xᵀ f, I S, S·f), as shipped
    /// before the block form: the reference of the bit-identity test.
    fn dense_crba(robot: &Robot, inert: &[Inertial], ia: &[Option<f64>], q: &[f64]) -> DMatrix<f64> {
        let n = robot.dof();
        let mut kin = Kin::new(n);
        joint_transforms(robot, q, &mut kin);
        let mut ic: Vec<Matrix6<f64>> = inert.iter().map(dense_spatial_inertia).collect();
        let xs: Vec<Matrix6<f64>> = (0..n).map(|i| dense_motion_x(&kin.rot[i], &kin.pos[i])).collect();
        for i in (0..n).rev() {
            if let Some(p) = robot.joints[i].parent {
                let add = xs[i].transpose() * ic[i] * xs[i];
                ic[p] += add;
            }
        }
        let s = |i: usize| {
            let (a, l) = (robot.s_ang[i], robot.s_lin[i]);
            nalgebra::Vector6::new(a.x, a.y, a.z, l.x, l.y, l.z)
        };
        let mut m = DMatrix::zeros(n, n);
        for i in 0..n {
            let mut f = ic[i] * s(i);
            m[(i, i)] = s(i).dot(&f);
            let mut j = i;
            while let Some(p) = robot.joints[j].parent {
                f = xs[j].transpose() * f;
                j = p;
                m[(i, j)] = s(j).dot(&f);
                m[(j, i)] = m[(i, j)];
            }
        }
        if robot.coupling.is_none() {
            for j in 0..n {
                if let Some(v) = ia[j] {
                    m[(j, j)] += v;
                }
            }
        } else {
            for &(j, a, ca) in &robot.c_sparse {
                if let Some(v) = ia[j] {
                    for &(jj, b, cb) in &robot.c_sparse {
                        if jj == j {
                            m[(a, b)] += ca * v * cb;
                        }
                    }
                }
            }
        }
        m
    }

    /// Test states: zeros, multiples of π/2 and π/4 (exact zeros and ones in
    /// the transforms), then pseudo-random ones in ±2.5.
    fn test_configurations(n: usize, count: usize) -> Vec<Vec<f64>> {
        use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
        let mut out = vec![vec![0.0; n], vec![FRAC_PI_2; n], vec![-FRAC_PI_2; n], vec![FRAC_PI_4; n]];
        out.push((0..n).map(|i| FRAC_PI_2 * i as f64).collect());
        out.push((0..n).map(|i| if i % 2 == 0 { 0.0 } else { -1.0 }).collect());
        let mut x = 0x9e37_79b9_7f4a_7c15_u64;
        for _ in 0..count {
            out.push(
                (0..n)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        5.0 * ((x >> 11) as f64 / (1u64 << 53) as f64) - 2.5
                    })
                    .collect(),
            );
        }
        out
    }

    /// Every shipped robot model, and the RPR robots of the simulation designs.
    fn shipped_robots() -> Vec<(String, Robot)> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/robots");
        let mut paths: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        paths.sort();
        // and the RPR robots of the shipped simulation designs
        let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/ident");
        paths.extend(["rpr_drives.toml", "rpr_drives_tanh.toml"].map(|f| data.join(f)));
        let out: Vec<(String, Robot)> = paths
            .iter()
            .filter_map(|p| crate::robot::load(p).ok().map(|r| (p.file_stem().unwrap().to_string_lossy().into_owned(), r)))
            .collect();
        for must in ["ur5", "panda", "puma560", "industrial6", "iiwa14", "rpr_drives", "rpr_drives_tanh"] {
            assert!(out.iter().any(|(n, _)| n == must), "{must} not loaded");
        }
        out
    }

    /// The test robots of tests/data: a coupled wrist, an RPR arm with a
    /// prismatic joint, a branching tree.
    fn test_robots() -> Vec<(String, Robot)> {
        let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        ["coupled6_modified.toml", "rpr_standard.toml", "tree.urdf", "rxz_chain.urdf"]
            .iter()
            .map(|f| (f.to_string(), crate::robot::load(&data.join(f)).unwrap()))
            .collect()
    }

    /// θ with every parameter changed (non-physical values included).
    fn perturbed_params(r: &Robot) -> Vec<f64> {
        r.nominal_params()
            .iter()
            .enumerate()
            .map(|(k, v)| v * (1.0 + 0.37 * (k as f64).sin()) + 1e-3 * (k as f64).cos())
            .collect()
    }

    /// The ten-parameter CRBA equals the mass matrix of the dense 6×6
    /// products (spatial inertias and motion transforms) to 1e-12 of its
    /// largest entry, for every shipped and test robot, nominal and
    /// perturbed parameters, on exact and random configurations.
    #[test]
    fn crba_equals_the_dense_products() {
        let mut robots = shipped_robots();
        robots.extend(test_robots());
        let mut checked = 0;
        for (name, r) in robots {
            let n = r.dof();
            let mut ws = Workspace::new(&r);
            let nominal: Vec<Inertial> = r.links.iter().map(|l| l.inertial).collect();
            let perturbed = perturbed_params(&r);
            let pert_inert: Vec<Inertial> = (0..n)
                .map(|i| {
                    let o = r.link_param_offset(i);
                    Inertial::from_params(&perturbed[o..o + 10])
                })
                .collect();
            let ia_nom: Vec<Option<f64>> = r.drives.iter().map(|d| d.rotor_inertia).collect();
            let ia_pert: Vec<Option<f64>> = (0..n).map(|j| r.drives[j].rotor_inertia.map(|_| perturbed[r.drive_param_offset(j)])).collect();
            let mut m = DMatrix::zeros(n, n);
            for q in test_configurations(n, 300) {
                mass_matrix_into(&r, &mut ws, &q, &mut m);
                let want = dense_crba(&r, &nominal, &ia_nom, &q);
                assert!((&m - &want).amax() <= 1e-12 * want.amax(), "{name}: nominal at q = {q:?}: {m} vs {want}");
                mass_matrix_with_into(&r, &mut ws, &perturbed, &q, &mut m);
                let want = dense_crba(&r, &pert_inert, &ia_pert, &q);
                assert!((&m - &want).amax() <= 1e-12 * want.amax(), "{name}: perturbed at q = {q:?}: {m} vs {want}");
                checked += 1;
            }
        }
        assert!(checked >= 10 * 306, "{checked} configurations");
    }

    /// The test chain exercises every Rx(α) Rz(θ) case of the CRBA's
    /// shortcut (α = 0, π/2, π, −π/2) on a chain walked by index, and the
    /// tree the general walk; `crba_equals_the_dense_products` checks them.
    #[test]
    fn crba_paths_are_exercised_by_the_test_robots() {
        let robots = test_robots();
        let ws = |name: &str| Workspace::new(&robots.iter().find(|(n, _)| n == name).unwrap().1);
        let chain = ws("rxz_chain.urdf");
        assert!(chain.chain && chain.rxz_crba);
        let alphas: Vec<i8> = chain
            .placed
            .iter()
            .filter_map(|p| if let Placed::RxZ(a) = p { Some(*a) } else { None })
            .collect();
        assert_eq!(alphas, vec![0, 1, 2, -1, 0]);
        let tree = ws("tree.urdf");
        assert!(!tree.chain && !tree.rxz_crba);
        let panda = Workspace::new(&crate::robot::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/robots/panda.toml")).unwrap());
        assert!(panda.chain && panda.rxz_crba);
    }

    /// The CRBA with the Rx(α) Rz(θ) shortcut computes of each joint's
    /// transform only what it reads ([`Need`]): M is the same to the bit as
    /// with every transform computed in full, and a turn's (cos θ, sin θ)
    /// are the bits the full transform holds (signed zeros included), on
    /// every shipped and test robot that takes the shortcut.
    #[test]
    fn crba_reads_of_the_transforms_only_what_it_needs() {
        let mut robots = shipped_robots();
        robots.extend(test_robots());
        let (mut shortcut, mut turns) = (0, 0);
        for (name, r) in robots {
            let n = r.dof();
            let mut ws = Workspace::new(&r);
            if !ws.rxz_crba {
                continue;
            }
            shortcut += 1;
            let need = ws.need.clone();
            let (mut a, mut b) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
            for q in test_configurations(n, 100) {
                ws.need.clone_from(&need);
                mass_matrix_into(&r, &mut ws, &q, &mut a);
                for i in (0..n).filter(|&i| ws.need[i] == Need::Turn) {
                    let Placed::RxZ(alpha) = ws.placed[i] else {
                        panic!("{name}: turn {i} is not RxZ")
                    };
                    let (c, s) = ws.cs[i];
                    let (rc, rs) = Placed::cs(alpha, &joint_transform(&r, i, q[i]).0.column(0).into_owned());
                    assert_eq!((c.to_bits(), s.to_bits()), (rc.to_bits(), rs.to_bits()), "{name}: joint {i} at {}", q[i]);
                    turns += 1;
                }
                ws.need.iter_mut().for_each(|x| *x = Need::Full);
                mass_matrix_into(&r, &mut ws, &q, &mut b);
                let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
                assert_eq!(bits(&a), bits(&b), "{name}: at q = {q:?}: {a} vs {b}");
            }
        }
        assert!(shortcut >= 2 && turns >= 1000, "{shortcut} robots, {turns} turns");
    }

    /// ∂τ/∂q and ∂τ/∂q̇ by forward-mode dual numbers: 2n dual passes of the
    /// generic inverse dynamics (the computation the recursive derivatives
    /// replaced), the oracle of `id_derivatives_equal_the_dual_passes`.
    fn dual_id_derivatives(robot: &Robot, theta: &[f64], q: &[f64], qd: &[f64], qdd: &[f64]) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = robot.dof();
        let mut dq = DMatrix::zeros(n, n);
        let mut dqd = DMatrix::zeros(n, n);
        let mut inert: Vec<Inertial> = robot.links.iter().map(|l| l.inertial).collect();
        let mut dual = Kin::new(n);
        let mut tau = vec![Dual64::from(0.0); n];
        for which in 0..2 {
            for k in 0..n {
                let seed = |x: &[f64], on: bool| -> Vec<Dual64> { (0..n).map(|i| Dual64::new(x[i], if on && i == k { 1.0 } else { 0.0 })).collect() };
                let (qv, qdv, qddv) = (seed(q, which == 0), seed(qd, which == 1), seed(qdd, false));
                inverse_dynamics_generic(robot, &mut inert, theta, &qv, &qdv, &qddv, ALL, &mut dual, &mut tau);
                let m = if which == 0 { &mut dq } else { &mut dqd };
                for i in 0..n {
                    m[(i, k)] = tau[i].eps;
                }
            }
        }
        (dq, dqd)
    }

    /// The recursive RNEA derivatives equal the dual-number passes to 1e-11
    /// of the largest entry, for every shipped and test robot (coupling,
    /// prismatic joints, a branching tree, rotor inertias, sign / tanh /
    /// Stribeck friction), nominal and perturbed parameters, at random
    /// states and at rest.
    #[test]
    fn id_derivatives_equal_the_dual_passes() {
        let mut robots = shipped_robots();
        robots.extend(test_robots());
        for (name, r) in robots {
            let n = r.dof();
            let mut ws = Workspace::new(&r);
            let nominal = r.nominal_params();
            let perturbed = perturbed_params(&r);
            let qs = test_configurations(n, 40);
            for (s, q) in qs.iter().enumerate() {
                // |q̇| ≤ 0.3: the dual tanh of num-dual (sinh/cosh) overflows to NaN beyond |w/v_s| ≈ 355 (v_s = 1e-3 in rpr_drives_tanh)
                let qd: Vec<f64> = if s == 0 {
                    vec![0.0; n]
                } else {
                    (0..n).map(|i| 0.3 * (0.7 * (s * n + i) as f64).cos()).collect()
                };
                let qdd: Vec<f64> = (0..n).map(|i| 3.0 * (1.1 * (s * n + i) as f64 + 0.3).sin()).collect();
                for theta in [nominal.as_slice(), perturbed.as_slice()] {
                    let (dq, dqd) = id_derivatives(&r, &mut ws, theta, q, &qd, &qdd);
                    let (wq, wqd) = dual_id_derivatives(&r, theta, q, &qd, &qdd);
                    for (got, want, what) in [(&dq, &wq, "∂τ/∂q"), (&dqd, &wqd, "∂τ/∂q̇")] {
                        let scale = want.amax().max(1e-300);
                        assert!((got - want).amax() <= 1e-11 * scale, "{name}: {what} at state {s}:{got}{want}");
                    }
                }
            }
        }
    }

    /// The closed-form friction slopes equal central differences of the
    /// friction columns (and the dual-number slope where num-dual's tanh
    /// does not overflow), are finite at any velocity, for every drive
    /// model of the shipped and test robots.
    #[test]
    fn friction_slopes_equal_differences() {
        let mut robots = shipped_robots();
        robots.extend(test_robots());
        let mut smooth = 0;
        for (name, r) in robots {
            for d in &r.drives {
                for &w in &[-2000.0, -3.0, -0.7, -1e-3, -2e-4, 2.5e-4, 1e-3, 0.013, 0.4, 1.0, 5.0, 1e4] {
                    let mut got = [0.0; MAX_FRICTION_COLUMNS];
                    let m = friction_slopes(d, w, &mut got);
                    let mut cols = [Dual64::from(0.0); MAX_FRICTION_COLUMNS];
                    assert_eq!(friction_columns(d, Dual64::new(w, 1.0), &mut cols), m, "{name}");
                    let h = 1e-7 * w.abs();
                    let (mut a, mut b) = ([0.0; MAX_FRICTION_COLUMNS], [0.0; MAX_FRICTION_COLUMNS]);
                    friction_columns(d, w + h, &mut a);
                    friction_columns(d, w - h, &mut b);
                    for c in 0..m {
                        assert!(got[c].is_finite(), "{name}: slope at {w}");
                        let fd = (a[c] - b[c]) / (2.0 * h);
                        assert!((got[c] - fd).abs() <= 1e-6 * (1.0 + fd.abs()), "{name}: column {c} at {w}: {} vs {fd}", got[c]);
                        if cols[c].eps.is_finite() {
                            assert!((got[c] - cols[c].eps).abs() <= 1e-12 * (1.0 + got[c].abs()), "{name}: column {c} at {w}");
                        }
                    }
                    if !d.coulomb.is_sign() && m > 0 && w.abs() < 1e-3 {
                        smooth += 1;
                    }
                }
            }
        }
        assert!(smooth > 0, "no smooth Coulomb model checked near 0");
    }

    /// The CRBA equals the mass matrix from n RNEA passes (column k:
    /// τ_rb(q, 0, e_k) without gravity) to 1e-12 of its largest entry, for
    /// every shipped and test robot, nominal and perturbed parameters.
    #[test]
    fn crba_equals_rnea_columns() {
        let mut robots = shipped_robots();
        robots.extend(test_robots());
        for (name, r) in robots {
            let n = r.dof();
            let mut ws = Workspace::new(&r);
            let perturbed = perturbed_params(&r);
            let pert: Vec<Inertial> = (0..n)
                .map(|i| {
                    let o = r.link_param_offset(i);
                    Inertial::from_params(&perturbed[o..o + 10])
                })
                .collect();
            for s in 0..40 {
                let inert = if s % 2 == 0 { Inertials::Nominal } else { Inertials::Of(&pert) };
                let q: Vec<f64> = (0..n).map(|i| 2.5 * (1.3 * (s * n + i) as f64).sin()).collect();
                let mut m = DMatrix::zeros(n, n);
                crba_into(&r, &mut ws, inert, |_| None, &q, &mut m);
                let zero = vec![0.0; n];
                let mut col = vec![0.0; n];
                for k in 0..n {
                    let e: Vec<f64> = (0..n).map(|i| if i == k { 1.0 } else { 0.0 }).collect();
                    rnea_rigid(&r, inert, &q, &zero, &e, false, &mut ws.kin, &mut col);
                    for i in 0..n {
                        assert!((m[(i, k)] - col[i]).abs() <= 1e-12 * m.amax(), "{name}: M[{i},{k}] {} vs {}", m[(i, k)], col[i]);
                    }
                }
            }
        }
    }

    /// The allocation-free forward dynamics inverts inverse dynamics.
    #[test]
    fn forward_dynamics_into_inverts_rnea() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        for name in ["ur5", "industrial6", "panda"] {
            let r = crate::robot::load(&root.join(format!("designs/robots/{name}.toml"))).unwrap();
            let n = r.dof();
            let mut ws = Workspace::new(&r);
            let q: Vec<f64> = (0..n).map(|i| 0.3 * i as f64 - 0.7).collect();
            let qd: Vec<f64> = (0..n).map(|i| 0.2 - 0.1 * i as f64).collect();
            let qdd: Vec<f64> = (0..n).map(|i| 0.5 * (i as f64).sin()).collect();
            let mut tau = vec![0.0; n];
            rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            let mut got = vec![0.0; n];
            forward_dynamics_into(&r, &mut ws, &q, &qd, &tau, &mut got).unwrap();
            for i in 0..n {
                assert!((got[i] - qdd[i]).abs() < 1e-9 * (1.0 + qdd[i].abs()), "{name}: {got:?} vs {qdd:?}");
            }
            let old = forward_dynamics(&r, &mut ws, &q, &qd, &tau).unwrap();
            assert_eq!(old.as_slice(), &got[..]);
        }
    }
}
