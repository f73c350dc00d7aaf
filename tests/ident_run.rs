//! The run format: strict checks with errors naming file, row and column;
//! round trip of written repetitions; folder reading; the CLI end to end.

mod ident_util;
use idexp::data::{Repetition, Run};
use idexp::Error;
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const GOOD: &str = "t,q1,q2,tau1,tau2\n0,0.1,0.2,1,2\n0.01,0.11,0.21,1.1,2.1\n0.02,0.12,0.22,1.2,2.2\n0.03,0.13,0.23,1.3,2.3\n";

fn data_err(e: Error) -> (PathBuf, usize, String, String) {
    match e {
        Error::Data { path, row, column, msg } => (path, row, column, msg),
        other => panic!("expected a data error, got {other}"),
    }
}

#[test]
fn bad_files_are_rejected_naming_file_row_and_column() {
    let d = tempfile::tempdir().unwrap();
    let good = write(d.path(), "a.csv", GOOD);
    // NaN
    let nan = write(d.path(), "nan.csv", &GOOD.replace("1.2,2.2", "NaN,2.2"));
    let (p, row, col, _) = data_err(Run::read(&[good.clone(), nan.clone()], 2).unwrap_err());
    assert_eq!((p, row, col.as_str()), (nan, 3, "tau1"));
    // unknown column
    let unk = write(d.path(), "unk.csv", "t,q1,q2,tau1,tau2,temp\n0,0,0,0,0,20\n0.01,0,0,0,0,20\n0.02,0,0,0,0,20\n");
    let (p, row, col, msg) = data_err(Run::read(std::slice::from_ref(&unk), 2).unwrap_err());
    assert_eq!((p, row, col.as_str()), (unk, 0, "temp"));
    assert!(msg.contains("unknown column"));
    // non-uniform time
    let nut = write(d.path(), "nut.csv", &GOOD.replace("0.02,", "0.025,"));
    let (p, row, col, msg) = data_err(Run::read(std::slice::from_ref(&nut), 2).unwrap_err());
    assert_eq!((p, col.as_str()), (nut, "t"));
    assert!(row == 3 || row == 4, "row {row}");
    assert!(msg.contains("non-uniform"));
    // different lengths
    let short = write(
        d.path(),
        "short.csv",
        "t,q1,q2,tau1,tau2\n0,0.1,0.2,1,2\n0.01,0.11,0.21,1.1,2.1\n0.02,0.12,0.22,1.2,2.2\n",
    );
    let (p, _, col, msg) = data_err(Run::read(&[good.clone(), short.clone()], 2).unwrap_err());
    assert_eq!((p, col.as_str()), (short, "t"));
    assert!(msg.contains("same length"), "{msg}");
    // missing torque column, wrong joint count
    let miss = write(d.path(), "miss.csv", "t,q1,q2,tau1\n0,0,0,0\n0.01,0,0,0\n0.02,0,0,0\n");
    let (_, row, col, _) = data_err(Run::read(&[miss], 2).unwrap_err());
    assert_eq!((row, col.as_str()), (0, "tau2"));
    let (_, _, col, _) = data_err(Run::read(std::slice::from_ref(&good), 1).unwrap_err());
    assert_eq!(col, "q2");
    // a non-number
    let txt = write(d.path(), "txt.csv", &GOOD.replace("0.21", "abc"));
    let (_, row, col, _) = data_err(Run::read(&[txt], 2).unwrap_err());
    assert_eq!((row, col.as_str()), (2, "q2"));
    // optional columns in one file only
    let withr = write(
        d.path(),
        "withr.csv",
        "t,q1,q2,tau1,tau2,r1,r2\n0,0.1,0.2,1,2,0,0\n0.01,0.11,0.21,1.1,2.1,0,0\n0.02,0.12,0.22,1.2,2.2,0,0\n0.03,0.13,0.23,1.3,2.3,0,0\n",
    );
    let (_, _, col, _) = data_err(Run::read(&[good.clone(), withr], 2).unwrap_err());
    assert_eq!(col, "r1");
    // a missing path
    assert!(Run::read(&[d.path().join("nope.csv")], 2).is_err());
}

#[test]
fn repetitions_round_trip_and_folders_are_read_in_order() {
    let d = tempfile::tempdir().unwrap();
    let rep = Repetition {
        t: vec![0.0, 0.5, 1.0],
        q: vec![vec![0.1, -0.2], vec![0.3, 0.4], vec![1e-9, 5.0]],
        tau: vec![vec![1.0, 2.0], vec![3.0, 4.0], vec![5.0, 6.0]],
        r: Some(vec![vec![0.0, 0.1], vec![0.2, 0.3], vec![0.4, 0.5]]),
        qd: None,
        qdd: None,
    };
    rep.write(&d.path().join("rep_002.csv")).unwrap();
    let mut rep1 = rep.clone();
    rep1.tau[0][0] = -1.0;
    rep1.write(&d.path().join("rep_001.csv")).unwrap();
    std::fs::write(d.path().join("reference.csv"), "t,q1,q2,qd1,qd2,qdd1,qdd2\n0,0,0,0,0,0,0\n").unwrap();
    let run = Run::read(&[d.path().to_path_buf()], 2).unwrap();
    assert_eq!(run.n_reps(), 2);
    assert_eq!(run.reps[0], rep1);
    assert_eq!(run.reps[1], rep);
}

#[cfg(feature = "cli")]
#[test]
fn cli_simulate_then_identify_writes_every_output() {
    let d = tempfile::tempdir().unwrap();
    let design = d.path().join("sim.toml");
    std::fs::write(
        &design,
        format!(
            r#"
robot = "{}"
rate = 500.0
decimate = 5
repetitions = 4
seed = 3
[noise]
torque = 0.05
[reference]
kind = "random_fourier"
frequency = 0.2
amplitude = 0.6
"#,
            ident_util::root("tests/data/ident/rpr_drives.toml").display()
        ),
    )
    .unwrap();
    let exe = env!("CARGO_BIN_EXE_idexp");
    let sim_out = d.path().join("run");
    let st = std::process::Command::new(exe)
        .args(["simulate", design.to_str().unwrap(), "--out", sim_out.to_str().unwrap()])
        .env("IDEXP_NO_PROGRESS", "1")
        .status()
        .unwrap();
    assert!(st.success());
    for f in [
        "rep_001.csv",
        "rep_004.csv",
        "reference.csv",
        "trajectory.json",
        "truth.json",
        "design.json",
        "status.json",
    ] {
        assert!(sim_out.join(f).exists(), "{f}");
    }
    let id_out = d.path().join("id");
    let robot = ident_util::root("tests/data/ident/rpr_drives.toml");
    let o = std::process::Command::new(exe)
        .args([
            "identify",
            robot.to_str().unwrap(),
            sim_out.to_str().unwrap(),
            "--reduce",
            "--out",
            id_out.to_str().unwrap(),
        ])
        .args(["--truth", sim_out.join("truth.json").to_str().unwrap(), "--validate", sim_out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the one-run form writes a one-experiment study's folder: the measured
    // vs predicted torques per experiment and validation run (the old
    // torques.svg), the resolved design (the old options.json); the old
    // residuals.svg and params.svg have no counterpart
    let est: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(id_out.join("estimate.json")).unwrap()).unwrap();
    let (name, vname) = (
        est["experiments"][0]["name"].as_str().unwrap().to_string(),
        est["validation"][0]["name"].as_str().unwrap().to_string(),
    );
    for f in [
        "estimate.json",
        "report.txt",
        "study.json",
        "params.csv",
        "experiments.csv",
        &format!("experiments/{name}.svg"),
        "validation.csv",
        &format!("validation/{vname}.csv"),
        &format!("validation/{vname}.svg"),
        "validation.svg",
        "reduction.csv",
        "reduction.svg",
        "status.json",
    ] {
        assert!(id_out.join(f).exists(), "{f}");
    }
    assert!(est["reduction"]["steps"].as_array().is_some_and(|s| !s.is_empty()));
    assert!(est["validation"][0]["errors"]["e"].is_array());
    // a bad run folder gives a message naming the file
    let bad = d.path().join("bad");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(
        bad.join("r.csv"),
        "t,q1,q2,q3,tau1,tau2,tau3\n0,0,0,0,0,0,0\n0.1,0,0,0,0,0,x\n0.2,0,0,0,0,0,0\n",
    )
    .unwrap();
    let o = std::process::Command::new(exe)
        .args(["identify", robot.to_str().unwrap(), bad.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("r.csv") && err.contains("row 2") && err.contains("tau3"), "{err}");
}
