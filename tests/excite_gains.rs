//! The excitation criterion of a drive-gain calibration (`objective.columns =
//! "gains"`): its columns against inverse dynamics (the known mass's torque
//! as the difference of two robots' RNEA torques, not through the
//! regressor's columns), its analytic gradients against central finite
//! differences (row-wise and dual-number paths, every criterion and
//! scaling), and plain columns written as combinations giving the plain
//! criterion bit for bit.

use idexp::excitation::design::ExciteDesign;
use idexp::excitation::objective::{gains_columns, BaseColumns, ColumnMix, Criterion, Objective, Scaling, Scoring};
use idexp::excitation::Problem;
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Robot};
use idexp::trajectory::TrajectoryShape;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn problem() -> Problem {
    Problem::from_file(&root("designs/gains_ur5_excite.toml")).unwrap()
}

/// A random design vector inside the problem's box (around its middle).
fn random_x(p: &Problem, frac: f64, seed: u64) -> Vec<f64> {
    let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    p.lower
        .iter()
        .zip(&p.upper)
        .map(|(&lo, &hi)| {
            let (c, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
            c + frac * h * g.random_range(-1.0..1.0)
        })
        .collect()
}

fn tau(r: &Robot, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
    let mut ws = robot::Workspace::new(r);
    let mut t = vec![0.0; r.dof()];
    robot::rnea(r, &mut ws, q, qd, qdd, &mut t);
    t
}

#[test]
fn gain_columns_are_the_known_masss_torques_by_inverse_dynamics() {
    let p = problem();
    let o = &p.objective;
    assert_eq!(o.n_cols(), 15);
    assert_eq!(o.column_names[0], "gain shoulder_pan_joint");
    assert_eq!(o.column_names[14], "payload MZ");
    let x = random_x(&p, 0.5, 1);
    let mut w = o.workspace();
    assert!(o.value(&x, &mut w).is_finite());
    let rec = o.record(&p.shape.motion(&x)).unwrap();
    // the robot without the mass, and the mass on its frame
    let bare = robot::load(&root("designs/gains_ur5_robot.toml")).unwrap();
    let d = ExciteDesign::load(&root("designs/gains_ur5_excite.toml")).unwrap();
    let spec = d.payload.as_ref().unwrap();
    let (mount, payload) = robot::payload::resolve(&bare, spec, "test", "payload").unwrap();
    let loaded = mount.attach(&bare, &payload.params()).unwrap();
    // a robot whose payload is e_k (k < 9: first moments and inertia about the frame's origin)
    let unit: Vec<Robot> = (0..9)
        .map(|k| {
            let mut e = [0.0; 10];
            e[k] = 1.0;
            mount.attach(&bare, &e).unwrap()
        })
        .collect();
    let (n, rows) = (6, o.n_rows());
    let s = &rec.samples;
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for i in 0..s.len() {
        let t0 = tau(&bare, &s.q[i], &s.qd[i], &s.qdd[i]);
        let tl = tau(&loaded, &s.q[i], &s.qd[i], &s.qdd[i]);
        for j in 0..n {
            for r in 0..n {
                let want = if r == j { tl[r] - t0[r] } else { 0.0 };
                let got = w.c[j * rows + i * n + r];
                worst = worst.max((got - want).abs());
                scale = scale.max(want.abs());
                if r != j {
                    assert_eq!(got, 0.0, "gain column {j} on joint {r}'s row");
                }
            }
        }
        for (k, rk) in unit.iter().enumerate() {
            let tk = tau(rk, &s.q[i], &s.qd[i], &s.qdd[i]);
            for r in 0..n {
                let want = tk[r] - t0[r];
                worst = worst.max((w.c[(n + k) * rows + i * n + r] - want).abs());
            }
        }
    }
    assert!(scale > 0.5, "the mass's torque is {scale} N·m at most");
    assert!(worst < 1e-9 * scale.max(1.0), "largest difference from inverse dynamics {worst:e}");
}

fn mixed(p: &Problem, criterion: Criterion, scaling: Scaling, noise: &[f64]) -> Objective {
    let d = &p.design;
    let bare = robot::load(&d.robot).unwrap();
    let (mount, payload) = robot::payload::resolve(&bare, d.payload.as_ref().unwrap(), "test", "payload").unwrap();
    let (mixes, names, nominal) = gains_columns(&p.robot, &mount, &payload);
    let times: Vec<f64> = (0..40).map(|i| i as f64 * 0.25).collect();
    Objective::mixed(
        p.robot.clone(),
        p.shape.clone(),
        mixes,
        names,
        nominal,
        times,
        Scoring {
            criterion,
            scaling,
            noise: noise.to_vec(),
        },
    )
    .unwrap()
}

fn check_gradient(o: &Objective, x: &[f64], tol: f64, what: &str) {
    let mut w = o.workspace();
    let mut g = vec![0.0; x.len()];
    let f = o.value_grad(x, &mut w, &mut g);
    assert!(f.is_finite(), "{what}: {f}");
    let h = 1e-6;
    let gmax = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(gmax > 0.0, "{what}: zero gradient");
    for i in 0..x.len() {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[i] += h;
        xm[i] -= h;
        let fd = (o.value(&xp, &mut w) - o.value(&xm, &mut w)) / (2.0 * h);
        assert!((fd - g[i]).abs() <= tol * gmax, "{what} var {i}: analytic {} vs fd {fd}", g[i]);
    }
}

#[test]
fn gains_criterion_gradients_match_finite_differences() {
    let p = problem();
    let x = random_x(&p, 0.4, 2);
    let noise = [0.5, 1.0, 2.0, 1.0, 0.3, 0.4];
    for crit in [Criterion::Cond, Criterion::LogDet, Criterion::InvSigmaMin] {
        for scaling in [Scaling::UnitColumn, Scaling::Nominal, Scaling::None] {
            let o = mixed(&p, crit, scaling, &noise);
            check_gradient(&o, &x, 1e-5, &format!("{crit:?} {scaling:?}"));
        }
    }
    // the epigraph bundle: 4 + 4 eigenvalues, more than the row-wise path
    // takes, so through the dual-number regressor passes
    let o = mixed(&p, Criterion::Cond, Scaling::UnitColumn, &noise);
    let mut w = o.workspace();
    let nv = x.len();
    let (mut vals, mut grads) = (vec![0.0; 8], vec![0.0; 8 * nv]);
    o.log_eigen_bundle(&x, &mut w, 4, 4, &mut vals, Some(&mut grads));
    let h = 1e-6;
    let gmax = grads.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (mut vp, mut vm) = (vec![0.0; 8], vec![0.0; 8]);
    for i in 0..nv {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[i] += h;
        xm[i] -= h;
        o.log_eigen_bundle(&xp, &mut w, 4, 4, &mut vp, None);
        o.log_eigen_bundle(&xm, &mut w, 4, 4, &mut vm, None);
        for t in 0..8 {
            let fd = (vp[t] - vm[t]) / (2.0 * h);
            let an = grads[t * nv + i];
            assert!((fd - an).abs() <= 1e-5 * gmax, "bundle eigenvalue {t} var {i}: analytic {an} vs fd {fd}");
        }
    }
}

#[test]
fn plain_columns_as_combinations_give_the_plain_criterion_bit_for_bit() {
    let r = robot::load(&root("designs/robots/ur5.toml")).unwrap();
    let b = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    let nominal: Vec<f64> = b.base_values(r.nominal_params().as_slice()).iter().copied().collect();
    let p = problem();
    let times: Vec<f64> = (0..50).map(|i| i as f64 * 0.2).collect();
    let scoring = || Scoring {
        criterion: Criterion::Cond,
        scaling: Scaling::UnitColumn,
        noise: vec![1.0, 2.0, 1.0, 0.5, 0.5, 0.5],
    };
    let plain = Objective::new(
        r.clone(),
        p.shape.clone(),
        BaseColumns {
            indices: b.independent.clone(),
            names: b.names.clone(),
            nominal: nominal.clone(),
        },
        times.clone(),
        scoring(),
    )
    .unwrap();
    let mixes = b
        .independent
        .iter()
        .map(|&c| ColumnMix {
            row: None,
            terms: vec![(c, 1.0)],
        })
        .collect();
    let mix = Objective::mixed(r.clone(), p.shape.clone(), mixes, b.names.clone(), nominal, times, scoring()).unwrap();
    let x = random_x(&p, 0.5, 3);
    let (mut wa, mut wb) = (plain.workspace(), mix.workspace());
    let (mut ga, mut gb) = (vec![0.0; x.len()], vec![0.0; x.len()]);
    let fa = plain.value_grad(&x, &mut wa, &mut ga);
    let fb = mix.value_grad(&x, &mut wb, &mut gb);
    assert_eq!(fa.to_bits(), fb.to_bits());
    assert!(ga.iter().zip(&gb).all(|(a, b)| a.to_bits() == b.to_bits()), "row-wise gradients differ");
    let nv = x.len();
    let (mut va, mut vb) = (vec![0.0; 8], vec![0.0; 8]);
    let (mut da, mut db) = (vec![0.0; 8 * nv], vec![0.0; 8 * nv]);
    plain.log_eigen_bundle(&x, &mut wa, 4, 4, &mut va, Some(&mut da));
    mix.log_eigen_bundle(&x, &mut wb, 4, 4, &mut vb, Some(&mut db));
    assert_eq!(va, vb);
    assert!(da.iter().zip(&db).all(|(a, b)| a.to_bits() == b.to_bits()), "dual-path gradients differ");
}

#[test]
fn gains_columns_without_a_payload_or_with_bad_mixes_are_errors() {
    let text = std::fs::read_to_string(root("designs/gains_ur5_excite.toml")).unwrap();
    let cut = text.find("[payload]").unwrap();
    let end = text.find("[collision]").unwrap();
    let no_payload = format!("{}{}", &text[..cut], &text[end..]).replace(
        "robot = \"gains_ur5_robot.toml\"",
        &format!("robot = {:?}", root("designs/gains_ur5_robot.toml")),
    );
    let dir = std::env::temp_dir().join(format!("idexp-excite-gains-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("no_payload.toml");
    std::fs::write(&f, no_payload).unwrap();
    let e = ExciteDesign::load(&f).unwrap_err().to_string();
    assert!(
        e.contains("no_payload.toml") && e.contains("objective.columns") && e.contains("[payload]"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
    // a mix on a joint the robot does not have
    let p = problem();
    let e = Objective::mixed(
        p.robot.clone(),
        p.shape.clone(),
        vec![ColumnMix {
            row: Some(6),
            terms: vec![(0, 1.0)],
        }],
        vec!["x".into()],
        vec![1.0],
        vec![0.0, 1.0],
        Scoring {
            criterion: Criterion::Cond,
            scaling: Scaling::UnitColumn,
            noise: vec![1.0; 6],
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("columns[0]"), "{e}");
}
