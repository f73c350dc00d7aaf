//! Excitation design runs end to end: reproducibility across thread counts,
//! the restrained workspace against the full one (paper 000), infeasible
//! settings reported by constraint, the `idexp excite` / `idexp assess`
//! commands and their outputs. Budgets are small so the default run stays
//! short; the full-budget studies are `#[ignore]`d (see docs/testing.md).

use idexp::excitation::design::ExciteDesign;
use idexp::excitation::{run, ExciteResult, Problem, Status};
#[cfg(feature = "cli")]
use idexp::trajectory::FourierTrajectory;
use std::path::{Path, PathBuf};
#[cfg(feature = "cli")]
use std::process::Command;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn problem_from(text: &str, ctx: &str) -> Problem {
    let mut d: ExciteDesign = idexp::io::parse_toml(Path::new(ctx), text).unwrap();
    if d.name.is_empty() {
        d.name = "test".into();
    }
    d.robot = root("designs").join(&d.robot);
    let robot = idexp::robot::load(&d.robot).unwrap();
    Problem::new(d, robot, ctx).unwrap()
}

fn shipped(name: &str, tweak: impl FnOnce(&mut ExciteDesign)) -> Problem {
    let mut d = ExciteDesign::load(&root(&format!("designs/{name}.toml"))).unwrap();
    tweak(&mut d);
    let robot = idexp::robot::load(&d.robot).unwrap();
    Problem::new(d, robot, name).unwrap()
}

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

const SMALL_UR5: &str = r#"
name = "small"
robot = "robots/ur5.toml"
seed = 11
[trajectory]
harmonics = 4
frequency = 0.2
q0 = [0.0, -0.5, 0.5, 0.0, 0.0, 0.0]
[objective]
sample_rate = 8.0
[limits]
position = 0.8
[ga]
population = 12
generations = 4
[refine]
starts = 3
max_evals = 25
# these tests are about limits, workspace boxes and determinism; collision
# constraints are tested in tests/collision.rs
[collision]
enabled = false
"#;

#[test]
fn the_same_seed_gives_the_same_design_on_one_and_two_threads() {
    let p = problem_from(SMALL_UR5, "small.toml");
    let r1 = in_pool(1, || run(&p, &idexp::optim::Control::new()).unwrap());
    let r2 = in_pool(2, || run(&p, &idexp::optim::Control::new()).unwrap());
    assert_eq!(r1.threads, 1);
    assert_eq!(r2.threads, 2);
    assert_eq!(r1.x, r2.x);
    assert_eq!(r1.criterion, r2.criterion);
    assert_eq!(r1.ga.evaluations, r2.ga.evaluations);
    let ev1: Vec<u64> = r1.refinements.iter().map(|r| r.evaluations).collect();
    let ev2: Vec<u64> = r2.refinements.iter().map(|r| r.evaluations).collect();
    assert_eq!(ev1, ev2);
    // a different seed gives a different design
    let mut p3 = p.clone();
    p3.design.seed = 12;
    let r3 = run(&p3, &idexp::optim::Control::new()).unwrap();
    assert_ne!(r3.x, r1.x);
}

fn assert_feasible_on_the_check_grid(r: &ExciteResult) {
    assert_eq!(r.status, Status::Feasible, "violated: {:?}", r.violated);
    assert!(r.violated.is_empty());
    assert!(!r.margins.is_empty());
    for m in &r.margins {
        assert!(m.margin >= 0.0, "{}: margin {}", m.name, m.margin);
    }
}

#[test]
fn restrained_workspace_is_feasible_with_a_higher_condition_number_than_the_full_one() {
    let small = |d: &mut ExciteDesign| {
        d.ga.population = 24;
        d.ga.generations = 12;
        d.refine.starts = 2;
        d.refine.max_evals = 120;
    };
    let full = shipped("excite_industrial6_full", small);
    let restrained = shipped("excite_industrial6_restrained", small);
    let rf = run(&full, &idexp::optim::Control::new()).unwrap();
    let rr = run(&restrained, &idexp::optim::Control::new()).unwrap();
    assert_feasible_on_the_check_grid(&rf);
    assert_feasible_on_the_check_grid(&rr);
    // the Cartesian margins are part of what was checked
    assert!(rr.margins.iter().filter(|m| m.name.contains("sector")).count() >= 12);
    assert!(
        rr.spectrum.cond > rf.spectrum.cond,
        "restrained {} vs full {}",
        rr.spectrum.cond,
        rf.spectrum.cond
    );
    assert!(rf.spectrum.cond < 20.0);
}

#[test]
fn infeasible_settings_name_the_constraint_and_the_amount() {
    // the UR5 flange at q0 = 0 is at about (0.82, 0.19, −0.01): outside this box
    let text = format!("{SMALL_UR5}\n[[workspace]]\nframe = \"tool0\"\nshape = {{ type = \"box\", min = [-0.3, -0.3, 0.3], max = [0.3, 0.3, 0.8] }}\n")
        .replace("q0 = [0.0, -0.5, 0.5, 0.0, 0.0, 0.0]", "q0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]");
    let p = problem_from(&text, "infeasible.toml");
    let r = run(&p, &idexp::optim::Control::new()).unwrap();
    assert_eq!(r.status, Status::Infeasible);
    assert!(!r.violated.is_empty());
    let worst = &r.violated[0];
    assert!(worst.name.contains("tool0") && worst.name.contains("box"), "{}", worst.name);
    assert!(worst.margin < -0.1, "{}", worst.margin);
    assert_eq!(worst.unit, "m");
    let ident = idexp::excitation::report::assess(&p.robot, &p.base, &r.trajectory.sample(8.0).unwrap(), &[1.0; 6]).unwrap();
    let text = idexp::excitation::report::excite_text(&p, &r, &ident);
    assert!(
        text.contains("INFEASIBLE") && text.contains("beyond the limit") && text.contains("x ≤ max"),
        "{text}"
    );
    // an unreachable joint range: q0 outside the allowed positions
    let text = SMALL_UR5.replace("q0 = [0.0, -0.5, 0.5, 0.0, 0.0, 0.0]", "q0 = [0.0, -0.5, 2.9, 0.0, 0.0, 0.0]");
    let p = problem_from(&text, "q0_out.toml");
    let r = run(&p, &idexp::optim::Control::new()).unwrap();
    assert_eq!(r.status, Status::Infeasible);
    assert!(r.violated.iter().any(|m| m.name.starts_with("q3 ") && m.margin < -0.3), "{:?}", r.violated);
}

#[cfg(feature = "cli")]
fn idexp() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_idexp"));
    c.env("IDEXP_NO_PROGRESS", "1").current_dir(root(""));
    c
}

#[cfg(feature = "cli")]
#[test]
fn idexp_excite_on_the_readme_design_writes_every_output_and_assess_reads_the_trajectory() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ur5");
    let o = idexp().args(["excite", "designs/excite_ur5.toml", "--out"]).arg(&out).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.starts_with("feasible"), "{stdout}");
    for f in [
        "coefficients.json",
        "trajectory.csv",
        "periodic.csv",
        "report.json",
        "report.txt",
        "design.json",
        "status.json",
        "joints.svg",
        "singular_values.svg",
        "ee_path.svg",
        "preview.html",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    // coefficients reload, and reproduce periodic.csv (1 kHz, one period;
    // trajectory.csv is the delivered rest-to-rest trajectory, tests/excite_execution.rs)
    let tr = FourierTrajectory::load(&out.join("coefficients.json")).unwrap();
    assert_eq!(tr.n_harmonics(), 5);
    let s = idexp::io::States::read(&out.join("periodic.csv"), 6).unwrap();
    assert_eq!(s.len(), 10_000);
    let mut q = [0.0; 6];
    let (mut qd, mut qdd) = ([0.0; 6], [0.0; 6]);
    let t = s.t.as_ref().unwrap();
    tr.eval(t[1234], &mut q, &mut qd, &mut qdd);
    for j in 0..6 {
        assert!((q[j] - s.q[1234][j]).abs() < 1e-12);
    }
    // every limit verified on the 1 kHz grid
    let rep: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(rep["result"]["status"], "feasible");
    assert_eq!(rep["verification_rate"], 1000.0);
    let margins = rep["result"]["margins"].as_array().unwrap();
    // 36 joint limits + 21 minimum distances (15 self pairs, 6 links above the floor)
    assert_eq!(margins.len(), 57);
    assert!(margins.iter().all(|m| m["margin"].as_f64().unwrap() >= 0.0));
    assert_eq!(rep["identifiability"]["rank"], 48);
    let cond = rep["result"]["spectrum"]["cond"].as_f64().unwrap();
    assert!(cond < 8.0, "cond {cond}");
    let status: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("status.json")).unwrap()).unwrap();
    assert_eq!(status["command"], "excite");
    assert_eq!(status["status"], "complete");
    assert_eq!(status["summary"]["design_status"], "feasible");
    // assess the written trajectory
    let o = idexp()
        .args(["assess", "designs/robots/ur5.toml"])
        .arg(out.join("trajectory.csv"))
        .args(["--every", "100", "--noise", "0.5", "--out"])
        .arg(dir.path().join("assess"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("rank: 48") && text.contains("every base parameter is excited"), "{text}");
    for f in ["report.json", "report.txt", "singular_values.svg", "inputs.json"] {
        assert!(dir.path().join("assess").join(f).is_file(), "assess output {f}");
    }
    // bad input: errors name the file
    let o = idexp().args(["excite", "designs/does_not_exist.toml"]).output().unwrap();
    assert_eq!(o.status.code(), Some(1), "an input error exits with 1");
    assert!(String::from_utf8_lossy(&o.stderr).contains("does_not_exist.toml"));
    let o = idexp().args(["assess", "designs/robots/ur5.toml", "Cargo.toml"]).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("Cargo.toml"));
}

/// Study: the shipped industrial designs at their full budgets (about a
/// minute): `cargo test --release --test excitation_designs -- --ignored --nocapture`.
#[test]
#[ignore]
fn study_full_budgets_restrained_vs_full_and_panda() {
    let mut conds = Vec::new();
    for name in ["excite_industrial6_full", "excite_industrial6_restrained", "excite_panda_table"] {
        let p = shipped(name, |_| {});
        let r = run(&p, &idexp::optim::Control::new()).unwrap();
        println!("{name}: {:?}, cond {:.4}, {:.1} s, chosen {}", r.status, r.spectrum.cond, r.seconds, r.chosen);
        assert_feasible_on_the_check_grid(&r);
        conds.push(r.spectrum.cond);
    }
    assert!(conds[1] > conds[0]);
}

/// Study: the benchmark design with a 60 s budget (and 10 s for comparison):
/// `cargo test --release --test excitation_designs -- --ignored --nocapture study_ur5_bench`.
#[test]
#[ignore]
fn study_ur5_bench_ten_seconds_and_one_minute() {
    for t in [10.0, 60.0] {
        let p = shipped("excite_ur5_bench", |d| {
            d.time_limit = Some(t);
            d.refine.starts = if t > 30.0 { 48 } else { d.refine.starts };
        });
        let r = run(&p, &idexp::optim::Control::new()).unwrap();
        println!(
            "budget {t} s: cond {:.4} after {:.1} s ({:?}, chosen {})",
            r.spectrum.cond, r.seconds, r.status, r.chosen
        );
        assert_feasible_on_the_check_grid(&r);
        assert!(r.spectrum.cond <= 4.9);
    }
}
