//! B-splines with free start and end poses (`[trajectory] start = "free"`,
//! `end = "free"`) on FIGAROH's UR10 problem (designs/excite_ur10_figaroh_free.toml):
//! the objective's gradient (unscaled cond of FIGAROH's 36 base columns) and
//! the constraints' Jacobian (limits, torques, 1 cm self-collision) against
//! central finite differences, the design fields' validation, and the
//! delivered trajectory: from home at rest through a lead-in to the free
//! start, the motion, a lead-out from the free end back to home at rest.

use idexp::excitation::{self, Problem};
use idexp::optim::Control;
use idexp::trajectory::{Motion, TrajectoryShape};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// Deterministic values in (−scale, scale).
fn values(n: usize, scale: f64, seed: f64) -> Vec<f64> {
    (0..n).map(|i| scale * ((i as f64 + 1.0) * 12.9898 + seed * 78.233).sin()).collect()
}

fn problem() -> Problem {
    Problem::from_file(&root("designs/excite_ur10_figaroh_free.toml")).unwrap()
}

#[test]
fn free_ends_objective_gradient_matches_finite_differences() {
    let p = problem();
    let nv = p.shape.n_vars();
    // 12 interior control points + start + end per joint
    assert_eq!(nv, 6 * 12);
    let o = &p.objective;
    let mut w = o.workspace();
    for seed in [1.0, 2.0] {
        let x = values(nv, 0.4, seed);
        let mut g = vec![0.0; nv];
        let f = o.value_grad(&x, &mut w, &mut g);
        assert!(f.is_finite() && f > 1.0, "{f}");
        let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(gmax > 0.0);
        let h = 1e-6;
        for i in 0..nv {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[i] += h;
            xm[i] -= h;
            let fd = (o.value(&xp, &mut w) - o.value(&xm, &mut w)) / (2.0 * h);
            assert!(
                (fd - g[i]).abs() <= 1e-4 * gmax + 1e-6 * g[i].abs(),
                "seed {seed} var {i}: analytic {} vs fd {fd}",
                g[i]
            );
        }
    }
}

#[test]
fn free_ends_constraint_gradients_match_finite_differences() {
    let p = problem();
    let c = &p.constraints;
    let mut cw = c.workspace();
    let nv = p.shape.n_vars();
    let x = values(nv, 0.3, 3.0);
    let mut val = vec![0.0; c.len()];
    let mut jac = vec![0.0; c.len() * nv];
    c.eval(&x, &mut cw, &mut val, Some(&mut jac));
    let (mut vp, mut vm) = (vec![0.0; c.len()], vec![0.0; c.len()]);
    let h = 1e-7;
    let mut nonzero = 0;
    for v in 0..nv {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[v] += h;
        xm[v] -= h;
        c.eval(&xp, &mut cw, &mut vp, None);
        c.eval(&xm, &mut cw, &mut vm, None);
        for i in 0..c.len() {
            let fd = (vp[i] - vm[i]) / (2.0 * h);
            let an = jac[i * nv + v];
            nonzero += usize::from(an != 0.0);
            let rowmax = (0..nv).map(|k| jac[i * nv + k].abs()).fold(0.0, f64::max);
            assert!(
                (fd - an).abs() <= 1e-3 * rowmax.max(1e-6),
                "constraint `{}` var {v}: analytic {an} vs fd {fd}",
                c.info[i].name
            );
        }
    }
    // 1e-3 of the row: the torque and distance constraints are maxima over a grid refined by a parabola,
    // whose envelope gradient differs from the difference quotient by the parabola's curvature term
    assert!(nonzero > c.len(), "the Jacobian is not trivially zero");
}
