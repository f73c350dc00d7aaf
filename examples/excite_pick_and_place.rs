//! A production-like motion for `idexp assess` (paper 000, process 1): a UR5
//! picks parts at random points of one area and places them at random points
//! of another, joint-space quintic moves with rest at every waypoint, 50
//! cycles; the wrist joint 5 keeps the tool vertical (it does not move).
//! Writes the `t, q, qd, qdd` CSV at 100 Hz.
//!
//! Run: `cargo run --release --example excite_pick_and_place [-- out/pick_and_place.csv]`,
//! then `cargo run --release -- assess designs/robots/ur5.toml out/pick_and_place.csv`.

use idexp::io::States;
use rand::{RngExt, SeedableRng};
use std::path::PathBuf;

/// Quintic rest-to-rest blend s(τ), τ ∈ [0, 1], with s', s''.
fn quintic(tau: f64) -> (f64, f64, f64) {
    let (t2, t3) = (tau * tau, tau * tau * tau);
    (
        10.0 * t3 - 15.0 * t3 * tau + 6.0 * t3 * t2,
        30.0 * t2 - 60.0 * t3 + 30.0 * t2 * t2,
        60.0 * tau - 180.0 * t2 + 120.0 * t3,
    )
}

fn main() -> Result<(), idexp::Error> {
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("out/pick_and_place.csv"));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let area = |centre: f64, rng: &mut rand_chacha::ChaCha8Rng| -> [f64; 6] {
        [
            centre + rng.random_range(-0.25..0.25),
            -1.2 + rng.random_range(-0.2..0.2),
            1.6 + rng.random_range(-0.2..0.2),
            -1.97 + rng.random_range(-0.1..0.1),
            -std::f64::consts::FRAC_PI_2,
            rng.random_range(-1.0..1.0),
        ]
    };
    // waypoints: above pick, pick, above pick, above place, place, above place, ...
    let mut way: Vec<[f64; 6]> = Vec::new();
    for _ in 0..50 {
        for centre in [0.7, -0.7] {
            let p = area(centre, &mut rng);
            let mut above = p;
            above[1] += 0.25;
            above[2] -= 0.35;
            above[3] += 0.1;
            way.extend([above, p, above]);
        }
    }
    let (rate, seg) = (100.0, 0.8);
    let mut s = States {
        t: Some(Vec::new()),
        q: Vec::new(),
        qd: Vec::new(),
        qdd: Vec::new(),
    };
    let steps = (seg * rate) as usize;
    for w in way.windows(2) {
        for i in 0..steps {
            let tau = i as f64 / steps as f64;
            let (b, bd, bdd) = quintic(tau);
            let t = s.q.len() as f64 / rate;
            if let Some(v) = s.t.as_mut() {
                v.push(t);
            }
            s.q.push((0..6).map(|j| w[0][j] + b * (w[1][j] - w[0][j])).collect());
            s.qd.push((0..6).map(|j| bd / seg * (w[1][j] - w[0][j])).collect());
            s.qdd.push((0..6).map(|j| bdd / (seg * seg) * (w[1][j] - w[0][j])).collect());
        }
    }
    s.write(&out)?;
    println!(
        "wrote {} samples ({:.0} s of pick and place) to {}",
        s.len(),
        s.len() as f64 / rate,
        out.display()
    );
    Ok(())
}
