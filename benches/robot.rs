//! Kernel benchmarks, single thread: RNEA calls, regressor rows (one n×p block
//! per state), regressor derivatives, mass matrix (allocating and into a
//! buffer), allocation-free forward dynamics, the derivatives of inverse
//! dynamics into buffers (`id_derivatives`) and row by row, one parameter
//! vector per torque row (`id_derivative_rows`, the excitation gradient's
//! kernel), for a 6-axis (UR5, PUMA 560,
//! the coupled-wrist industrial arm) and a 7-axis (iiwa 14, Panda) robot.
//!
//! Run: `cargo bench --bench robot`. Each run also writes its states, one
//! line per state (q, q̇, q̈), to `target/bench-states/<robot>.txt`: the
//! states that `scripts/pinocchio-timing.sh` times Pinocchio on.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::robot::{self, Workspace};
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use std::path::Path;

fn states(r: &robot::Robot, k: usize) -> Vec<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    (0..k)
        .map(|_| {
            let n = r.dof();
            let f = |g: &mut rand_chacha::ChaCha8Rng, a: f64| (0..n).map(|_| g.random_range(-a..a)).collect::<Vec<f64>>();
            (f(&mut g, 2.0), f(&mut g, 1.5), f(&mut g, 4.0))
        })
        .collect()
}

/// The bench's states as text for the Pinocchio side (scripts/pinocchio-timing.sh).
fn write_states(root: &Path, name: &str, st: &[(Vec<f64>, Vec<f64>, Vec<f64>)]) {
    let dir = std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), std::path::PathBuf::from)
        .join("bench-states");
    let text: String = st
        .iter()
        .map(|(q, qd, qdd)| {
            let v: Vec<String> = q.iter().chain(qd).chain(qdd).map(|x| format!("{x:e}")).collect();
            v.join(" ") + "\n"
        })
        .collect();
    if let Err(e) = std::fs::create_dir_all(&dir).and_then(|_| std::fs::write(dir.join(format!("{name}.txt")), text)) {
        eprintln!("bench states not written to {}: {e}", dir.display());
    }
}

fn bench(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for name in ["ur5", "puma560", "industrial6", "iiwa14", "panda"] {
        let path = root.join(format!("designs/robots/{name}.toml"));
        let Ok(r) = robot::load(&path) else { continue };
        let n = r.dof();
        let p = r.n_params();
        let st = states(&r, 64);
        write_states(root, name, &st);
        let mut ws = Workspace::new(&r);
        let mut tau = vec![0.0; n];
        let mut y = vec![0.0; n * p];
        let mut g = c.benchmark_group(format!("{name}_{n}dof"));
        let mut k = 0usize;
        g.bench_function("rnea", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                robot::rnea(&r, &mut ws, black_box(&s.0), black_box(&s.1), black_box(&s.2), &mut tau);
                black_box(&tau);
            })
        });
        g.bench_function("regressor_row_block", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                robot::regressor_rows(&r, &mut ws, black_box(&s.0), black_box(&s.1), black_box(&s.2), &mut y);
                black_box(&y);
            })
        });
        g.bench_function("mass_matrix", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                black_box(robot::mass_matrix(&r, &mut ws, black_box(&s.0)));
            })
        });
        let mut mm = nalgebra::DMatrix::zeros(n, n);
        g.bench_function("mass_matrix_into", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                robot::mass_matrix_into(&r, &mut ws, black_box(&s.0), &mut mm);
                black_box(&mm);
            })
        });
        let mut qdd = vec![0.0; n];
        g.bench_function("forward_dynamics_into", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                // s.2 as motor torques (N·m): any finite input will do
                robot::forward_dynamics_into(&r, &mut ws, black_box(&s.0), black_box(&s.1), black_box(&s.2), &mut qdd).expect("fd");
                black_box(&qdd);
            })
        });
        let mut dq = vec![vec![0.0; n * p]; n];
        let mut dqd = dq.clone();
        let mut dqdd = dq.clone();
        g.bench_function("regressor_derivatives", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                robot::regressor_derivatives(&r, &mut ws, &s.0, &s.1, &s.2, &mut y, &mut dq, &mut dqd, &mut dqdd);
                black_box(&dq);
            })
        });
        let theta = r.nominal_params();
        let (mut gq, mut gqd) = (nalgebra::DMatrix::zeros(n, n), nalgebra::DMatrix::zeros(n, n));
        g.bench_function("id_derivatives", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                robot::dynamics::id_derivatives_into(&r, &mut ws, theta.as_slice(), &s.0, &s.1, &s.2, &mut gq, &mut gqd);
                black_box((&gq, &gqd));
            })
        });
        // one parameter vector per torque row (the excitation gradient's kernel)
        let thetas: Vec<f64> = (0..n).flat_map(|_| theta.iter().copied()).collect();
        let (mut rq, mut rqd, mut rqdd) = (vec![0.0; n * n], vec![0.0; n * n], vec![0.0; n * n]);
        g.bench_function("id_derivative_rows", |b| {
            b.iter(|| {
                let s = &st[k % st.len()];
                k += 1;
                robot::id_derivative_rows(&r, &mut ws, &thetas, &s.0, &s.1, &s.2, &mut rq, &mut rqd, &mut rqdd);
                black_box((&rq, &rqd, &rqdd));
            })
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
