//! The process motions' building blocks (paper 000 §III-B, paper 002
//! §3.2): exact piecewise-constant-acceleration profiles, minimum-jerk moves
//! through via points with dwell, the home pose and end-effector frame of a
//! design, and position inverse kinematics by damped least squares.

use super::reference::{check_len, mid_range};
use super::Reference;
use crate::error::{Error, Result};
use crate::robot::{frame_jacobian, frame_pose, Robot, Workspace};
use nalgebra::{DMatrix, DVector, Vector3};

/// One joint integrated exactly through piecewise-constant accelerations
/// (the others constant), sampled every dt.
pub(super) fn piecewise_acceleration(start: &[f64], j: usize, pieces: &[(f64, f64)], dt: f64) -> Reference {
    let total: f64 = pieces.iter().map(|p| p.0).sum();
    let m = (total / dt).round() as usize + 1;
    let (mut oq, mut oqd, mut oqdd) = (Vec::with_capacity(m), Vec::with_capacity(m), Vec::with_capacity(m));
    let n = start.len();
    for i in 0..m {
        let t = i as f64 * dt;
        // state at t
        let (mut p, mut v, mut a, mut t0) = (start[j], 0.0, 0.0, 0.0);
        for &(d, acc) in pieces {
            if t <= t0 + d {
                let s = t - t0;
                p += v * s + 0.5 * acc * s * s;
                v += acc * s;
                a = acc;
                t0 = f64::NAN;
                break;
            }
            p += v * d + 0.5 * acc * d * d;
            v += acc * d;
            t0 += d;
        }
        if !t0.is_nan() {
            a = 0.0;
        }
        let mut q = start.to_vec();
        q[j] = p;
        let mut qd = vec![0.0; n];
        qd[j] = v;
        let mut qdd = vec![0.0; n];
        qdd[j] = a;
        oq.push(q);
        oqd.push(qd);
        oqdd.push(qdd);
    }
    Reference::Sampled {
        dt,
        q: oq,
        qd: oqd,
        qdd: oqdd,
        periodic: false,
    }
}

pub(super) fn joint_index(joint: usize, n: usize, ctx: &str) -> Result<usize> {
    if joint == 0 || joint > n {
        return Err(Error::invalid(ctx, "reference.joint", format!("expected a joint number 1..{n}, got {joint}")));
    }
    Ok(joint - 1)
}

pub(super) fn home(robot: &Robot, q_home: &Option<Vec<f64>>, ctx: &str) -> Result<Vec<f64>> {
    match q_home {
        Some(q) => {
            check_len(ctx, "reference.q_home", q, robot.dof())?;
            Ok(q.clone())
        }
        None => Ok(mid_range(robot)),
    }
}

pub(super) fn ee_frame(robot: &Robot, frame: &Option<String>, ctx: &str) -> Result<crate::robot::Frame> {
    match frame {
        None => Ok(robot.end_effector()),
        Some(f) => robot
            .find_frame(f)
            .ok_or_else(|| Error::invalid(ctx, "reference.frame", format!("no link or frame named {f:?}"))),
    }
}

/// min-jerk profile s(u) = 10u³ − 15u⁴ + 6u⁵ on [0, 1].
pub(super) fn min_jerk(u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
}

/// Joint-space minimum-jerk moves through `pts` (each `move_time` long) with a
/// dwell at every point, sampled every dt (starts with a dwell at the first point).
pub(super) fn via_points(pts: &[Vec<f64>], move_time: f64, dwell: f64, dt: f64) -> Vec<Vec<f64>> {
    let mut q = Vec::new();
    let nd = (dwell / dt).round() as usize;
    let nm = (move_time / dt).round().max(1.0) as usize;
    for _ in 0..nd.max(1) {
        q.push(pts[0].clone());
    }
    for w in pts.windows(2) {
        for i in 1..=nm {
            let s = min_jerk(i as f64 / nm as f64);
            q.push(w[0].iter().zip(&w[1]).map(|(a, b)| a + (b - a) * s).collect());
        }
        for _ in 0..nd {
            q.push(w[1].clone());
        }
    }
    q
}

/// Position inverse kinematics by damped least squares from `seed`, clamped to
/// the joint limits. Error message if the target is not reached to 0.1 mm.
pub fn ik_position(
    robot: &Robot,
    ws: &mut Workspace,
    frame: &crate::robot::Frame,
    target: &Vector3<f64>,
    seed: &[f64],
) -> std::result::Result<Vec<f64>, String> {
    let n = robot.dof();
    let mut q = seed.to_vec();
    let lambda2 = 1e-4;
    for _ in 0..200 {
        let p = frame_pose(robot, ws, &q, frame).translation.vector;
        let e = target - p;
        if e.norm() < 1e-7 {
            return Ok(q);
        }
        let jac = frame_jacobian(robot, ws, &q, frame);
        let jl = DMatrix::from_fn(3, n, |i, k| jac[(i, k)]);
        let a = &jl * jl.transpose() + DMatrix::identity(3, 3) * lambda2;
        let Some(ch) = a.cholesky() else { break };
        let dq = jl.transpose() * ch.solve(&DVector::from_column_slice(e.as_slice()));
        let step = dq.amax().max(1e-300);
        let scale = if step > 0.2 { 0.2 / step } else { 1.0 };
        for k in 0..n {
            let l = &robot.joints[k].limits;
            q[k] = (q[k] + scale * dq[k]).clamp(l.lower, l.upper);
        }
    }
    let p = frame_pose(robot, ws, &q, frame).translation.vector;
    let err = (target - p).norm();
    if err < 1e-4 {
        Ok(q)
    } else {
        Err(format!(
            "target ({:.3}, {:.3}, {:.3}) m is out of reach of frame {:?} within the joint limits (closest {:.1} mm away)",
            target.x,
            target.y,
            target.z,
            frame.name,
            err * 1e3
        ))
    }
}
