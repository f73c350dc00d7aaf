//! Shared helpers for the integration tests.
#![allow(dead_code)]

use idexp::robot::{self, Robot};
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

/// Path relative to the crate root.
pub fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The test robots plus every robot file shipped in designs/robots/.
pub fn all_robots() -> Vec<Robot> {
    let mut v: Vec<Robot> = ["tests/data/coupled6_modified.toml", "tests/data/rpr_standard.toml", "tests/data/tree.urdf"]
        .iter()
        .map(|p| robot::load(&root(p)).unwrap_or_else(|e| panic!("{p}: {e}")))
        .collect();
    v.extend(shipped_robots().into_iter().map(|(_, r)| r));
    v
}

/// Every `.toml` robot file in designs/robots/ with its stem.
pub fn shipped_robots() -> Vec<(String, Robot)> {
    let dir = root("designs/robots");
    let mut out = Vec::new();
    if let Ok(rd) = std::fs::read_dir(&dir) {
        let mut paths: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        paths.sort();
        for p in paths {
            let r = robot::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            out.push((p.file_stem().unwrap().to_string_lossy().into_owned(), r));
        }
    }
    out
}

/// A random state within the joint limits (velocities bounded away from zero
/// so that finite differences do not cross a friction discontinuity).
pub fn random_state(robot: &Robot, rng: &mut rand_chacha::ChaCha8Rng) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = robot.dof();
    let mut q = vec![0.0; n];
    let mut qd = vec![0.0; n];
    let mut qdd = vec![0.0; n];
    for j in 0..n {
        let l = &robot.joints[j].limits;
        let lo = if l.lower.is_finite() { l.lower } else { -3.0 };
        let hi = if l.upper.is_finite() { l.upper } else { 3.0 };
        q[j] = rng.random_range(lo..=hi);
        let s: f64 = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        qd[j] = s * rng.random_range(0.05..2.0);
        qdd[j] = rng.random_range(-5.0..5.0);
    }
    (q, qd, qdd)
}

/// Seeded RNG.
pub fn rng(seed: u64) -> rand_chacha::ChaCha8Rng {
    rand_chacha::ChaCha8Rng::seed_from_u64(seed)
}
