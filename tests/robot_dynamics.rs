//! Physics checks of the rigid-body kernels on every shipped robot and the
//! test robots: regressor × parameters = RNEA, mass matrix symmetric positive
//! definite and consistent with RNEA, power balance along a trajectory,
//! derivatives = central finite differences, forward ∘ inverse dynamics = id.

mod common;
use common::*;
use idexp::robot::{self, Robot, Workspace};
use nalgebra::{DMatrix, DVector};
use rand::RngExt;

fn rel(a: f64, b: f64, scale: f64) -> f64 {
    (a - b).abs() / scale.max(1.0)
}

#[test]
fn regressor_times_parameters_equals_rnea() {
    for r in all_robots() {
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let theta = r.nominal_params();
        let mut y = DMatrix::zeros(n, p);
        let mut tau = vec![0.0; n];
        let mut tau2 = vec![0.0; n];
        let mut g = rng(7);
        for _ in 0..1000 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            robot::regressor(&r, &mut ws, &q, &qd, &qdd, &mut y);
            robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            robot::inverse_dynamics(&r, &mut ws, theta.as_slice(), &q, &qd, &qdd, &mut tau2);
            let yt = &y * &theta;
            let scale = tau.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for j in 0..n {
                assert!(rel(yt[j], tau[j], scale) < 1e-9, "{}: joint {j}: Yθ = {} vs RNEA {}", r.name, yt[j], tau[j]);
                assert!(rel(tau2[j], tau[j], scale) < 1e-9, "{}: inverse_dynamics(θ) ≠ rnea", r.name);
            }
        }
    }
}

/// Regressor × an arbitrary (non-physical) parameter vector = inverse dynamics
/// with that vector: the linearity the excitation gradients rely on.
#[test]
fn regressor_is_linear_in_any_parameter_vector() {
    use rand::RngExt;
    for r in all_robots() {
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let mut g = rng(11);
        let mut y = DMatrix::zeros(n, p);
        let mut tau = vec![0.0; n];
        for _ in 0..50 {
            let theta = DVector::from_fn(p, |_, _| g.random_range(-1.0..1.0));
            let (q, qd, qdd) = random_state(&r, &mut g);
            robot::regressor(&r, &mut ws, &q, &qd, &qdd, &mut y);
            robot::inverse_dynamics(&r, &mut ws, theta.as_slice(), &q, &qd, &qdd, &mut tau);
            let yt = &y * &theta;
            for j in 0..n {
                assert!(rel(yt[j], tau[j], yt.amax()) < 1e-9, "{}", r.name);
            }
        }
    }
}

#[test]
fn mass_matrix_is_spd_and_consistent_with_rnea() {
    for r in all_robots() {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let mut g = rng(3);
        let c = r.coupling_matrix();
        for _ in 0..200 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            let m = robot::mass_matrix(&r, &mut ws, &q);
            assert!((&m - m.transpose()).amax() <= 1e-12 * m.amax(), "{}: M not symmetric", r.name);
            let eig = m.clone().symmetric_eigen().eigenvalues;
            assert!(eig.min() > 0.0, "{}: M not positive definite, eigenvalues {eig}", r.name);
            // Cᵀ τ_motor = M q̈ + c + g + Cᵀ f(C q̇)
            let mut tau = vec![0.0; n];
            robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            let lhs = c.transpose() * DVector::from_vec(tau);
            let w = &c * DVector::from_column_slice(&qd);
            let fr = DVector::from_fn(n, |j, _| robot::friction_torque(&r.drives[j], w[j]));
            let rhs = &m * DVector::from_column_slice(&qdd) + robot::bias_forces(&r, &mut ws, &q, &qd) + c.transpose() * fr;
            assert!((&lhs - &rhs).amax() < 1e-9 * lhs.amax().max(1.0), "{}: {lhs} vs {rhs}", r.name);
            // forward dynamics inverts inverse dynamics
            let mut tau = vec![0.0; n];
            robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            let acc = robot::forward_dynamics(&r, &mut ws, &q, &qd, &tau).unwrap();
            for j in 0..n {
                assert!((acc[j] - qdd[j]).abs() < 1e-8 * (1.0 + qdd[j].abs()), "{}: forward dynamics", r.name);
            }
        }
    }
}

/// Potential energy −Σ m_i g·c_i with world centres of mass.
fn potential(r: &Robot, ws: &mut Workspace, q: &[f64]) -> f64 {
    let poses = robot::link_poses(r, ws, q);
    let mut e = 0.0;
    for (i, l) in r.links.iter().enumerate() {
        let h_world = poses[i].rotation * l.inertial.first_moment;
        let mc = l.inertial.mass * poses[i].translation.vector + h_world;
        e -= r.gravity.dot(&mc);
    }
    e
}

/// d/dt (kinetic + potential energy) = θ̇ᵀ(τ − f(θ̇)) along an analytic trajectory.
#[test]
fn power_balance_holds_along_a_trajectory() {
    for r in all_robots() {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let c = r.coupling_matrix();
        let traj = |t: f64| {
            let mut q = vec![0.0; n];
            let mut qd = vec![0.0; n];
            let mut qdd = vec![0.0; n];
            for j in 0..n {
                let l = &r.joints[j].limits;
                let mid = if l.lower.is_finite() { 0.5 * (l.lower + l.upper) } else { 0.0 };
                let amp = if l.lower.is_finite() { 0.3 * (l.upper - l.lower) } else { 1.0 };
                let w = 1.0 + 0.37 * j as f64;
                q[j] = mid + amp * (w * t + j as f64).sin();
                qd[j] = amp * w * (w * t + j as f64).cos();
                qdd[j] = -amp * w * w * (w * t + j as f64).sin();
            }
            (q, qd, qdd)
        };
        let energy = |ws: &mut Workspace, t: f64| {
            let (q, qd, _) = traj(t);
            let m = robot::mass_matrix(&r, ws, &q);
            let v = DVector::from_vec(qd);
            0.5 * v.dot(&(&m * &v)) + potential(&r, ws, &q)
        };
        let h = 1e-5;
        for k in 0..40 {
            let t = 0.1 + 0.137 * k as f64;
            let de = (energy(&mut ws, t + h) - energy(&mut ws, t - h)) / (2.0 * h);
            let (q, qd, qdd) = traj(t);
            let mut tau = vec![0.0; n];
            robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            let w = &c * DVector::from_column_slice(&qd);
            let power: f64 = (0..n).map(|j| w[j] * (tau[j] - robot::friction_torque(&r.drives[j], w[j]))).sum();
            assert!(
                (de - power).abs() < 1e-5 * (1.0 + power.abs()),
                "{} at t={t}: dE/dt = {de}, power = {power}",
                r.name
            );
        }
    }
}

#[test]
fn inverse_dynamics_derivatives_match_finite_differences() {
    for r in all_robots() {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let theta = r.nominal_params();
        let mut g = rng(5);
        for _ in 0..20 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            let (dq, dqd) = robot::id_derivatives(&r, &mut ws, theta.as_slice(), &q, &qd, &qdd);
            let h = 1e-6;
            for k in 0..n {
                for (which, an) in [(0, &dq), (1, &dqd)] {
                    let mut a = [q.clone(), qd.clone()];
                    let mut b = [q.clone(), qd.clone()];
                    a[which][k] += h;
                    b[which][k] -= h;
                    let (mut ta, mut tb) = (vec![0.0; n], vec![0.0; n]);
                    robot::rnea(&r, &mut ws, &a[0], &a[1], &qdd, &mut ta);
                    robot::rnea(&r, &mut ws, &b[0], &b[1], &qdd, &mut tb);
                    for i in 0..n {
                        let fd = (ta[i] - tb[i]) / (2.0 * h);
                        assert!(
                            (fd - an[(i, k)]).abs() < 1e-5 * (1.0 + fd.abs()),
                            "{}: ∂τ{i}/∂x{k} ({which}) analytic {} fd {fd}",
                            r.name,
                            an[(i, k)]
                        );
                    }
                }
            }
            // ∂τ/∂q̈ = C⁻ᵀ M_total
            let mi = robot::motor_inertia(&r, &mut ws, theta.as_slice(), &q);
            for k in 0..n {
                let mut a = qdd.clone();
                a[k] += 1.0;
                let (mut ta, mut tb) = (vec![0.0; n], vec![0.0; n]);
                robot::rnea(&r, &mut ws, &q, &qd, &a, &mut ta);
                robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tb);
                for i in 0..n {
                    assert!(((ta[i] - tb[i]) - mi[(i, k)]).abs() < 1e-9 * (1.0 + mi.amax()), "{}: motor inertia", r.name);
                }
            }
        }
    }
}

#[test]
fn regressor_derivatives_match_finite_differences() {
    for r in all_robots() {
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let mut g = rng(9);
        let mut y = vec![0.0; n * p];
        let mut dq = vec![vec![0.0; n * p]; n];
        let mut dqd = vec![vec![0.0; n * p]; n];
        let mut dqdd = vec![vec![0.0; n * p]; n];
        for _ in 0..5 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            robot::regressor_derivatives(&r, &mut ws, &q, &qd, &qdd, &mut y, &mut dq, &mut dqd, &mut dqdd);
            let h = 1e-6;
            for k in 0..n {
                for (which, an) in [(0usize, &dq[k]), (1, &dqd[k]), (2, &dqdd[k])] {
                    let mut a = [q.clone(), qd.clone(), qdd.clone()];
                    let mut b = a.clone();
                    a[which][k] += h;
                    b[which][k] -= h;
                    let (mut ya, mut yb) = (vec![0.0; n * p], vec![0.0; n * p]);
                    robot::regressor_rows(&r, &mut ws, &a[0], &a[1], &a[2], &mut ya);
                    robot::regressor_rows(&r, &mut ws, &b[0], &b[1], &b[2], &mut yb);
                    for e in 0..n * p {
                        let fd = (ya[e] - yb[e]) / (2.0 * h);
                        assert!(
                            (fd - an[e]).abs() < 1e-5 * (1.0 + fd.abs()),
                            "{}: ∂Y[{e}]/∂x{k} ({which}): {} vs fd {fd}",
                            r.name,
                            an[e]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn frame_jacobian_matches_finite_differences() {
    for r in all_robots() {
        let n = r.dof();
        let mut ws = Workspace::new(&r);
        let ee = r.end_effector();
        let mut g = rng(13);
        for _ in 0..10 {
            let (q, _, _) = random_state(&r, &mut g);
            let j = robot::frame_jacobian(&r, &mut ws, &q, &ee);
            for k in 0..n {
                let h = 1e-6;
                let mut a = q.clone();
                let mut b = q.clone();
                a[k] += h;
                b[k] -= h;
                let pa = robot::frame_pose(&r, &mut ws, &a, &ee);
                let pb = robot::frame_pose(&r, &mut ws, &b, &ee);
                let dp = (pa.translation.vector - pb.translation.vector) / (2.0 * h);
                // angular: (R_a R_bᵀ) ≈ I + S(ω)·2h
                let dr = (pa.rotation * pb.rotation.inverse()).scaled_axis() / (2.0 * h);
                for i in 0..3 {
                    assert!((dp[i] - j[(i, k)]).abs() < 1e-6, "{}: linear Jacobian", r.name);
                    assert!((dr[i] - j[(3 + i, k)]).abs() < 1e-6, "{}: angular Jacobian", r.name);
                }
            }
        }
    }
}

#[test]
fn row_wise_derivatives_equal_the_regressor_derivatives_contracted_row_by_row() {
    // ∂τ_r(θ_r)/∂x = Σ_c ∂Y_rc/∂x θ_r,c for arbitrary (non-physical) θ_r:
    // the row kernel (RNEA derivatives) against the forward tangents of the
    // regressor, two independent computations, on every robot (a coupled
    // one, a tree, smooth friction among them)
    for r in all_robots() {
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let mut g = rng(11);
        for _ in 0..10 {
            let (q, qd, qdd) = random_state(&r, &mut g);
            let thetas: Vec<f64> = (0..n * p).map(|_| g.random_range(-2.0..2.0)).collect();
            let (mut rq, mut rqd, mut rqdd) = (vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]);
            robot::id_derivative_rows(&r, &mut ws, &thetas, &q, &qd, &qdd, &mut rq, &mut rqd, &mut rqdd);
            let mut y = vec![0.0; n * p];
            let mk = || vec![vec![0.0; n * p]; n];
            let (mut dq, mut dqd, mut dqdd) = (mk(), mk(), mk());
            robot::regressor_derivatives(&r, &mut ws, &q, &qd, &qdd, &mut y, &mut dq, &mut dqd, &mut dqdd);
            for row in 0..n {
                let th = &thetas[row * p..(row + 1) * p];
                for k in 0..n {
                    for (name, dy, got) in [("q", &dq, &rq), ("qd", &dqd, &rqd), ("qdd", &dqdd, &rqdd)] {
                        let want: f64 = (0..p).map(|c| dy[k][row * p + c] * th[c]).sum();
                        let scale: f64 = (0..p).map(|c| (dy[k][row * p + c] * th[c]).abs()).sum();
                        let v = got[row * n + k];
                        assert!(
                            (v - want).abs() <= 1e-11 * (1.0 + scale),
                            "{}: row {row}, d/d{name}_{k}: rows kernel {v}, contracted regressor derivative {want}",
                            r.name
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn several_sets_of_rows_in_one_call_give_each_sets_own_rows_bit_for_bit() {
    // the excitation gradient passes every eigenvalue's rows in one call
    // (one motion pass); each set must be exactly what its own call gives
    for r in all_robots() {
        let (n, p) = (r.dof(), r.n_params());
        let mut ws = Workspace::new(&r);
        let mut g = rng(12);
        let (q, qd, qdd) = random_state(&r, &mut g);
        let sets = 3;
        let thetas: Vec<f64> = (0..sets * n * p).map(|_| g.random_range(-2.0..2.0)).collect();
        let out = || vec![0.0; sets * n * n];
        let (mut aq, mut aqd, mut aqdd) = (out(), out(), out());
        robot::id_derivative_rows(&r, &mut ws, &thetas, &q, &qd, &qdd, &mut aq, &mut aqd, &mut aqdd);
        for s in 0..sets {
            let (mut bq, mut bqd, mut bqdd) = (vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]);
            robot::id_derivative_rows(&r, &mut ws, &thetas[s * n * p..(s + 1) * n * p], &q, &qd, &qdd, &mut bq, &mut bqd, &mut bqdd);
            for (name, all, one) in [("q", &aq, &bq), ("qd", &aqd, &bqd), ("qdd", &aqdd, &bqdd)] {
                let part = &all[s * n * n..(s + 1) * n * n];
                assert!(
                    part.iter().zip(one.iter()).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{}: set {s}, d/d{name}: {part:?} in one call, {one:?} alone",
                    r.name
                );
            }
        }
    }
}
