//! Recursive Newton–Euler inverse dynamics (RNEA), motor side, and the
//! coupling products C·x and C⁻ᵀ·τ.

use super::friction::{friction_columns, friction_torque, MAX_FRICTION_COLUMNS};
use super::{Terms, Workspace, ALL};
use crate::robot::kinematics::{joint_transforms, lift3, Kin, Real};
use crate::robot::model::{Friction, Inertial, Robot};
use nalgebra::{DVector, Matrix3, Vector3};

/// Forward pass: link velocities and accelerations.
fn forward_pass<T: Real>(robot: &Robot, q: &[T], qd: &[T], qdd: &[T], gravity: bool, kin: &mut Kin<T>) {
    joint_transforms(robot, q, kin);
    forward_pass_given_transforms(robot, qd, qdd, gravity, kin);
}

/// [`forward_pass`] with `kin.rot`, `kin.pos` already set.
pub(super) fn forward_pass_given_transforms<T: Real>(robot: &Robot, qd: &[T], qdd: &[T], gravity: bool, kin: &mut Kin<T>) {
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
pub(super) enum Inertials<'a> {
    /// `robot.links[i].inertial`.
    Nominal,
    /// One per link, from θ.
    Of(&'a [Inertial]),
}

/// Rigid-body link-side torques for inertials `inert` (generic), into `out`.
#[allow(clippy::too_many_arguments)] // kernel: robot, inertials, state (q, q̇, q̈), flag, buffers, output
pub(super) fn rnea_rigid<T: Real>(robot: &Robot, inert: Inertials<'_>, q: &[T], qd: &[T], qdd: &[T], gravity: bool, kin: &mut Kin<T>, out: &mut [T]) {
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

/// Motor positions-like product C·x (identity when no coupling), into `out`.
pub(super) fn couple<T: Real>(robot: &Robot, x: &[T], out: &mut [T]) {
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

pub(super) fn check_state(robot: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) {
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
