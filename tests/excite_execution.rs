//! The delivered (rest-to-rest) trajectory of every shipped excitation
//! design, checked independently on a 1 kHz grid; missing limit classes are
//! named errors; a home pose outside the limits ends INFEASIBLE naming the
//! joint; `idexp excite --export` and `idexp export` write the same files,
//! which hold the rows of trajectory.csv at their rate.

use idexp::excitation::constraints::frame_point;
use idexp::excitation::design::{ExciteDesign, MissingLimits, RefineAlgorithm};
use idexp::excitation::{run, Problem, Status};
use idexp::optim::Control;
use idexp::robot::{inverse_dynamics, Workspace};
use idexp::trajectory::lead::Delivered;
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

const SHIPPED: [&str; 5] = [
    "excite_ur5",
    "excite_ur5_bench",
    "excite_industrial6_full",
    "excite_industrial6_restrained",
    "excite_panda_table",
];

/// Every sample at 1 kHz within every joint limit, torque limit and
/// workspace constraint of the design (computed here, not by the library's
/// check); first and last rows exactly at rest at home.
fn assert_playable(p: &Problem, d: &Delivered) {
    let s = d.sample(1000.0).unwrap();
    let n = p.robot.dof();
    assert_eq!(s.q[0], d.home);
    assert_eq!(*s.q.last().unwrap(), d.home);
    for row in [0, s.len() - 1] {
        assert!(s.qd[row].iter().chain(&s.qdd[row]).all(|v| *v == 0.0));
    }
    let theta = p.robot.nominal_params().as_slice().to_vec();
    let mut ws = Workspace::new(&p.robot);
    let mut tau = vec![0.0; n];
    let frames: Vec<_> = p
        .design
        .workspace
        .iter()
        .map(|c| (c.resolve(&p.robot, "t", "w").unwrap(), c.shape.clone()))
        .collect();
    let tol = 1e-9;
    for k in 0..s.len() {
        for j in 0..n {
            let [lo, hi] = p.limits.position[j];
            assert!(
                s.q[k][j] >= lo - tol && s.q[k][j] <= hi + tol,
                "{}: q{} at t = {}",
                p.design.name,
                j + 1,
                s.t[k]
            );
            assert!(
                s.qd[k][j].abs() <= p.limits.velocity[j] * (1.0 + tol),
                "{}: qd{} at t = {}",
                p.design.name,
                j + 1,
                s.t[k]
            );
            assert!(
                s.qdd[k][j].abs() <= p.limits.acceleration[j] * (1.0 + tol),
                "{}: qdd{} at t = {}",
                p.design.name,
                j + 1,
                s.t[k]
            );
        }
        if p.limits.torque.iter().any(|t| t.is_finite()) {
            inverse_dynamics(&p.robot, &mut ws, &theta, &s.q[k], &s.qd[k], &s.qdd[k], &mut tau);
            for j in 0..n {
                assert!(
                    tau[j].abs() <= p.limits.torque[j] * (1.0 + tol),
                    "{}: torque {} at t = {}",
                    p.design.name,
                    j + 1,
                    s.t[k]
                );
            }
        }
        for (f, shape) in &frames {
            let pt = frame_point(&p.robot, &mut ws, &s.q[k], f);
            assert!(shape.margin(&pt) >= -1e-9, "{}: workspace at t = {}", p.design.name, s.t[k]);
        }
    }
    // lead-in, the periods, lead-out, in order
    assert_eq!(s.segment[0], 0);
    assert_eq!(*s.segment.last().unwrap(), -1);
    assert!(s.segment.contains(&(d.periods as i64)));
}

fn shipped(name: &str, small: bool) -> Problem {
    let mut d = ExciteDesign::load(&root(&format!("designs/{name}.toml"))).unwrap();
    if small {
        // a short search: the delivery (leads, periods, checks) is what is tested here
        d.ga.population = 12;
        d.ga.generations = 3;
        d.refine.algorithm = RefineAlgorithm::None;
        d.time_limit = None;
    }
    let robot = idexp::robot::load(&d.robot).unwrap();
    Problem::new(d, robot, name).unwrap()
}

#[test]
fn every_shipped_design_delivers_a_rest_to_rest_trajectory_within_all_limits_on_1khz() {
    for name in SHIPPED {
        let p = shipped(name, true);
        let r = run(&p, &Control::new()).unwrap();
        if r.violated.is_empty() {
            assert!(r.execution.problem.is_none(), "{name}: {:?}", r.execution.problem);
            assert!(r.execution.verified, "{name}");
            assert_eq!(r.status, Status::Feasible, "{name}");
        }
        let d = r.execution.delivered.as_ref().unwrap_or_else(|| panic!("{name}: {:?}", r.execution.problem));
        assert_eq!(d.periods, 3, "{name}: three periods by default");
        assert_eq!(d.home, idexp::trajectory::Motion::rest_pose(&r.trajectory), "{name}: home defaults to q0");
        if r.status == Status::Feasible {
            assert_playable(&p, d);
        }
    }
}

/// The shipped designs with their full budgets (about 2 minutes on 2 cores):
/// `cargo test --release --test excite_execution -- --ignored`.
#[test]
#[ignore]
fn study_every_shipped_design_full_budget_is_playable() {
    for name in SHIPPED {
        let p = shipped(name, false);
        let r = run(&p, &Control::new()).unwrap();
        assert_eq!(r.status, Status::Feasible, "{name}");
        assert_playable(&p, r.execution.delivered.as_ref().unwrap());
        println!(
            "{name}: cond {:.4}, delivered {:.2} s",
            r.spectrum.cond,
            r.execution.delivered.as_ref().unwrap().duration()
        );
    }
}

#[test]
fn a_limit_class_missing_in_the_robot_is_a_named_error_or_an_explicit_skip() {
    let mut d = ExciteDesign::load(&root("designs/excite_ur5.toml")).unwrap();
    d.robot = root("designs/robots/ur5.urdf"); // the URDF has no acceleration limits
    d.collision.enabled = false; // its package:// meshes are found only through the robot file's mesh_path
    let robot = idexp::robot::load(&d.robot).unwrap();
    let e = Problem::new(d.clone(), robot.clone(), "excite_ur5.toml").unwrap_err().to_string();
    for want in [
        "excite_ur5.toml",
        "limits.acceleration",
        "`shoulder_pan_joint`",
        "ur5.urdf",
        "`acceleration`",
        "missing = \"skip\"",
    ] {
        assert!(e.contains(want), "{want} not in: {e}");
    }
    d.limits.missing = MissingLimits::Skip;
    let p = Problem::new(d.clone(), robot.clone(), "excite_ur5.toml").unwrap();
    assert_eq!(p.constraints.len(), 24, "positions and velocities only");
    let acc: Vec<_> = p.applied_limits.iter().filter(|a| a.class == "acceleration").collect();
    assert_eq!(acc.len(), 6);
    assert!(acc.iter().all(|a| a.source.contains("not imposed") && a.source.contains("skip")));
    // the shipped robot file states them: 36 constraints, sources named
    let p = shipped("excite_ur5", true);
    use idexp::excitation::constraints::ConstraintKind as K;
    let joint = p
        .constraints
        .info
        .iter()
        .filter(|i| matches!(i.kind, K::Position | K::Velocity | K::Acceleration | K::Torque))
        .count();
    assert_eq!(joint, 36, "every joint limit class imposed (collision constraints come on top)");
    let a = p
        .applied_limits
        .iter()
        .find(|a| a.class == "acceleration" && a.joint == "wrist_1_joint")
        .unwrap();
    assert_eq!(a.imposed, [-12.0, 12.0]);
    assert!(a.source.contains("ur5.toml [[drive]] wrist_1_joint"), "{}", a.source);
    let v = p.applied_limits.iter().find(|a| a.class == "velocity" && a.joint == "elbow_joint").unwrap();
    assert!(v.source.starts_with("URDF") && v.source.contains("ur5.urdf"), "{}", v.source);
    // torque asked for on the URDF, which has efforts: fine; with limits.torque = 0: listed as not imposed
    assert!(p
        .applied_limits
        .iter()
        .filter(|a| a.class == "torque")
        .all(|a| a.source == "not imposed (limits.torque = 0)"));
}

#[test]
fn a_home_pose_outside_the_limits_ends_infeasible_naming_the_joint() {
    let mut d = ExciteDesign::load(&root("designs/excite_ur5.toml")).unwrap();
    d.ga.population = 12;
    d.ga.generations = 2;
    d.refine.algorithm = RefineAlgorithm::None;
    d.execution.home = Some(vec![0.0, 0.0, 3.0, 0.0, 0.0, 0.0]); // elbow beyond 0.8 · π
    let robot = idexp::robot::load(&d.robot).unwrap();
    let p = Problem::new(d, robot, "t").unwrap();
    let r = run(&p, &Control::new()).unwrap();
    assert_eq!(r.status, Status::Infeasible);
    let why = r.execution.problem.unwrap();
    assert!(why.contains("lead-in") && why.contains("`elbow_joint` position 3.0"), "{why}");
}

#[cfg(feature = "cli")]
#[test]
fn excite_export_and_idexp_export_write_the_same_files_holding_the_trajectory_rows() {
    use std::process::Command;
    let idexp = || {
        let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
        c.env("IDEXP_NO_PROGRESS", "1").current_dir(root(""));
        c
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ur5");
    let o = idexp()
        .args([
            "excite",
            "designs/excite_ur5.toml",
            "--export",
            "ur,ros2,csv",
            "--ur",
            "cb3",
            "--rate",
            "1000",
            "--csv-derivatives",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // trajectory.csv: delivered rows with segment column, rest at both ends
    let t = idexp::io::Table::read(&out.join("trajectory.csv")).unwrap();
    let seg = t.index("segment").unwrap();
    let first = &t.rows[0];
    let last = t.rows.last().unwrap();
    assert_eq!(first[seg], 0.0);
    assert_eq!(last[seg], -1.0);
    // at rest at home (the design's q0: UR's upright pose) at both ends
    let home = ExciteDesign::load(&root("designs/excite_ur5.toml")).unwrap().trajectory.q0.clone().unwrap();
    for row in [first, last] {
        for j in 0..6 {
            assert!((row[1 + j] - home[j]).abs() < 1e-12, "q{} = {} at an end, home {}", j + 1, row[1 + j], home[j]);
        }
        assert!(row[7..seg].iter().all(|v| *v == 0.0), "at rest at both ends");
    }
    assert_eq!(idexp::io::States::read(&out.join("periodic.csv"), 6).unwrap().len(), 10_000);
    // the CSV export at 1 kHz holds exactly trajectory.csv's q, q̇, q̈
    let e = idexp::io::Table::read(&out.join("excite_ur5_export.csv")).unwrap();
    assert_eq!(e.rows.len(), t.rows.len());
    for (a, b) in e.rows.iter().zip(&t.rows) {
        assert_eq!(a[..19], b[..19]);
    }
    // idexp export rebuilds the same delivered trajectory: identical files
    let again = dir.path().join("again");
    let o = idexp()
        .args(["export"])
        .arg(out.join("coefficients.json"))
        .args(["--format", "ur,ros2,csv", "--ur", "cb3", "--rate", "1000", "--csv-derivatives", "--out"])
        .arg(&again)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "excite_ur5.script",
        "excite_ur5_ros2.yaml",
        "excite_ur5_ros2_goal.yaml",
        "excite_ur5_export.csv",
    ] {
        assert_eq!(std::fs::read(out.join(f)).unwrap(), std::fs::read(again.join(f)).unwrap(), "{f}");
    }
    // the URScript at 125 Hz holds every 8th row of trajectory.csv
    let script = std::fs::read_to_string(out.join("excite_ur5.script")).unwrap();
    let servo: Vec<&str> = script.lines().filter(|l| l.trim_start().starts_with("servoj(")).collect();
    assert_eq!(servo.len(), (t.rows.len() - 1) / 8 + 1);
    let q: Vec<f64> = servo[100]
        .split('[')
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap()
        .split(',')
        .map(|x| x.trim().parse().unwrap())
        .collect();
    for j in 0..6 {
        assert!((q[j] - t.rows[800][1 + j]).abs() < 1e-9);
    }
    // bad input: exit 1 naming the file; an unknown format: exit 1 naming the choices
    let o = idexp().args(["export", "Cargo.toml", "--format", "ur"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("Cargo.toml"));
    let o = idexp()
        .args(["export"])
        .arg(out.join("coefficients.json"))
        .args(["--format", "kuka"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("ur, ros2 or csv"));
}

/// The segment column switches exactly on the sample grid: for every lead-in
/// and lead-out duration on the quantum ladder (k × 40 ms, whose sums are
/// not exact in binary: 35 × 0.04 = 1.4000000000000001) and every usual
/// controller rate, the lead-in has round(T_in · rate) rows, every period
/// period · rate rows, and the first row of period p is at phase 0 (its
/// state is the periodic trajectory's at t = 0, the criterion's first
/// sample). Before, the sample at t = 1.4 s was labelled lead-in and period
/// 1 started one sample late.
#[test]
fn segments_switch_on_the_sample_grid_for_every_lead_duration() {
    use idexp::trajectory::lead::{Quintic, State};
    use idexp::trajectory::FourierTrajectory;
    let w = 2.0 * std::f64::consts::PI * 0.5;
    let periodic = FourierTrajectory::new(w, vec![0.1, -0.2], vec![vec![0.3, 0.1], vec![-0.2, 0.05]], vec![vec![0.1, 0.0], vec![0.0, 0.2]]).unwrap();
    let (mut q, mut qd, mut qdd) = (vec![0.0; 2], vec![0.0; 2], vec![0.0; 2]);
    periodic.eval(0.0, &mut q, &mut qd, &mut qdd);
    let start = State {
        q: q.clone(),
        qd: qd.clone(),
        qdd: qdd.clone(),
    };
    let home = State {
        q: vec![0.0; 2],
        qd: vec![0.0; 2],
        qdd: vec![0.0; 2],
    };
    let mut checked = 0;
    for k_in in 1..=60 {
        let t_in = (0..k_in).fold(0.0, |t, _| t + 0.04); // as the ladder sums it
        let t_out = (k_in % 7 + 1) as f64 * 0.04;
        let d = Delivered {
            home: home.q.clone(),
            lead_in: Some(Quintic::new(&home, &start, t_in)),
            periodic: periodic.clone().into(),
            periods: 3,
            lead_out: Some(Quintic::new(&start, &home, t_out)),
        };
        for rate in [1000.0, 500.0, 250.0, 125.0, 100.0] {
            let s = d.sample(rate).unwrap();
            let count = |seg: i64| s.segment.iter().filter(|&&x| x == seg).count();
            let n_in = (t_in * rate).round() as usize;
            let per = (periodic.period() * rate).round() as usize;
            assert_eq!(count(0), n_in, "lead-in {t_in} s at {rate} Hz");
            for p in 1..=3 {
                assert_eq!(count(p), per, "period {p}, lead-in {t_in} s at {rate} Hz");
                let first = s.segment.iter().position(|&x| x == p).unwrap();
                assert_eq!(first, n_in + (p as usize - 1) * per);
                for j in 0..2 {
                    assert!(
                        (s.q[first][j] - q[j]).abs() < 1e-12 && (s.qdd[first][j] - qdd[j]).abs() < 1e-9,
                        "period {p} starts at phase 0"
                    );
                }
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 300);
}
