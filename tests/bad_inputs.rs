//! Bad inputs of issue 14 (resources, hangs, messages) tried again: each is
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
