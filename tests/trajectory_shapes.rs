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
