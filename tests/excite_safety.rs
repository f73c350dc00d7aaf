//! The safety verdict of a delivered trajectory. A design that imposes no
//! collision constraint (`[collision] enabled = false`, the benchmark
//! designs) is still checked afterwards against the robot's collision
//! geometry on the 1 kHz grid: the benchmark designs start at q = 0, where
//! the UR5's wrist is below its mounting plane, so they are called NOT safe
//! to play and get no controller export, although every constraint they
//! impose holds. (An independent replay on the vendor's meshes, Pinocchio +
//! coal, agrees: python/tests/test_safety_replay.py.)

use idexp::excitation::design::{ExciteDesign, RefineAlgorithm};
use idexp::excitation::execution::{deliver, CollisionCheck, SAFETY_CAP};
use idexp::excitation::{run, Problem, Status};
use idexp::optim::Control;
use idexp::robot::collision::CollisionScene;
use idexp::robot::kinematics::Kin;
use idexp::trajectory::FourierTrajectory;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn design(name: &str, edit: impl FnOnce(&mut ExciteDesign)) -> Problem {
    let mut d = ExciteDesign::load(&root(&format!("designs/{name}.toml"))).unwrap();
    // a short search: the verdict on the delivered trajectory is what is tested
    d.ga.population = 12;
    d.ga.generations = 3;
    d.refine.algorithm = RefineAlgorithm::None;
    d.time_limit = None;
    edit(&mut d);
    let robot = idexp::robot::load(&d.robot).unwrap();
    Problem::new(d, robot, name).unwrap()
}

/// The scene the after-the-fact check uses, built here from the design:
/// self, floor, obstacles, no margin.
fn check_scene(p: &Problem) -> CollisionScene {
    let spec = idexp::robot::collision::CollisionSpec {
        enabled: true,
        margin: 0.0,
        ..p.design.collision.clone()
    };
    CollisionScene::new(&p.robot, &spec, Path::new(""), "test").unwrap().unwrap()
}

/// Least distance over every pair with an exact query each (no broad
/// phase), capped like the check.
fn brute_min(p: &Problem, sc: &CollisionScene, q: &[f64]) -> (f64, String) {
    let mut kin = Kin::new(p.robot.dof());
    let all = sc.distances(&p.robot, &mut kin, q, SAFETY_CAP);
    let w = all.iter().min_by(|a, b| a.distance.total_cmp(&b.distance)).unwrap();
    (w.distance, w.label.clone())
}

#[test]
fn benchmark_design_without_collision_constraints_is_not_safe_to_play() {
    let p = design("excite_ur5_bench", |_| {});
    assert!(!p.design.collision.enabled);
    let r = run(&p, &Control::new()).unwrap();
    let s = &r.execution.safety;
    assert_eq!(s.collisions, CollisionCheck::CheckedAfterwards);
    assert_eq!(s.safe, Some(false), "{}", s.statement);
    assert!(s.statement.starts_with("NOT safe to play"), "{}", s.statement);
    let c = s.closest.as_ref().unwrap();
    assert!(c.distance < 0.0, "{c:?}");
    assert!(c.colliding_samples >= 1 && c.colliding_samples <= c.samples, "{c:?}");
    assert!(
        s.statement.contains(&format!("{} of its {} samples", c.colliding_samples, c.samples)),
        "{}",
        s.statement
    );
    // the reported pose: every pair computed exactly gives the same least distance
    let d = r.execution.delivered.as_ref().unwrap();
    let n = p.robot.dof();
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    assert_eq!(d.eval(c.t, &mut q, &mut qd, &mut qdd), c.segment);
    let sc = check_scene(&p);
    let (least, label) = brute_min(&p, &sc, &q);
    assert!((least - c.distance).abs() < 1e-12, "{least} vs {c:?}");
    assert_eq!(label, c.pair);
    // the count of colliding samples: every sample of the 1 kHz grid (whose
    // periods 2, 3 repeat period 1 bitwise) with every pair computed exactly
    let s1k = d.sample(1000.0).unwrap();
    assert_eq!(s1k.len(), c.samples);
    let colliding = (0..s1k.len()).filter(|&k| brute_min(&p, &sc, &s1k.q[k]).0 <= 0.0).count();
    assert_eq!(colliding, c.colliding_samples);
    // no sample of a 20 ms subgrid is closer than the reported minimum
    let mut t = 0.0;
    while t <= d.duration() {
        d.eval(t, &mut q, &mut qd, &mut qdd);
        let (v, _) = brute_min(&p, &sc, &q);
        assert!(v >= c.distance - 1e-12, "t = {t}: {v} < {}", c.distance);
        t += 0.02;
    }
    // the design's own constraints hold: feasible, but not playable
    assert_eq!(r.status, Status::Feasible);
    let why = r.playable().unwrap_err();
    assert!(why.contains("NOT safe to play") && why.contains(&c.pair), "{why}");
}

#[test]
fn the_check_of_a_still_trajectory_is_the_distance_at_its_pose() {
    // q = 0: the UR5 stretched out horizontally, wrist below the mounting plane;
    // the excite_ur5 q0: clear of everything
    let safe_q0 = ExciteDesign::load(&root("designs/excite_ur5.toml")).unwrap().trajectory.q0.unwrap();
    for (q0, safe) in [(vec![0.0; 6], false), (safe_q0, true)] {
        let p = design("excite_ur5_bench", |d| d.trajectory.q0 = Some(q0.clone()));
        let tr = FourierTrajectory::at_rest(q0.clone(), 5, 2.0 * std::f64::consts::PI * 0.1);
        let e = deliver(&p, &tr.into()).unwrap();
        let s = &e.safety;
        assert_eq!(s.collisions, CollisionCheck::CheckedAfterwards);
        assert_eq!(s.safe, Some(safe), "{}", s.statement);
        let c = s.closest.as_ref().unwrap();
        let (least, label) = brute_min(&p, &check_scene(&p), &q0);
        assert_eq!(c.distance, least, "{q0:?}");
        assert_eq!(c.pair, label);
        // every sample is the same pose: the first one is reported, and every
        // sample collides or none
        assert_eq!(c.t, 0.0);
        assert_eq!(c.colliding_samples, if safe { 0 } else { c.samples });
        if safe {
            assert!(c.distance > 0.0 && s.statement.contains("collision-free"), "{}", s.statement);
        }
    }
}

#[test]
fn the_verdict_does_not_depend_on_the_thread_count() {
    let p = design("excite_ur5_bench", |_| {});
    let r = run(&p, &Control::new()).unwrap();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let three = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
    let a = one.install(|| deliver(&p, &r.trajectory).unwrap());
    let b = three.install(|| deliver(&p, &r.trajectory).unwrap());
    assert_eq!(a.safety, b.safety);
    assert_eq!(a.safety, r.execution.safety);
}

#[test]
fn imposed_and_unchecked_collisions_are_named() {
    let p = design("excite_ur5", |_| {});
    let r = run(&p, &Control::new()).unwrap();
    assert_eq!(r.status, Status::Feasible);
    assert_eq!(r.execution.safety.collisions, CollisionCheck::Imposed);
    assert_eq!(r.execution.safety.safe, Some(true));
    assert!(r.playable().is_ok());
    // the stand-in industrial robot has no collision geometry: nothing is claimed
    let p = design("excite_industrial6_full", |_| {});
    let r = run(&p, &Control::new()).unwrap();
    let s = &r.execution.safety;
    assert_eq!(r.status, Status::Feasible);
    assert_eq!(s.collisions, CollisionCheck::NotChecked);
    assert_eq!(s.safe, None);
    assert!(s.statement.contains("NOT checked"), "{}", s.statement);
    assert!(r.playable().is_ok());
}

#[test]
fn the_command_line_names_the_collision_and_writes_no_export() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench");
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .current_dir(root(""))
        .args(["excite", "designs/excite_ur5_bench.toml", "--time-limit", "2", "--export", "csv", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("NOT safe to play"), "{stdout}");
    assert!(stderr.contains("no controller export: NOT safe to play"), "{stderr}");
    let report = std::fs::read_to_string(out.join("report.txt")).unwrap();
    assert!(report.contains("\nsafety: NOT safe to play"), "{report}");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let s = &json["result"]["execution"]["safety"];
    assert_eq!(s["collisions"], "checked_afterwards");
    assert_eq!(s["safe"], false);
    assert!(s["closest"]["distance"].as_f64().unwrap() < 0.0);
    let status = std::fs::read_to_string(out.join("status.json")).unwrap();
    assert!(status.contains("NOT safe to play"), "{status}");
    let status: serde_json::Value = serde_json::from_str(&status).unwrap();
    assert_eq!(status["summary"]["safe_to_play"], false);
    // `idexp export` of the written coefficients refuses as well (input error)
    let o = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["export", "--format", "csv"])
        .arg(out.join("coefficients.json"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("coefficients.json") && stderr.contains("safety") && stderr.contains("NOT safe to play"),
        "{stderr}"
    );
    // no export of any kind was written
    for e in std::fs::read_dir(&out).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().to_string();
        assert!(!name.contains("_export"), "{name}");
    }
}
