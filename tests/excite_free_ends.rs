//! B-splines with free start and end poses (`[trajectory] start = "free"`,
//! `end = "free"`) on FIGAROH's UR10 problem (designs/excite_ur10_figaroh_free.toml):
//! the objective's gradient (unscaled cond of FIGAROH's 36 base columns) and
//! the constraints' Jacobian (limits, torques, 1 cm self-collision) against
//! central finite differences, the design fields' validation, and the
//! delivered trajectory: from home at rest through a lead-in to the free
//! start, the motion, a lead-out from the free end back to home at rest.

use idexp::excitation::design::ExciteDesign;
use idexp::excitation::{self, Problem};
use idexp::optim::Control;
use idexp::trajectory::{Motion, TrajectoryShape};
use std::path::{Path, PathBuf};

mod excite_fd;
use excite_fd::values;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
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
    for seed in [1.0, 2.0] {
        let f = excite_fd::check_objective_gradient(&p.objective, &values(nv, 0.4, seed), &format!("seed {seed}"));
        assert!(f > 1.0, "{f}");
    }
}

#[test]
fn free_ends_constraint_gradients_match_finite_differences() {
    let p = problem();
    let x = values(p.shape.n_vars(), 0.3, 3.0);
    // the distances between convex hulls: the witness points' gradient
    // holds while the closest features stay the same, which a step of
    // 1e-7 over a 50 Hz grid refined by a parabola does not always keep;
    // 1e-3 of the row elsewhere: the torque constraints are maxima over a grid refined by a parabola,
    // whose envelope gradient differs from the difference quotient by the parabola's curvature term
    excite_fd::check_constraint_jacobian(&p.constraints, &x, |name| if name.starts_with("distance") { 0.1 } else { 1e-3 });
}

#[test]
fn free_ends_fields_are_validated_with_the_field_named() {
    let dir = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(root("designs/excite_ur10_figaroh_free.toml")).unwrap();
    let base = base.replace(
        "robot = \"robots/ur10.toml\"",
        &format!("robot = \"{}\"", root("designs/robots/ur10.toml").display()),
    );
    let check = |text: String, field: &str, words: &str| {
        let f = dir.path().join("d.toml");
        std::fs::write(&f, text).unwrap();
        let e = ExciteDesign::load(&f).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains(words), "{e}");
    };
    // a free end cannot be repeated back to back
    check(base.replace("periods = 1", "periods = 3"), "execution.periods", "periods = 1");
    check(
        base.replace("start = \"free\"", "start = \"anywhere\""),
        "`anywhere`",
        "expected `q0` or `free`",
    );
    // the Fourier series has no start pose (its centre: vary_q0)
    let fourier = base
        .replace("shape = \"bspline\"", "shape = \"fourier\"")
        .replace("degree = 5\n", "")
        .replace("segments = 11\n", "")
        .replace("duration = 12.0\n", "");
    check(fourier, "trajectory.start", "bspline");
    check(base.replace("algorithm = \"slsqp\"", "algorithm = \"mma\""), "refine.polish", "slsqp");
}

#[test]
fn free_ends_are_delivered_from_home_through_leads_and_back() {
    // a short search: the delivered trajectory, not the optimum, is under test
    let mut p = problem();
    p.design.time_limit = None;
    p.design.ga.population = 12;
    p.design.ga.generations = 3;
    p.design.refine.algorithm = idexp::excitation::design::RefineAlgorithm::None;
    p.design.refine.polish = 0;
    let r = excitation::run(&p, &Control::new()).unwrap();
    let d = r.execution.delivered.as_ref().expect("a delivered trajectory");
    let home = [0.0, -std::f64::consts::FRAC_PI_2, 0.0, -std::f64::consts::FRAC_PI_2, 0.0, 0.0];
    assert_eq!(d.home, home.to_vec());
    let n = 6;
    let at = |t: f64| {
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let seg = d.eval(t, &mut q, &mut qd, &mut qdd);
        (seg, q, qd, qdd)
    };
    // home at rest at both ends of what is played
    for t in [0.0, d.duration()] {
        let (_, q, qd, qdd) = at(t);
        for j in 0..n {
            assert!(
                (q[j] - home[j]).abs() < 1e-12 && qd[j].abs() < 1e-12 && qdd[j].abs() < 1e-12,
                "t {t}: joint {j} not at rest at home"
            );
        }
    }
    // the designed motion's start and end, at rest, where the leads meet it
    let m = &r.trajectory;
    let (mut q0, mut v0, mut a0) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    m.eval(0.0, &mut q0, &mut v0, &mut a0);
    let (mut q1, mut v1, mut a1) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    m.eval(m.duration(), &mut q1, &mut v1, &mut a1);
    assert!(q0.iter().zip(&home).any(|(a, b)| (a - b).abs() > 1e-3), "the start moved away from home");
    assert!(q0.iter().zip(&q1).any(|(a, b)| (a - b).abs() > 1e-3), "the end is not the start");
    let t_in = d.lead_in_duration();
    assert!(t_in > 0.0 && d.lead_out_duration() > 0.0);
    for (t, want) in [(t_in, &q0), (t_in + m.duration(), &q1)] {
        for dt in [-1e-4, 1e-4] {
            let (_, q, qd, _) = at(t + dt);
            for j in 0..n {
                assert!(
                    (q[j] - want[j]).abs() < 1e-5 && qd[j].abs() < 1e-3,
                    "t {t}{dt:+}: joint {j}: q {} (want {}), qd {}",
                    q[j],
                    want[j],
                    qd[j]
                );
            }
        }
    }
    assert_eq!(at(t_in + 1.0).0, 1);
    assert_eq!(at(t_in - 0.01).0, 0);
    assert_eq!(at(t_in + m.duration() + 0.01).0, -1);
    assert!(r.execution.verified, "{:?}", r.execution.problem);
}
