//! One identification engine: the one-run command line (`idexp identify
//! ROBOT RUN… --flags`) is a one-experiment study. For every estimator —
//! OLS, WLS, the projection method, maximum likelihood, WLS with the model
//! reduction, WLS with the consistent fit — the one-run form and the study
//! file that says the same give byte-identical estimate.json (but the
//! solver's wall-clock time), and the study's numbers are those of the
//! estimator run by hand on the same data (projection, ML: the library's
//! closed-loop functions on the processed run).

mod ident_util;

use std::path::{Path, PathBuf};
use std::process::Command;

fn exe() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.env("IDEXP_NO_PROGRESS", "1");
    c
}

fn run(args: &[&str]) -> std::process::Output {
    let o = exe().args(args).output().unwrap();
    assert!(o.status.success(), "idexp {args:?}: {}", String::from_utf8_lossy(&o.stderr));
    o
}

/// The simulated closed-loop RPR run (Fourier reference, 8 repetitions) and a validation run.
fn simulate(dir: &Path, name: &str, seed: u64) -> PathBuf {
    let design = dir.join(format!("{name}.toml"));
    std::fs::write(
        &design,
        format!(
            "robot = \"{}\"\nrate = 500.0\ndecimate = 5\nrepetitions = 8\nseed = {seed}\n[truth]\nperturbation = 0.1\nseed = 7\n[noise]\ntorque = 0.05\n[reference]\nkind = \"random_fourier\"\nfrequency = 0.2\namplitude = 0.6\nseed = {seed}\n",
            ident_util::root("tests/data/ident/rpr_drives.toml").display()
        ),
    )
    .unwrap();
    let out = dir.join(name);
    run(&["simulate", design.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    out
}

/// estimate.json without the keys that hold wall-clock times.
fn estimate(dir: &Path) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.remove("solve_time");
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("estimate.json")).unwrap()).unwrap();
    strip(&mut v);
    v
}

/// A study file's lines split into the top-level keys and the tables (from the first line that opens one).
fn split_tables(lines: &str) -> (&str, &str) {
    let at = if lines.starts_with('[') { Some(0) } else { lines.find("\n[").map(|i| i + 1) };
    match at {
        Some(i) => lines.split_at(i),
        None => (lines, ""),
    }
}

#[test]
fn the_one_run_form_is_a_one_experiment_study_for_every_estimator() {
    let d = tempfile::tempdir().unwrap();
    let robot = ident_util::root("tests/data/ident/rpr_drives.toml");
    let (r, id_run, val) = (robot.to_str().unwrap(), simulate(d.path(), "id", 3), simulate(d.path(), "val", 4));
    let (id_s, val_s) = (id_run.to_str().unwrap(), val.to_str().unwrap());
    // (flags of the one-run form, the study file's lines that say the same)
    let cases: [(&str, &[&str], &str); 6] = [
        ("ols", &["--method", "ols"], "method = \"ols\"\n"),
        ("wls", &[], ""),
        ("projection", &["--method", "projection"], "method = \"projection\"\n"),
        ("ml", &["--method", "ml"], "method = \"ml\"\n"),
        ("reduce", &["--reduce", "--reduce-tol", "0.1"], "[reduce]\ntol = 0.1\n"),
        (
            "consistent",
            &["--consistent", "--margin", "1e-6", "--export", "csv,toml"],
            "export = [\"csv\", \"toml\"]\n[consistent]\nmetric = \"euclidean\"\nweight = { relative = 1e-6 }\nscale = 1.0\nunknown = \"none\"\nmargin = 1e-6\n",
        ),
    ];
    for (name, flags, lines) in cases {
        let one = d.path().join(format!("one_{name}"));
        let mut args = vec!["identify", r, id_s, "--validate", val_s, "--harmonics", "12", "--out", one.to_str().unwrap()];
        args.extend_from_slice(flags);
        run(&args);
        // the same as a study file: top-level keys first, then the tables
        let (top, tables) = split_tables(lines);
        let study = d.path().join(format!("{name}.toml"));
        std::fs::write(
            &study,
            format!(
                "name = \"id\"\nrobot = \"{r}\"\nweights = \"repetitions\"\nrepetition_weights = \"sample\"\n{top}\n[[experiment]]\nfiles = [\"{id_s}\"]\nharmonics = 12\nstandstill = \"auto\"\n[[validation]]\nfiles = [\"{val_s}\"]\nharmonics = 12\nstandstill = \"auto\"\n{tables}"
            ),
        )
        .unwrap();
        let st = d.path().join(format!("study_{name}"));
        run(&["identify", study.to_str().unwrap(), "--out", st.to_str().unwrap()]);
        let (a, b) = (estimate(&one), estimate(&st));
        assert_eq!(a, b, "{name}: the one-run form and its study differ");
        assert_eq!(
            a["method"],
            if name == "reduce" || name == "consistent" || name == "wls" {
                "wls"
            } else {
                name
            }
        );
        match name {
            "projection" => assert!(a["projection"]["m1"].is_u64(), "{name}: {}", a["projection"]),
            "ml" => assert!(a["ml"]["evaluations"].as_u64().unwrap() > 0),
            "reduce" => assert!(a["names"].as_array().unwrap().len() < 18 && a["reduction"]["steps"].is_array()),
            "consistent" => {
                assert_eq!(a["consistent"]["status"], "ok");
                for f in ["params.csv", "robot.toml"] {
                    assert_eq!(std::fs::read(one.join(f)).unwrap(), std::fs::read(st.join(f)).unwrap(), "{name}: {f} differs");
                }
            }
            _ => {}
        }
    }
}

#[test]
fn design_rules_of_the_one_experiment_estimators_name_the_field() {
    let d = tempfile::tempdir().unwrap();
    let robot = ident_util::root("tests/data/ident/rpr_drives.toml");
    for (extra, field, words) in [
        ("method = \"ml\"\n", "method", "one experiment"),
        ("method = \"projection\"\n", "method", "one experiment"),
        ("method = \"ols\"\n[reduce]\n", "method", "weighted least squares"),
        ("[reduce]\ntol = -1\n", "reduce", "one experiment"),
        ("method = \"ml\"\n[consistent]\n", "consistent", "least-squares fit"),
        ("[ml]\nmax_eval = 0\n", "max_eval", "max_eval ≥ 1"),
    ] {
        let (top, tables) = split_tables(extra);
        let study = d.path().join("s.toml");
        std::fs::write(
            &study,
            format!(
                "robot = \"{}\"\n{top}[[experiment]]\nfiles = [\"a\"]\n[[experiment]]\nfiles = [\"b\"]\n{tables}",
                robot.display()
            ),
        )
        .unwrap();
        let o = exe().args(["identify", study.to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{extra}: {err}");
        assert!(err.contains(field) && err.contains(words), "{extra}: {err}");
    }
}

/// Requests the stop when the entries are read: Ctrl-C during the estimator.
struct StopAfterReading(idexp::optim::StopFlag);

impl idexp::optim::Observer for StopAfterReading {
    fn phase_done(&self) {
        self.0.request();
    }
}

#[test]
fn a_reduction_stopped_by_ctrl_c_is_written_as_interrupted() {
    use idexp::io::status::RunState;
    let res = ident_util::simulate(&ident_util::rpr_fourier(1, 1, 11, 10, 1e-5));
    let run = |stop: bool| {
        let flag = idexp::optim::StopFlag::new();
        let mut ctl = idexp::optim::Control::new().with_stop(flag.clone());
        if stop {
            ctl = ctl.with_observer(std::sync::Arc::new(StopAfterReading(flag)));
        }
        ident_util::try_ident_with(&res, None, |d| d.reduce = Some(Default::default()), &ctl).unwrap().0
    };
    let (done, stopped) = (run(false), run(true));
    assert!(!done.interrupted && done.estimate.state(done.interrupted) == RunState::Complete);
    // the reduction returns what it has (fewer steps), and the folder says so
    assert!(stopped.interrupted, "a stopped reduction must be marked interrupted");
    assert_eq!(stopped.estimate.state(stopped.interrupted), RunState::Interrupted);
    let steps = |r: &idexp::ident::study::StudyResult| r.estimate.reduction.as_ref().unwrap().steps.len();
    assert!(steps(&stopped) < steps(&done), "{} vs {}", steps(&stopped), steps(&done));
}
