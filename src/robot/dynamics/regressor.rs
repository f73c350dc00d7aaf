//! The joint-torque regressor Y(q, q̇, q̈) (τ = Y θ) and its derivatives with
//! respect to q, q̇, q̈.

use super::friction::{friction_columns, MAX_FRICTION_COLUMNS};
use super::rnea::{check_state, couple, forward_pass_given_transforms};
use super::{Terms, Workspace, ALL};
use crate::robot::kinematics::{joint_transforms, lift3, Kin, Real};
use crate::robot::model::Robot;
use nalgebra::{DMatrix, Vector3};

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
pub(super) fn couple_rows_inv_t<T: Real>(robot: &Robot, y: &mut [T], col: &mut [T]) {
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
pub(super) fn sym_bilinear<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> [T; 6] {
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
pub(super) fn regressor_inner<T: Real>(robot: &Robot, q: &[T], qd: &[T], qdd: &[T], terms: Terms, transforms: bool, kin: &mut Kin<T>, y: &mut [T]) {
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
