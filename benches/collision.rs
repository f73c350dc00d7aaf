//! Cost of the collision constraints (issue 11): the constraint set of
//! designs/excite_ur5.toml (UR5 meshes, 21 pairs) and
//! designs/excite_panda_table.toml (Panda meshes, 28 pairs), one evaluation
//! at a fixed random design point:
//!
//! * `ga_eval_*`: what one GA evaluation costs (values only): without
//!   collision checking; with it as the GA now evaluates it
//!   ([`Constraints::eval_selection`]: distances capped at the margin,
//!   hill-climbing support points); and as before (`eval` with the full cap,
//!   support points by a scan over every hull vertex: parry's `contact`);
//! * `refine_eval_*`: one refinement step (values and the Jacobian): without
//!   collision, with it (climbing), with parry's scan (before), and without
//!   the broad phase (every pair at every grid time);
//! * the distances of every pair at one configuration;
//! * the per-pose collision check of the delivered trajectory over one
//!   second of the trajectory at 1 kHz: each pose alone
//!   (`Constraints::collision_at`) and along the path with the pairs' last
//!   normals carried over (`Constraints::collision_along`, what the check
//!   uses: the support-function bound clears most poses without a query).
//!
//! The query counts printed are those of the culled evaluation (spheres,
//! support-function bound along the last exact normal, capsules, then the
//! exact query), with the number of grid times the support bound ruled out.
//!
//! Run: `cargo bench --bench collision -- --warm-up-time 1 --measurement-time 3`.

use criterion::{criterion_group, criterion_main, Criterion};
use idexp::excitation::constraints::Constraints;
use idexp::excitation::Problem;
use idexp::robot::collision::NarrowPhase;
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
            let nv = idexp::trajectory::TrajectoryShape::n_vars(&p.shape);
            let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
            let mut x: Vec<f64> = (0..nv).map(|i| g.random_range(p.lower[i]..p.upper[i]) * 0.3).collect();
            p.constraints.repair_joints(&mut x, &p.limits, 1e-6);
            let nc = p.constraints.len();
            let mut cval = vec![0.0; nc];
            let mut jac = vec![0.0; nc * nv];
            let variants: Vec<(&str, Constraints, bool)> = if on {
                vec![
                    ("with_collision", p.constraints.clone(), false),
                    ("with_collision_scan", p.constraints.clone().with_narrow_phase(NarrowPhase::Scan), false),
                    ("with_collision_exhaustive", p.constraints.clone(), true),
                ]
            } else {
                vec![("without_collision", p.constraints.clone(), false)]
            };
            for (tag, cons, exhaustive) in &variants {
                let mut cw = cons.workspace();
                cw.set_exhaustive(*exhaustive);
                if !exhaustive {
                    grp.bench_function(format!("ga_eval_{tag}"), |b| {
                        b.iter(|| {
                            cons.eval_selection(black_box(&x), &mut cw, &mut cval);
                            black_box(&cval);
                        })
                    });
                }
                if *tag != "without_collision" && !exhaustive {
                    grp.bench_function(format!("ga_eval_full_cap_{tag}"), |b| {
                        b.iter(|| {
                            cons.eval(black_box(&x), &mut cw, &mut cval, None);
                            black_box(&cval);
                        })
                    });
                }
                grp.bench_function(format!("refine_eval_{tag}"), |b| {
                    b.iter(|| {
                        cons.eval(black_box(&x), &mut cw, &mut cval, Some(&mut jac));
                        black_box(&jac);
                    })
                });
                if on {
                    cons.eval(&x, &mut cw, &mut cval, None);
                    let full = cw.distance_queries();
                    let per_pair = cw.distance_queries_per_pair();
                    cons.eval_selection(&x, &mut cw, &mut cval);
                    eprintln!(
                        "{label} {tag}: {full} exact distance queries per evaluation (full cap; per pair {per_pair:?}), {} for the selection ({} grid times ruled out by the support bound)",
                        cw.distance_queries(),
                        cw.support_skips_per_pair().iter().sum::<usize>()
                    );
                }
            }
            if on {
                let sc = p.constraints.scene().expect("scene");
                let mut kin = Kin::new(p.robot.dof());
                let q = p.shape.fourier().expect("a Fourier design").trajectory(&x).q0.clone();
                grp.bench_function("all_pairs_one_configuration", |b| {
                    b.iter(|| black_box(sc.distances(&p.robot, &mut kin, black_box(&q), sc.cap)))
                });
                // one second of the trajectory at 1 kHz, as the delivered-trajectory check sees it
                let tr = p.shape.fourier().expect("a Fourier design").trajectory(&x);
                let n = p.robot.dof();
                let path: Vec<Vec<f64>> = (0..1000)
                    .map(|i| {
                        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                        tr.eval(i as f64 * 1e-3, &mut q, &mut qd, &mut qdd);
                        q
                    })
                    .collect();
                let mut ws = idexp::robot::Workspace::new(&p.robot);
                grp.bench_function("check_1000_poses_each_alone", |b| {
                    b.iter(|| {
                        for q in &path {
                            black_box(p.constraints.collision_at(&mut ws, q));
                        }
                    })
                });
                grp.bench_function("check_1000_poses_along_the_path", |b| {
                    b.iter(|| {
                        let mut hints = Vec::new();
                        for q in &path {
                            black_box(p.constraints.collision_along(&mut ws, q, &mut hints));
                        }
                    })
                });
            }
        }
        grp.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
