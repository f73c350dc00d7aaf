//! Cost of the collision constraints (issue 11): the constraint set of
//! designs/excite_ur5.toml (UR5 meshes, 21 pairs) and
//! designs/excite_panda_table.toml (Panda meshes, 28 pairs) evaluated with
//! and without collision checking, values only (one GA evaluation's
//! constraints) and with the Jacobian (one refinement step), the latter also
//! without the broad phase (every pair queried at every grid time: the cost
//! before culling); plus the distances of every pair at one configuration.
//!
//! Run: `cargo bench --bench collision -- --warm-up-time 1 --measurement-time 3`.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::excitation::Problem;
use idexp::robot::kinematics::Kin;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use std::path::Path;

fn problem(design: &str, collision: bool) -> Problem {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("designs");
    let mut d = idexp::excitation::design::ExciteDesign::load(&root.join(design)).expect("design");
    d.collision.enabled = collision;
    let robot = idexp::robot::load(&d.robot).expect("robot");
    Problem::new(d, robot, design).expect("problem")
}

fn bench(c: &mut Criterion) {
    for (design, label) in [("excite_ur5.toml", "ur5"), ("excite_panda_table.toml", "panda")] {
        let mut grp = c.benchmark_group(format!("collision_{label}"));
        for on in [false, true] {
            let p = problem(design, on);
            let nv = p.layout.n_vars();
            let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
            let mut x: Vec<f64> = (0..nv).map(|i| g.random_range(p.lower[i]..p.upper[i]) * 0.3).collect();
            p.constraints.repair_joints(&mut x, &p.limits, 1e-6);
            let mut cw = p.constraints.workspace();
            let mut cval = vec![0.0; p.constraints.len()];
            let mut jac = vec![0.0; p.constraints.len() * nv];
            let tag = if on { "with_collision" } else { "without_collision" };
            grp.bench_function(format!("constraints_{tag}"), |b| {
                b.iter(|| {
                    p.constraints.eval(black_box(&x), &mut cw, &mut cval, None);
                    black_box(&cval);
                })
            });
            grp.bench_function(format!("constraints_and_jacobian_{tag}"), |b| {
                b.iter(|| {
                    p.constraints.eval(black_box(&x), &mut cw, &mut cval, Some(&mut jac));
                    black_box(&jac);
                })
            });
            if on {
                // the reference: every pair queried at every grid time (no broad phase)
                let mut bw = p.constraints.workspace();
                bw.set_exhaustive(true);
                grp.bench_function("constraints_and_jacobian_with_collision_exhaustive", |b| {
                    b.iter(|| {
                        p.constraints.eval(black_box(&x), &mut bw, &mut cval, Some(&mut jac));
                        black_box(&jac);
                    })
                });
                p.constraints.eval(&x, &mut cw, &mut cval, None);
                p.constraints.eval(&x, &mut bw, &mut cval, None);
                eprintln!(
                    "{label}: {} exact distance queries per evaluation with the broad phase, {} without",
                    cw.distance_queries(),
                    bw.distance_queries()
                );
                let sc = p.constraints.scene().expect("scene");
                let mut kin = Kin::new(p.robot.dof());
                let q = p.layout.trajectory(&x).q0.clone();
                grp.bench_function("all_pairs_one_configuration", |b| {
                    b.iter(|| black_box(sc.distances(&p.robot, &mut kin, black_box(&q), sc.cap)))
                });
            }
        }
        grp.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
