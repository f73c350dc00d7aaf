//! The command line's grammar through the `idexp` binary: one `status.json`
//! schema in every output folder, the documented exit codes (0 success,
//! 1 input error, 2 usage, 3 result not usable), `--out` as the folder that
//! receives the files, `--json` reports, and the old flag spellings kept as
//! hidden aliases.
#![cfg(feature = "cli")]

mod common;

use common::root;
use idexp::io::status::{RunState, StatusFile};
use std::path::Path;
use std::process::{Command, Output};

fn idexp() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.env("IDEXP_NO_PROGRESS", "1").current_dir(root(""));
    c
}

fn run(c: &mut Command) -> Output {
    c.output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Reads `dir/status.json` with the common schema (unknown fields are an error).
fn status(dir: &Path) -> StatusFile {
    StatusFile::read(&dir.join("status.json")).unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
}

fn assert_common(s: &StatusFile, command: &str, state: RunState) {
    assert_eq!(s.command, command);
    assert_eq!(s.status, state, "{s:?}");
    assert_eq!(s.idexp_version, env!("CARGO_PKG_VERSION"));
    assert_eq!(s.design_fingerprint.len(), 16, "{s:?}");
    assert!(s.finished.ends_with('Z') && s.finished.len() == 20, "{s:?}");
    assert!(s.summary.is_object(), "{s:?}");
}

#[test]
fn every_output_folder_has_the_one_status_schema() {
    let d = tempfile::tempdir().unwrap();
    // positions
    let pos = d.path().join("pos");
    let o = run(idexp().args(["positions", "designs/positions_file_d.toml", "--out"]).arg(&pos));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = status(&pos);
    assert_common(&s, "positions", RunState::Complete);
    assert!(s.started.is_some());
    // multisine (writes <out>/multisine)
    let el = d.path().join("el");
    let o = run(idexp().args(["multisine", "designs/elastic_industrial6.toml", "--out"]).arg(&el));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_common(&status(&el.join("multisine")), "multisine", RunState::Complete);
    // simulate: a short run
    let design = d.path().join("sim.toml");
    let text = std::fs::read_to_string(root("designs/sim_rpr_fourier.toml"))
        .unwrap()
        .replace(
            "../tests/data/ident/rpr_drives.toml",
            root("tests/data/ident/rpr_drives.toml").to_str().unwrap(),
        )
        .replace("repetitions = 50", "repetitions = 2")
        .replace("frequency = 0.1", "frequency = 0.5");
    std::fs::write(&design, text).unwrap();
    let sim = d.path().join("sim");
    let o = run(idexp().arg("simulate").arg(&design).arg("--out").arg(&sim).arg("--json"));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let js: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap_or_else(|e| panic!("--json is not JSON: {e}\n{}", stdout(&o)));
    assert_eq!(js["repetitions"], 2);
    assert_common(&status(&sim), "simulate", RunState::Complete);
    // identify on it, with the old spelling of --reduce-tol
    let id = d.path().join("id");
    let o = run(idexp()
        .args(["identify", "tests/data/ident/rpr_drives.toml"])
        .arg(&sim)
        .args(["--reduce", "--tol", "0.05", "--out"])
        .arg(&id));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("weighted least squares"), "human words, not enum names: {}", stdout(&o));
    assert_common(&status(&id), "identify", RunState::Complete);
}

#[test]
fn exit_codes_are_the_documented_ones() {
    // 2: usage (clap)
    let o = run(idexp().args(["robot", "info", "designs/robots/puma560.toml", "--no-such-flag"]));
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = run(idexp().args(["identify", "designs/robots/puma560.toml", "x", "--method", "magic"]));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("ols, wls, projection or ml"), "{}", stderr(&o));
    // 1: error in the input, with the file named
    let o = run(idexp().args(["robot", "info", "designs/robots/no_such_robot.toml"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no_such_robot.toml"), "{}", stderr(&o));
    // 3: an INFEASIBLE excitation design (q0 outside the allowed positions)
    let d = tempfile::tempdir().unwrap();
    let design = d.path().join("infeasible.toml");
    let text = std::fs::read_to_string(root("designs/excite_ur5.toml"))
        .unwrap()
        .replace("robots/ur5.toml", root("designs/robots/ur5.toml").to_str().unwrap())
        .replace(
            "q0 = [0.0, -1.5707963267948966, 0.0, -1.5707963267948966, 0.0, 0.0]",
            "q0 = [0.0, -1.5707963267948966, 2.9, -1.5707963267948966, 0.0, 0.0]",
        )
        .replace("population = 32", "population = 8")
        .replace("generations = 20", "generations = 2")
        .replace("algorithm = \"slsqp\"", "algorithm = \"none\"");
    std::fs::write(&design, text).unwrap();
    let out = d.path().join("out");
    let o = run(idexp().arg("excite").arg(&design).arg("--out").arg(&out));
    assert_eq!(o.status.code(), Some(3), "{}\n{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).starts_with("INFEASIBLE"), "{}", stdout(&o));
    assert!(stderr(&o).contains("not usable"), "{}", stderr(&o));
    let s = status(&out);
    assert_common(&s, "excite", RunState::Infeasible);
    assert_eq!(s.summary["design_status"], "infeasible");
}

#[test]
fn robot_out_is_a_folder_and_json_and_old_spellings_work() {
    let d = tempfile::tempdir().unwrap();
    let o = run(idexp()
        .args(["robot", "torques", "designs/robots/ur5.toml", "--states", "tests/data/ur5_states.csv", "--out"])
        .arg(d.path()));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let csv = std::fs::read_to_string(d.path().join("torques.csv")).unwrap();
    assert!(csv.starts_with("t,tau1") || csv.starts_with("tau1"), "{csv}");
    // without --out the same table goes to standard output
    let o = run(idexp().args(["robot", "torques", "designs/robots/ur5.toml", "--states", "tests/data/ur5_states.csv"]));
    assert_eq!(stdout(&o), csv);
    let o = run(idexp()
        .args([
            "robot",
            "regressor",
            "designs/robots/ur5.toml",
            "--states",
            "tests/data/ur5_states.csv",
            "--base",
            "--out",
        ])
        .arg(d.path()));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(d.path().join("regressor.csv").is_file());
    // --rank-tol and its old spelling --tol give the same report
    let a = run(idexp().args(["robot", "info", "designs/robots/puma560.toml", "--json", "--rank-tol", "1e-6"]));
    let b = run(idexp().args(["robot", "info", "designs/robots/puma560.toml", "--json", "--tol", "1e-6"]));
    assert_eq!(a.status.code(), Some(0));
    assert_eq!(stdout(&a), stdout(&b));
    let js: serde_json::Value = serde_json::from_str(&stdout(&a)).unwrap();
    assert_eq!(js["name"], "puma560");
}

/// Sends SIGINT to `child` after `delay` and waits (at most 60 s) for it to exit.
fn interrupt(child: &mut std::process::Child, delay: f64) -> std::process::ExitStatus {
    std::thread::sleep(std::time::Duration::from_secs_f64(delay));
    let ok = Command::new("kill").arg("-INT").arg(child.id().to_string()).status().unwrap();
    assert!(ok.success(), "kill -INT failed");
    for _ in 0..600 {
        if let Some(st) = child.try_wait().unwrap() {
            return st;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    let _ = child.kill();
    panic!("the command did not stop within 60 s of SIGINT");
}

#[test]
fn ctrl_c_exits_130_with_valid_results() {
    // excite: stopped during the search, the best design so far is written and says so
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("excite");
    let mut child = idexp()
        .args(["excite", "designs/excite_ur5_bench.toml", "--time-limit", "120", "--out"])
        .arg(&out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let st = interrupt(&mut child, 2.0);
    assert_eq!(st.code(), Some(130));
    let s = status(&out);
    assert_common(&s, "excite", RunState::Interrupted);
    assert!(out.join("coefficients.json").is_file());
    // simulate at a high rate (20 kHz): interrupted inside the first repetition,
    // before any result exists: 130 and nothing written
    let design = d.path().join("fast.toml");
    let text = std::fs::read_to_string(root("designs/sim_puma_fourier.toml")).unwrap();
    let text: String = text
        .lines()
        .map(|l| {
            if l.starts_with("rate = ") {
                "rate = 20000.0".to_string()
            } else {
                l.to_string()
            }
        })
        .map(|l| l.replace("\"robots/", &format!("\"{}/", root("designs/robots").display())))
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&design, text).unwrap();
    let out = d.path().join("sim");
    let mut child = idexp()
        .arg("simulate")
        .arg(&design)
        .arg("--out")
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let st = interrupt(&mut child, 1.5);
    assert_eq!(st.code(), Some(130));
    assert!(!out.join("status.json").exists() || status(&out).status == RunState::Interrupted);
}
