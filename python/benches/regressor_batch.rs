//! The Rust side of the binding-overhead benchmark: what `robot.regressor(q,
//! qd, qdd)` does for a batch of 10,000 UR5 states, in Rust — allocate the
//! (N·n × p) stack and fill it state by state with one workspace — so that
//! `python/bench/regressor_overhead.py` (the same call from Python, with the
//! same states) measures the binding's overhead (argument conversion, output
//! wrapping).
//!
//! Run: `cargo bench -p idexp-python --bench regressor_batch`.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::robot::{self, Workspace};
use std::hint::black_box;
use std::path::Path;

/// The states of the Python script: q_kj = 2 sin(0.37 k + j), q̇ = 1.5 cos(0.23 k + 2 j), q̈ = 4 sin(0.11 k + 3 j).
fn states(n: usize, k: usize) -> [Vec<f64>; 3] {
    let f = |a: f64, w: f64, c: f64, trig: fn(f64) -> f64| -> Vec<f64> {
        (0..k).flat_map(|i| (0..n).map(move |j| a * trig(w * i as f64 + c * j as f64))).collect()
    };
    [f(2.0, 0.37, 1.0, f64::sin), f(1.5, 0.23, 2.0, f64::cos), f(4.0, 0.11, 3.0, f64::sin)]
}

fn bench(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let r = robot::load(&root.join("designs/robots/ur5.toml")).expect("the shipped UR5");
    let (n, p) = (r.dof(), r.n_params());
    let big = 10_000;
    let [q, qd, qdd] = states(n, big);
    let mut g = c.benchmark_group("ur5_regressor_batch");
    g.sample_size(20);
    g.bench_function("10000_states", |b| {
        b.iter(|| {
            let mut ws = Workspace::new(&r);
            let mut out = vec![0.0; big * n * p];
            for (k, y) in out.chunks_mut(n * p).enumerate() {
                let s = k * n..(k + 1) * n;
                robot::regressor_rows(&r, &mut ws, &q[s.clone()], &qd[s.clone()], &qdd[s], y);
            }
            black_box(out)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
