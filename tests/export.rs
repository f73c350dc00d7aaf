//! Rest-to-rest delivery and controller exports :
//! the quintic leads meet their boundary states, the delivered trajectory is
//! continuous and starts and ends at rest, and every export (URScript,
//! ROS 2 JointTrajectory YAML, CSV) parses — the YAML with an independent
//! parser (yaml-rust2), the URScript with a small structural grammar — and
//! holds exactly the delivered samples at its rate.

use idexp::trajectory::export::{self, CsvOptions, Format, Samples, UrController};
use idexp::trajectory::lead::{shortest, Delivered, Quintic, State, LEAD_IN, LEAD_OUT};
use idexp::trajectory::FourierTrajectory;
use yaml_rust2::{Yaml, YamlLoader};

fn periodic() -> FourierTrajectory {
    // 3 joints, 3 harmonics of 0.25 Hz (period 4 s), not at rest at t = 0
    FourierTrajectory::new(
        std::f64::consts::TAU * 0.25,
        vec![0.1, -0.4, 0.3],
        vec![vec![0.3, -0.1, 0.05], vec![-0.2, 0.15, 0.0], vec![0.1, 0.0, -0.08]],
        vec![vec![0.1, 0.2, -0.05], vec![0.0, -0.1, 0.07], vec![0.25, 0.05, 0.0]],
    )
    .unwrap()
}

fn delivered() -> Delivered {
    let tr = periodic();
    let home = vec![0.0, -0.5, 0.2];
    let start = State::of(&tr, 0.0);
    let ok = |_: f64, _: &[f64], qd: &[f64], qdd: &[f64]| -> Result<(), String> {
        if qd.iter().any(|v| v.abs() > 1.5) || qdd.iter().any(|v| v.abs() > 4.0) {
            Err("too fast".into())
        } else {
            Ok(())
        }
    };
    let lead_in = shortest(&State::rest(&home), &start, 0.2, 30.0, 1e-3, ok).unwrap();
    let lead_out = shortest(&start, &State::rest(&home), 0.2, 30.0, 1e-3, ok).unwrap();
    Delivered {
        home,
        lead_in: Some(lead_in),
        periodic: tr.into(),
        periods: 2,
        lead_out: Some(lead_out),
    }
}

#[test]
fn quintic_meets_both_boundary_states_and_its_derivatives_are_consistent() {
    let a = State {
        q: vec![0.3, -1.0],
        qd: vec![0.5, 0.0],
        qdd: vec![-1.0, 2.0],
    };
    let b = State {
        q: vec![-0.2, 0.4],
        qd: vec![-0.3, 1.1],
        qdd: vec![0.7, -0.4],
    };
    let p = Quintic::new(&a, &b, 1.7);
    for (s, want) in [(0.0, &a), (1.7, &b)] {
        let (q, qd, qdd) = p.eval(s);
        for j in 0..2 {
            assert!((q[j] - want.q[j]).abs() < 1e-12, "q at {s}");
            assert!((qd[j] - want.qd[j]).abs() < 1e-12, "qd at {s}");
            assert!((qdd[j] - want.qdd[j]).abs() < 1e-11, "qdd at {s}");
        }
    }
    // central differences of q and q̇ give q̇ and q̈
    let h = 1e-5;
    for s in [0.3, 0.9, 1.4] {
        let (q1, qd1, _) = p.eval(s - h);
        let (q2, qd2, _) = p.eval(s + h);
        let (_, qd, qdd) = p.eval(s);
        for j in 0..2 {
            assert!(((q2[j] - q1[j]) / (2.0 * h) - qd[j]).abs() < 1e-8);
            assert!(((qd2[j] - qd1[j]) / (2.0 * h) - qdd[j]).abs() < 1e-7);
        }
    }
}

#[test]
fn shortest_lead_is_the_first_duration_that_passes_and_an_impossible_check_is_a_named_error() {
    let a = State::rest(&[0.0]);
    let b = State::rest(&[1.0]);
    // rest-to-rest quintic: peak speed 1.875 h / T, so |q̇| ≤ 1 needs T ≥ 1.875 s
    let p = shortest(&a, &b, 0.1, 10.0, 1e-3, |_, _, qd, _| {
        if qd[0].abs() > 1.0 {
            Err(format!("speed {}", qd[0]))
        } else {
            Ok(())
        }
    })
    .unwrap();
    assert!(p.duration >= 1.875 && p.duration < 1.875 * 1.05 + 0.04 + 1e-9, "{}", p.duration);
    let steps = (p.duration / 0.04).round();
    assert!((p.duration - steps * 0.04).abs() < 1e-9, "a whole number of 40 ms quanta");
    let e = shortest(&a, &b, 0.1, 2.0, 1e-3, |_, q, _, _| {
        if q[0] > 0.5 {
            Err("joint `j1` position beyond 0.5".into())
        } else {
            Ok(())
        }
    })
    .unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("joint `j1` position beyond 0.5") && msg.contains("duration"), "{msg}");
}

#[test]
fn delivered_trajectory_starts_and_ends_at_rest_is_continuous_and_labels_its_segments() {
    let d = delivered();
    let s = d.sample(1000.0).unwrap();
    let n = 3;
    assert_eq!(s.q[0], d.home);
    assert_eq!(*s.q.last().unwrap(), d.home);
    for row in [0, s.len() - 1] {
        assert!(s.qd[row].iter().chain(&s.qdd[row]).all(|v| *v == 0.0), "row {row} at rest");
    }
    assert!(*s.t.last().unwrap() >= d.duration() - 1e-9);
    // segments: 0 … 0, 1 … 1, 2 … 2, −1 … −1, in order
    let mut order = vec![s.segment[0]];
    for &g in &s.segment {
        if g != *order.last().unwrap() {
            order.push(g);
        }
    }
    assert_eq!(order, vec![LEAD_IN, 1, 2, LEAD_OUT]);
    // the periodic rows are the periodic trajectory at t − t_in (mod period)
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let t_in = d.lead_in_duration();
    for k in (0..s.len()).filter(|&k| s.segment[k] >= 1).step_by(97) {
        let local = s.t[k] - t_in - (s.segment[k] - 1) as f64 * d.periodic.fourier().unwrap().period();
        d.periodic.fourier().unwrap().eval(local, &mut q, &mut qd, &mut qdd);
        for j in 0..n {
            assert!((q[j] - s.q[k][j]).abs() < 1e-12 && (qd[j] - s.qd[k][j]).abs() < 1e-12);
        }
    }
    // continuity at 1 kHz: no step in q, q̇, q̈ larger than the limits
    // (|q̇| ≤ 1.5, |q̈| ≤ 4 by the check of the leads) and the jerk allow
    let (dt, jerk) = (1e-3, jerk_bound(&d));
    for k in 1..s.len() {
        for j in 0..n {
            assert!((s.q[k][j] - s.q[k - 1][j]).abs() <= 1.5 * dt + 1e-12, "q jump at row {k}");
            assert!((s.qd[k][j] - s.qd[k - 1][j]).abs() <= 4.0 * dt + 1e-12, "q̇ jump at row {k}");
            assert!((s.qdd[k][j] - s.qdd[k - 1][j]).abs() <= jerk * dt * (1.0 + 1e-9), "q̈ jump at row {k}");
        }
    }
}

/// An upper bound of |d³q/dt³| over the delivered trajectory: the quintics'
/// jerk 6c₃ + 24c₄s + 60c₅s² on [0, T] and Σ (kω)² r_k for the series.
fn jerk_bound(d: &Delivered) -> f64 {
    let mut b: f64 = 0.0;
    for p in [&d.lead_in, &d.lead_out].into_iter().flatten() {
        let t = p.duration;
        for c in &p.coef {
            b = b.max(6.0 * c[3].abs() + 24.0 * c[4].abs() * t + 60.0 * c[5].abs() * t * t);
        }
    }
    let tr = d.periodic.fourier().unwrap();
    for j in 0..tr.n_joints() {
        let s: f64 = (0..tr.n_harmonics())
            .map(|k| ((k + 1) as f64 * tr.omega).powi(2) * tr.a[j][k].hypot(tr.b[j][k]))
            .sum();
        b = b.max(s);
    }
    b
}

fn names() -> Vec<String> {
    vec!["shoulder".into(), "elbow".into(), "slide".into()]
}

fn parse_list(s: &str) -> Vec<f64> {
    let inner = s.trim().strip_prefix('[').and_then(|r| r.strip_suffix(']')).expect("a [..] list");
    inner.split(',').map(|x| x.trim().parse::<f64>().expect("a number")).collect()
}

#[test]
fn urscript_is_one_program_with_one_servoj_per_sample_at_the_controller_rate() {
    let d = delivered();
    for ctl in [UrController::Cb3, UrController::ESeries] {
        let s = Samples::from_delivered(names(), &d, ctl.rate()).unwrap();
        let text = export::urscript(&s, ctl, "excite_test", (1.0, 0.5)).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        // grammar: def NAME():  (indented statements | comments)*  end  NAME()
        assert_eq!(lines[0], "def excite_test():");
        let end = lines.iter().position(|l| *l == "end").expect("end");
        assert_eq!(lines[end + 1], "excite_test()");
        assert_eq!(lines.len(), end + 2);
        let mut servo = Vec::new();
        let mut movej = 0;
        for l in &lines[1..end] {
            assert!(l.starts_with("  "), "statement indented: {l}");
            let st = l.trim();
            if st.starts_with('#') {
                continue;
            }
            let (name, rest) = st.split_once('(').expect("a call");
            assert!(rest.ends_with(')'), "{st}");
            let args = &rest[..rest.len() - 1];
            match name {
                "servoj" => {
                    let (list, tail) = args.split_once(']').unwrap();
                    let q = parse_list(&format!("{list}]"));
                    let tail: Vec<f64> = tail.trim_start_matches(',').split(',').map(|x| x.trim().parse().unwrap()).collect();
                    assert_eq!(tail.len(), 5);
                    assert!((tail[2] - 1.0 / ctl.rate()).abs() < 1e-12, "servoj t = sample period");
                    servo.push(q);
                }
                "movej" => {
                    movej += 1;
                    assert!(servo.is_empty(), "movej to the start before streaming");
                }
                "textmsg" | "sleep" | "stopj" => {}
                other => panic!("unexpected statement {other}"),
            }
        }
        assert_eq!(movej, 1);
        assert_eq!(servo.len(), s.q.len(), "one servoj per sample");
        for (k, q) in servo.iter().enumerate() {
            for j in 0..3 {
                assert!((q[j] - s.q[k][j]).abs() <= 5e-10, "sample {k}");
            }
        }
        assert_eq!(servo[0], d.home);
        assert_eq!(*servo.last().unwrap(), d.home);
        // from rest: the first step moves at most jerk·dt³/6 (q̇ = q̈ = 0 at the start)
        let dt = 1.0 / ctl.rate();
        let first = jerk_bound(&d) * dt.powi(3) / 6.0;
        for j in 0..3 {
            assert!((servo[1][j] - servo[0][j]).abs() <= first + 1e-9, "first step {}", servo[1][j] - servo[0][j]);
        }
    }
    let s = Samples::from_delivered(names(), &d, 1000.0).unwrap();
    assert!(export::urscript(&s, UrController::Cb3, "x", (1.0, 0.5))
        .unwrap_err()
        .to_string()
        .contains("125"));
    let s = Samples::from_delivered(names(), &d, 125.0).unwrap();
    assert!(export::urscript(&s, UrController::Cb3, "bad-name", (1.0, 0.5)).is_err());
}

fn yaml_f64(y: &Yaml) -> f64 {
    match y {
        Yaml::Real(r) => r.parse().unwrap(),
        Yaml::Integer(i) => *i as f64,
        other => panic!("not a number: {other:?}"),
    }
}

fn check_joint_trajectory(msg: &Yaml, s: &Samples) {
    let jn: Vec<&str> = msg["joint_names"].as_vec().unwrap().iter().map(|y| y.as_str().unwrap()).collect();
    assert_eq!(jn, ["shoulder", "elbow", "slide"]);
    let pts = msg["points"].as_vec().unwrap();
    assert_eq!(pts.len(), s.q.len());
    for (k, p) in pts.iter().enumerate() {
        let t = msg_time(&p["time_from_start"]);
        assert!((t - s.t[k]).abs() < 1e-9, "time of point {k}");
        for (field, want) in [("positions", &s.q[k]), ("velocities", &s.qd[k]), ("accelerations", &s.qdd[k])] {
            let got: Vec<f64> = p[field].as_vec().unwrap().iter().map(yaml_f64).collect();
            assert_eq!(&got, want, "{field} of point {k}");
        }
        assert!(p["effort"].as_vec().unwrap().is_empty());
    }
    let last = pts.last().unwrap();
    for f in ["velocities", "accelerations"] {
        assert!(pts[0][f].as_vec().unwrap().iter().chain(last[f].as_vec().unwrap()).all(|v| yaml_f64(v) == 0.0));
    }
}

fn msg_time(y: &Yaml) -> f64 {
    let ns = y["nanosec"].as_i64().unwrap();
    assert!((0..1_000_000_000).contains(&ns));
    y["sec"].as_i64().unwrap() as f64 + ns as f64 * 1e-9
}

#[test]
fn ros2_yaml_parses_with_an_independent_parser_and_holds_the_samples() {
    let d = delivered();
    let s = Samples::from_delivered(names(), &d, 50.0).unwrap();
    let text = export::ros2_yaml(&s).unwrap();
    let docs = YamlLoader::load_from_str(&text).unwrap();
    assert_eq!(docs.len(), 1);
    assert_eq!(docs[0]["header"]["frame_id"].as_str(), Some(""));
    check_joint_trajectory(&docs[0], &s);
    let goal = YamlLoader::load_from_str(&export::ros2_goal_yaml(&s).unwrap()).unwrap();
    check_joint_trajectory(&goal[0]["trajectory"], &s);
    // waypoints
    let poses = vec![vec![0.0, 0.1, 0.2], vec![1.0, -0.1, 0.0]];
    let w = YamlLoader::load_from_str(&export::ros2_waypoints_yaml(&names(), &poses, &[2.0, 4.5]).unwrap()).unwrap();
    let pts = w[0]["points"].as_vec().unwrap();
    assert_eq!(pts.len(), 2);
    assert!((msg_time(&pts[1]["time_from_start"]) - 4.5).abs() < 1e-12);
}

#[test]
fn csv_export_holds_the_samples_in_the_chosen_units() {
    let d = delivered();
    let s = Samples::from_delivered(names(), &d, 200.0).unwrap();
    let revolute = [true, true, false];
    for (deg, der) in [(false, false), (true, true)] {
        let text = export::csv(
            &s,
            &revolute,
            CsvOptions {
                derivatives: der,
                degrees: deg,
            },
        )
        .unwrap();
        let mut r = csv::Reader::from_reader(text.as_bytes());
        let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
        assert_eq!(h[0], "t[s]");
        assert_eq!(h[1], if deg { "shoulder[deg]" } else { "shoulder[rad]" });
        assert_eq!(h[3], "slide[m]", "prismatic joints stay in m");
        assert_eq!(h.len(), 1 + if der { 9 } else { 3 });
        if der {
            assert_eq!(h[4], "shoulder_vel[deg/s]");
            assert_eq!(h[9], "slide_acc[m/s^2]");
        }
        let rows: Vec<Vec<f64>> = r.records().map(|rec| rec.unwrap().iter().map(|x| x.parse().unwrap()).collect()).collect();
        assert_eq!(rows.len(), s.q.len());
        for (k, row) in rows.iter().enumerate() {
            assert_eq!(row[0], s.t[k]);
            for j in 0..3 {
                let f = if deg && revolute[j] { 180.0 / std::f64::consts::PI } else { 1.0 };
                assert!((row[1 + j] - f * s.q[k][j]).abs() <= 1e-12 * (1.0 + row[1 + j].abs()));
                if der {
                    assert!((row[4 + j] - f * s.qd[k][j]).abs() <= 1e-12 * (1.0 + row[4 + j].abs()));
                }
            }
        }
    }
}

#[test]
fn write_exports_writes_every_format_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = delivered();
    let o = export::ExportOptions {
        formats: vec![Format::Ur, Format::Ros2, Format::Csv],
        rate: 100.0,
        ur: UrController::Cb3,
        csv: CsvOptions {
            derivatives: false,
            degrees: false,
        },
        stem: export::program_name("excite-test 1"),
        approach: (1.0, 0.5),
    };
    assert_eq!(o.stem, "excite_test_1");
    let files = export::write_exports(dir.path(), &names(), &[true, true, false], &d, &o).unwrap();
    assert_eq!(files.len(), 4);
    for f in &files {
        assert!(f.is_file(), "{}", f.display());
    }
    assert!(Format::parse("kuka").unwrap_err().to_string().contains("ur, ros2 or csv"));
    assert!(export::write_exports(dir.path(), &names()[..2], &[true, true], &d, &o).is_err());
    assert!(d.sample(-1.0).is_err());
    assert!(d.sample(1e9).unwrap_err().to_string().contains("samples"));
}

/// `idexp positions --export ur,ros2,csv`: one `movej` per pose of the
/// rounded plan with a dwell per measurement, JointTrajectory waypoints that
/// parse, reach every pose at rest and hold it; the poses are plan.csv's.
#[cfg(feature = "cli")]
#[test]
fn positions_plan_exports_hold_the_plan_poses() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("pos");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_idexp"))
        .env("IDEXP_NO_PROGRESS", "1")
        .current_dir(root)
        .args([
            "positions",
            "designs/positions_file_a.toml",
            "--export",
            "ur,ros2,csv",
            "--dwell",
            "1.5",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the rounded plan: rows of plan.csv with m > 0
    let plan = idexp::io::Table::read(&out.join("plan.csv")).unwrap();
    let im = plan.index("m").unwrap();
    let q: Vec<Vec<f64>> = plan.rows.iter().filter(|r| r[im] > 0.0).map(|r| r[1..7].to_vec()).collect();
    let m: Vec<f64> = plan.rows.iter().filter(|r| r[im] > 0.0).map(|r| r[im]).collect();
    assert!(!q.is_empty());
    let script = std::fs::read_to_string(out.join("positions_file_a_poses.script")).unwrap();
    let lines: Vec<&str> = script.lines().collect();
    assert_eq!(lines[0], "def positions_file_a_poses():");
    assert_eq!(lines[lines.len() - 2], "end");
    let moves: Vec<Vec<f64>> = lines
        .iter()
        .filter_map(|l| l.trim().strip_prefix("movej("))
        .map(|rest| parse_list(&format!("{}]", rest.split(']').next().unwrap())))
        .collect();
    let sleeps: Vec<f64> = lines
        .iter()
        .filter_map(|l| l.trim().strip_prefix("sleep("))
        .map(|rest| rest.split(')').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(moves.len(), q.len());
    for (k, pose) in moves.iter().enumerate() {
        for j in 0..6 {
            assert!((pose[j] - q[k][j]).abs() < 5e-9 * (1.0 + q[k][j].abs()), "pose {k}");
        }
        assert!((sleeps[k] - 1.5 * m[k]).abs() < 1e-12, "dwell per measurement");
    }
    let y = YamlLoader::load_from_str(&std::fs::read_to_string(out.join("positions_file_a_poses_ros2.yaml")).unwrap()).unwrap();
    let pts = y[0]["points"].as_vec().unwrap();
    assert_eq!(pts.len(), 2 * q.len(), "arrive and leave each pose");
    let mut last = -1.0;
    for (i, p) in pts.iter().enumerate() {
        let t = msg_time(&p["time_from_start"]);
        assert!(t > last, "times increase");
        last = t;
        let pos: Vec<f64> = p["positions"].as_vec().unwrap().iter().map(yaml_f64).collect();
        assert_eq!(pos, q[i / 2]);
        assert!(
            p["velocities"].as_vec().unwrap().iter().all(|v| yaml_f64(v) == 0.0),
            "at rest at every waypoint"
        );
    }
    assert!(out.join("positions_file_a_poses.csv").is_file());
}
