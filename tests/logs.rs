//! Robot logs as they come from the field (`idexp::data::logs`): ROS 2 bags
//! written by the Python `rosbags` package (MCAP and sqlite3), a UR
//! RTDE-recorder CSV with the recorder's header, a headerless CSV; all
//! written by scripts/make-log-fixtures.py, not by idexp. The acceptance
//! test: identification from a bag or an RTDE CSV equals identification
//! from the same samples in idexp's run CSV.

use idexp::data::logs::{bag_info, read_log, BagStamps, LogFormat, LogSpec, RtdeTorque, TimeUnit};
use idexp::data::{Repetition, Run};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn data(p: &str) -> PathBuf {
    root(&format!("tests/data/logs/{p}"))
}

fn ur5() -> idexp::robot::Robot {
    idexp::robot::load(&data("ur5_drives.toml")).unwrap_or_else(|e| panic!("{e}"))
}

/// The samples in idexp's own run CSV (written by the fixture script).
fn reference() -> Repetition {
    Repetition::read(&data("ur5_idexp.csv"), 6).unwrap_or_else(|e| panic!("{e}"))
}

fn bag(p: &str) -> idexp::data::logs::LogRead {
    read_log(&data(p), &ur5(), &LogSpec::new(LogFormat::Bag)).unwrap_or_else(|e| panic!("{p}: {e}"))
}

fn err_text<T: std::fmt::Debug>(r: idexp::Result<T>) -> String {
    r.unwrap_err().to_string()
}

#[test]
fn bags_of_both_storages_give_the_samples_of_the_run_csv_bit_for_bit() {
    let want = reference();
    for p in ["ur5_mcap", "ur5_sqlite3", "ur5_mcap/ur5_mcap.mcap", "ur5_sqlite3/ur5_sqlite3.db3"] {
        let r = bag(p);
        // joints in another order in the bag, a gripper joint, a text topic
        assert_eq!(r.rep.t, want.t, "{p}: t");
        assert_eq!(r.rep.q, want.q, "{p}: q");
        assert_eq!(r.rep.tau, want.tau, "{p}: tau");
        assert_eq!(r.rep.qd, want.qd, "{p}: qd");
        assert!(r.rep.qdd.is_none());
        let rep = &r.report;
        assert_eq!(rep.samples, 400);
        assert_eq!(rep.start, "1733400000.123456789 s since the epoch");
        assert!(rep.steps.unwrap().uniform);
        assert!((rep.steps.unwrap().median - 0.005).abs() < 1e-15);
        assert!(rep.ignored.iter().any(|s| s.contains("gripper_finger_joint")), "{:?}", rep.ignored);
        assert!(rep.ignored.iter().any(|s| s.contains("/notes")), "{:?}", rep.ignored);
        assert!(rep.source.contains(if p.contains("mcap") { "mcap" } else { "sqlite3" }), "{}", rep.source);
        assert!(rep.columns.iter().any(|c| c.column == "q3" && c.source == "elbow_joint position"));
    }
}

#[test]
fn the_rtde_recorder_csv_gives_the_same_samples_with_torques_from_currents() {
    let want = reference();
    let robot = ur5();
    let r = read_log(&data("ur5_rtde.csv"), &robot, &LogSpec::new(LogFormat::Rtde)).unwrap_or_else(|e| panic!("{e}"));
    // uptime stamps subtracted as decimals: the same f64 as k·5 ms
    assert_eq!(r.rep.t, want.t);
    assert_eq!(r.rep.q, want.q);
    assert_eq!(r.rep.qd, want.qd);
    for (a, b) in r.rep.tau.iter().flatten().zip(want.tau.iter().flatten()) {
        assert!((a - b).abs() <= 1e-14 * b.abs().max(1.0), "{a} vs {b}");
    }
    assert_eq!(r.report.start, "timestamp = 8123.456 s (controller uptime)");
    let k = r.report.torque_per_ampere.clone().unwrap();
    assert_eq!(k[2], -0.125 * 101.0);
    assert!(r.report.torque.contains("actual_current_{j}"), "{}", r.report.torque);
    // the same file read as a CSV with a column map
    let map = LogSpec {
        t: Some("timestamp".into()),
        index_base: Some(0),
        q: Some("actual_q_{j}".into()),
        qd: Some("actual_qd_{j}".into()),
        current: Some("actual_current_{j}".into()),
        delimiter: Some(' '),
        ..LogSpec::new(LogFormat::Csv)
    };
    let m = read_log(&data("ur5_rtde.csv"), &robot, &map).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.rep, r.rep);
    // target_moment: the controller's model torque (here the rigid body without friction)
    let tm = LogSpec {
        torque: Some(RtdeTorque::TargetMoment),
        ..LogSpec::new(LogFormat::Rtde)
    };
    let t = read_log(&data("ur5_rtde.csv"), &robot, &tm).unwrap_or_else(|e| panic!("{e}"));
    assert_ne!(t.rep.tau, r.rep.tau);
    assert!(t.report.torque.contains("target_moment"));
    // currents without torque constants: an error naming the joint and the key
    let plain = idexp::robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let e = err_text(read_log(&data("ur5_rtde.csv"), &plain, &LogSpec::new(LogFormat::Rtde)));
    assert!(
        e.contains("actual_current_0") && e.contains("shoulder_pan_joint") && e.contains("torque_constant"),
        "{e}"
    );
}

#[test]
fn a_headerless_log_with_a_column_list_and_time_in_ms() {
    let want = reference();
    let mut cols = vec!["-".to_string(), "t".into()];
    cols.extend((1..=6).map(|j| format!("q{j}")));
    cols.extend((1..=6).map(|j| format!("tau{j}")));
    let spec = LogSpec {
        columns: Some(cols.clone()),
        time_unit: Some(TimeUnit::Ms),
        ..LogSpec::new(LogFormat::Headerless)
    };
    let r = read_log(&data("ur5_headerless.txt"), &ur5(), &spec).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(r.rep.len(), 100);
    assert_eq!(r.rep.t[..], want.t[..100]);
    assert_eq!(r.rep.q[..], want.q[..100]);
    assert_eq!(r.rep.tau[..], want.tau[..100]);
    assert!(r.rep.qd.is_none());
    assert!(r.report.ignored[0].contains("- (field 1)"), "{:?}", r.report.ignored);
    // one column short: the row is refused, naming it
    let short = LogSpec {
        columns: Some(cols[1..].to_vec()),
        ..spec.clone()
    };
    let e = err_text(read_log(&data("ur5_headerless.txt"), &ur5(), &short));
    assert!(e.contains("row 1") && e.contains("expected 13 values"), "{e}");
}

#[test]
fn irregular_stamps_are_kept_and_topics_are_chosen_by_name() {
    let robot = ur5();
    // two JointState topics: the default refuses to guess, listing them
    let e = err_text(read_log(&data("irregular_mcap"), &robot, &LogSpec::new(LogFormat::Bag)));
    assert!(
        e.contains("/joint_commands (10 messages)") && e.contains("/joint_states (40 messages)") && e.contains("topic = "),
        "{e}"
    );
    let pick = |p: &str, topic: &str, stamps: BagStamps| {
        let s = LogSpec {
            topic: Some(topic.into()),
            stamps: Some(stamps),
            ..LogSpec::new(LogFormat::Bag)
        };
        read_log(&data(p), &robot, &s)
    };
    let a = pick("irregular_mcap", "/joint_states", BagStamps::Header).unwrap();
    let b = pick("irregular_sqlite3", "joint_states", BagStamps::Header).unwrap();
    assert_eq!(a.rep, b.rep);
    assert_eq!(a.rep.len(), 40);
    let st = a.report.steps.unwrap();
    assert!(!st.uniform && st.min < st.median && st.median < st.max, "{st:?}");
    assert!(st.min >= 0.0014 - 1e-12 && st.max <= 0.0026 + 1e-12, "{st:?}");
    assert!(a.rep.t.windows(2).all(|w| w[1] > w[0]));
    // receive times: the recorder got each message 0.3 ms after its stamp
    let r = pick("irregular_mcap", "/joint_states", BagStamps::Receive).unwrap();
    assert_eq!(r.rep.t, a.rep.t);
    // the other topic lacks a robot joint: the error names it
    let e = err_text(pick("irregular_sqlite3", "/joint_commands", BagStamps::Header));
    assert!(e.contains("message 1 on topic /joint_commands") && e.contains("`wrist_3_joint`"), "{e}");
    let e = err_text(pick("irregular_mcap", "/nothing", BagStamps::Header));
    assert!(
        e.contains("no topic /nothing") && e.contains("/joint_states (sensor_msgs/msg/JointState, 40 messages)"),
        "{e}"
    );
}

#[test]
fn duplicate_stamps_are_an_error_naming_the_message_and_value() {
    let e = err_text(read_log(&data("duplicate_mcap"), &ur5(), &LogSpec::new(LogFormat::Bag)));
    assert!(
        e.contains("message 4 on topic /joint_states") && e.contains("1733400000.133456789 s since the epoch is a duplicate"),
        "{e}"
    );
}

#[test]
fn joints_are_mapped_by_name_and_extra_joints_ignored() {
    let robot = ur5();
    // the robot's joints named differently in the log: the spec maps them
    let mut names: Vec<String> = robot.joints.iter().map(|j| j.name.clone()).collect();
    names.swap(0, 1);
    let spec = LogSpec {
        joints: Some(names),
        ..LogSpec::new(LogFormat::Bag)
    };
    let r = read_log(&data("ur5_mcap"), &robot, &spec).unwrap();
    let want = reference();
    for k in [0, 199, 399] {
        assert_eq!(r.rep.q[k][0], want.q[k][1]);
        assert_eq!(r.rep.tau[k][1], want.tau[k][0]);
    }
    let short = LogSpec {
        joints: Some(vec!["a".into()]),
        ..LogSpec::new(LogFormat::Bag)
    };
    assert!(err_text(read_log(&data("ur5_mcap"), &robot, &short)).contains("1 names for a robot with 6 joints"));
}

#[test]
fn bag_info_lists_topics_joints_and_rates() {
    let i = bag_info(&data("irregular_sqlite3")).unwrap();
    assert_eq!(i.storage, "sqlite3");
    let js = i.topics.iter().find(|t| t.topic == "/joint_states").unwrap();
    assert_eq!(js.messages, 40);
    assert_eq!(js.joint_names.as_ref().unwrap()[3], "gripper_finger_joint");
    assert!(!js.steps.unwrap().uniform);
    let u = bag_info(&data("ur5_mcap")).unwrap();
    let notes = u.topics.iter().find(|t| t.topic == "/notes").unwrap();
    assert_eq!((notes.msg_type.as_str(), notes.messages), ("std_msgs/msg/String", 3));
    let js = u.topics.iter().find(|t| t.topic == "/joint_states").unwrap();
    assert!((js.span.unwrap() - 399.0 * 0.005).abs() < 1e-12);
    assert!((1.0 / js.steps.unwrap().mean - 200.0).abs() < 1e-9);
    let d = bag_info(&data("duplicate_mcap")).unwrap();
    assert!(d.topics[0].problems[0].contains("1 header stamps not after"), "{:?}", d.topics[0].problems);
    assert!(i.text().contains("/joint_commands"));
}

/// Identification of the UR5 base parameters (36 + 12 drive) from a run, by
/// the study engine: a one-experiment design with the run in memory,
/// per-joint least-squares weights.
fn identify(run: &Run) -> idexp::ident::Estimate {
    use idexp::ident::study::{run_study_with, ExperimentSpec, Given, Inputs, StudyDesign};
    let mut e = ExperimentSpec::new(vec![]);
    e.name = "run".into();
    let d = StudyDesign::one_experiment("ur5", "ur5_drives.toml".into(), e).repetition_weighted(idexp::ident::Weights::Joint);
    let mut inputs = Inputs {
        robot: Some(ur5()),
        ..Default::default()
    };
    inputs.entries.insert(
        "run".into(),
        Given {
            run: run.clone(),
            trajectory: None,
            torque_source: idexp::data::TorqueSource::logged_torques(),
        },
    );
    let r = run_study_with(&d, Path::new(""), &inputs, &idexp::optim::Control::new()).unwrap_or_else(|e| panic!("{e}"));
    r.estimate
}

fn assert_same_estimate(a: &idexp::ident::Estimate, b: &idexp::ident::Estimate, what: &str) {
    assert_eq!(a.names, b.names);
    assert_eq!(a.status, b.status);
    let scale = a.theta.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    for (i, (x, y)) in a.theta.iter().zip(&b.theta).enumerate() {
        assert!((x - y).abs() <= 1e-9 * x.abs().max(1e-6 * scale), "{what}: {} = {x} vs {y}", a.names[i]);
    }
}

#[test]
fn identification_from_a_bag_or_an_rtde_csv_equals_identification_from_the_run_csv() {
    let csv = Run::read(&[data("ur5_idexp.csv")], 6).unwrap();
    let from_csv = identify(&csv);
    assert_eq!(from_csv.status, idexp::ident::EstimateStatus::Ok, "{}", from_csv.text());
    for (what, log) in [
        ("mcap bag", bag("ur5_mcap")),
        ("sqlite3 bag", bag("ur5_sqlite3")),
        ("RTDE CSV", read_log(&data("ur5_rtde.csv"), &ur5(), &LogSpec::new(LogFormat::Rtde)).unwrap()),
    ] {
        let run = Run::new(vec![log.report.file.clone()], vec![log.rep.clone()]).unwrap();
        assert_same_estimate(&identify(&run), &from_csv, what);
        // and through idexp's run CSV written from the log
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("run.csv");
        log.rep.write(&p).unwrap();
        assert_same_estimate(&identify(&Run::read(&[p], 6).unwrap()), &from_csv, &format!("{what} as run CSV"));
    }
}

#[test]
fn specs_are_validated_naming_the_field() {
    let parse = |text: &str| -> idexp::Result<LogSpec> {
        let s: LogSpec = idexp::io::parse_toml(Path::new("map.toml"), text)?;
        s.validate("map.toml")?;
        Ok(s)
    };
    assert!(parse("format = \"rtde\"").is_ok());
    assert!(parse("format = \"bag\"\ntopic = \"/joint_states\"\nstamps = \"receive\"").is_ok());
    let cases = [
        ("format = \"csv\"\ntopic = \"/x\"\nq = \"q{j}\"\ntau = \"t{j}\"", "`topic`", "format bag only"),
        ("format = \"csv\"\nq = \"q\"\ntau = \"tau{j}\"", "`q`", "one {j}"),
        ("format = \"csv\"\nq = \"q{j}\"", "`tau`", "current"),
        ("format = \"csv\"\nq = \"q{j}\"\ntau = \"t{j}\"\ncurrent = \"i{j}\"", "`current`", "not both"),
        ("format = \"csv\"\nq = \"q{j}\"\ntau = \"t{j}\"\nindex_base = 2", "`index_base`", "0 or 1"),
        ("format = \"csv\"\nq = \"q{j}\"\ntau = \"t{j}\"\nqdd = \"a{j}\"", "`qdd`", "qd"),
        ("format = \"headerless\"\ncolumns = [\"q1\", \"tau1\"]", "`columns`", "time"),
        ("format = \"headerless\"\ncolumns = [\"t\", \"x1\"]", "`columns`", "\"x1\""),
        ("format = \"rtde\"\ndelimiter = \"1\"", "`delimiter`", "separator"),
        ("format = \"bag\"\njoints = [\"a\", \"a\"]", "`joints`", "twice"),
    ];
    for (text, field, what) in cases {
        let e = parse(text).unwrap_err().to_string();
        assert!(e.contains(field) && e.contains(what), "{text}: {e}");
    }
    let e = parse("format = \"rtde\"\ntorqe = \"current\"").unwrap_err().to_string();
    assert!(e.contains("torqe"), "{e}");
    let e = parse("format = \"excel\"").unwrap_err().to_string();
    assert!(e.contains("excel"), "{e}");
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn bad_csv_logs_are_refused_naming_file_row_column_and_value() {
    let d = tempfile::tempdir().unwrap();
    let robot = idexp::robot::load(&root("tests/data/rpr_standard.toml")).unwrap();
    let n = robot.dof();
    let spec = LogSpec {
        q: Some("pos{j}".into()),
        tau: Some("trq{j}".into()),
        ..LogSpec::new(LogFormat::Csv)
    };
    let head = format!(
        "t,{},{}\n",
        (1..=n).map(|j| format!("pos{j}")).collect::<Vec<_>>().join(","),
        (1..=n).map(|j| format!("trq{j}")).collect::<Vec<_>>().join(",")
    );
    let row = |t: &str, v: &str| format!("{t},{}\n", vec![v; 2 * n].join(","));
    let cases: Vec<(String, &str, Vec<&str>)> = vec![
        (
            head.clone() + &row("0", "1") + &row("0.01", "1") + &row("0.01", "1"),
            "dup.csv",
            vec!["row 3", "`t`", "0.01 s is a duplicate"],
        ),
        (
            head.clone() + &row("0", "1") + &row("0.02", "1") + &row("0.01", "1"),
            "back.csv",
            vec!["row 3", "0.01 s is before the previous one (0.02)"],
        ),
        (
            head.clone() + &row("0", "1") + &row("0.01", "nan"),
            "nan.csv",
            vec!["row 2", "`pos1`", "finite", "nan"],
        ),
        (head.clone() + &row("0", "1") + &row("x", "1"), "time.csv", vec!["row 2", "`t`", "\"x\""]),
        (head.clone() + &row("0", "1") + "0.01,1\n", "short.csv", vec!["row 2", "expected"]),
        (
            head.replace("pos2", "p2") + &row("0", "1"),
            "miss.csv",
            vec!["row 0", "`pos2`", "missing column", "q = \"pos{j}\""],
        ),
        (head.clone(), "empty.csv", vec!["no samples"]),
        (String::new(), "nothing.csv", vec!["empty file"]),
    ];
    for (text, name, want) in cases {
        let p = write(d.path(), name, &text);
        let e = err_text(read_log(&p, &robot, &spec));
        assert!(e.contains(name), "{name}: {e}");
        for w in want {
            assert!(e.contains(w), "{name}: `{w}` not in: {e}");
        }
    }
    // a binary file and a missing one
    let bin = d.path().join("bin.csv");
    std::fs::write(&bin, [0xffu8, 0xfe, 0, 1, 2, 3]).unwrap();
    assert!(err_text(read_log(&bin, &robot, &spec)).contains("UTF-8"));
    assert!(read_log(&d.path().join("none.csv"), &robot, &spec).is_err());
}

#[test]
fn corrupt_bags_are_errors_not_panics() {
    let d = tempfile::tempdir().unwrap();
    let robot = ur5();
    let spec = LogSpec::new(LogFormat::Bag);
    for src in ["ur5_mcap/ur5_mcap.mcap", "ur5_sqlite3/ur5_sqlite3.db3"] {
        let bytes = std::fs::read(data(src)).unwrap();
        let ext = Path::new(src).extension().unwrap().to_str().unwrap();
        // truncated at several places, and with bytes flipped in the middle
        for cut in [9, 100, bytes.len() / 3, bytes.len() / 2, bytes.len() - 7] {
            let p = d.path().join(format!("cut{cut}.{ext}"));
            std::fs::write(&p, &bytes[..cut]).unwrap();
            let r = read_log(&p, &robot, &spec);
            // MCAP: the reader stops at the cut with an error; sqlite3 may
            // still read every row when only unused page bytes are cut
            assert!(ext == "db3" || r.is_err(), "{src} cut at {cut}");
            let _ = bag_info(&p);
        }
        for at in [bytes.len() / 4, bytes.len() / 2, 3 * bytes.len() / 4] {
            let mut b = bytes.clone();
            for x in &mut b[at..at + 64] {
                *x ^= 0x5a;
            }
            let p = d.path().join(format!("flip{at}.{ext}"));
            std::fs::write(&p, &b).unwrap();
            let _ = read_log(&p, &robot, &spec);
            let _ = bag_info(&p);
        }
    }
    let junk = write(d.path(), "junk.mcap", "not a bag");
    assert!(err_text(read_log(&junk, &robot, &spec)).contains("not a ROS 2 bag file"));
    let empty = d.path().join("emptydir");
    std::fs::create_dir(&empty).unwrap();
    assert!(err_text(read_log(&empty, &robot, &spec)).contains("not a ROS 2 bag"));
    // a bag folder whose metadata names a compressed file
    let c = d.path().join("compressed");
    std::fs::create_dir(&c).unwrap();
    write(
        &c,
        "metadata.yaml",
        "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [a.mcap.zstd]\n  compression_format: zstd\n  compression_mode: FILE\n",
    );
    let e = err_text(read_log(&c, &robot, &spec));
    assert!(e.contains("compression_mode") && e.contains("decompress"), "{e}");
}

#[test]
fn the_cli_converts_a_bag_into_a_run_folder_and_lists_its_topics() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("run");
    let bin = env!("CARGO_BIN_EXE_idexp");
    let o = std::process::Command::new(bin)
        .args(["log", "convert"])
        .arg(data("ur5_sqlite3"))
        .arg("--robot")
        .arg(data("ur5_drives.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let run = Run::read(std::slice::from_ref(&out), 6).unwrap();
    assert_eq!(run.reps[0], reference());
    assert!(out.join("log.json").is_file() && out.join("status.json").is_file());
    let o = std::process::Command::new(bin).args(["log", "info"]).arg(data("ur5_mcap")).output().unwrap();
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("/joint_states (sensor_msgs/msg/JointState): 400 messages") && s.contains("200.00 Hz"),
        "{s}"
    );
    // a bad --format is usage (2), a missing joint an input error (1)
    let o = std::process::Command::new(bin)
        .args(["log", "convert", "x.csv", "--robot", "r.toml", "--format", "excel", "--out", "o"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let o = std::process::Command::new(bin)
        .args(["log", "convert"])
        .arg(data("irregular_mcap"))
        .args(["--topic", "/joint_commands", "--robot"])
        .arg(data("ur5_drives.toml"))
        .arg("--out")
        .arg(d.path().join("x"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("wrist_3_joint"));
}

mod properties {
    use idexp::data::logs::cdr::{decode_joint_state, encode_joint_state, Header, JointState, Time};
    use idexp::data::logs::parse_decimal;
    use proptest::prelude::*;

    fn message() -> impl Strategy<Value = JointState> {
        (
            any::<i32>(),
            0u32..1_000_000_000,
            "[a-z_/]{0,12}",
            proptest::collection::vec(("[a-z_0-9]{1,16}", any::<f64>(), any::<f64>(), any::<f64>()), 0..8),
        )
            .prop_map(|(sec, nanosec, frame_id, j)| JointState {
                header: Header {
                    stamp: Time { sec, nanosec },
                    frame_id,
                },
                name: j.iter().map(|x| x.0.clone()).collect(),
                position: j.iter().map(|x| x.1).collect(),
                velocity: j.iter().map(|x| x.2).collect(),
                effort: j.iter().map(|x| x.3).collect(),
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]

        /// Arbitrary bytes never panic the CDR decoder.
        #[test]
        fn cdr_decoder_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let _ = decode_joint_state(&bytes);
        }

        /// Messages round trip; any truncation or byte change is an error or
        /// another message, never a panic.
        #[test]
        fn cdr_round_trip_and_mutations(m in message(), at in any::<prop::sample::Index>(), x in any::<u8>()) {
            let b = encode_joint_state(&m).unwrap();
            let back = decode_joint_state(&b).unwrap();
            prop_assert_eq!(back.header, m.header.clone());
            prop_assert_eq!(&back.name, &m.name);
            prop_assert_eq!(back.position.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), m.position.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
            let i = at.index(b.len());
            prop_assert!(decode_joint_state(&b[..i]).is_err() || i >= b.len());
            let mut c = b.clone();
            c[i] ^= x;
            let _ = decode_joint_state(&c);
        }

        /// Column patterns: never a panic; with one {j} the name round trips.
        #[test]
        fn column_patterns(p in "\\PC{0,20}", q in "[a-z_]{0,8}", s in "[a-z_]{0,8}", j in 0usize..100) {
            let _ = idexp::data::logs::LogSpec { q: Some(p), tau: Some("t{j}".into()), ..idexp::data::logs::LogSpec::new(idexp::data::logs::LogFormat::Csv) }.validate("p");
            let spec = idexp::data::logs::LogSpec { q: Some(format!("{q}{{j}}{s}")), tau: Some("t{j}".into()), ..idexp::data::logs::LogSpec::new(idexp::data::logs::LogFormat::Csv) };
            prop_assert!(spec.validate("p").is_ok());
            let _ = j;
        }

        /// Decimals: never a panic; integers and fixed-point texts exact.
        #[test]
        fn decimals(s in "\\PC{0,24}", i in -1_000_000_000_000i64..1_000_000_000_000, f in 0u32..1_000_000_000) {
            let _ = parse_decimal(&s);
            let d = parse_decimal(&format!("{i}.{f:09}")).unwrap();
            let sign: i128 = if i < 0 { -1 } else { 1 };
            prop_assert_eq!(d.mantissa, i128::from(i) * 1_000_000_000 + sign * i128::from(f));
            prop_assert_eq!(d.exponent, -9);
        }
    }
}
