//! Results do not depend on `--threads`: excite, assess, positions, simulate,
//! multisine, frf and fit write byte-identical files with 1 and 2 threads
//! (wall-clock fields — `started`, `finished`, `seconds`, … — excepted).
#![cfg(feature = "cli")]

mod common;
use common::root;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Keys that hold wall-clock times or durations (they differ between any two runs).
const CLOCK_KEYS: &[&str] = &["started", "finished", "seconds", "information_time", "elapsed", "wall_seconds", "time_s"];

fn idexp(threads: usize, args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .current_dir(root(""))
        .env("IDEXP_NO_PROGRESS", "1")
        .arg("--threads")
        .arg(threads.to_string())
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.code().is_some_and(|c| c == 0 || c == 3),
        "--threads {threads} {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn files(dir: &Path) -> Vec<PathBuf> {
    fn walk(base: &Path, d: &Path, v: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(base, &p, v);
            } else {
                v.push(p.strip_prefix(base).unwrap().to_path_buf());
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

fn strip_clock(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(m) => {
            for k in CLOCK_KEYS {
                m.remove(*k);
            }
            m.values_mut().for_each(strip_clock);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(strip_clock),
        _ => {}
    }
}

/// Byte comparison of two folders; JSON files (and JSON lines) without their clock fields.
fn assert_same(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    assert_eq!(fa, fb, "{} and {} hold different files", a.display(), b.display());
    assert!(!fa.is_empty());
    for f in fa {
        let (x, y) = (std::fs::read(a.join(&f)).unwrap(), std::fs::read(b.join(&f)).unwrap());
        let ext = f.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext == "json" || ext == "jsonl" || f.ends_with("report.txt") {
            let norm = |t: &[u8]| -> Vec<String> {
                String::from_utf8_lossy(t)
                    .lines()
                    .map(|l| {
                        if ext == "jsonl" {
                            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
                            strip_clock(&mut v);
                            v.to_string()
                        } else {
                            l.to_string()
                        }
                    })
                    .collect()
            };
            if ext == "json" {
                let mut vx: serde_json::Value = serde_json::from_slice(&x).unwrap();
                let mut vy: serde_json::Value = serde_json::from_slice(&y).unwrap();
                strip_clock(&mut vx);
                strip_clock(&mut vy);
                assert_eq!(vx, vy, "{}: differs between --threads 1 and 2", f.display());
            } else if ext == "jsonl" {
                assert_eq!(norm(&x), norm(&y), "{}: differs between --threads 1 and 2", f.display());
            } else {
                // report.txt: lines naming a duration excepted
                let keep = |v: Vec<String>| -> Vec<String> { v.into_iter().filter(|l| !l.contains(" s)") && !l.contains("time")).collect() };
                assert_eq!(keep(norm(&x)), keep(norm(&y)), "{}: differs between --threads 1 and 2", f.display());
            }
        } else {
            assert!(x == y, "{}: differs between --threads 1 and 2", f.display());
        }
    }
}

/// Runs `args` (with `{out}` replaced by the output folder) with 1 and 2 threads and compares.
fn same_for_threads(name: &str, args: &[&str], sub: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let mut dirs = Vec::new();
    for t in [1, 2] {
        let out = tmp.path().join(format!("{name}_{t}"));
        let o = out.to_str().unwrap().to_string();
        let a: Vec<String> = args.iter().map(|s| s.replace("{out}", &o)).collect();
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        idexp(t, &a);
        dirs.push(out.join(sub));
    }
    assert_same(&dirs[0], &dirs[1]);
}

#[test]
fn excite_and_assess_do_not_depend_on_threads() {
    same_for_threads("excite", &["excite", "designs/excite_ur5.toml", "--out", "{out}"], "");
    let tmp = tempfile::tempdir().unwrap();
    let ex = tmp.path().join("ex");
    idexp(2, &["excite", "designs/excite_ur5.toml", "--out", ex.to_str().unwrap()]);
    let traj = ex.join("trajectory.csv");
    same_for_threads(
        "assess",
        &["assess", "designs/robots/ur5.toml", traj.to_str().unwrap(), "--every", "10", "--out", "{out}"],
        "",
    );
}

#[test]
fn positions_do_not_depend_on_threads() {
    same_for_threads("pos_a", &["positions", "designs/positions_file_a.toml", "--out", "{out}"], "");
    same_for_threads("pos_el", &["positions", "designs/positions_elastic6_small.toml", "--out", "{out}"], "");
}

#[test]
fn simulate_does_not_depend_on_threads() {
    same_for_threads("sim", &["simulate", "designs/sim_rpr_fourier.toml", "--out", "{out}"], "");
}

#[test]
fn the_elastic_pipeline_does_not_depend_on_threads() {
    same_for_threads("ms", &["multisine", "designs/elastic_industrial6.toml", "--out", "{out}"], "multisine");
    let tmp = tempfile::tempdir().unwrap();
    for t in [1, 2] {
        let out = tmp.path().join(format!("el_{t}"));
        let o = out.to_str().unwrap();
        idexp(t, &["frf", "designs/elastic_industrial6.toml", "--out", o]);
        idexp(t, &["fit", "designs/elastic_industrial6.toml", "--starts", "4", "--out", o]);
    }
    assert_same(&tmp.path().join("el_1/frf"), &tmp.path().join("el_2/frf"));
    assert_same(&tmp.path().join("el_1/fit_lls_user"), &tmp.path().join("el_2/fit_lls_user"));
}
