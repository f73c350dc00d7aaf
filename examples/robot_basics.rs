//! Load a shipped robot, evaluate its inverse dynamics along a Fourier
//! trajectory, check τ = Y θ and print its base parameters.
//!
//! Run: `cargo run --release --example robot_basics [designs/robots/<robot>.toml]`

use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Workspace};
use idexp::trajectory::FourierTrajectory;
use std::path::PathBuf;

fn main() -> idexp::Result<()> {
    let path = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("designs/robots/puma560.toml"));
    let r = robot::load(&path)?;
    let n = r.dof();
    println!("{}: {} joints, {} standard parameters", r.name, n, r.n_params());

    // A small periodic motion: 2 harmonics of 0.2 Hz on every joint.
    let a: Vec<Vec<f64>> = (0..n).map(|j| vec![0.2 + 0.02 * j as f64, -0.1]).collect();
    let b: Vec<Vec<f64>> = (0..n).map(|_| vec![0.05, 0.1]).collect();
    let traj = FourierTrajectory::new(std::f64::consts::TAU * 0.2, vec![0.0; n], a, b)?;
    let states = traj.sample(50.0)?;

    let mut ws = Workspace::new(&r);
    let theta = r.nominal_params();
    let mut tau = vec![0.0; n];
    let mut y = nalgebra::DMatrix::zeros(n, r.n_params());
    let mut worst: f64 = 0.0;
    let mut peak = vec![0.0f64; n];
    for k in 0..states.len() {
        robot::rnea(&r, &mut ws, &states.q[k], &states.qd[k], &states.qdd[k], &mut tau);
        robot::regressor(&r, &mut ws, &states.q[k], &states.qd[k], &states.qdd[k], &mut y);
        let ytheta = &y * &theta;
        for j in 0..n {
            worst = worst.max((ytheta[j] - tau[j]).abs());
            peak[j] = peak[j].max(tau[j].abs());
        }
    }
    println!("{} samples over {:.1} s; max |Yθ − τ| = {worst:.2e} N·m", states.len(), traj.period());
    println!(
        "peak |τ| per joint (N·m): {:?}",
        peak.iter().map(|v| (v * 10.0).round() / 10.0).collect::<Vec<_>>()
    );

    let base = BaseParams::compute(&r, &BaseOptions::default())?;
    println!("{} base parameters, for example:", base.n_base());
    for g in base.groupings.iter().take(5) {
        println!("  {g}");
    }
    Ok(())
}
