//! Forward dynamics (CRBA and a Cholesky solve) and the Runge–Kutta step of
//! the simulator.

use super::crba::mass_matrix_into;
use super::friction::friction_torque;
use super::rnea::{couple, rnea_rigid, Inertials};
use super::Workspace;
use crate::robot::model::Robot;
use nalgebra::{DMatrix, DVector};

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
