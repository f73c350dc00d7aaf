//! The whole chain through the `idexp` binary: multisine → frf (simulated) →
//! fit; a fit killed with SIGKILL and started again gives the same files as an
//! uninterrupted run; shards merged with `idexp merge` give the same files;
//! bad arguments give errors.
#![cfg(feature = "cli")]

use std::path::{Path, PathBuf};
use std::process::Command;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn idexp() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.env("IDEXP_NO_PROGRESS", "1");
    c
}

fn ok(c: &mut Command) -> String {
    let o = c.output().unwrap();
    assert!(o.status.success(), "{:?} failed: {}", c, String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn design(dir: &Path) -> PathBuf {
    let s = std::fs::read_to_string(root("designs/elastic_industrial6.toml")).unwrap();
    let s = s.replace("robots/industrial6.toml", root("designs/robots/industrial6.toml").to_str().unwrap());
    let i = s.find("positions = [\n").unwrap() + "positions = [\n".len();
    let j = i + s[i..].find("]\n\n").unwrap();
    let rows: Vec<&str> = s[i..j].lines().take(2).collect();
    let s = format!("{}{}\n{}", &s[..i], rows.join("\n"), &s[j..])
        .replace("band = [2.0, 150.0]", "band = [2.0, 61.0]")
        .replace("band = [3.0, 150.0]", "band = [3.0, 61.0]")
        .replace("starts = 100", "starts = 12")
        .replace("max_iter = 200", "max_iter = 60");
    let p = dir.join("d.toml");
    std::fs::write(&p, s).unwrap();
    p
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn chain_kill_resume_shards_merge() {
    let dir = tempfile::tempdir().unwrap();
    let d = design(dir.path());
    let x = dir.path().join("x");
    let s = ok(idexp().arg("multisine").arg(&d).arg("--out").arg(&x));
    assert!(s.contains("crest factor"), "{s}");
    assert!(x.join("multisine/ref_block4_exp6.csv").exists() && x.join("multisine/multisine.json").exists());
    ok(idexp().arg("frf").arg(&d).arg("--out").arg(&x));
    let data = x.join("frf/frf.json");
    assert!(data.exists());

    // uninterrupted reference
    let a = dir.path().join("a");
    let out = ok(idexp().args(["--threads", "2", "fit"]).arg(&d).arg("--out").arg(&a).arg("--data").arg(&data));
    assert!(out.contains("reasonable models"), "{out}");
    let fa = a.join("fit_lls_user");
    let ref_log = read(&fa.join("starts.jsonl"));
    let ref_fit = read(&fa.join("fit.json"));

    // killed run, then the same command again
    let b = dir.path().join("b");
    let log = b.join("fit_lls_user/starts.jsonl");
    let mut child = idexp()
        .args(["--threads", "1", "fit"])
        .arg(&d)
        .arg("--out")
        .arg(&b)
        .arg("--data")
        .arg(&data)
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while std::fs::read_to_string(&log).map(|t| t.lines().count()).unwrap_or(0) < 2 && t0.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let at_kill = std::fs::read_to_string(&log).map(|t| t.lines().count()).unwrap_or(0);
    assert!(at_kill < 12, "the run finished before it could be killed");
    assert!(!b.join("fit_lls_user/fit.json").exists());
    ok(idexp().args(["--threads", "2", "fit"]).arg(&d).arg("--out").arg(&b).arg("--data").arg(&data));
    assert_eq!(read(&log), ref_log, "killed after {at_kill} starts and resumed");
    assert_eq!(read(&b.join("fit_lls_user/fit.json")), ref_fit);

    // shards as array-job tasks, then merge
    let sdir = dir.path().join("s");
    for i in 0..3 {
        let out = ok(idexp()
            .args(["--threads", "1", "fit"])
            .arg(&d)
            .arg("--out")
            .arg(&sdir)
            .arg("--data")
            .arg(&data)
            .arg("--shard")
            .arg(format!("{i}/3")));
        assert!(out.contains("shard complete"), "{out}");
    }
    let f = sdir.join("fit_lls_user");
    let m = ok(idexp()
        .arg("merge")
        .arg(f.join("starts.shard-0-of-3.jsonl"))
        .arg(f.join("starts.shard-1-of-3.jsonl"))
        .arg(f.join("starts.shard-2-of-3.jsonl")));
    assert!(m.contains("reasonable models"), "{m}");
    assert_eq!(read(&f.join("starts.jsonl")), ref_log);
    assert_eq!(read(&f.join("fit.json")), ref_fit);
    // every file of the merged folder is the single run's; status.json
    // differs only in the run's own start and end times
    assert_eq!(read(&f.join("run.json")), read(&fa.join("run.json")));
    let status = |p: &Path| -> serde_json::Value {
        let mut v: serde_json::Value = serde_json::from_str(&read(&p.join("status.json"))).unwrap();
        let o = v.as_object_mut().unwrap();
        assert!(o.remove("started").is_some() && o.remove("finished").is_some());
        v
    };
    assert_eq!(status(&f), status(&fa));
    assert_eq!(status(&f)["command"], "fit");
    let files = |p: &Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(p)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with("starts.shard-"))
            .collect();
        v.sort();
        v
    };
    assert_eq!(files(&f), files(&fa));
    for n in files(&fa) {
        let p = fa.join(&n);
        if p.is_file() && n != "status.json" {
            assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(f.join(&n)).unwrap(), "{n}");
        }
    }

    // other estimators write their own folders
    ok(idexp()
        .arg("fit")
        .arg(&d)
        .arg("--out")
        .arg(&a)
        .arg("--data")
        .arg(&data)
        .args(["--estimator", "nls", "--starts", "2"]));
    assert!(a.join("fit_nls_user/fit.json").exists());
    ok(idexp().arg("fit").arg(&d).arg("--out").arg(&a).arg("--data").arg(&data).args([
        "--estimator",
        "lls_magnitude",
        "--weights",
        "optimal",
        "--starts",
        "2",
    ]));
    assert!(a.join("fit_lls_magnitude_optimal/costs.svg").exists());

    // errors
    for (args, msg) in [
        (vec!["fit", "nope.toml"], "nope.toml"),
        (vec!["fit", d.to_str().unwrap(), "--shard", "3/3"], "--shard"),
        (vec!["fit", d.to_str().unwrap(), "--estimator", "ls"], "estimator"),
        (vec!["fit", d.to_str().unwrap(), "--out", "/nonexistent-dir-idexp"], "idexp frf"),
    ] {
        let o = idexp().args(&args).output().unwrap();
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(msg), "{args:?}: {e}");
    }
}
