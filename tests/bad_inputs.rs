//! Bad inputs (resources, hangs, messages) tried again: each is
//! refused with exit code 1 and a message naming the file or field, the value
//! and what is allowed, under a 4 GB address-space limit and within 10 s.
#![cfg(all(feature = "cli", unix))]

mod common;
use common::root;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs idexp under `ulimit -v 4000000` (KiB) and a 10 s wall-clock bound;
/// returns (exit code, stderr).
fn limited(args: &[&str]) -> (Option<i32>, String) {
    let mut c = Command::new("sh");
    c.arg("-c")
        .arg("ulimit -v 4000000; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_idexp"))
        .args(args)
        .current_dir(root(""))
        .env("IDEXP_NO_PROGRESS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    let mut child = c.spawn().unwrap();
    let t0 = Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
            return (st.code(), err);
        }
        if t0.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{args:?} ran past 10 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn refused(args: &[&str], needles: &[&str]) {
    let (code, err) = limited(args);
    assert_eq!(code, Some(1), "{args:?}: exit {code:?}\n{err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
}

/// designs/sim_rpr_pick_place.toml with `from` replaced by `to`, written to `dir`.
fn sim_variant(dir: &Path, name: &str, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(root("designs/sim_rpr_pick_place.toml")).unwrap();
    assert!(text.contains(from), "{from}");
    let robot = root("tests/data/ident/rpr_drives_tanh.toml");
    let text = text
        .replace(from, to)
        .replace("\"../tests/data/ident/rpr_drives_tanh.toml\"", &format!("{:?}", robot.to_str().unwrap()));
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn a_robot_file_naming_a_device_is_refused_without_reading_it() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("zero.toml");
    std::fs::write(&p, "name = \"zero\"\nurdf = \"/dev/zero\"\n").unwrap();
    refused(&["robot", "info", p.to_str().unwrap()], &["/dev/zero", "not a regular file"]);
}

#[test]
fn simulate_bounds_are_checked_before_allocating() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let o = out.to_str().unwrap();
    let d = sim_variant(tmp.path(), "dwell.toml", "dwell = 0.2", "dwell = 1e308");
    refused(&["simulate", &d, "--out", o], &["dwell.toml", "reference.dwell", "3600"]);
    let d = sim_variant(tmp.path(), "rate.toml", "rate = 1000.0", "rate = 1e9");
    refused(&["simulate", &d, "--out", o], &["rate.toml", "`rate`", "100000"]);
    let d = sim_variant(tmp.path(), "long.toml", "cycles = 4", "cycles = 90000");
    refused(&["simulate", &d, "--out", o], &["long.toml", "at most"]);
    let d = sim_variant(tmp.path(), "filter.toml", "[truth]", "[controller]\nvelocity_filter = 900.0\n\n[truth]");
    refused(&["simulate", &d, "--out", o], &["filter.toml", "velocity_filter", "Nyquist", "500"]);
    assert!(!out.exists(), "a refused run wrote its folder");
}

#[test]
fn fit_starts_are_bounded_before_allocating() {
    refused(
        &[
            "fit",
            "designs/elastic_industrial6.toml",
            "--starts",
            "1000000000",
            "--out",
            "/nonexistent/idexp",
        ],
        &["--starts", "1000000000", "1..=100000"],
    );
}

#[test]
fn a_missing_file_prints_the_os_message_once() {
    let (code, err) = limited(&["robot", "info", "no/such/robot.toml"]);
    assert_eq!(code, Some(1));
    assert!(err.contains("no/such/robot.toml"), "{err}");
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
}

#[test]
fn json_inputs_with_a_byte_order_mark_are_read() {
    let tmp = tempfile::tempdir().unwrap();
    let src = std::fs::read(root("designs/positions_example_information.json")).unwrap();
    let mut bom = vec![0xEF, 0xBB, 0xBF];
    bom.extend(src);
    let p = tmp.path().join("info.json");
    std::fs::write(&p, &bom).unwrap();
    let text = idexp::io::read_to_string(&p).unwrap();
    assert!(text.starts_with(['{', '[']), "{}", &text[..10]);
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(!v.is_null());
}

/// `src` (relative to the repository) with each `(from, to)` replaced, written
/// to `dir/name`; every `from` must occur.
fn variant(dir: &Path, src: &str, name: &str, edits: &[(&str, &str)]) -> String {
    let mut text = std::fs::read_to_string(root(src)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from} not in {src}");
        text = text.replacen(from, to, 1);
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// `robot info` on a variant of `src` is refused with exit 1 and a message
/// holding the file name and every needle.
fn robot_refused(src: &str, name: &str, edits: &[(&str, &str)], needles: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let p = variant(tmp.path(), src, name, edits);
    let mut all = vec![name];
    all.extend_from_slice(needles);
    refused(&["robot", "info", &p], &all);
}

const TREE: &str = "tests/data/tree.urdf";

#[test]
fn urdf_non_finite_joint_origins_are_refused() {
    for v in ["nan", "inf", "-inf"] {
        let to = format!("<origin xyz=\"{v} 0.2 0.4\" rpy=\"0.3 0 0.2\"/>");
        robot_refused(
            TREE,
            "origin.urdf",
            &[("<origin xyz=\"0.1 0.2 0.4\" rpy=\"0.3 0 0.2\"/>", &to)],
            &["joint `shoulder_a` <origin>", "finite"],
        );
    }
    robot_refused(
        TREE,
        "origin_rpy.urdf",
        &[(
            "<origin xyz=\"0 0 0.1\"/><axis xyz=\"1 0 0\"/>",
            "<origin xyz=\"0 0 0.1\" rpy=\"0 NaN 0\"/><axis xyz=\"1 0 0\"/>",
        )],
        &["joint `elbow_b` <origin>", "finite"],
    );
}

#[test]
fn urdf_negative_or_impossible_inertia_is_refused() {
    let arm = "<inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.05\"";
    robot_refused(
        TREE,
        "neg.urdf",
        &[(arm, "<inertia ixx=\"-0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.05\"")],
        &["link `arm_a` <inertia>", "not positive semidefinite"],
    );
    // 0.2 > 0.05 + 0.05: positive, but no rigid body has it; published lumped
    // models (the PUMA 560's link 3) do, so it is read with a warning
    let tmp = tempfile::tempdir().unwrap();
    let p = variant(
        tmp.path(),
        TREE,
        "triangle.urdf",
        &[(arm, "<inertia ixx=\"0.2\" ixy=\"0\" ixz=\"0\" iyy=\"0.05\"")],
    );
    let out = Command::new(env!("CARGO_BIN_EXE_idexp")).args(["robot", "info", &p]).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{text}");
    assert!(text.contains("link `arm_a`: physically inconsistent inertia"), "{text}");
}

#[test]
fn urdf_duplicate_joint_names_are_refused() {
    robot_refused(
        TREE,
        "dup.urdf",
        &[("<joint name=\"elbow_b\"", "<joint name=\"shoulder_a\"")],
        &["line 30, column 3: joint `shoulder_a` is defined twice", "first at line 18"],
    );
}

#[test]
fn urdf_mimic_joints_in_the_arm_are_refused_with_the_reason() {
    robot_refused(
        TREE,
        "mimic.urdf",
        &[(
            "effort=\"50\" velocity=\"3\"/>",
            "effort=\"50\" velocity=\"3\"/><mimic joint=\"shoulder_a\" multiplier=\"2\"/>",
        )],
        &[
            "joint `elbow_b` <mimic> (line 30, column 191)",
            "only when it is all that moves below the link carrying it (a gripper's fingers on `torso`)",
            "joint `slide_b` moves below `torso` too",
            "independent",
        ],
    );
}

#[test]
fn urdf_zero_velocity_is_not_read_as_no_limit() {
    robot_refused(
        TREE,
        "vel0.urdf",
        &[("effort=\"50\" velocity=\"3\"", "effort=\"50\" velocity=\"0\"")],
        &["joint `elbow_b` <limit velocity>", "positive", "found 0", "not \"no limit\""],
    );
}

#[test]
fn urdf_negative_effort_or_damping_is_refused() {
    robot_refused(
        TREE,
        "effort.urdf",
        &[("effort=\"50\"", "effort=\"-50\"")],
        &["joint `elbow_b` <limit effort>", "found -50"],
    );
    robot_refused(
        TREE,
        "damping.urdf",
        &[("damping=\"0.5\"", "damping=\"-0.5\"")],
        &["joint `shoulder_a` <dynamics damping>", "≥ 0", "found -0.5"],
    );
}

#[test]
fn urdf_unclosed_tags_are_located_by_line_and_column() {
    robot_refused(
        TREE,
        "unclosed.urdf",
        &[("</robot>", "")],
        &["<robot> opened at line 5, column 1", "never closed"],
    );
    robot_refused(
        TREE,
        "mismatch.urdf",
        &[("<link name=\"hand_a\">", "<link name=\"hand_a\"><visual>")],
        &["malformed URDF at line 21, column 3", "expected `</visual>`"],
    );
}

const RPR: &str = "tests/data/rpr_standard.toml";

#[test]
fn robot_toml_non_psd_inertia_is_refused() {
    robot_refused(
        RPR,
        "psd.toml",
        &[("inertia = [0.001, 0.0, 0.0, 0.004", "inertia = [-0.001, 0.0, 0.0, 0.004")],
        &["link `link3` inertia", "not positive semidefinite"],
    );
}

#[test]
fn robot_toml_degenerate_or_half_open_limits_are_refused() {
    robot_refused(
        RPR,
        "equal.toml",
        &[("lower = -2.0\nupper = 2.0", "lower = 2.0\nupper = 2.0")],
        &["joint `wrist` limits", "lower 2 ≥ upper 2"],
    );
    robot_refused(
        RPR,
        "inf.toml",
        &[("lower = -2.0\nupper = 2.0", "lower = -2.0\nupper = inf")],
        &["joint `wrist` limits", "upper inf", "both position limits"],
    );
}

#[test]
fn robot_toml_negative_friction_is_refused() {
    robot_refused(
        "tests/data/ident/rpr_drives.toml",
        "fc.toml",
        &[("fc = 1.5", "fc = -1.5")],
        &["drive of joint `base` fc", "≥ 0", "found -1.5"],
    );
}

#[test]
fn robot_toml_bad_frames_are_refused() {
    let frame = |name: &str, xyz: &str| format!("\n[[frame]]\nname = \"{name}\"\nlink = \"link3\"\nxyz = {xyz}\n");
    let nan = format!("{}{}", "inertia = [0.001, 0.0, 0.0, 0.004, 0.0, 0.004] }", frame("tool", "[nan, 0.0, 0.0]"));
    robot_refused(
        RPR,
        "nan_frame.toml",
        &[("inertia = [0.001, 0.0, 0.0, 0.004, 0.0, 0.004] }", &nan)],
        &["frame `tool` xyz/rpy", "finite"],
    );
    let dup = format!(
        "{}{}{}",
        "inertia = [0.001, 0.0, 0.0, 0.004, 0.0, 0.004] }",
        frame("tool", "[0.1, 0.0, 0.0]"),
        frame("tool", "[0.2, 0.0, 0.0]")
    );
    robot_refused(
        RPR,
        "dup_frame.toml",
        &[("inertia = [0.001, 0.0, 0.0, 0.004, 0.0, 0.004] }", &dup)],
        &["frame `tool`", "duplicate frame name"],
    );
}

#[test]
fn robot_toml_near_singular_coupling_is_refused_with_its_condition_number() {
    robot_refused(
        RPR,
        "coupling.toml",
        &[(
            "dh = \"standard\"",
            "dh = \"standard\"\ncoupling = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1e-15]]",
        )],
        &["field `coupling`", "condition number 1.000e15", "≤ 1e8"],
    );
    // exactly singular: the file is named (not only the robot)
    robot_refused(
        RPR,
        "singular.toml",
        &[(
            "dh = \"standard\"",
            "dh = \"standard\"\ncoupling = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]",
        )],
        &["field `coupling`", "singular"],
    );
}

#[test]
fn robot_toml_absurd_gravity_is_refused() {
    robot_refused(
        RPR,
        "gravity.toml",
        &[("dh = \"standard\"", "dh = \"standard\"\ngravity = [0.0, 0.0, 1e308]")],
        &["field `gravity`", "1e308", "≤ 981"],
    );
}

/// designs/elastic_industrial6.toml with `(from, to)` edits and the robot path made absolute.
fn elastic_variant(dir: &Path, name: &str, edits: &[(&str, &str)]) -> String {
    let robot = root("designs/robots/industrial6.toml");
    let abs = format!("robot = {:?}", robot.to_str().unwrap());
    let mut all: Vec<(&str, &str)> = vec![("robot = \"robots/industrial6.toml\"", abs.as_str())];
    all.extend_from_slice(edits);
    variant(dir, "designs/elastic_industrial6.toml", name, &all)
}

fn fit_refused(name: &str, edits: &[(&str, &str)], needles: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let d = elastic_variant(tmp.path(), name, edits);
    let out = tmp.path().join("o");
    let mut all = vec![name];
    all.extend_from_slice(needles);
    refused(&["fit", &d, "--out", out.to_str().unwrap(), "--starts", "2"], &all);
}

#[test]
fn elastic_unknown_damper_at_zero_is_refused() {
    fit_refused(
        "d0.toml",
        &[("k = 3.0e5\nd = 120.0", "k = 3.0e5\nd = 0.0")],
        &["unknown `d_a1`", "nominal value is 0", "log space"],
    );
}

#[test]
fn elastic_non_psd_payload_inertia_is_refused() {
    fit_refused(
        "payload.toml",
        &[("inertia = [0.08, 0.0, 0.0, 0.08, 0.0, 0.05]", "inertia = [-0.08, 0.0, 0.0, 0.08, 0.0, 0.05]")],
        &["payload.inertia", "not positive semidefinite"],
    );
}

/// A payload far outside the robot (a mutation the fuzz test found):
/// refused naming the file and the field, not the robot's link.
#[test]
fn elastic_payload_com_overflowing_the_link_inertia_is_refused() {
    fit_refused(
        "com.toml",
        &[("com = [0.0, 0.0, 0.2]", "com = [1e308, 0.0, 0.2]")],
        &["payload.com", "overflows"],
    );
}

#[test]
fn arrays_longer_than_their_field_are_refused() {
    fit_refused(
        "band.toml",
        &[("band = [3.0, 150.0]", "band = [2.0, 40.0, 60.0]")],
        &["`fit.user.band`", "3 elements", "more than the field takes"],
    );
    robot_refused(
        RPR,
        "gravity4.toml",
        &[("dh = \"standard\"", "dh = \"standard\"\ngravity = [0.0, 0.0, -9.81, 5.0]")],
        &["line 4: `gravity`", "4 elements"],
    );
}

/// designs/positions_file_d.toml with edits, next to a copy of its
/// information file (or `info`, when given) and the robots.
fn positions_refused(name: &str, edits: &[(&str, &str)], info: Option<&str>, needles: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(root("designs/robots"), tmp.path().join("robots")).unwrap();
    let json = match info {
        Some(t) => t.to_string(),
        None => std::fs::read_to_string(root("designs/positions_example_information.json")).unwrap(),
    };
    std::fs::write(tmp.path().join("positions_example_information.json"), json).unwrap();
    let d = variant(tmp.path(), "designs/positions_file_d.toml", name, edits);
    let out = tmp.path().join("o");
    refused(&["positions", &d, "--out", out.to_str().unwrap()], needles);
    assert!(!out.join("positions_file_d").join("plan.csv").exists());
}

#[test]
fn positions_sdp_with_criterion_a_is_refused() {
    positions_refused(
        "sdp.toml",
        &[
            ("criterion = \"d\"", "criterion = \"a\""),
            (
                "path = \"positions_example_information.json\"",
                "path = \"positions_example_information.json\"\n\n[solver]\nformulation = \"sdp\"",
            ),
        ],
        None,
        &["sdp.toml", "solver.formulation", "criterion = \"a\""],
    );
}

#[test]
fn positions_too_few_experiments_are_refused_not_reported_optimal() {
    // 300 candidates of rank 3, p = 8: one experiment reaches rank 3 at most
    positions_refused(
        "one.toml",
        &[("experiments = 10", "experiments = 1")],
        None,
        &["field `experiments`", "rank ≤ 3 < p = 8", "expected experiments ≥ 3"],
    );
}

#[test]
fn positions_candidates_without_full_joint_rank_are_refused_with_the_cause() {
    // two candidates of rank 6 spanning the same 6 of p = 8 directions (rows
    // e_i + e_7/2 + e_8/2: every parameter has information, jointly rank 6)
    let row = |i: usize| {
        (0..8)
            .map(|j| {
                if j == i {
                    "1.0"
                } else if j >= 6 {
                    "0.5"
                } else {
                    "0.0"
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let jac = (0..6).map(|i| format!("[{}]", row(i))).collect::<Vec<_>>().join(", ");
    let cand = |q: f64| format!("{{\"q\": [{q}, -1.2, 0.2, 0.0, 0.5, 0.0], \"jacobian\": [{jac}]}}");
    let info = format!(
        "{{\"parameters\": [\"k1\", \"k2\", \"k3\", \"k4\", \"d1\", \"d2\", \"d3\", \"d4\"], \"candidates\": [{}, {}]}}",
        cand(0.0),
        cand(0.5)
    );
    positions_refused(
        "rank.toml",
        &[],
        Some(&info),
        &["field `candidates`", "all 2 candidates together has rank 6 < p = 8", "6 ×2"],
    );
}

/// A simulated run of designs/sim_rpr_fourier.toml in `dir` (its folder).
fn rpr_run(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("run");
    let st = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args([
            "simulate",
            root("designs/sim_rpr_fourier.toml").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .env("IDEXP_NO_PROGRESS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(st.success());
    out
}

#[test]
fn identify_argument_mismatches_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let run = rpr_run(tmp.path());
    let robot = root("tests/data/ident/rpr_drives.toml");
    let (r, d) = (robot.to_str().unwrap(), run.to_str().unwrap());
    // a trajectory of another robot (6 joints) on this 3-joint run
    let mut t: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("trajectory.json")).unwrap()).unwrap();
    for key in ["a", "b", "q0"] {
        let rows = t["trajectory"][key].as_array().unwrap().clone();
        t["trajectory"][key] = serde_json::Value::Array(rows.iter().chain(rows.iter()).cloned().collect());
    }
    let six = tmp.path().join("six.json");
    std::fs::write(&six, serde_json::to_string(&t).unwrap()).unwrap();
    refused(
        &[
            "identify",
            r,
            d,
            "--trajectory",
            six.to_str().unwrap(),
            "--out",
            tmp.path().join("o").to_str().unwrap(),
        ],
        // the one-run form is a one-experiment study: its errors name the
        // study key (`trajectory`) of the flag (--trajectory)
        &["field `trajectory`", "six.json", "6 joints", "3 in robot"],
    );
    refused(
        &[
            "identify",
            r,
            d,
            "--reduce",
            "--essential",
            "Fc1,Fc1",
            "--out",
            tmp.path().join("o").to_str().unwrap(),
        ],
        &["field `essential`", "`Fc1` is listed twice"],
    );
    // one repetition without variance columns: the one-run form names its own way out
    let one = run.join("rep_001.csv");
    refused(
        &["identify", r, one.to_str().unwrap(), "--out", tmp.path().join("o1").to_str().unwrap()],
        &["field `weights`", "one repetition", "--weights joint"],
    );
}

#[test]
fn excite_into_an_existing_file_is_refused_before_the_search() {
    let tmp = tempfile::tempdir().unwrap();
    let f = tmp.path().join("file");
    std::fs::write(&f, "keep").unwrap();
    // the bench design searches for 10 s: a refusal within the 10 s bound is up front
    refused(
        &["excite", "designs/excite_ur5_bench.toml", "--out", f.to_str().unwrap()],
        &["field `output folder`", "exists and is not a folder"],
    );
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "keep");
}

#[test]
fn excite_with_limits_leaving_no_excitation_is_unusable_not_feasible() {
    let tmp = tempfile::tempdir().unwrap();
    let robot = root("designs/robots/ur5.toml");
    let abs = format!("robot = {:?}", robot.to_str().unwrap());
    let d = variant(
        tmp.path(),
        "designs/excite_ur5_bench.toml",
        "tiny.toml",
        &[
            ("robot = \"robots/ur5.toml\"", abs.as_str()),
            ("time_limit = 10.0", "time_limit = 2.0"),
            ("velocity = 1.0", "velocity = 1e-9"),
        ],
    );
    let out = tmp.path().join("o");
    let (code, err) = limited(&["excite", &d, "--out", out.to_str().unwrap()]);
    // exit 3: finished without a usable result (not "feasible: cond 1e12")
    assert_eq!(code, Some(3), "exit {code:?}\n{err}");
    for n in ["INFEASIBLE", "no trajectory within these limits excites", "rank-deficient", "limits.velocity"] {
        assert!(err.contains(n), "`{n}` not in\n{err}");
    }
    let status = std::fs::read_to_string(out.join("status.json")).unwrap();
    assert!(status.contains("infeasible") && status.contains("rank-deficient"), "{status}");
}

#[test]
fn gravity_experiment_on_a_fourier_run_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let run = rpr_run(tmp.path());
    let robot = root("tests/data/ident/rpr_drives.toml");
    let out = tmp.path().join("o");
    refused(
        &[
            "identify",
            robot.to_str().unwrap(),
            run.to_str().unwrap(),
            "--experiment",
            "gravity",
            "--joint",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[
            run.to_str().unwrap(),
            "gravity experiment",
            "not a gravity-slopes run of joint 2",
            "moves too",
            "at rest",
        ],
    );
    // refused before any output: no folder left behind
    assert!(!out.exists(), "{} was created by a refused experiment", out.display());
}

#[test]
fn identify_with_no_row_fast_enough_names_the_speed_rule() {
    let tmp = tempfile::tempdir().unwrap();
    let run = rpr_run(tmp.path());
    let robot = root("tests/data/ident/rpr_drives.toml");
    let out = tmp.path().join("o");
    let (r, d, o) = (robot.to_str().unwrap(), run.to_str().unwrap(), out.to_str().unwrap());
    // a run at rest: the first repetition with every position held at its first value
    let text = std::fs::read_to_string(run.join("rep_001.csv")).unwrap();
    let mut lines = text.lines();
    let head = lines.next().unwrap();
    let cols: Vec<&str> = head.split(',').collect();
    let first: Vec<String> = text.lines().nth(1).unwrap().split(',').map(str::to_string).collect();
    let mut rest = format!("{head}\n");
    for l in lines {
        let v: Vec<&str> = l
            .split(',')
            .enumerate()
            .map(|(c, x)| {
                if cols[c].starts_with('q') || cols[c].starts_with('r') {
                    first[c].as_str()
                } else {
                    x
                }
            })
            .collect();
        rest.push_str(&v.join(","));
        rest.push('\n');
    }
    let rest_csv = tmp.path().join("rest.csv");
    std::fs::write(&rest_csv, rest).unwrap();
    let rc = rest_csv.to_str().unwrap();
    let (code, err) = limited(&["identify", r, rc, "--method", "ols", "--out", o]);
    assert_eq!(code, Some(1), "exit {code:?}\n{err}");
    for n in [
        "rest.csv",
        "no row is fast enough",
        "0 of 6000 rows",
        "0.01 rad/s",
        "[0.000e0, 0.000e0, 0.000e0]",
    ] {
        assert!(err.contains(n), "`{n}` not in\n{err}");
    }
    for extra in [&["--min-speed", "1e9", "--standstill", "drop"][..], &["--min-speed", "1e9"][..]] {
        let mut args = vec!["identify", r, d, "--out", o];
        args.extend_from_slice(extra);
        let (code, err) = limited(&args);
        assert_eq!(code, Some(1), "{args:?}: exit {code:?}\n{err}");
        assert!(!err.contains("too short"), "{err}");
        for n in ["no row is fast enough", "min_speed", "1000000000 rad/s", "largest |q̇_j|"] {
            assert!(err.contains(n), "{args:?}: `{n}` not in\n{err}");
        }
    }
}

#[test]
fn elastic_controller_bandwidth_above_nyquist_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let robot = root("designs/robots/industrial6.toml");
    let abs = format!("robot = {:?}", robot.to_str().unwrap());
    let d = variant(
        tmp.path(),
        "designs/elastic_industrial6_time.toml",
        "bw.toml",
        &[("robot = \"robots/industrial6.toml\"", abs.as_str()), ("bandwidth = 3.0", "bandwidth = 900.0")],
    );
    let out = tmp.path().join("o");
    let o = out.to_str().unwrap();
    let needles = ["bw.toml", "simulate.bandwidth", "Nyquist", "500 Hz", "900 Hz"];
    refused(&["frf", &d, "--out", o], &needles);
    refused(&["fit", &d, "--out", o, "--starts", "2"], &needles);
}

#[test]
fn merge_names_the_truncated_shard() {
    let tmp = tempfile::tempdir().unwrap();
    let d = elastic_variant(tmp.path(), "el.toml", &[]);
    let out = tmp.path().join("o");
    let o = out.to_str().unwrap();
    let ok = |args: &[&str]| {
        let (code, err) = limited(args);
        assert_eq!(code, Some(0), "{args:?}: {err}");
    };
    ok(&["frf", &d, "--out", o]);
    ok(&["fit", &d, "--out", o, "--starts", "4", "--shard", "0/2"]);
    ok(&["fit", &d, "--out", o, "--starts", "4", "--shard", "1/2"]);
    let dir = out.join("fit_lls_user");
    let (s0, s1) = (dir.join("starts.shard-0-of-2.jsonl"), dir.join("starts.shard-1-of-2.jsonl"));
    // cut the second shard's last record short
    let text = std::fs::read_to_string(&s1).unwrap();
    std::fs::write(&s1, &text[..text.len() - 30]).unwrap();
    let (code, err) = limited(&[
        "merge",
        s0.to_str().unwrap(),
        s1.to_str().unwrap(),
        "--out",
        tmp.path().join("m").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("starts.shard-1-of-2.jsonl"), "{err}");
    assert!(!err.contains("starts.shard-0-of-2.jsonl"), "{err}");
    assert!(err.contains("1 of 4 starts missing"), "{err}");
}

/// Every design kind with `robot` (or `[model] robot`) naming a file that
/// does not exist: exit 1, and the message names the design file, the field,
/// the path as written and what it resolved to (relative to the design's
/// folder). A robot file whose `urdf` is missing likewise.
#[test]
fn a_missing_robot_path_names_the_design_file_and_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let out = out.to_str().unwrap();
    // (design, robot line as shipped, field, command before the design, after it)
    type Case<'a> = (&'a str, &'a str, &'a str, &'a [&'a str], &'a [&'a str]);
    let cases: [Case; 8] = [
        ("designs/excite_ur5.toml", "robot = \"robots/ur5.toml\"", "robot", &["excite"], &["--out", out]),
        (
            "designs/payload_ur5_excite.toml",
            "robot = \"robots/ur5.toml\"",
            "robot",
            &["payload", "excite"],
            &["--out", out],
        ),
        (
            "designs/payload_ur5.toml",
            "robot = \"robots/ur5.toml\"",
            "robot",
            &["payload", "identify"],
            &["--out", out],
        ),
        (
            "designs/study_rpr.toml",
            "robot = \"../tests/data/ident/rpr_drives.toml\"",
            "robot",
            &["identify"],
            &["--out", out],
        ),
        (
            "designs/sim_rpr_fourier.toml",
            "robot = \"../tests/data/ident/rpr_drives.toml\"",
            "robot",
            &["simulate"],
            &["--out", out],
        ),
        (
            "designs/positions_industrial6_rigid.toml",
            "robot = \"robots/industrial6.toml\"",
            "robot",
            &["positions"],
            &["--out", out],
        ),
        (
            "designs/elastic_industrial6.toml",
            "robot = \"robots/industrial6.toml\"",
            "model.robot",
            &["frf"],
            &["--out", out],
        ),
        (
            "designs/elastic_industrial6.toml",
            "robot = \"robots/industrial6.toml\"",
            "model.robot",
            &["fit"],
            &["--out", out],
        ),
    ];
    for (k, (src, line, field, before, after)) in cases.iter().enumerate() {
        let name = format!("design_{k}.toml");
        let p = variant(tmp.path(), src, &name, &[(line, "robot = \"robots/no_such_robot.toml\"")]);
        let mut args: Vec<&str> = before.to_vec();
        args.push(&p);
        args.extend_from_slice(after);
        let resolved = tmp.path().join("robots/no_such_robot.toml");
        refused(
            &args,
            &[
                &p,
                &format!("field `{field}`"),
                "`robots/no_such_robot.toml` does not exist",
                &resolved.display().to_string(),
            ],
        );
    }
    // a robot file's `urdf`
    let robot = tmp.path().join("robot.toml");
    std::fs::write(&robot, "urdf = \"urdf/arm.urdf\"\n").unwrap();
    refused(
        &["robot", "info", robot.to_str().unwrap()],
        &[robot.to_str().unwrap(), "field `urdf`", "`urdf/arm.urdf` does not exist", "(no folder "],
    );
    // an excite design's obstacle mesh
    let p = variant(
        tmp.path(),
        "designs/excite_ur5.toml",
        "mesh.toml",
        &[
            (
                "robot = \"robots/ur5.toml\"",
                &format!("robot = {:?}", root("designs/robots/ur5.toml").to_str().unwrap()),
            ),
            (
                "[collision]\nmargin = 0.01\n",
                "[collision]\nmargin = 0.01\nobstacle = [{ name = \"fixture\", shape = { type = \"mesh\", file = \"cell/fixture.stl\" } }]\n",
            ),
        ],
    );
    let (code, err) = limited(&["excite", &p, "--out", out]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains(&p) && err.contains("field `collision.obstacle[0].shape.file`") && err.contains("`cell/fixture.stl` does not exist"),
        "{err}"
    );
}
