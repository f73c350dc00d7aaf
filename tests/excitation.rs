//! Excitation design kernels: the criterion against an independent
//! computation, analytic gradients of the criterion and of every constraint
//! type against central finite differences, the continuous joint extrema
//! against a dense grid, the identifiability report.

use idexp::excitation::constraints::{joint_extremum, Constraints, JointLimitSpec};
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::grid::TrigGrid;
use idexp::excitation::objective::{BaseColumns, Criterion, Objective, Scaling, Scoring};
use idexp::excitation::{assess, Problem};
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::cartesian::{CartesianConstraint, Shape};
use idexp::robot::{self, Robot};
use idexp::trajectory::{period_grid, FourierLayout, FourierTrajectory};
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn load(name: &str) -> Robot {
    robot::load(&root(&format!("designs/robots/{name}.toml"))).unwrap()
}

fn random_x(n: usize, scale: f64, seed: u64) -> Vec<f64> {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| g.random_range(-scale..scale)).collect()
}

fn objective(r: &Robot, lay: &FourierLayout, rate: f64, crit: Criterion, scaling: Scaling, noise: &[f64]) -> (Objective, BaseParams) {
    let b = BaseParams::compute(r, &BaseOptions::default()).unwrap();
    let th = r.nominal_params();
    let nom: Vec<f64> = b.base_values(th.as_slice()).iter().copied().collect();
    let times = period_grid(std::f64::consts::TAU / lay.omega, rate).unwrap();
    let o = Objective::new(
        r.clone(),
        lay.clone(),
        BaseColumns {
            indices: b.independent.clone(),
            names: b.names.clone(),
            nominal: nom,
        },
        times,
        Scoring {
            criterion: crit,
            scaling,
            noise: noise.to_vec(),
        },
    )
    .unwrap();
    (o, b)
}

#[test]
fn criterion_equals_an_independent_svd_of_the_stacked_base_regressor() {
    let r = load("ur5");
    let lay = FourierLayout::new(vec![0.1, -0.3, 0.5, 0.0, 0.2, -0.1], 5, std::f64::consts::TAU * 0.1, false, false).unwrap();
    let (o, b) = objective(&r, &lay, 10.0, Criterion::Cond, Scaling::UnitColumn, &[1.0; 6]);
    let x = random_x(lay.n_vars(), 0.6, 3);
    let mut w = o.workspace();
    let cond = o.value(&x, &mut w);
    // independent: nalgebra regressor, selected columns, normalised, nalgebra SVD
    let tr = lay.trajectory(&x);
    let s = tr.sample(10.0).unwrap();
    let mut ws = robot::Workspace::new(&r);
    let p = r.n_params();
    let mut stack = nalgebra::DMatrix::zeros(6 * s.len(), p);
    let mut y = nalgebra::DMatrix::zeros(6, p);
    for i in 0..s.len() {
        robot::regressor(&r, &mut ws, &s.q[i], &s.qd[i], &s.qdd[i], &mut y);
        stack.view_mut((6 * i, 0), (6, p)).copy_from(&y);
    }
    let mut cb = b.select(&stack);
    for mut c in cb.column_iter_mut() {
        let n = c.norm();
        c /= n;
    }
    let sv = cb.singular_values();
    let want = sv.max() / sv.min();
    assert_eq!(cb.ncols(), 48);
    assert!((cond - want).abs() < 1e-9 * want, "{cond} vs {want}");
    // log det and 1/σ_min as well
    let (o2, _) = objective(&r, &lay, 10.0, Criterion::LogDet, Scaling::UnitColumn, &[1.0; 6]);
    let ld = o2.value(&x, &mut o2.workspace());
    let want_ld = -2.0 * sv.iter().map(|v| v.ln()).sum::<f64>();
    assert!((ld - want_ld).abs() < 1e-8 * want_ld.abs().max(1.0), "{ld} vs {want_ld}");
    let (o3, _) = objective(&r, &lay, 10.0, Criterion::InvSigmaMin, Scaling::UnitColumn, &[1.0; 6]);
    let is = o3.value(&x, &mut o3.workspace());
    assert!((is - 1.0 / sv.min()).abs() < 1e-9 / sv.min());
}

#[allow(clippy::too_many_arguments)] // test helper: one argument per varied setting of the gradient check
fn check_objective_gradient(r: &Robot, lay: &FourierLayout, rate: f64, crit: Criterion, scaling: Scaling, noise: &[f64], seed: u64, tol: f64) {
    let (o, _) = objective(r, lay, rate, crit, scaling, noise);
    let mut w = o.workspace();
    let mut x = random_x(lay.n_vars(), 0.5, seed);
    if lay.vary_q0 {
        let vpj = lay.vars_per_joint();
        for j in 0..lay.n {
            x[j * vpj] = 0.3 * (j as f64 - 2.0);
        }
    }
    let mut g = vec![0.0; x.len()];
    let f = o.value_grad(&x, &mut w, &mut g);
    assert!(f.is_finite());
    let h = 1e-6;
    let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for i in 0..x.len() {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[i] += h;
        xm[i] -= h;
        let fd = (o.value(&xp, &mut w) - o.value(&xm, &mut w)) / (2.0 * h);
        assert!(
            (fd - g[i]).abs() <= tol * gmax.max(1e-8) + 1e-6 * g[i].abs(),
            "{} {crit:?} {scaling:?} var {i}: analytic {} vs fd {fd}",
            r.name,
            g[i]
        );
    }
}

#[test]
fn objective_gradients_match_finite_differences() {
    let ur5 = load("ur5");
    let w = std::f64::consts::TAU * 0.2;
    let lay = FourierLayout::new(vec![0.0; 6], 3, w, false, false).unwrap();
    for crit in [Criterion::Cond, Criterion::LogDet, Criterion::InvSigmaMin] {
        check_objective_gradient(&ur5, &lay, 8.0, crit, Scaling::UnitColumn, &[1.0; 6], 1, 1e-5);
    }
    // nominal scaling: badly conditioned (small nominal values), the finite differences lose digits
    check_objective_gradient(&ur5, &lay, 8.0, Criterion::Cond, Scaling::Nominal, &[0.5, 1.0, 2.0, 1.0, 0.3, 0.4], 2, 1e-4);
    check_objective_gradient(&ur5, &lay, 8.0, Criterion::LogDet, Scaling::None, &[1.0; 6], 3, 1e-5);
    // coupled wrist, q0 free, start and end at rest
    let ind = load("industrial6");
    let lay = FourierLayout::new(vec![0.0, -1.0, 0.2, 0.0, 0.3, 0.0], 3, w, true, true).unwrap();
    check_objective_gradient(&ind, &lay, 8.0, Criterion::Cond, Scaling::UnitColumn, &[2.0, 2.0, 1.0, 0.5, 0.5, 0.2], 4, 1e-5);
    // 7 joints
    let panda = load("panda");
    let lay = FourierLayout::new(vec![0.0, 0.0, 0.0, -1.5, 0.0, 1.8, 0.0], 2, w, false, false).unwrap();
    check_objective_gradient(&panda, &lay, 10.0, Criterion::Cond, Scaling::UnitColumn, &[1.0; 7], 5, 1e-5);
}

fn limits_for(r: &Robot, frac: f64, torque: bool) -> JointLimitSpec {
    JointLimitSpec {
        position: r
            .joints
            .iter()
            .map(|j| {
                let (c, h) = (0.5 * (j.limits.lower + j.limits.upper), 0.5 * (j.limits.upper - j.limits.lower));
                [c - frac * h, c + frac * h]
            })
            .collect(),
        velocity: r.joints.iter().map(|j| j.limits.velocity).collect(),
        acceleration: r.joints.iter().map(|j| j.limits.acceleration).collect(),
        torque: r.joints.iter().map(|j| if torque { j.limits.effort } else { f64::INFINITY }).collect(),
    }
}

#[test]
fn constraint_gradients_match_finite_differences_for_every_constraint_type() {
    let r = load("industrial6");
    let w = std::f64::consts::TAU * 0.2;
    let q0 = vec![0.0, -1.047, 0.209, 0.0, 0.3, 0.0];
    let lay = FourierLayout::new(q0.clone(), 3, w, true, false).unwrap();
    let shapes = vec![
        Shape::Box {
            min: [0.2, -1.5, 0.5],
            max: [2.0, 1.5, 2.5],
        },
        Shape::Sphere {
            center: [0.0, 0.0, 0.675],
            radius: 2.0,
        },
        Shape::HalfSpace {
            normal: [0.2, 0.1, 1.0],
            offset: 0.3,
        },
        // a wall-like obstacle: the nearest face stays the y = 1 face (the
        // margin is a maximum over faces, not differentiable where faces swap)
        Shape::OutsideBox {
            min: [-5.0, 1.0, -5.0],
            max: [5.0, 2.0, 5.0],
            clearance: 0.05,
        },
        Shape::Sector {
            center: [0.0, 0.0, 0.0],
            azimuth: [-0.9, 0.9],
            radius: [0.5, 1.8],
            z: [0.8, 2.4],
        },
    ];
    let cart: Vec<CartesianConstraint> = shapes
        .into_iter()
        .enumerate()
        .map(|(i, shape)| CartesianConstraint {
            frame: Some(if i % 2 == 0 { "tool0".into() } else { "link4".into() }),
            shape,
        })
        .collect();
    let c = Constraints::new(r.clone(), lay.clone(), &limits_for(&r, 0.9, true), &cart, 200.0, "test").unwrap();
    let kinds: std::collections::BTreeSet<String> = c.info.iter().map(|i| format!("{:?}", i.kind)).collect();
    assert_eq!(kinds.len(), 5, "{kinds:?}");
    let mut cw = c.workspace();
    let nv = lay.n_vars();
    for seed in 0..3u64 {
        let mut x = random_x(nv, 0.4, 10 + seed);
        for j in 0..6 {
            x[j * lay.vars_per_joint()] = q0[j];
        }
        let mut val = vec![0.0; c.len()];
        let mut jac = vec![0.0; c.len() * nv];
        c.eval(&x, &mut cw, &mut val, Some(&mut jac));
        let h = 1e-7;
        let mut vp = vec![0.0; c.len()];
        let mut vm = vec![0.0; c.len()];
        for v in 0..nv {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[v] += h;
            xm[v] -= h;
            c.eval(&xp, &mut cw, &mut vp, None);
            c.eval(&xm, &mut cw, &mut vm, None);
            for i in 0..c.len() {
                let fd = (vp[i] - vm[i]) / (2.0 * h);
                let an = jac[i * nv + v];
                let rowmax = (0..nv).map(|k| jac[i * nv + k].abs()).fold(0.0, f64::max);
                assert!(
                    (fd - an).abs() <= 2e-4 * rowmax.max(1e-6),
                    "seed {seed} constraint `{}` var {v}: analytic {an} vs fd {fd}",
                    c.info[i].name
                );
            }
        }
    }
}

#[test]
fn continuous_joint_extrema_bound_a_dense_grid_and_are_attained() {
    let tr = FourierTrajectory::new(
        0.9,
        vec![0.2, -0.1],
        vec![vec![0.3, -0.5, 0.2, 0.1, -0.2], vec![0.0, 0.2, -0.3, 0.4, 0.1]],
        vec![vec![-0.2, 0.4, 0.1, -0.3, 0.2], vec![0.1, 0.0, 0.25, -0.1, 0.3]],
    )
    .unwrap();
    let period = tr.period();
    let scan = TrigGrid::new((0..120).map(|i| period * i as f64 / 120.0).collect(), tr.omega, 5);
    let shape = FourierLayout::new(tr.q0.clone(), 5, tr.omega, false, false).unwrap();
    let dense = tr.sample(20000.0 / period).unwrap();
    for j in 0..2 {
        for order in 0..3 {
            for upper in [true, false] {
                let (v, t) = joint_extremum(&shape, &tr, &scan, j, order, upper);
                let col: Vec<f64> = match order {
                    0 => dense.q.iter().map(|r| r[j]).collect(),
                    1 => dense.qd.iter().map(|r| r[j]).collect(),
                    _ => dense.qdd.iter().map(|r| r[j]).collect(),
                };
                let g = if upper {
                    col.iter().cloned().fold(f64::MIN, f64::max)
                } else {
                    col.iter().cloned().fold(f64::MAX, f64::min)
                };
                let s = if upper { 1.0 } else { -1.0 };
                assert!(s * (v - g) >= -1e-12, "j{j} order {order} upper {upper}: {v} vs grid {g}");
                assert!(s * (v - g) < 1e-5 * (1.0 + g.abs()), "j{j} order {order}: {v} vs grid {g} too far");
                let at = idexp::excitation::constraints::series_derivative(&tr, j, order, t);
                assert!((at - v).abs() < 1e-12 * (1.0 + v.abs()));
            }
        }
    }
}

fn state_csv(dir: &Path, name: &str, tr: &FourierTrajectory, rate: f64) -> PathBuf {
    let p = dir.join(name);
    tr.sample(rate).unwrap().write(&p).unwrap();
    p
}

#[test]
fn assess_reports_rank_cond_and_the_parameters_a_trajectory_does_not_excite() {
    let r = load("ur5");
    let base = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let lay = FourierLayout::new(vec![0.0; 6], 5, std::f64::consts::TAU * 0.1, false, false).unwrap();
    let x = random_x(lay.n_vars(), 0.5, 7);
    let tr = lay.trajectory(&x);
    let path = state_csv(dir.path(), "rich.csv", &tr, 20.0);
    let s = idexp::excitation::report::read_states(&path, 6, 1).unwrap();
    let id = assess(&r, &base, &s, &[1.0; 6]).unwrap();
    assert_eq!(id.rank, 48);
    assert!(id.cond.is_finite() && id.cond > 1.0);
    assert!(id.unexcited.is_empty(), "{:?}", id.unexcited);
    assert_eq!(id.sensitivity.len(), 48);
    // sensitivities are mean absolute column values (eq. 10): check one by hand
    let k = base.names.iter().position(|n| n == "Fv1").unwrap();
    let mean_abs_qd1: f64 = s.qd.iter().map(|q| q[0].abs()).sum::<f64>() / (6.0 * s.len() as f64);
    assert!((id.sensitivity[k] - mean_abs_qd1).abs() < 1e-12);
    // a production-like motion: joint 6 never moves → its friction is not excited
    let mut tr6 = tr.clone();
    tr6.a[5].iter_mut().for_each(|v| *v = 0.0);
    tr6.b[5].iter_mut().for_each(|v| *v = 0.0);
    let path = state_csv(dir.path(), "still6.csv", &tr6, 20.0);
    let s6 = idexp::excitation::report::read_states(&path, 6, 2).unwrap();
    let id6 = assess(&r, &base, &s6, &[1.0; 6]).unwrap();
    assert!(id6.rank < 48);
    assert!(id6.cond.is_infinite());
    for name in ["Fc6", "Fv6"] {
        assert!(id6.unexcited.iter().any(|n| n == name), "{name} not in {:?}", id6.unexcited);
    }
    assert!(id6.text().contains("NOT excited"));
    // more noise → proportionally larger predicted standard deviations
    let id2 = assess(&r, &base, &s, &[2.0; 6]).unwrap();
    for i in 0..48 {
        assert!((id2.std_dev[i] - 2.0 * id.std_dev[i]).abs() < 1e-8 * id.std_dev[i]);
    }
    // bad input: a file without q columns
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "t,x\n0,1\n").unwrap();
    let e = idexp::excitation::report::read_states(&bad, 6, 1).unwrap_err().to_string();
    assert!(e.contains("bad.csv"), "{e}");
}

#[test]
fn design_files_are_validated_with_the_field_named() {
    let dir = tempfile::tempdir().unwrap();
    let robot = root("designs/robots/ur5.toml");
    let write = |body: &str| {
        let p = dir.path().join("d.toml");
        std::fs::write(&p, format!("robot = {:?}\n{body}", robot.display().to_string())).unwrap();
        p
    };
    let e = ExciteDesign::load(&write("[trajectory]\nharmonix = 5\n")).unwrap_err().to_string();
    assert!(e.contains("harmonix"), "{e}");
    let e = ExciteDesign::load(&write("[limits]\nposition = 1.5\n")).unwrap_err().to_string();
    assert!(e.contains("limits.position"), "{e}");
    let e = ExciteDesign::load(&write("[objective]\nsample_rate = 0.5\n")).unwrap_err().to_string();
    assert!(e.contains("objective.sample_rate"), "{e}");
    let e = ExciteDesign::load(&write("[ga]\npopulation = 10\nelite = 10\n")).unwrap_err().to_string();
    assert!(e.contains("ga.elite"), "{e}");
    let e = ExciteDesign::load(&write("[[workspace]]\nshape = { type = \"sphere\", center = [0,0,0], radius = -1.0 }\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("workspace[0].shape"), "{e}");
    let e = ExciteDesign::load(&write("[objective]\ncriterion = \"trace\"\n")).unwrap_err().to_string();
    assert!(e.contains("trace") || e.contains("criterion"), "{e}");
    // per-joint lengths are checked against the robot
    let e = Problem::from_file(&write("[trajectory]\nq0 = [0.0, 0.0]\n")).unwrap_err().to_string();
    assert!(e.contains("trajectory.q0") && e.contains("6"), "{e}");
    // every shipped design file loads
    for f in std::fs::read_dir(root("designs")).unwrap() {
        let p = f.unwrap().path();
        if p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("excite_")) {
            let pr = Problem::from_file(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            assert!(pr.objective.n_cols() >= 36);
        }
    }
}

#[test]
fn smooth_condition_surrogate_gradient_matches_finite_differences_and_bounds_the_cond() {
    let r = load("ur5");
    let lay = FourierLayout::new(vec![0.0; 6], 3, std::f64::consts::TAU * 0.2, false, false).unwrap();
    let (o, _) = objective(&r, &lay, 8.0, Criterion::Cond, Scaling::UnitColumn, &[1.0; 6]);
    let mut w = o.workspace();
    let x = random_x(lay.n_vars(), 0.5, 9);
    let mut g = vec![0.0; x.len()];
    let p = 20.0;
    let l = o.soft_log_cond_grad(&x, &mut w, &mut g, p);
    let cond = o.value(&x, &mut w);
    let m = o.n_cols() as f64;
    assert!(
        l >= 2.0 * cond.ln() - 1e-12 && l <= 2.0 * cond.ln() + 2.0 * m.ln() / p + 1e-12,
        "{l} vs 2 ln {cond}"
    );
    let mut gt = vec![0.0; x.len()];
    let gmax = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for i in 0..x.len() {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[i] += 1e-6;
        xm[i] -= 1e-6;
        let fd = (o.soft_log_cond_grad(&xp, &mut w, &mut gt, p) - o.soft_log_cond_grad(&xm, &mut w, &mut gt, p)) / 2e-6;
        assert!((fd - g[i]).abs() < 1e-5 * gmax, "var {i}: {} vs {fd}", g[i]);
    }
}

#[test]
fn the_row_wise_and_the_dual_number_gradients_agree() {
    // A bundle of 1 + 1 eigenvalues takes the row-wise path (RNEA
    // derivatives at one parameter vector per torque row), one of 4 + 4 the
    // dual-number regressor passes: the gradients of the eigenvalues both
    // bundles hold (the largest and the smallest) must agree, on a robot
    // without and one with joint coupling
    for name in ["ur5", "industrial6"] {
        let r = load(name);
        let lay = FourierLayout::new(vec![0.0; r.dof()], 3, std::f64::consts::TAU * 0.2, false, false).unwrap();
        let (o, _) = objective(&r, &lay, 8.0, Criterion::Cond, Scaling::UnitColumn, &vec![1.0; r.dof()]);
        let mut w = o.workspace();
        let x = random_x(lay.n_vars(), 0.5, 13);
        let nv = x.len();
        let (mut v2, mut g2) = (vec![0.0; 2], vec![0.0; 2 * nv]);
        o.log_eigen_bundle(&x, &mut w, 1, 1, &mut v2, Some(&mut g2));
        let (mut v8, mut g8) = (vec![0.0; 8], vec![0.0; 8 * nv]);
        o.log_eigen_bundle(&x, &mut w, 4, 4, &mut v8, Some(&mut g8));
        for (a, b) in [(0, 0), (1, 7)] {
            let (ga, gb) = (&g2[a * nv..(a + 1) * nv], &g8[b * nv..(b + 1) * nv]);
            let scale = gb.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in 0..nv {
                assert!(
                    (ga[i] - gb[i]).abs() <= 1e-10 * scale,
                    "{name}: eigenvalue {a}, var {i}: row-wise {} dual {}",
                    ga[i],
                    gb[i]
                );
            }
        }
    }
}
