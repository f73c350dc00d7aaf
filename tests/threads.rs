//! Results do not depend on `--threads`: excite, assess, positions, simulate,
//! multisine, frf and fit write byte-identical files with 1 and 2 threads
//! (wall-clock fields — `started`, `finished`, `seconds`, … — excepted).
#![cfg(feature = "cli")]

mod common;
use common::root;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Keys that hold wall-clock times, durations or the thread count itself
/// (they differ between any two runs); also every key ending in `time`.
const CLOCK_KEYS: &[&str] = &["started", "finished", "seconds", "elapsed", "threads"];

fn is_clock_key(k: &str) -> bool {
    CLOCK_KEYS.contains(&k) || k.ends_with("time")
}

/// The first JSON pointer at which `a` and `b` differ.
fn first_difference(a: &serde_json::Value, b: &serde_json::Value, at: String) -> Option<String> {
    use serde_json::Value::{Array, Object};
    match (a, b) {
        (Object(x), Object(y)) => {
            for (k, v) in x {
                match y.get(k) {
                    Some(w) => {
                        if let Some(d) = first_difference(v, w, format!("{at}/{k}")) {
                            return Some(d);
                        }
                    }
                    None => return Some(format!("{at}/{k} only in the first")),
                }
            }
            y.keys().find(|k| !x.contains_key(*k)).map(|k| format!("{at}/{k} only in the second"))
        }
        (Array(x), Array(y)) if x.len() == y.len() => x.iter().zip(y).enumerate().find_map(|(i, (v, w))| first_difference(v, w, format!("{at}/{i}"))),
        _ if a == b => None,
        _ => Some(format!("{at}: {a} vs {b}")),
    }
}

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

/// `l` with every number followed by the unit `s`, and the count in "on N threads", replaced by `#`.
fn mask_durations(l: &str) -> String {
    let w: Vec<&str> = l.split(' ').collect();
    let mut out = Vec::with_capacity(w.len());
    for (i, t) in w.iter().enumerate() {
        let next = w.get(i + 1).copied().unwrap_or("");
        let unit = next.trim_end_matches([',', ';', ')']) == "s" || next.starts_with("threads");
        let num = t.trim_start_matches('(').parse::<f64>().is_ok();
        out.push(if unit && num { "#" } else { t });
    }
    out.join(" ")
}

fn strip_clock(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(m) => {
            m.retain(|k, _| !is_clock_key(k));
            m.values_mut().for_each(strip_clock);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(strip_clock),
        _ => {}
    }
}

/// Byte comparison of two folders; JSON files (and JSON lines) without their
/// clock fields, and with each folder's own path replaced by `{out}`.
fn assert_same(a: &Path, b: &Path) {
    let (fa, fb) = (files(a), files(b));
    assert_eq!(fa, fb, "{} and {} hold different files", a.display(), b.display());
    assert!(!fa.is_empty());
    for f in fa {
        let read = |root: &Path| -> Vec<u8> {
            let bytes = std::fs::read(root.join(&f)).unwrap();
            // the run folder (the parent of a subfolder output) as written in the files
            let base = if root.file_name().is_some_and(|n| n.to_string_lossy().ends_with(char::is_numeric)) {
                root
            } else {
                root.parent().unwrap()
            };
            match String::from_utf8(bytes) {
                Ok(t) => t.replace(base.to_str().unwrap(), "{out}").into_bytes(),
                Err(e) => e.into_bytes(),
            }
        };
        let (x, y) = (read(a), read(b));
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
                if let Some(d) = first_difference(&vx, &vy, String::new()) {
                    panic!("{}: differs between --threads 1 and 2 at {d}", f.display());
                }
            } else if ext == "jsonl" {
                assert_eq!(norm(&x), norm(&y), "{}: differs between --threads 1 and 2", f.display());
            } else {
                // report.txt: durations ("1.21 s") and the thread count masked
                let mask = |v: Vec<String>| -> Vec<String> { v.iter().map(|l| mask_durations(l)).collect() };
                assert_eq!(mask(norm(&x)), mask(norm(&y)), "{}: differs between --threads 1 and 2", f.display());
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
