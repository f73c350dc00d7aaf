//! The trajectory-shape seam (`trajectory::shape`): both shapes' Jacobians of
//! the samples against central finite differences, the B-spline's rest-to-rest
//! ends, derivatives, box and validation.

use idexp::trajectory::bspline::BSplineLayout;
use idexp::trajectory::{Ends, FourierLayout, JointBox, Motion, StateGradient, TrajectoryShape};

/// Deterministic values in (−1, 1).
fn values(n: usize, seed: f64) -> Vec<f64> {
    (0..n).map(|i| ((i as f64 + 1.0) * 12.9898 + seed * 78.233).sin()).collect()
}

fn state<M: Motion>(m: &M, t: f64) -> [Vec<f64>; 3] {
    let n = m.n_joints();
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    m.eval(t, &mut q, &mut qd, &mut qdd);
    [q, qd, qdd]
}

/// max |analytic − central difference| relative to max(1, |value|), over
/// orders, joints and variables.
fn jacobian_error<S: TrajectoryShape>(s: &S, x: &[f64], t: f64) -> f64 {
    let jac = s.sample_jacobian(x, t);
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for v in 0..s.n_vars() {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[v] += h;
        xm[v] -= h;
        let (sp, sm) = (state(&s.motion(&xp), t), state(&s.motion(&xm), t));
        for order in 0..3 {
            for j in 0..sp[order].len() {
                let fd = (sp[order][j] - sm[order][j]) / (2.0 * h);
                let an = jac[order][j][v];
                worst = worst.max((an - fd).abs() / an.abs().max(1.0));
            }
        }
    }
    worst
}

#[test]
fn fourier_jacobian_matches_finite_differences() {
    for (vary_q0, at_rest) in [(false, false), (true, false), (false, true), (true, true)] {
        let l = FourierLayout::new(vec![0.1, -0.4, 0.7], 4, std::f64::consts::TAU * 0.2, vary_q0, at_rest).unwrap();
        let x: Vec<f64> = values(TrajectoryShape::n_vars(&l), 1.0).iter().map(|v| 0.3 * v).collect();
        for t in [0.0, 0.37, 2.1, 4.9] {
            let e = jacobian_error(&l, &x, t);
            assert!(e < 1e-7, "vary_q0 {vary_q0}, at_rest {at_rest}, t {t}: {e:e}");
        }
        assert_eq!(l.motion(&x).ends(), Ends::Periodic);
    }
}

#[test]
fn bspline_jacobian_matches_finite_differences() {
    for (degree, segments) in [(3, 4), (4, 5), (5, 6), (5, 2)] {
        let l = BSplineLayout::new(vec![0.2, -1.0], degree, segments, 8.0).unwrap();
        let x: Vec<f64> = values(l.n_vars(), 2.0).iter().map(|v| 0.5 * v).collect();
        for t in [0.0, 0.3, 1.7, 4.0, 5.33, 7.99, 8.0] {
            let e = jacobian_error(&l, &x, t);
            assert!(e < 1e-7, "degree {degree}, {segments} segments, t {t}: {e:e}");
        }
    }
}

#[test]
fn bspline_pull_back_is_the_transposed_jacobian() {
    let l = BSplineLayout::new(vec![0.0, 0.5, -0.5], 5, 5, 6.0).unwrap();
    let x = values(l.n_vars(), 3.0);
    let m = l.motion(&x);
    let t = 2.2;
    let g = StateGradient {
        factor: -1.5,
        q: values(3, 4.0),
        qd: values(3, 5.0),
        qdd: values(3, 6.0),
    };
    let mut gx = vec![f64::NAN; l.n_vars()];
    l.pull_back(&m, t, &g, &mut Default::default(), &mut gx);
    let jac = l.sample_jacobian(&x, t);
    for (v, &got) in gx.iter().enumerate() {
        let want: f64 = (0..3)
            .map(|j| g.factor * (g.q[j] * jac[0][j][v] + g.qd[j] * jac[1][j][v] + g.qdd[j] * jac[2][j][v]))
            .sum();
        assert!((got - want).abs() < 1e-12, "variable {v}: {got} vs {want}");
    }
}

#[test]
fn bspline_starts_and_ends_at_rest_at_q0() {
    let q0 = vec![0.3, -1.2, 2.0];
    for degree in 3..=5 {
        let l = BSplineLayout::new(q0.clone(), degree, 6, 10.0).unwrap();
        let m = l.motion(&values(l.n_vars(), 7.0));
        assert_eq!(m.ends(), Ends::RestToRest);
        assert!((m.duration() - 10.0).abs() < 1e-12);
        for t in [0.0, 10.0, -1.0, 11.0] {
            let [q, qd, qdd] = state(&m, t);
            for j in 0..3 {
                assert!((q[j] - q0[j]).abs() < 1e-12, "degree {degree}, t {t}: q{j} = {}", q[j]);
                assert!(qd[j].abs() < 1e-12 && qdd[j].abs() < 1e-12, "degree {degree}, t {t}: not at rest");
            }
        }
        // it moves in between
        let [q, _, _] = state(&m, 5.0);
        assert!((q[0] - q0[0]).abs() > 1e-3);
    }
}

#[test]
fn bspline_derivatives_match_eval_and_finite_differences() {
    let l = BSplineLayout::new(vec![0.0, 1.0], 5, 7, 7.0).unwrap();
    let m = l.motion(&values(l.n_vars(), 8.0));
    let h = 1e-5;
    for t in [0.4, 1.5, 3.3, 6.2] {
        let s = state(&m, t);
        for j in 0..2 {
            for order in 0..3 {
                let d = m.derivatives(j, order, t);
                assert!((d[0] - s[order][j]).abs() < 1e-12, "order {order}");
                // the next two orders by central differences of the previous ones
                for k in 1..3 {
                    let fd = (m.derivatives(j, order, t + h)[k - 1] - m.derivatives(j, order, t - h)[k - 1]) / (2.0 * h);
                    assert!(
                        (d[k] - fd).abs() < 1e-5 * d[k].abs().max(1.0),
                        "t {t}, joint {j}, order {}: {} vs {fd}",
                        order + k,
                        d[k]
                    );
                }
            }
        }
    }
}

#[test]
fn bspline_box_keeps_the_position_limits() {
    let q0 = vec![0.0, -0.5];
    let position = [[-1.0, 1.0], [-2.0, 0.5]];
    let l = BSplineLayout::new(q0, 5, 8, 10.0).unwrap();
    let (lo, hi) = l.bounds(&JointBox {
        position: &position,
        velocity: &[1.0, 1.0],
        acceleration: &[1.0, 1.0],
    });
    // the box's corners, alternating: the motion stays within the limits
    let x: Vec<f64> = (0..l.n_vars()).map(|i| if i % 2 == 0 { lo[i] } else { hi[i] }).collect();
    let m = l.motion(&x);
    for k in 0..=1000 {
        let [q, _, _] = state(&m, 10.0 * k as f64 / 1000.0);
        for j in 0..2 {
            assert!(q[j] >= position[j][0] - 1e-12 && q[j] <= position[j][1] + 1e-12, "joint {j}: {}", q[j]);
        }
    }
}

#[test]
fn bspline_layout_errors_name_the_field() {
    let e = BSplineLayout::new(vec![0.0], 7, 6, 1.0).unwrap_err().to_string();
    assert!(e.contains("degree"), "{e}");
    let e = BSplineLayout::new(vec![0.0], 3, 3, 1.0).unwrap_err().to_string();
    assert!(e.contains("segments"), "{e}");
    let e = BSplineLayout::new(vec![0.0], 5, 6, -1.0).unwrap_err().to_string();
    assert!(e.contains("duration"), "{e}");
}

/// Every combination of free start and end poses (`[trajectory] start`, `end`).
fn free_layouts(q0: &[f64], degree: usize, segments: usize, duration: f64) -> Vec<(bool, bool, BSplineLayout)> {
    [(true, false), (false, true), (true, true)]
        .into_iter()
        .map(|(s, e)| (s, e, BSplineLayout::new(q0.to_vec(), degree, segments, duration).unwrap().with_free_ends(s, e)))
        .collect()
}

#[test]
fn bspline_free_ends_jacobian_matches_finite_differences() {
    for (degree, segments) in [(3, 4), (5, 6), (5, 2)] {
        for (s, e, l) in free_layouts(&[0.2, -1.0], degree, segments, 8.0) {
            let fixed = BSplineLayout::new(vec![0.2, -1.0], degree, segments, 8.0).unwrap();
            assert_eq!(l.n_vars(), fixed.n_vars() + 2 * (usize::from(s) + usize::from(e)));
            let x: Vec<f64> = values(l.n_vars(), 2.5).iter().map(|v| 0.5 * v).collect();
            for t in [0.0, 0.3, 1.7, 4.0, 7.99, 8.0] {
                let err = jacobian_error(&l, &x, t);
                assert!(err < 1e-7, "start {s}, end {e}, degree {degree}, {segments} segments, t {t}: {err:e}");
            }
        }
    }
}

#[test]
fn bspline_free_ends_start_and_end_at_rest_where_the_variables_say() {
    let q0 = vec![0.3, -1.2, 2.0];
    for degree in 3..=5 {
        for (s, e, l) in free_layouts(&q0, degree, 6, 10.0) {
            let vpj = l.vars_per_joint();
            let x = values(l.n_vars(), 8.0);
            let m = l.motion(&x);
            assert_eq!(m.ends(), Ends::RestToRest);
            // the block of joint j: [start?] interior… [end?]
            let start: Vec<f64> = (0..3).map(|j| q0[j] + if s { x[j * vpj] } else { 0.0 }).collect();
            let end: Vec<f64> = (0..3)
                .map(|j| match (s, e) {
                    (_, true) => q0[j] + x[j * vpj + vpj - 1],
                    (true, false) => start[j],
                    (false, false) => q0[j],
                })
                .collect();
            for (t, want) in [(0.0, &start), (-1.0, &start), (10.0, &end), (11.0, &end)] {
                let [q, qd, qdd] = state(&m, t);
                for j in 0..3 {
                    assert!(
                        (q[j] - want[j]).abs() < 1e-12,
                        "start {s}, end {e}, degree {degree}, t {t}: q{j} = {} not {}",
                        q[j],
                        want[j]
                    );
                    assert!(
                        qd[j].abs() < 1e-12 && qdd[j].abs() < 1e-12,
                        "start {s}, end {e}, degree {degree}, t {t}: not at rest"
                    );
                }
            }
            assert_eq!(m.rest_pose(), start);
            // the design vector read back from the motion
            let back = l.vars(&m);
            assert!(
                back.iter().zip(&x).all(|(a, b)| (a - b).abs() < 1e-12),
                "start {s}, end {e}: vars(motion(x)) != x"
            );
        }
    }
}

#[test]
fn bspline_free_ends_grid_gradient_is_the_pull_back() {
    for (s, e, l) in free_layouts(&[0.0, 0.5, -0.5], 5, 5, 6.0) {
        assert_grid_gradient_is_the_pull_back(&format!("start {s}, end {e}"), &l, &[0.0, 1.1, 2.2, 5.9, 6.0]);
    }
}

/// The grid's accumulated gradient of a 3-joint layout equals the
/// pull-back at each of `times`, and the grid's state the motion's.
fn assert_grid_gradient_is_the_pull_back(what: &str, l: &BSplineLayout, times: &[f64]) {
    let x = values(l.n_vars(), 3.5);
    let m = l.motion(&x);
    let grid = l.grid(times.to_vec());
    let n = 3;
    for (i, &t) in times.iter().enumerate() {
        let g: Vec<f64> = values(3 * n, 4.0 + i as f64);
        let mut acc = vec![0.0; l.acc_len()];
        l.grid_accumulate(&grid, &m, i, &g, &mut Default::default(), &mut acc);
        let mut got = vec![0.0; l.n_vars()];
        l.grid_finish(&acc, &mut got);
        let sg = StateGradient {
            factor: 1.0,
            q: g[..n].to_vec(),
            qd: g[n..2 * n].to_vec(),
            qdd: g[2 * n..].to_vec(),
        };
        let mut want = vec![0.0; l.n_vars()];
        l.pull_back(&m, t, &sg, &mut Default::default(), &mut want);
        for v in 0..l.n_vars() {
            assert!((got[v] - want[v]).abs() < 1e-12, "{what}, t {t}, variable {v}: {} vs {}", got[v], want[v]);
        }
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        l.grid_state(&grid, &m, i, &mut q, &mut qd, &mut qdd);
        let [q2, qd2, qdd2] = state(&m, t);
        for j in 0..n {
            assert!(
                (q[j] - q2[j]).abs() < 1e-12 && (qd[j] - qd2[j]).abs() < 1e-10 && (qdd[j] - qdd2[j]).abs() < 1e-9,
                "{what}, t {t}"
            );
        }
    }
}

#[test]
fn bspline_free_ends_box_keeps_the_start_and_end_within_the_limits() {
    let q0 = vec![0.0, 1.0];
    let position = [[-2.0, 2.0], [0.5, 3.0]];
    let limits = JointBox {
        position: &position,
        velocity: &[1.0, 1.0],
        acceleration: &[1.0, 1.0],
    };
    for (s, e, l) in free_layouts(&q0, 5, 8, 10.0) {
        let (lo, hi) = l.bounds(&limits);
        // the box's corners, alternating, and its two extreme corners
        let alt: Vec<f64> = (0..l.n_vars()).map(|i| if i % 2 == 0 { lo[i] } else { hi[i] }).collect();
        for x in [lo.clone(), hi.clone(), alt] {
            let m = l.motion(&x);
            for k in 0..=1000 {
                let [q, _, _] = state(&m, 10.0 * k as f64 / 1000.0);
                for j in 0..2 {
                    assert!(
                        q[j] >= position[j][0] - 1e-12 && q[j] <= position[j][1] + 1e-12,
                        "start {s}, end {e}: q{j} = {}",
                        q[j]
                    );
                }
            }
        }
        // the free ends reach the limits (the box is not narrower than they are)
        let m = l.motion(&lo);
        let [q, _, _] = state(&m, if s { 0.0 } else { 10.0 });
        assert!((q[0] - position[0][0]).abs() < 1e-12, "start {s}, end {e}: {}", q[0]);
    }
}

/// B-splines through waypoints at rest (`[trajectory] waypoints`) with free,
/// given or home ends: (description, layout).
fn waypoint_layouts(q0: &[f64], duration: f64) -> Vec<(String, BSplineLayout)> {
    let n = q0.len();
    let given_start: Vec<f64> = (0..n).map(|j| q0[j] + 0.3 - 0.1 * j as f64).collect();
    let given_end: Vec<f64> = (0..n).map(|j| q0[j] - 0.2 + 0.15 * j as f64).collect();
    let mut out = Vec::new();
    // (degree, segments, waypoints): one segment per piece (the waypoints
    // are the only variables), two and three per piece
    for (degree, segments, waypoints) in [(5, 6, 7), (3, 9, 4), (4, 6, 4), (5, 10, 6), (3, 6, 3)] {
        for (ends, fs, fe, gs, ge) in [
            ("home", false, false, None, None),
            ("free", true, true, None, None),
            ("given", false, false, Some(given_start.clone()), Some(given_end.clone())),
            ("given start, free end", false, true, Some(given_start.clone()), None),
            ("free start, given end", true, false, None, Some(given_end.clone())),
        ] {
            let l = BSplineLayout::new(q0.to_vec(), degree, segments, duration)
                .unwrap()
                .with_free_ends(fs, fe)
                .with_given_ends(gs, ge)
                .unwrap()
                .with_waypoints(waypoints)
                .unwrap();
            out.push((format!("degree {degree}, {segments} segments, {waypoints} waypoints, {ends} ends"), l));
        }
    }
    out
}

#[test]
fn bspline_waypoints_jacobian_matches_finite_differences() {
    for (what, l) in waypoint_layouts(&[0.2, -1.0], 6.0) {
        let x: Vec<f64> = values(l.n_vars(), 2.5).iter().map(|v| 0.5 * v).collect();
        // the waypoint times among them (each piece 6/(w − 1) s)
        for t in [0.0, 0.3, 1.0, 1.7, 2.0, 3.0, 4.0, 5.33, 5.99, 6.0] {
            let err = jacobian_error(&l, &x, t);
            assert!(err < 1e-7, "{what}, t {t}: {err:e}");
        }
    }
}

/// Each waypoint is at rest where its variable (or the given pose) says:
/// positions from `eval`, rest by central differences of the positions alone
/// (h = 1 ms, as a 1 kHz controller sees it), and the motion moves between
/// the waypoints.
#[test]
fn bspline_waypoints_rest_at_every_waypoint_by_finite_differences() {
    let q0 = vec![0.3, -1.2, 2.0];
    let duration = 6.0;
    for (what, l) in waypoint_layouts(&q0, duration) {
        let n = 3;
        let vpj = l.vars_per_joint();
        let x = values(l.n_vars(), 8.0);
        let m = l.motion(&x);
        assert_eq!(m.ends(), Ends::RestToRest);
        let pieces = l.pieces;
        let inner = l.segments / pieces + l.degree - 6;
        let lead = usize::from(l.free_start);
        // the documented block: [start?] (inner…, waypoint) per piece … [end?]
        let pose_at = |k: usize, j: usize| -> f64 {
            if k == 0 {
                return match (&l.start_pose, l.free_start) {
                    (Some(p), _) => p[j],
                    (None, true) => q0[j] + x[j * vpj],
                    (None, false) => q0[j],
                };
            }
            if k == pieces {
                return match (&l.end_pose, l.free_end) {
                    (Some(p), _) => p[j],
                    (None, true) => q0[j] + x[j * vpj + vpj - 1],
                    (None, false) => pose_at_start(&l, &x, &q0, j),
                };
            }
            q0[j] + x[j * vpj + lead + k * (inner + 1) - 1]
        };
        let pos = |t: f64| state(&m, t)[0].clone();
        let h = 1e-3;
        for k in 0..=pieces {
            let t = duration * k as f64 / pieces as f64;
            let (qm, q, qp) = (pos(t - h), pos(t), pos(t + h));
            for j in 0..n {
                assert!(
                    (q[j] - pose_at(k, j)).abs() < 1e-12,
                    "{what}: waypoint {k}, joint {j}: q {} not {}",
                    q[j],
                    pose_at(k, j)
                );
                let v = (qp[j] - qm[j]) / (2.0 * h);
                let a = (qp[j] - 2.0 * q[j] + qm[j]) / (h * h);
                assert!(
                    v.abs() < 1e-4 && a.abs() < 2e-2,
                    "{what}: waypoint {k} (t {t}), joint {j}: velocity {v:e}, acceleration {a:e} by differences"
                );
            }
        }
        // between the waypoints it moves (the rest is not the whole motion)
        let mut fastest: f64 = 0.0;
        for i in 0..600 {
            let t = duration * (i as f64 + 0.5) / 600.0;
            let (qm, qp) = (pos(t - h), pos(t + h));
            fastest = fastest.max((0..n).map(|j| ((qp[j] - qm[j]) / (2.0 * h)).abs()).fold(0.0, f64::max));
        }
        assert!(fastest > 0.05, "{what}: {fastest}");
        let back = l.vars(&m);
        assert!(back.iter().zip(&x).all(|(a, b)| (a - b).abs() < 1e-12), "{what}: vars(motion(x)) != x");
    }
}

/// The start pose as the layout places it (q0, given or free).
fn pose_at_start(l: &BSplineLayout, x: &[f64], q0: &[f64], j: usize) -> f64 {
    match (&l.start_pose, l.free_start) {
        (Some(p), _) => p[j],
        (None, true) => q0[j] + x[j * l.vars_per_joint()],
        (None, false) => q0[j],
    }
}

#[test]
fn bspline_waypoints_grid_gradient_is_the_pull_back() {
    for (what, l) in waypoint_layouts(&[0.0, 0.5, -0.5], 6.0) {
        assert_grid_gradient_is_the_pull_back(&what, &l, &[0.0, 1.0, 1.1, 2.0, 2.2, 5.9, 6.0]);
    }
}

#[test]
fn bspline_waypoints_box_keeps_the_motion_within_the_limits() {
    let q0 = vec![0.0, 1.0];
    let position = [[-2.0, 2.0], [0.5, 3.0]];
    let limits = JointBox {
        position: &position,
        velocity: &[1.0, 1.0],
        acceleration: &[1.0, 1.0],
    };
    for (what, l) in waypoint_layouts(&q0, 6.0) {
        let (lo, hi) = l.bounds(&limits);
        let alt: Vec<f64> = (0..l.n_vars()).map(|i| if i % 2 == 0 { lo[i] } else { hi[i] }).collect();
        for x in [lo.clone(), hi.clone(), alt] {
            let m = l.motion(&x);
            for k in 0..=1200 {
                let [q, _, _] = state(&m, 6.0 * k as f64 / 1200.0);
                for j in 0..2 {
                    assert!(q[j] >= position[j][0] - 1e-12 && q[j] <= position[j][1] + 1e-12, "{what}: q{j} = {}", q[j]);
                }
            }
        }
    }
}

#[test]
fn bspline_waypoints_are_validated() {
    let l = || BSplineLayout::new(vec![0.0, 0.0], 5, 6, 12.0).unwrap();
    let e = l().with_waypoints(1).unwrap_err().to_string();
    assert!(e.contains("waypoints") && e.contains("at least 2"), "{e}");
    // 6 segments over 4 pieces
    let e = l().with_waypoints(5).unwrap_err().to_string();
    assert!(e.contains("segments") && e.contains("multiple of the 4 pieces"), "{e}");
    // degree 3 needs 3 segments per piece (6 control points)
    let e = BSplineLayout::new(vec![0.0], 3, 12, 12.0).unwrap().with_waypoints(7).unwrap_err().to_string();
    assert!(e.contains("at least 3 segments per piece"), "{e}");
    let e = l().with_given_ends(Some(vec![0.0]), None).unwrap_err().to_string();
    assert!(e.contains("start") && e.contains("2 joint values"), "{e}");
    // FIGAROH's form: the 5 interior waypoints per joint are the variables
    assert_eq!(l().with_waypoints(7).unwrap().n_vars(), 2 * 5);
    assert_eq!(l().with_free_ends(true, true).with_waypoints(7).unwrap().n_vars(), 2 * 7);
}

#[test]
fn grid_series_equals_grid_derivative_at_every_grid_time_bit_for_bit() {
    // the joint-limit scan takes a joint's whole series at once
    // (`grid_series`, the Fourier one with its factors out of the loop); its
    // values must be the point-by-point ones exactly, for every order
    // including those past the acceleration (quarter-turn signs 0..3)
    let l = FourierLayout::new(vec![0.1, -0.4, 0.7], 5, std::f64::consts::TAU * 0.1, true, false).unwrap();
    let x: Vec<f64> = values(TrajectoryShape::n_vars(&l), 2.0).iter().map(|v| 0.3 * v).collect();
    let b = BSplineLayout::new(vec![0.1, -0.4, 0.7], 5, 11, 10.0).unwrap();
    let xb: Vec<f64> = values(TrajectoryShape::n_vars(&b), 3.0).iter().map(|v| 0.3 * v).collect();
    fn check<S: TrajectoryShape>(what: &str, s: &S, x: &[f64]) {
        let grid = s.grid(s.scan_times());
        let m = s.motion(x);
        let mut out = Vec::new();
        for j in 0..3 {
            for order in 0..5 {
                s.grid_series(&grid, &m, j, order, &mut out);
                assert_eq!(out.len(), s.scan_times().len(), "{what}");
                for (i, v) in out.iter().enumerate() {
                    let one = s.grid_derivative(&grid, &m, j, order, i);
                    assert_eq!(
                        v.to_bits(),
                        one.to_bits(),
                        "{what}: joint {j}, order {order}, time {i}: {v} in the series, {one} alone"
                    );
                }
            }
        }
    }
    check("fourier", &l, &x);
    check("bspline", &b, &xb);
}
