//! Output folders are never mixed or half-written: a run killed (SIGKILL) or
//! stopped by two Ctrl-C while it writes into a folder holding an earlier
//! result leaves either the complete new set, or a folder marked `running`
//! with the complete earlier set in `.previous/`; the next run leaves no
//! temporary file and no `.previous/`; a folder marked `running` is refused
//! as input.
#![cfg(feature = "cli")]

mod common;
use common::root;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn idexp() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.current_dir(root("")).env("IDEXP_NO_PROGRESS", "1");
    c
}

fn run_ok(args: &[&str]) {
    let o = idexp().args(args).output().unwrap();
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
}

fn status_of(dir: &Path) -> Option<serde_json::Value> {
    serde_json::from_str(&std::fs::read_to_string(dir.join("status.json")).ok()?).ok()
}

fn state(dir: &Path) -> String {
    status_of(dir).and_then(|s| s["status"].as_str().map(String::from)).unwrap_or_default()
}

/// Every file below `dir` (relative paths), sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
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
    walk(dir, dir, &mut v);
    v.sort();
    v
}

fn temps(dir: &Path) -> Vec<PathBuf> {
    files(dir).into_iter().filter(|p| p.to_string_lossy().ends_with(".tmp")).collect()
}

/// Waits until `dir`'s status.json says `running` and was written by this
/// child (the write phase began), or the child exits.
fn wait_running(child: &mut Child, dir: &Path, timeout: Duration) -> bool {
    let t0 = Instant::now();
    let spawned = std::time::SystemTime::now();
    while t0.elapsed() < timeout {
        let fresh = std::fs::metadata(dir.join("status.json")).and_then(|m| m.modified()).is_ok_and(|t| t > spawned);
        // past the move aside (see io::folder::begin): the new files are being written
        let writing = status_of(dir).is_some_and(|s| s["status"] == "running" && s["summary"].get("previous_set").is_none());
        if fresh && writing {
            return true;
        }
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    false
}

fn signal(child: &Child, sig: &str) {
    let _ = Command::new("kill").args([sig, &child.id().to_string()]).status();
}

/// The simulate set is whole: status final, 50 repetitions, every file of the reference list.
fn assert_whole_sim(dir: &Path, reference: &[PathBuf]) {
    let st = state(dir);
    assert!(st == "complete" || st == "interrupted", "{}: status {st}", dir.display());
    // a temporary file of the process killed a moment before may still be
    // there: the next run removes such files only once they are 2 s old
    // (io::folder), so they are not part of the result set compared here
    let listed: Vec<PathBuf> = files(dir).into_iter().filter(|p| !p.to_string_lossy().ends_with(".tmp")).collect();
    assert_eq!(listed, reference, "{}", dir.display());
}

#[test]
fn a_killed_simulate_leaves_the_previous_set_aside_and_is_refused_as_input() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("sim");
    let d = dir.to_str().unwrap();
    run_ok(&["simulate", "designs/sim_rpr_fourier.toml", "--out", d]);
    let reference = files(&dir);
    assert!(reference.len() > 50, "{reference:?}");
    let mut caught = 0;
    for delay_ms in [0u64, 15, 40] {
        let mut child = idexp()
            .args(["simulate", "designs/sim_rpr_fourier.toml", "--out", d])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // wait for the write phase (status.json "running"), then kill
        if wait_running(&mut child, &dir, Duration::from_secs(60)) {
            std::thread::sleep(Duration::from_millis(delay_ms));
            signal(&child, "-KILL");
        }
        let _ = child.wait();
        match state(&dir).as_str() {
            "running" => {
                caught += 1;
                // the earlier set is whole in .previous
                assert_whole_sim(&dir.join(".previous"), &reference);
                // and the partial folder is refused as input
                let o = idexp().args(["identify", "tests/data/ident/rpr_drives.toml", d]).output().unwrap();
                assert_eq!(o.status.code(), Some(1));
                let err = String::from_utf8_lossy(&o.stderr);
                assert!(err.contains("status.json") && err.contains("running"), "{err}");
            }
            _ => assert_whole_sim(&dir, &reference),
        }
    }
    assert!(caught > 0, "no kill landed in the write phase");
    // the next run removes the killed run's temporary files (once older than
    // 2 s, so that a live writer's file is never taken: io::folder) and .previous
    std::thread::sleep(Duration::from_millis(2500));
    run_ok(&["simulate", "designs/sim_rpr_fourier.toml", "--out", d]);
    assert_whole_sim(&dir, &reference);
    assert!(temps(&dir).is_empty(), "{:?}", temps(&dir));
}

/// The excite set is whole and consistent: all files, and the condition
/// number in coefficients.json and criterion.json is the one in status.json.
fn assert_whole_excite(dir: &Path) {
    let st = status_of(dir).unwrap_or_else(|| panic!("{}: no status.json", dir.display()));
    let s = st["status"].as_str().unwrap();
    assert!(["complete", "interrupted", "infeasible"].contains(&s), "{}: {s}", dir.display());
    for f in [
        "coefficients.json",
        "trajectory.csv",
        "design.json",
        "report.json",
        "report.txt",
        "singular_values.svg",
        "joints.svg",
        "ee_path.svg",
        "criterion.json",
        "criterion_samples.csv",
        "preview.html",
    ] {
        assert!(dir.join(f).is_file(), "{}: {f} missing", dir.display());
    }
    let c: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("coefficients.json")).unwrap()).unwrap();
    assert_eq!(c["cond"], st["summary"]["cond"], "{}: mixed result set", dir.display());
    let k: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("criterion.json")).unwrap()).unwrap();
    assert_eq!(
        k["figures"][0]["cond"],
        st["summary"]["cond"],
        "{}: mixed result set (criterion.json)",
        dir.display()
    );
}

#[test]
fn two_ctrl_c_during_excite_never_leave_a_mixed_folder_nor_temporary_files() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("ex");
    let d = dir.to_str().unwrap();
    run_ok(&["excite", "designs/excite_ur5.toml", "--time-limit", "1", "--seed", "1", "--out", d]);
    assert_whole_excite(&dir);
    let mut outcomes = Vec::new();
    // Ctrl-C twice: during the search (the first stops it, the second lands in the writing), and in the write phase
    for (i, wait_write) in [false, true, false, true].into_iter().enumerate() {
        let seed = (10 + i).to_string();
        let mut child = idexp()
            .args(["excite", "designs/excite_ur5.toml", "--time-limit", "2", "--seed", &seed, "--out", d])
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        if wait_write {
            wait_running(&mut child, &dir, Duration::from_secs(60));
        } else {
            std::thread::sleep(Duration::from_millis(700));
        }
        signal(&child, "-INT");
        std::thread::sleep(Duration::from_millis(if wait_write { 1 } else { 30 }));
        signal(&child, "-INT");
        let status = child.wait().unwrap();
        let code = status.code();
        assert!(
            matches!(code, Some(0) | Some(130)),
            "exit {code:?}, signal {:?}",
            std::os::unix::process::ExitStatusExt::signal(&status)
        );
        assert!(temps(&dir).is_empty(), "temporary files left: {:?}", temps(&dir));
        let st = state(&dir);
        if st == "running" {
            assert_whole_excite(&dir.join(".previous"));
        } else {
            assert_whole_excite(&dir);
            assert!(!dir.join(".previous").exists());
        }
        outcomes.push(st);
    }
    eprintln!("outcomes: {outcomes:?}");
    run_ok(&["excite", "designs/excite_ur5.toml", "--time-limit", "1", "--seed", "1", "--out", d]);
    assert_whole_excite(&dir);
    assert!(!dir.join(".previous").exists());
}

#[test]
fn an_existing_file_as_output_folder_is_refused_before_the_work() {
    let tmp = tempfile::tempdir().unwrap();
    let f = tmp.path().join("a_file");
    std::fs::write(&f, "x").unwrap();
    let t0 = Instant::now();
    let o = idexp()
        .args(["excite", "designs/excite_ur5.toml", "--time-limit", "30", "--out", f.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("a_file") && err.contains("not a folder"), "{err}");
    assert!(t0.elapsed() < Duration::from_secs(10), "the search ran first");
}

#[test]
fn an_interrupted_run_folder_needs_allow_incomplete() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("sim");
    let d = dir.to_str().unwrap();
    run_ok(&["simulate", "designs/sim_rpr_fourier.toml", "--out", d]);
    // mark it interrupted, as a Ctrl-C during the simulation does
    let mut st = status_of(&dir).unwrap();
    st["status"] = "interrupted".into();
    std::fs::write(dir.join("status.json"), serde_json::to_string_pretty(&st).unwrap()).unwrap();
    let robot = "tests/data/ident/rpr_drives.toml";
    let out = tmp.path().join("id");
    let o = idexp().args(["identify", robot, d, "--out", out.to_str().unwrap()]).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    // (library errors name the study key `allow_incomplete`, not the flag)
    assert!(err.contains("interrupted") && err.contains("allow_incomplete"), "{err}");
    let o = idexp()
        .args(["identify", robot, d, "--allow-incomplete", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
#[cfg(unix)]
fn results_get_the_mode_of_an_ordinary_file_not_of_a_temporary_one() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ur5");
    run_ok(&["excite", "designs/excite_ur5_bench.toml", "--time-limit", "0.2", "--out", out.to_str().unwrap()]);
    // the oracle: what this process's umask gives a file created the ordinary way
    let plain = dir.path().join("plain.txt");
    std::fs::write(&plain, "x").unwrap();
    let want = std::fs::metadata(&plain).unwrap().permissions().mode() & 0o777;
    for f in ["report.txt", "trajectory.csv", "coefficients.json", "status.json", "joints.svg"] {
        let mode = std::fs::metadata(out.join(f)).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, want, "{f}: mode {mode:o}, a file created here gets {want:o}");
    }
}
