//! Excitation design with a rest-to-rest B-spline (`[trajectory] shape =
//! "bspline"`): the objective's and the constraints' gradients through the
//! shape seam against finite differences, the design fields' validation, and
//! the shipped design end to end (`idexp excite`, the criterion recomputed
//! from the written trajectory.csv, rest at both ends, the limits on every
//! 1 kHz row, the files read back by `assess`, `export` and `view`).

use idexp::excitation::constraints::{Constraints, JointLimitSpec};
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::objective::{BaseColumns, Criterion, Objective, Scaling, Scoring};
use idexp::excitation::{assess, Problem};
use idexp::io::States;
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::cartesian::{CartesianConstraint, Shape};
use idexp::robot::{self, Robot};
use idexp::trajectory::bspline::BSplineLayout;
use idexp::trajectory::{period_grid, TrajectoryShape};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn load(name: &str) -> Robot {
    robot::load(&root(&format!("designs/robots/{name}.toml"))).unwrap()
}

mod excite_fd;
use excite_fd::values;

#[test]
fn bspline_objective_gradient_matches_finite_differences() {
    let r = load("ur5");
    let h = std::f64::consts::FRAC_PI_2;
    let q0 = vec![0.0, -h, 0.0, -h, 0.0, 0.0];
    let lay = BSplineLayout::new(q0, 4, 7, 6.0).unwrap();
    let b = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let nom: Vec<f64> = b.base_values(r.nominal_params().as_slice()).iter().copied().collect();
    for crit in [Criterion::Cond, Criterion::LogDet] {
        let o = Objective::new(
            r.clone(),
            lay.clone(),
            BaseColumns {
                indices: b.independent.clone(),
                names: b.names.clone(),
                nominal: nom.clone(),
            },
            period_grid(6.0, 10.0).unwrap(),
            Scoring {
                criterion: crit,
                scaling: Scaling::UnitColumn,
                noise: vec![1.0; 6],
            },
        )
        .unwrap();
        let f = excite_fd::check_objective_gradient(&o, &values(lay.n_vars(), 0.6, 1.0), &format!("{crit:?}"));
        assert!(f > 1.0, "{crit:?}: {f}");
    }
}

#[test]
fn bspline_constraint_gradients_match_finite_differences() {
    let r = load("industrial6");
    let q0 = vec![0.0, -1.047, 0.209, 0.0, 0.3, 0.0];
    let lay = BSplineLayout::new(q0, 5, 6, 4.0).unwrap();
    let n = r.dof();
    let lim = |f: fn(&idexp::robot::Joint) -> f64| r.joints.iter().map(|j| 0.9 * f(j)).collect::<Vec<f64>>();
    let limits = JointLimitSpec {
        position: r.joints.iter().map(|j| [0.9 * j.limits.lower, 0.9 * j.limits.upper]).collect(),
        velocity: lim(|j| j.limits.velocity),
        acceleration: vec![3.0; n],
        torque: lim(|j| j.limits.effort),
    };
    let cart = vec![CartesianConstraint {
        frame: Some("tool0".into()),
        shape: Shape::Box {
            min: [0.2, -1.5, 0.5],
            max: [2.0, 1.5, 2.5],
        },
    }];
    let c = Constraints::new(r.clone(), lay.clone(), &limits, &cart, 200.0, "test").unwrap();
    excite_fd::check_constraint_jacobian(&c, &values(lay.n_vars(), 0.3, 2.0), |_| 2e-4);
}

#[test]
fn bspline_fields_are_validated_with_the_field_named() {
    let base = std::fs::read_to_string(root("designs/excite_ur5_bspline.toml")).unwrap();
    for (from, to, field) in [
        ("degree = 5", "degree = 7", "trajectory.degree"),
        ("segments = 11", "segments = 1", "trajectory.segments"),
        ("duration = 10.0", "duration = -1.0", "trajectory.duration"),
        ("shape = \"bspline\"", "shape = \"bezier\"", "expected `fourier` or `bspline`"),
        ("shape = \"bspline\"", "shape = \"fourier\"", "trajectory.degree"),
        ("degree = 5", "degree = 5\nat_rest = true", "trajectory.at_rest"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.toml");
        std::fs::write(
            &path,
            base.replace(from, to)
                .replace("robots/ur5.toml", &root("designs/robots/ur5.toml").display().to_string()),
        )
        .unwrap();
        let e = ExciteDesign::load(&path).unwrap_err().to_string();
        assert!(e.contains(field), "{to}: {e}");
    }
}

/// The rows of trajectory.csv: (header, rows).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect())
}

#[test]
fn the_shipped_bspline_design_runs_end_to_end_and_its_files_read_back() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("run");
    let bin = env!("CARGO_BIN_EXE_idexp");
    let design = root("designs/excite_ur5_bspline.toml");
    let st = Command::new(bin)
        .arg("excite")
        .arg(&design)
        .arg("--out")
        .arg(&dir)
        .env("IDEXP_NO_PROGRESS", "1")
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    let coeff: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("coefficients.json")).unwrap()).unwrap();
    assert_eq!(coeff["shape"], "bspline");
    assert_eq!(coeff["status"], "feasible");
    assert!(coeff["delivered"]["lead_in"].is_null() && coeff["delivered"]["lead_out"].is_null(), "no leads");
    let criterion = coeff["criterion_value"].as_f64().unwrap();
    // the criterion from trajectory.csv: segment 1 (from t = 0, no lead-in), every 100th row
    let p = Problem::from_file(&design).unwrap();
    let n = p.robot.dof();
    let (header, rows) = read_csv(&dir.join("trajectory.csv"));
    assert_eq!(header.last().unwrap(), "segment");
    assert_eq!(rows.len(), 30001, "3 × 10 s at 1 kHz and the rest row");
    let picked: Vec<&Vec<f64>> = rows
        .iter()
        .enumerate()
        .filter(|(k, r)| r[3 * n + 1] == 1.0 && k % 100 == 0)
        .map(|(_, r)| r)
        .collect();
    assert_eq!(picked.len(), 100);
    let states = States {
        t: None,
        q: picked.iter().map(|r| r[1..=n].to_vec()).collect(),
        qd: picked
            .iter()
            .map(|r| r[n + 1..=2 * n].iter().map(|v| if v.abs() < 1e-12 { 0.0 } else { *v }).collect())
            .collect(),
        qdd: picked.iter().map(|r| r[2 * n + 1..=3 * n].to_vec()).collect(),
    };
    let id = assess(&p.robot, &p.base, &states, &vec![1.0; n]).unwrap();
    assert!(
        (id.cond - criterion).abs() <= 1e-6 * criterion,
        "cond from trajectory.csv {} vs the report's {criterion}",
        id.cond
    );
    // at rest at q0 at both ends (and between the repetitions)
    let q0 = p.design.trajectory.q0.clone().unwrap();
    for k in [0, 10000, 20000, 30000] {
        let r = &rows[k];
        for j in 0..n {
            assert!((r[1 + j] - q0[j]).abs() < 1e-12, "row {k} q{j}");
            assert!(r[n + 1 + j].abs() < 1e-12 && r[2 * n + 1 + j].abs() < 1e-12, "row {k} joint {j} not at rest");
        }
    }
    // every 1 kHz row within the limits the design imposed
    let l = &p.limits;
    for (k, r) in rows.iter().enumerate() {
        for j in 0..n {
            let [lo, hi] = l.position[j];
            assert!(r[1 + j] >= lo - 1e-9 && r[1 + j] <= hi + 1e-9, "row {k} q{j}");
            assert!(r[n + 1 + j].abs() <= l.velocity[j] * (1.0 + 1e-9), "row {k} qd{j}");
            assert!(r[2 * n + 1 + j].abs() <= l.acceleration[j] * (1.0 + 1e-9), "row {k} qdd{j}");
        }
    }
    // the motion in coefficients.json reproduces the rows
    let m: idexp::trajectory::ShapeMotion = serde_json::from_value(coeff["trajectory"].clone()).unwrap();
    m.validate("coefficients.json").unwrap();
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for k in (0..10000).step_by(137) {
        idexp::trajectory::Motion::eval(&m, rows[k][0], &mut q, &mut qd, &mut qdd);
        for j in 0..n {
            assert!((q[j] - rows[k][1 + j]).abs() < 1e-12, "row {k} joint {j}");
        }
    }
    // every command that reads the run's files takes them
    let run = |args: &[&str]| {
        let o = Command::new(bin).args(args).env("IDEXP_NO_PROGRESS", "1").output().unwrap();
        assert!(o.status.success(), "idexp {args:?}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let robot = root("designs/robots/ur5.toml");
    let traj = dir.join("trajectory.csv");
    let s = run(&[
        "assess",
        robot.to_str().unwrap(),
        traj.to_str().unwrap(),
        "--segment",
        "1",
        "--every",
        "100",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_str(&s).unwrap();
    let cond = v["cond"].as_f64().unwrap_or_else(|| v["identifiability"]["cond"].as_f64().unwrap());
    assert!((cond - criterion).abs() <= 1e-6 * criterion, "idexp assess: {cond} vs {criterion}");
    let exp = out.path().join("exp");
    run(&[
        "export",
        dir.join("coefficients.json").to_str().unwrap(),
        "--format",
        "csv",
        "--out",
        exp.to_str().unwrap(),
    ]);
    assert!(std::fs::read_dir(&exp).unwrap().count() > 0);
    let view = out.path().join("view");
    run(&["view", dir.to_str().unwrap(), "--out", view.to_str().unwrap()]);
    assert!(view.join("preview.html").is_file());
}
