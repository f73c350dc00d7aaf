//! The drive side: friction models per drive (sign, tanh,
//! Stribeck; symmetric and asymmetric), standstill rows in identification,
//! motor currents in runs, and the bad inputs of each.

mod common;
use common::{random_state, rng, root};
use idexp::excitation::objective::{BaseColumns, Criterion, Objective, Scaling, Scoring};
use idexp::ident::study::{run_study_with, ExperimentSpec, FilterName, Given, Inputs, StudyDesign, StudyResult};
use idexp::params::{BaseOptions, BaseParams};
use idexp::robot::{self, Coulomb, Friction, Robot, Workspace};
use idexp::trajectory::{period_grid, FourierLayout};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use std::path::Path;

/// The RPR test arm (tests/data/ident/rpr_drives.toml) with its `[[drive]]`
/// entries replaced by `drives` and `top` inserted at the top of the file.
pub fn rpr_with(top: &str, drives: &str) -> String {
    let text = std::fs::read_to_string(root("tests/data/ident/rpr_drives.toml")).unwrap();
    let cut = text.find("[[drive]]").unwrap();
    format!("{top}\n{}\n{drives}", &text[..cut])
}

fn parse(text: &str) -> idexp::Result<Robot> {
    robot::file::parse_robot_toml(Path::new("drive_test.toml"), text)
}

/// One robot per friction model: {sign, tanh, stribeck} × {symmetric, asymmetric},
/// with offsets on some drives.
fn model_robots() -> Vec<(String, Robot)> {
    let mut out = Vec::new();
    for shape in ["sign", "tanh", "stribeck"] {
        let extra = match shape {
            "sign" => "",
            "tanh" => "velocity_scale = 0.05\n",
            _ => "velocity_scale = 0.05\nstribeck_velocity = 0.2\n",
        };
        let (fs_sym, fs_asym) = if shape == "stribeck" {
            ("fs = 0.7\n", "fs_pos = 0.4\nfs_neg = -0.3\n")
        } else {
            ("", "")
        };
        let sym = format!(
            "[[drive]]\njoint = \"base\"\nia = 0.2\nfc = 1.5\nfv = 0.8\nf0 = 0.1\ncoulomb = \"{shape}\"\n{extra}{fs_sym}\n\
             [[drive]]\njoint = \"slide\"\nia = 1.0\nfc = 4.0\nfv = 10.0\ncoulomb = \"{shape}\"\n{extra}{fs_sym}\n\
             [[drive]]\njoint = \"wrist\"\nfc = 0.3\nfv = 0.05\ncoulomb = \"{shape}\"\n{extra}{fs_sym}\n"
        );
        let asym = format!(
            "[[drive]]\njoint = \"base\"\nia = 0.2\nfriction = \"asymmetric\"\nfc_pos = 1.5\nfc_neg = -1.2\nfv_pos = 0.8\nfv_neg = 0.7\nf0 = -0.2\ncoulomb = \"{shape}\"\n{extra}{fs_asym}\n\
             [[drive]]\njoint = \"slide\"\nfriction = \"asymmetric\"\nfc_pos = 4.0\nfc_neg = -3.0\nfv_pos = 10.0\nfv_neg = 9.0\ncoulomb = \"{shape}\"\n{extra}{fs_asym}\n\
             [[drive]]\njoint = \"wrist\"\nfc = 0.3\nfv = 0.05\n"
        );
        out.push((format!("{shape}/symmetric"), parse(&rpr_with("", &sym)).unwrap()));
        out.push((format!("{shape}/asymmetric"), parse(&rpr_with("", &asym)).unwrap()));
    }
    out
}

/// The friction torque of drive `d` at velocity `w`, written out from the
/// model's formulas (independent of the library's column code).
fn friction_by_hand(r: &Robot, j: usize, w: f64) -> f64 {
    let d = &r.drives[j];
    let (s, e) = match d.coulomb {
        Coulomb::Sign => (w.signum() * f64::from(w != 0.0), 0.0),
        Coulomb::Tanh { velocity_scale } => ((w / velocity_scale).tanh(), 0.0),
        Coulomb::Stribeck {
            velocity_scale,
            stribeck_velocity,
            ..
        } => ((w / velocity_scale).tanh(), (-(w / stribeck_velocity).powi(2)).exp()),
    };
    let fs = match d.coulomb {
        Coulomb::Stribeck { fs, .. } => fs,
        _ => [0.0, 0.0],
    };
    match d.friction {
        Friction::None => 0.0,
        Friction::Symmetric { fc, fv, offset } => (fc + fs[0] * e) * s + fv * w + offset.unwrap_or(0.0),
        Friction::Asymmetric {
            fc_pos,
            fc_neg,
            fv_pos,
            fv_neg,
            offset,
        } => {
            let (sp, sn) = match d.coulomb {
                Coulomb::Sign => (f64::from(w > 0.0), f64::from(w < 0.0)),
                _ => ((1.0 + s) / 2.0, (1.0 - s) / 2.0),
            };
            sp * (fc_pos + fv_pos * w + fs[0] * e) + sn * (fc_neg + fv_neg * w + fs[1] * e) + offset.unwrap_or(0.0)
        }
    }
}

#[test]
fn regressor_times_parameters_equals_inverse_dynamics_for_every_friction_model() {
    for (name, r) in model_robots() {
        let (n, p) = (r.dof(), r.n_params());
        // the rigid part alone: the same arm without drives
        let mut rigid = r.clone();
        for d in rigid.drives.iter_mut() {
            d.rotor_inertia = None;
            d.friction = Friction::None;
        }
        let rigid = Robot::new(idexp::robot::RobotParts {
            name: rigid.name.clone(),
            joints: rigid.joints.clone(),
            links: rigid.links.clone(),
            drives: rigid.drives.clone(),
            coupling: None,
            frames: rigid.frames.clone(),
            gravity: rigid.gravity,
            source: "rigid".into(),
        })
        .unwrap();
        let mut ws = Workspace::new(&r);
        let mut wr = Workspace::new(&rigid);
        let theta = r.nominal_params();
        let mut y = DMatrix::zeros(n, p);
        let (mut tau, mut tau_id, mut tau_rb) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut g = rng(16);
        for k in 0..600 {
            let (q, mut qd, qdd) = random_state(&r, &mut g);
            // a third of the states near or at rest, where the models differ most
            if k % 3 == 0 {
                for v in qd.iter_mut() {
                    *v *= 1e-2 * g.random_range(0.0..1.0);
                }
            }
            if k % 50 == 0 {
                qd.iter_mut().for_each(|v| *v = 0.0);
            }
            robot::regressor(&r, &mut ws, &q, &qd, &qdd, &mut y);
            robot::rnea(&r, &mut ws, &q, &qd, &qdd, &mut tau);
            robot::inverse_dynamics(&r, &mut ws, theta.as_slice(), &q, &qd, &qdd, &mut tau_id);
            robot::rnea(&rigid, &mut wr, &q, &qd, &qdd, &mut tau_rb);
            let yt = &y * &theta;
            for j in 0..n {
                let ia = r.drives[j].rotor_inertia.unwrap_or(0.0) * qdd[j];
                let want = tau_rb[j] + ia + friction_by_hand(&r, j, qd[j]);
                let scale = want.abs().max(1.0);
                assert!(
                    (yt[j] - want).abs() < 1e-9 * scale,
                    "{name} joint {j}: Yθ = {} vs rigid + Ia q̈ + f = {want}",
                    yt[j]
                );
                assert!((tau[j] - want).abs() < 1e-9 * scale, "{name} joint {j}: rnea {} vs {want}", tau[j]);
                assert!(
                    (tau_id[j] - want).abs() < 1e-9 * scale,
                    "{name} joint {j}: inverse_dynamics {} vs {want}",
                    tau_id[j]
                );
            }
        }
        // and for an arbitrary parameter vector (linearity)
        for _ in 0..20 {
            let th = DVector::from_fn(p, |_, _| g.random_range(-1.0..1.0));
            let (q, qd, qdd) = random_state(&r, &mut g);
            robot::regressor(&r, &mut ws, &q, &qd, &qdd, &mut y);
            robot::inverse_dynamics(&r, &mut ws, th.as_slice(), &q, &qd, &qdd, &mut tau_id);
            let yt = &y * &th;
            for j in 0..n {
                assert!((yt[j] - tau_id[j]).abs() < 1e-9 * yt.amax().max(1.0), "{name}: Yθ ≠ inverse_dynamics(θ)");
            }
        }
    }
}

#[test]
fn stribeck_parameters_are_in_the_layout_and_round_trip_through_with_params() {
    let robots = model_robots();
    let (_, r) = robots.iter().find(|(n, _)| n == "stribeck/asymmetric").unwrap();
    let names = r.param_names();
    for want in ["Fs1", "Fsp1", "Fsn1", "Fsp2", "Fsn2"] {
        assert_eq!(names.iter().any(|n| n == want), want != "Fs1", "{want} in {names:?}");
    }
    let th = r.nominal_params();
    let th2: Vec<f64> = th.iter().map(|v| 2.0 * v).collect();
    let r2 = r.with_params(&th2).unwrap();
    assert_eq!(r2.nominal_params().as_slice(), th2.as_slice());
    match r2.drives[0].coulomb {
        Coulomb::Stribeck { fs, .. } => assert_eq!(fs, [0.8, -0.6]),
        c => panic!("{c:?}"),
    }
}

#[test]
fn excitation_gradient_equals_finite_differences_with_a_tanh_friction_column() {
    // a velocity scale of 0.2 rad/s: the tanh columns bend where the
    // trajectory crosses zero velocity, so their derivative matters
    let top = "coulomb = \"tanh\"\nvelocity_scale = 0.2\n";
    let drives = "[[drive]]\njoint = \"base\"\nia = 0.2\nfc = 1.5\nfv = 0.8\n\
                  [[drive]]\njoint = \"slide\"\nia = 1.0\nfc = 4.0\nfv = 10.0\ncoulomb = \"stribeck\"\nstribeck_velocity = 0.1\nfs = 0.5\n\
                  [[drive]]\njoint = \"wrist\"\nia = 0.01\nfriction = \"asymmetric\"\nfc_pos = 0.3\nfc_neg = -0.25\nfv_pos = 0.05\nfv_neg = 0.04\n";
    let r = parse(&rpr_with(top, drives)).unwrap();
    let b = BaseParams::compute(&r, &BaseOptions::default()).unwrap();
    assert!(b.names.iter().any(|n| n.starts_with("Fc1")), "{:?}", b.names);
    let nom: Vec<f64> = b.base_values(r.nominal_params().as_slice()).iter().copied().collect();
    let w = std::f64::consts::TAU * 0.2;
    let lay = FourierLayout::new(vec![0.0, 0.25, 0.0], 3, w, false, false).unwrap();
    let times = period_grid(std::f64::consts::TAU / w, 10.0).unwrap();
    for crit in [Criterion::Cond, Criterion::LogDet] {
        let o = Objective::new(
            r.clone(),
            lay.clone(),
            BaseColumns {
                indices: b.independent.clone(),
                names: b.names.clone(),
                nominal: nom.clone(),
            },
            times.clone(),
            Scoring {
                criterion: crit,
                scaling: Scaling::UnitColumn,
                noise: vec![1.0; 3],
            },
        )
        .unwrap();
        let mut ws = o.workspace();
        let mut g = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let x: Vec<f64> = (0..lay.n_vars()).map(|_| g.random_range(-0.1..0.1)).collect();
        let mut grad = vec![0.0; x.len()];
        let f = o.value_grad(&x, &mut ws, &mut grad);
        assert!(f.is_finite());
        let h = 1e-6;
        let gmax = grad.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(gmax > 0.0);
        for i in 0..x.len() {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[i] += h;
            xm[i] -= h;
            let fd = (o.value(&xp, &mut ws) - o.value(&xm, &mut ws)) / (2.0 * h);
            assert!(
                (fd - grad[i]).abs() <= 1e-5 * gmax + 1e-6 * grad[i].abs(),
                "{crit:?} var {i}: analytic {} vs fd {fd}",
                grad[i]
            );
        }
        // the tanh columns' derivative is in the gradient: dropping it (a
        // sign-like constant column) would not match; check the columns bend
        let tr = lay.trajectory(&x);
        let s = tr.sample(10.0).unwrap();
        let crossing = s.qd.iter().any(|v| v[0].abs() < 0.2);
        assert!(
            crossing,
            "the trajectory never comes near zero velocity: the tanh curvature would not be tested"
        );
    }
}

/// Simulates a shipped design (paths relative to designs/).
fn simulate_shipped(name: &str) -> idexp::sim::SimResult {
    let path = root(&format!("designs/{name}.toml"));
    let d = idexp::sim::SimDesign::read(&path).unwrap();
    let setup = idexp::sim::SimSetup::from_design(&d, &root("designs"), &path.display().to_string()).unwrap();
    setup.run(&idexp::optim::Control::new()).unwrap()
}

/// Identifies `run` (validated on `val`, with the truth `truth` if given)
/// with `robot` by the study engine: a one-experiment design with the runs
/// in memory and no Fourier reference (the low-pass filter), least-squares
/// weights of the repetitions `weights`; `set` adjusts the design (dead
/// band, the experiment's filter, standstill rule, velocity source).
fn study(
    robot: &Robot,
    run: idexp::ident::Run,
    torque_source: idexp::data::TorqueSource,
    val: Option<idexp::ident::Run>,
    truth: Option<idexp::data::Truth>,
    weights: idexp::ident::Weights,
    set: impl FnOnce(&mut StudyDesign),
) -> idexp::Result<StudyResult> {
    let given = |run: idexp::ident::Run, torque_source| Given {
        run,
        trajectory: None,
        torque_source,
    };
    let mut e = ExperimentSpec::new(vec![]);
    e.name = "run".into();
    let mut d = StudyDesign::one_experiment("test", "robot.toml".into(), e).repetition_weighted(weights);
    set(&mut d);
    let mut inputs = Inputs {
        robot: Some(robot.clone()),
        truth,
        ..Default::default()
    };
    inputs.entries.insert("run".into(), given(run, torque_source));
    if let Some(v) = val {
        let mut ve = d.experiment[0].validation_like(vec![], None);
        ve.name = "validate".into();
        d.validation = vec![ve];
        inputs.entries.insert("validate".into(), given(v, idexp::data::TorqueSource::logged_torques()));
    }
    run_study_with(&d, Path::new(""), &inputs, &idexp::optim::Control::new())
}

/// Identifies `run` with `robot` (validated on `val`, sample weights, the
/// design as `set` leaves it); returns the identification, the per-joint
/// RMS residual at standstill (reference at rest) over every sample, the
/// per-joint noise floor there, and max |z| against the truth.
fn ident_with(
    robot: &Robot,
    res: &idexp::sim::SimResult,
    val: &idexp::sim::SimResult,
    set: impl FnOnce(&mut StudyDesign),
) -> (StudyResult, Vec<f64>, Vec<f64>, f64) {
    use idexp::ident::{Dataset, Run, Weights};
    let base = BaseParams::compute(robot, &BaseOptions::default()).unwrap();
    let run = Run::new(vec![], res.reps.clone()).unwrap();
    let vrun = Run::new(vec![], val.reps.clone()).unwrap();
    let torques = idexp::data::TorqueSource::logged_torques();
    let id = study(robot, run, torques, Some(vrun), Some(res.truth().unwrap()), Weights::Sample, set).unwrap_or_else(|e| panic!("{e}"));
    let zmax = id.estimate.truth.as_ref().unwrap().iter().map(|r| r.z.abs()).fold(0.0, f64::max);
    let pr = &id.experiments[0].prep.pr;
    let n = robot.dof();
    let every = Dataset::every_row(robot, &base, pr);
    let pred = &every.c * DVector::from_column_slice(&id.estimate.theta);
    let (mut ss, mut fl, mut cnt) = (vec![0.0; n], vec![0.0; n], vec![0usize; n]);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for (i, (&j, &p)) in every.joint.iter().zip(&every.sample).enumerate() {
        res.setup.reference.eval(pr.t[p] - pr.t[0], &mut q, &mut qd, &mut qdd);
        if qd.iter().all(|v| v.abs() < 1e-9) && qdd.iter().all(|v| v.abs() < 1e-9) {
            ss[j] += (every.y[i] - pred[i]).powi(2);
            fl[j] += every.var.as_ref().unwrap()[i];
            cnt[j] += 1;
        }
    }
    assert!(cnt.iter().all(|&c| c > 50), "standstill samples {cnt:?}");
    let rms = (0..n).map(|j| (ss[j] / cnt[j] as f64).sqrt()).collect();
    let floor = (0..n).map(|j| (fl[j] / cnt[j] as f64).sqrt()).collect();
    (id, rms, floor, zmax)
}

/// The shipped pick-and-place process (dwell 0.2 s between moves) with tanh
/// friction as the truth, identified with the tanh model on every row and
/// with the sign model (slow rows dropped, as idexp did before; and every
/// row forced in). Measured, not tuned: the numbers are printed.
#[test]
fn pick_and_place_with_dwell_tanh_model_beats_sign_model_at_standstill() {
    use idexp::ident::Standstill;
    let res = simulate_shipped("sim_rpr_pick_place");
    let val = simulate_shipped("sim_rpr_pick_place_validate");
    let tanh = res.setup.nominal.clone();
    assert!(matches!(tanh.drives[0].coulomb, Coulomb::Tanh { velocity_scale } if velocity_scale == 1e-3));
    let sign = robot::load(&root("tests/data/ident/rpr_drives.toml")).unwrap();
    let (it, rt, ft, zt) = ident_with(&tanh, &res, &val, |_| {});
    // the tanh model keeps every row, and says so
    for r in &it.estimate.experiments[0].rows_used {
        assert_eq!(r.used, r.total, "{r:?}");
        assert!(r.reason.contains("continuous at rest"), "{r:?}");
    }
    // the sign model as sign(q̇) at every speed (no dead band): what the tanh
    // model is compared with; the dead band's own effect is measured below
    let (is, rs, _, zs) = ident_with(&sign, &res, &val, |d| d.dead_band = 0.0);
    assert!(is.estimate.experiments[0]
        .rows_used
        .iter()
        .all(|r| r.used < r.total && r.reason.contains("discontinuous")));
    let (ik, rk, _, zk) = ident_with(&sign, &res, &val, |d| {
        d.dead_band = 0.0;
        d.experiment[0].standstill = Some(Standstill::Keep);
    });
    // the default: |q̇| below the dead band is rest for the sign model's Coulomb term
    let (ib, rb, _, zb) = ident_with(&sign, &res, &val, |d| d.experiment[0].standstill = Some(Standstill::Keep));
    let (id_, rd, _, zd) = ident_with(&tanh, &res, &val, |d| d.experiment[0].standstill = Some(Standstill::Drop));
    let pct = |v: &[f64]| v.iter().map(|x| format!("{:.2}", 100.0 * x)).collect::<Vec<_>>().join(", ");
    let num = |v: &[f64]| v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ");
    println!("noise floor at standstill (σ of the averaged torque, N·m): [{}]", num(&ft));
    for (name, id, rms, z) in [
        ("tanh, every row", &it, &rt, zt),
        ("sign, slow rows dropped", &is, &rs, zs),
        ("sign, every row", &ik, &rk, zk),
        ("sign+band, every row", &ib, &rb, zb),
        ("tanh, slow rows dropped", &id_, &rd, zd),
    ] {
        println!(
            "{name:<24} e*_j all rows [{}] %, validation all rows [{}] %, standstill RMS [{}] N·m, max|z| {z:.2}",
            pct(&id.estimate.experiments[0].errors_all.e_rel),
            pct(&id.estimate.validation[0].errors_all.e_rel),
            num(rms)
        );
    }
    // with q̇ from the positions (this run logs no qd*), the standstill acceptance
    // is not met (docs/robots.md, "Drives"): the velocity estimated at rest is off by
    // amounts comparable to v_s, so the tanh estimate is biased beyond 3σ and
    // its standstill error is above the noise on joints 1 and 3 (see
    // `standstill_torque_error_of_the_tanh_model_comes_from_the_velocity_estimate`);
    // with the drive's logged velocities it is met
    // (`pick_and_place_with_logged_drive_velocities_meets_the_standstill_acceptance`)
    assert!(zt > 3.0, "max|z| {zt}: the acceptance is met now, update docs/robots.md \"Drives\"");
    assert!(rt[0] > 2.0 * ft[0] && rt[2] > 2.0 * ft[2] && rt[1] < 2.0 * ft[1], "{rt:?} vs {ft:?}");
    for j in 0..3 {
        // the dead band (the default): the sign model's Coulomb term no longer
        // takes the sign of the velocity noise near rest, and its prediction
        // over the whole motion improves (measured: 6.9/31/11.5 % → 4.4/23/4.7 %);
        // at standstill this tanh truth still favours the tanh model (below)
        assert!(
            ib.estimate.experiments[0].errors_all.e_rel[j] < ik.estimate.experiments[0].errors_all.e_rel[j],
            "joint {j}: dead band"
        );
        // over the whole motion and at standstill, the tanh model predicts better
        assert!(
            it.estimate.experiments[0].errors_all.e_rel[j] < is.estimate.experiments[0].errors_all.e_rel[j],
            "joint {j}"
        );
        assert!(
            it.estimate.experiments[0].errors_all.e_rel[j] < ik.estimate.experiments[0].errors_all.e_rel[j],
            "joint {j}"
        );
        assert!(
            rt[j] < rs[j] && rt[j] < rk[j],
            "joint {j}: standstill RMS tanh {} vs sign {} / {}",
            rt[j],
            rs[j],
            rk[j]
        );
    }
}

/// A small simulated run on the tanh RPR arm, written to `dir` with `record`.
fn write_sim(dir: &Path, record: &str) -> idexp::sim::SimResult {
    let text = format!(
        r#"
robot = "{}"
rate = 1000.0
substeps = 10
decimate = 5
repetitions = 4
seed = 3
record = "{record}"
[truth]
perturbation = 0.1
[noise]
torque = 0.05
position = 1e-5
[reference]
kind = "random_fourier"
n_h = 5
frequency = 0.2
amplitude = 0.5
seed = 2
"#,
        root("tests/data/ident/rpr_drives_tanh.toml").display()
    );
    let d: idexp::sim::SimDesign = idexp::io::parse_toml(Path::new("currents.toml"), &text).unwrap();
    d.validate("currents.toml").unwrap();
    let setup = idexp::sim::SimSetup::from_design(&d, &root(""), "currents.toml").unwrap();
    let res = setup.run(&idexp::optim::Control::new()).unwrap();
    res.write(dir, &d).unwrap();
    res
}

#[test]
fn a_run_of_currents_gives_the_same_estimate_as_the_run_of_torques() {
    use idexp::ident::{Run, TorqueFrom, Weights, CURRENT_TOLERANCE};
    let tmp = tempfile::tempdir().unwrap();
    let (dt, dc, db) = (tmp.path().join("tau"), tmp.path().join("cur"), tmp.path().join("both"));
    write_sim(&dt, "torque");
    write_sim(&dc, "current");
    write_sim(&db, "both");
    let r = robot::load(&root("tests/data/ident/rpr_drives_tanh.toml")).unwrap();
    let head = std::fs::read_to_string(dc.join("rep_001.csv")).unwrap();
    let header = head.lines().next().unwrap();
    assert!(header.contains("cur1") && !header.contains("tau1"), "{header}");
    // the current of the wrist has the opposite sign (current_sign = -1) and is τ/(k_t N)
    let (rt, st) = Run::read_drives(std::slice::from_ref(&dt), &r, None, TorqueFrom::Auto, CURRENT_TOLERANCE).unwrap();
    let (rc, sc) = Run::read_drives(std::slice::from_ref(&dc), &r, None, TorqueFrom::Auto, CURRENT_TOLERANCE).unwrap();
    let (rb, sb) = Run::read_drives(std::slice::from_ref(&db), &r, None, TorqueFrom::Current, CURRENT_TOLERANCE).unwrap();
    use idexp::data::TorqueColumns::{Current, Torque};
    assert_eq!((st.from, sc.from, sb.from), (Torque, Current, Current));
    assert_eq!(sc.torque_per_ampere.as_deref(), Some(&[0.12 * 50.0, 0.2 * 1000.0, -0.05 * 30.0][..]));
    let ag = sb.agreement.as_ref().unwrap();
    assert!(ag.iter().all(|&a| a < 1e-12), "{ag:?}");
    let t0 = &rt.reps[0].tau[7];
    let c0 = &rc.reps[0].tau[7];
    for j in 0..3 {
        assert!((t0[j] - c0[j]).abs() <= 1e-12 * t0[j].abs().max(1.0), "{t0:?} vs {c0:?}");
    }
    let est = |run: Run, src| {
        study(&r, run, src, None, None, Weights::Sample, |_| {})
            .unwrap_or_else(|e| panic!("{e}"))
            .estimate
    };
    let et = est(rt, st);
    let ec = est(rc, sc);
    let eb = est(rb, sb);
    for i in 0..et.theta.len() {
        for e in [&ec, &eb] {
            assert!(
                (et.theta[i] - e.theta[i]).abs() <= 1e-9 * et.std[i].max(1e-12) + 1e-12 * et.theta[i].abs(),
                "{}: {} vs {}",
                et.names[i],
                et.theta[i],
                e.theta[i]
            );
        }
    }
}

fn err_text<T: std::fmt::Debug>(r: idexp::Result<T>) -> String {
    r.unwrap_err().to_string()
}

#[test]
fn bad_drive_inputs_are_errors_naming_file_and_joint() {
    use idexp::ident::{Run, TorqueFrom, CURRENT_TOLERANCE};
    // v_s ≤ 0, non-finite, missing
    for (vs, what) in [("0.0", "found 0"), ("-0.001", "found -0.001"), ("nan", "found NaN"), ("inf", "found inf")] {
        let t = rpr_with(
            "",
            &format!("[[drive]]\njoint = \"slide\"\nfc = 4.0\ncoulomb = \"tanh\"\nvelocity_scale = {vs}\n"),
        );
        let e = err_text(parse(&t));
        assert!(
            e.contains("drive_test.toml") && e.contains("joint `slide`") && e.contains("velocity_scale") && e.contains(what),
            "{e}"
        );
    }
    let e = err_text(parse(&rpr_with("coulomb = \"tanh\"", "")));
    assert!(e.contains("drive_test.toml") && e.contains("velocity_scale") && e.contains("0.001"), "{e}");
    let e = err_text(parse(&rpr_with(
        "",
        "[[drive]]\njoint = \"base\"\ncoulomb = \"stribeck\"\nvelocity_scale = 0.01\n",
    )));
    assert!(e.contains("joint `base`") && e.contains("stribeck_velocity"), "{e}");
    let e = err_text(parse(&rpr_with("", "[[drive]]\njoint = \"base\"\nfs = 0.3\n")));
    assert!(e.contains("joint `base`") && e.contains("fs") && e.contains("stribeck"), "{e}");
    let e = err_text(parse(&rpr_with("", "[[drive]]\njoint = \"wrist\"\ntorque_constant = -0.1\n")));
    assert!(e.contains("joint `wrist`") && e.contains("torque_constant") && e.contains("-0.1"), "{e}");
    let e = err_text(parse(&rpr_with("", "[[drive]]\njoint = \"wrist\"\ncurrent_sign = 2\n")));
    assert!(e.contains("joint `wrist`") && e.contains("current_sign") && e.contains("1 or -1"), "{e}");

    let tmp = tempfile::tempdir().unwrap();
    // a current column without a torque constant
    let dc = tmp.path().join("cur");
    write_sim(&dc, "current");
    let plain = robot::load(&root("tests/data/ident/rpr_drives.toml")).unwrap();
    let e = err_text(Run::read_drives(std::slice::from_ref(&dc), &plain, None, TorqueFrom::Auto, CURRENT_TOLERANCE));
    assert!(
        e.contains("rep_001.csv") && e.contains("cur1") && e.contains("joint `base`") && e.contains("torque_constant"),
        "{e}"
    );
    // without a robot the run is an error that points to the currents
    let e = err_text(Run::read(std::slice::from_ref(&dc), 3));
    assert!(e.contains("rep_001.csv") && e.contains("currents"), "{e}");
    // --torque-from torque on a current-only run
    let r = robot::load(&root("tests/data/ident/rpr_drives_tanh.toml")).unwrap();
    let e = err_text(Run::read_drives(std::slice::from_ref(&dc), &r, None, TorqueFrom::Torque, CURRENT_TOLERANCE));
    assert!(e.contains("tau1") && e.contains("torque_from = \"current\""), "{e}");
    // torques and currents disagreeing: the slide's current scaled by 1.2
    let db = tmp.path().join("both");
    write_sim(&db, "both");
    let f = db.join("rep_002.csv");
    let text = std::fs::read_to_string(&f).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let c2 = header.iter().position(|c| *c == "cur2").unwrap();
    let mut out = vec![header.join(",")];
    for l in lines {
        let mut v: Vec<String> = l.split(',').map(String::from).collect();
        v[c2] = format!("{}", 1.2 * v[c2].parse::<f64>().unwrap());
        out.push(v.join(","));
    }
    std::fs::write(&f, out.join("\n") + "\n").unwrap();
    for from in [TorqueFrom::Auto, TorqueFrom::Torque, TorqueFrom::Current] {
        let e = err_text(Run::read_drives(std::slice::from_ref(&db), &r, None, from, CURRENT_TOLERANCE));
        assert!(
            e.contains("rep_002.csv") && e.contains("cur2") && e.contains("joint `slide`") && e.contains("tolerance 5.00 %"),
            "{e}"
        );
    }
    // a 25 % tolerance accepts the 20 % scale error
    assert!(Run::read_drives(std::slice::from_ref(&db), &r, None, TorqueFrom::Auto, 0.25).is_ok());
    // simulate: record = "current" on a robot without torque constants
    let text = format!(
        "robot = \"{}\"\nrecord = \"current\"\n[reference]\nkind = \"random_fourier\"\nn_h = 3\nfrequency = 0.2\namplitude = 0.3\nseed = 1\n",
        root("tests/data/ident/rpr_drives.toml").display()
    );
    let d: idexp::sim::SimDesign = idexp::io::parse_toml(Path::new("rec.toml"), &text).unwrap();
    let e = err_text(idexp::sim::SimSetup::from_design(&d, &root(""), "rec.toml"));
    assert!(
        e.contains("rec.toml") && e.contains("record") && e.contains("joint `base`") && e.contains("torque_constant"),
        "{e}"
    );
}

/// The robot file's sign check of the friction coefficients walks the drive
/// parameters with `ParamKind::sign`: every signed coefficient of both models
/// is checked under its file key (a wrong sign is an error naming the joint,
/// the key, the value and the allowed sign), the free ones (F0, Stribeck)
/// take either sign.
#[test]
fn friction_coefficient_signs_are_checked_under_their_file_keys() {
    let asym = |k: &str, v: f64| {
        let mut vals = [("fc_pos", 1.0), ("fc_neg", -1.0), ("fv_pos", 0.5), ("fv_neg", 0.5)];
        for e in vals.iter_mut().filter(|e| e.0 == k) {
            e.1 = v;
        }
        let body: String = vals.iter().map(|(k, v)| format!("{k} = {v}\n")).collect();
        rpr_with("", &format!("[[drive]]\njoint = \"slide\"\nfriction = \"asymmetric\"\n{body}"))
    };
    for (key, bad, allowed) in [
        ("fc_pos", -0.5, "≥ 0"),
        ("fc_neg", 0.5, "≤ 0"),
        ("fv_pos", -0.5, "≥ 0"),
        ("fv_neg", -0.5, "≥ 0"),
    ] {
        let e = err_text(parse(&asym(key, bad)));
        assert!(
            e.contains("drive_test.toml") && e.contains(&format!("joint `slide` {key}")) && e.contains(allowed) && e.contains(&format!("found {bad}")),
            "{key}: {e}"
        );
    }
    for (key, bad) in [("fc", -0.5), ("fv", -0.5)] {
        let e = err_text(parse(&rpr_with(
            "",
            &format!("[[drive]]\njoint = \"base\"\nfc = 1.0\nfv = 1.0\n{key} = {bad}\n").replacen(&format!("{key} = 1.0\n"), "", 1),
        )));
        assert!(
            e.contains(&format!("joint `base` {key}")) && e.contains("≥ 0") && e.contains(&format!("found {bad}")),
            "{key}: {e}"
        );
    }
    // offsets and Stribeck coefficients are free
    let free = rpr_with(
        "",
        "[[drive]]\njoint = \"slide\"\nfriction = \"asymmetric\"\nfc_pos = 1.0\nfc_neg = -1.0\nfv_pos = 0.5\nfv_neg = 0.5\nf0 = -0.3\ncoulomb = \"stribeck\"\nvelocity_scale = 0.01\nstribeck_velocity = 0.1\nfs_pos = -0.2\nfs_neg = 0.2\n",
    );
    parse(&free).unwrap();
    parse(&rpr_with("", "[[drive]]\njoint = \"base\"\nfc = 1.0\nfv = 1.0\nf0 = -2.0\n")).unwrap();
}

/// Why the tanh model misses the standstill acceptance on the shipped
/// pick-and-place (measured, see docs/robots.md, "Drives"): the arm is not at rest
/// during the dwell (it creeps at 0.1–1 v_s, so q̇ = q̈ = 0 is no fix), and
/// the estimated q̇ there is off by amounts comparable to v_s, where
/// ∂τ/∂q̇ = Fc/v_s is 300–4000 N·m·s/rad: the true model evaluated at the
/// estimated states is off by more than the noise, with every linear
/// filter tried. On the true states the same identification predicts the
/// standstill torques at the noise level.
#[test]
fn standstill_torque_error_of_the_tanh_model_comes_from_the_velocity_estimate() {
    use idexp::ident::{process, Filter, Repetition, Run};
    use idexp::sim::{PerJoint, SimDesign, SimResult, SimSetup};
    let path = root("designs/sim_rpr_pick_place.toml");
    let d = SimDesign::read(&path).unwrap();
    let sim = |d: &SimDesign| {
        SimSetup::from_design(d, &root("designs"), &path.display().to_string())
            .unwrap()
            .run(&idexp::optim::Control::new())
            .unwrap()
    };
    let noisy = sim(&d);
    // the same process without noise, recorded at the 1 kHz controller rate:
    // the torque τ_k recorded at t_k is held over [t_k, t_k + h], so the true
    // states it belongs to are those of the midpoint (differences of the 1 kHz
    // record about t_k + h/2; about t_k the held torque's steps leave 0.03 N·m)
    let mut dc = d.clone();
    dc.noise.position = PerJoint::All(0.0);
    dc.noise.torque = PerJoint::All(0.0);
    dc.decimate = 1;
    let clean = sim(&dc);
    let c = &clean.reps[0];
    let (n, h, m) = (3, 1e-3, noisy.reps[0].len());
    let k_of = |p: usize| (5 * p).clamp(1, c.len() - 3);
    let qt: Vec<Vec<f64>> = (0..m)
        .map(|p| (0..n).map(|j| 0.5 * (c.q[k_of(p)][j] + c.q[k_of(p) + 1][j])).collect())
        .collect();
    let vt: Vec<Vec<f64>> = (0..m).map(|p| (0..n).map(|j| (c.q[k_of(p) + 1][j] - c.q[k_of(p)][j]) / h).collect()).collect();
    let at: Vec<Vec<f64>> = (0..m)
        .map(|p| {
            let k = k_of(p);
            (0..n)
                .map(|j| (c.q[k + 2][j] - c.q[k + 1][j] - c.q[k][j] + c.q[k - 1][j]) / (2.0 * h * h))
                .collect()
        })
        .collect();
    let truth = &noisy.setup.truth;
    let th = truth.nominal_params();
    let ws = Workspace::new(truth);
    let tau_at = |q: &[f64], v: &[f64], a: &[f64]| {
        let mut t = vec![0.0; n];
        idexp::robot::inverse_dynamics(truth, &mut ws.clone(), th.as_slice(), q, v, a, &mut t);
        t
    };
    let rest: Vec<usize> = (3..m - 3)
        .filter(|&p| {
            let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            noisy.setup.reference.eval(noisy.reps[0].t[p] - noisy.reps[0].t[0], &mut q, &mut qd, &mut qdd);
            qd.iter().chain(&qdd).all(|v| v.abs() < 1e-9)
        })
        .collect();
    assert!(rest.len() > 300, "{}", rest.len());
    let rms = |f: &dyn Fn(usize) -> f64| (rest.iter().map(|&p| f(p).powi(2)).sum::<f64>() / rest.len() as f64).sqrt();
    let true_tau: Vec<Vec<f64>> = (0..m).map(|p| tau_at(&qt[p], &vt[p], &at[p])).collect();
    let v_s = 1e-3;
    let pr10 = process(&Run::new(vec![], noisy.reps.clone()).unwrap(), &Filter::LowPass { cutoff: 10.0 }).unwrap();
    // noise floor at rest: σ of the averaged torque
    let floor: Vec<f64> = (0..n)
        .map(|j| rms(&|p| (pr10.tau_var.as_ref().unwrap()[p][j] / pr10.n_reps as f64).sqrt()))
        .collect();
    println!("noise floor at rest {floor:.4?} N·m");
    for j in 0..n {
        let (r, zero) = (rms(&|p| vt[p][j]), rms(&|p| tau_at(&qt[p], &[0.0; 3], &[0.0; 3])[j] - true_tau[p][j]));
        println!("joint {j}: true q̇ at rest RMS {r:.2e} rad/s; true model at (q, 0, 0) off by {zero:.3} N·m");
        // the arm creeps: zeroing q̇, q̈ at rest puts the torque off by more than the
        // noise, except on the slide, whose floor (0.55 N·m, the PD loop feeding the
        // position noise back) is above its 0.40 N·m
        assert!(r > 0.05 * v_s, "joint {j}: {r}");
        assert!(if j == 1 { zero < floor[j] } else { zero > 2.0 * floor[j] }, "joint {j}: {zero}");
    }
    // the simulated states close the loop: the true model at them gives the
    // recorded torque, over every sample, to well below the torque noise
    for j in 0..n {
        let e = ((3..m - 3).map(|p| (c.tau[k_of(p)][j] - true_tau[p][j]).powi(2)).sum::<f64>() / (m - 6) as f64).sqrt();
        println!("joint {j}: recorded torque − true model at the true states, RMS {e:.1e} N·m");
        assert!(e < 0.3 * 0.05 / 10f64.sqrt(), "joint {j}: {e}");
    }
    for (name, f) in [
        ("low-pass 10 Hz", Filter::LowPass { cutoff: 10.0 }),
        ("low-pass 20 Hz", Filter::LowPass { cutoff: 20.0 }),
        ("low-pass 40 Hz", Filter::LowPass { cutoff: 40.0 }),
        ("central differences", Filter::None),
    ] {
        let pr = process(&Run::new(vec![], noisy.reps.clone()).unwrap(), &f).unwrap();
        let qd_err: Vec<f64> = (0..n).map(|j| rms(&|p| pr.qd[p][j] - vt[p][j])).collect();
        let tau_err: Vec<f64> = (0..n).map(|j| rms(&|p| tau_at(&pr.q[p], &pr.qd[p], &pr.qdd[p])[j] - true_tau[p][j])).collect();
        let qd_err: Vec<String> = qd_err.iter().map(|x| format!("{x:.2e}")).collect();
        println!(
            "{name:<20} q̇ error at rest [{}] rad/s, true model at these states off by {tau_err:.3?} N·m",
            qd_err.join(", ")
        );
        // no filter brings every joint to the noise level
        assert!((0..n).any(|j| tau_err[j] > 2.0 * floor[j]), "{name}: {tau_err:?} vs {floor:?}");
    }
    // the same closed loop identified on its true states (torque noise as in the design)
    let mut g = rng(11);
    let mut gauss = || {
        let (u, v): (f64, f64) = (g.random::<f64>().max(1e-300), g.random::<f64>());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let reps: Vec<Repetition> = (0..10)
        .map(|_| Repetition {
            t: noisy.reps[0].t.clone(),
            q: qt.clone(),
            tau: (0..m).map(|p| (0..n).map(|j| c.tau[k_of(p)][j] + 0.05 * gauss()).collect()).collect(),
            r: None,
            qd: Some(vt.clone()),
            qdd: Some(at.clone()),
        })
        .collect();
    let val = simulate_shipped("sim_rpr_pick_place_validate");
    let res = SimResult { reps, ..noisy.clone() };
    let (it, rt, ft, zt) = ident_with(&noisy.setup.nominal, &res, &val, |_| {});
    let big = |id: &StudyResult| -> String {
        let t = id.estimate.truth.as_ref().unwrap();
        t.iter()
            .filter(|r| r.z.abs() > 2.5)
            .map(|r| format!("{} {:+.2}", r.name, r.z))
            .collect::<Vec<_>>()
            .join(", ")
    };
    println!(
        "tanh model on the true states: standstill RMS {rt:.4?} N·m, noise {ft:.4?}, max|z| {zt:.2} (|z| > 2.5: {})",
        big(&it)
    );
    // at the noise level, and near 3σ (18 base parameters)
    for j in 0..n {
        assert!(rt[j] < 1.2 * ft[j], "joint {j}: {} vs {}", rt[j], ft[j]);
    }
    assert!(zt < 5.0, "max|z| {zt}");
    // chance or bias: the same true states with two more draws of the torque noise
    for seed in [12, 13] {
        let mut g = rng(seed);
        let mut gauss = || {
            let (u, v): (f64, f64) = (g.random::<f64>().max(1e-300), g.random::<f64>());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let reps: Vec<Repetition> = res
            .reps
            .iter()
            .map(|r| Repetition {
                tau: (0..m).map(|p| (0..n).map(|j| c.tau[k_of(p)][j] + 0.05 * gauss()).collect()).collect(),
                ..r.clone()
            })
            .collect();
        let res = SimResult { reps, ..noisy.clone() };
        let (id, r, _, z) = ident_with(&noisy.setup.nominal, &res, &val, |_| {});
        println!(
            "  torque-noise seed {seed}: standstill RMS {r:.4?} N·m, max|z| {z:.2} (|z| > 2.5: {})",
            big(&id)
        );
        assert!(z < 5.0, "seed {seed}: max|z| {z}");
    }
}

/// Simulates a shipped design with `edit` applied to it.
fn simulate_edited(name: &str, edit: impl Fn(&mut idexp::sim::SimDesign)) -> idexp::sim::SimResult {
    let path = root(&format!("designs/{name}.toml"));
    let mut d = idexp::sim::SimDesign::read(&path).unwrap();
    edit(&mut d);
    d.validate(&path.display().to_string()).unwrap();
    let setup = idexp::sim::SimSetup::from_design(&d, &root("designs"), &path.display().to_string()).unwrap();
    setup.run(&idexp::optim::Control::new()).unwrap()
}

/// The pick-and-place process of `pick_and_place_with_dwell_tanh_model_beats_sign_model_at_standstill`
/// with the drive's velocities logged (`record_velocity`, default noise
/// 1.7e-5 rad/s; q and τ are the same samples as without them). Identified
/// with the logged q̇ (q̈ from it, low-pass 40 Hz), the tanh model on every
/// row meets the standstill acceptance; the sign model on the same data does
/// not. Measured, not tuned: the numbers are printed (docs/robots.md, "Drives").
#[test]
fn pick_and_place_with_logged_drive_velocities_meets_the_standstill_acceptance() {
    use idexp::ident::{Standstill, VelocityFrom, VelocitySource};
    let logged = |d: &mut idexp::sim::SimDesign| d.record_velocity = true;
    let res = simulate_edited("sim_rpr_pick_place", logged);
    let val = simulate_edited("sim_rpr_pick_place_validate", logged);
    // logging velocities leaves the positions and torques of the run as they were
    let plain = simulate_shipped("sim_rpr_pick_place");
    assert_eq!((&res.reps[3].q, &res.reps[3].tau), (&plain.reps[3].q, &plain.reps[3].tau));
    let tanh = res.setup.nominal.clone();
    let sign = robot::load(&root("tests/data/ident/rpr_drives.toml")).unwrap();
    // the experiment (and so its validation run) low-pass filtered at 40 Hz
    let lp40 = |d: &mut StudyDesign| {
        d.experiment[0].filter = FilterName::Lowpass;
        d.experiment[0].cutoff = 40.0;
    };
    let (it, rt, ft, zt) = ident_with(&tanh, &res, &val, lp40);
    assert_eq!(it.estimate.experiments[0].velocity, VelocitySource::Logged);
    assert!(it.estimate.text().contains("q̇ logged (qd* columns, unfiltered)"), "{}", it.estimate.text());
    assert!(it.estimate.experiments[0].rows_used.iter().all(|r| r.used == r.total));
    let (i10, r10, _, z10) = ident_with(&tanh, &res, &val, |_| {});
    let (ip, rp, _, zp) = ident_with(&tanh, &res, &val, |d| d.experiment[0].velocity_from = VelocityFrom::Positions);
    assert_eq!(ip.estimate.experiments[0].velocity, VelocitySource::Positions);
    let (is, rs, _, zs) = ident_with(&sign, &res, &val, lp40);
    let (ik, rk, _, zk) = ident_with(&sign, &res, &val, |d| {
        lp40(d);
        d.experiment[0].standstill = Some(Standstill::Keep);
    });
    let pct = |v: &[f64]| v.iter().map(|x| format!("{:.2}", 100.0 * x)).collect::<Vec<_>>().join(", ");
    let num = |v: &[f64]| v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ");
    println!(
        "{} base parameters; noise floor at standstill (σ of the averaged torque, N·m): [{}]",
        it.estimate.names.len(),
        num(&ft)
    );
    for (name, id, rms, z) in [
        ("tanh, logged q̇, 40 Hz", &it, &rt, zt),
        ("tanh, logged q̇, 10 Hz", &i10, &r10, z10),
        ("tanh, q̇ from positions", &ip, &rp, zp),
        ("sign, dropped, logged", &is, &rs, zs),
        ("sign, every row, logged", &ik, &rk, zk),
    ] {
        let big: Vec<String> = id
            .estimate
            .truth
            .as_ref()
            .unwrap()
            .iter()
            .filter(|r| r.z.abs() > 2.5)
            .map(|r| format!("{} {:+.2}", r.name, r.z))
            .collect();
        println!(
            "{name:<24} e*_j all rows [{}] %, validation all rows [{}] %, standstill RMS [{}] N·m, max|z| {z:.2} (|z| > 2.5: {})",
            pct(&id.estimate.experiments[0].errors_all.e_rel),
            pct(&id.estimate.validation[0].errors_all.e_rel),
            num(rms),
            big.join(", ")
        );
    }
    // the acceptance: within 3σ, standstill torques at the noise level
    assert!(zt < 3.0, "max|z| {zt}");
    for j in 0..3 {
        assert!(rt[j] < 1.2 * ft[j], "joint {j}: standstill RMS {} vs noise {}", rt[j], ft[j]);
        // the sign model on the same data: standstill error several times the noise
        assert!(rs[j] > 3.0 * ft[j] && rk[j] > 2.0 * ft[j], "joint {j}: {} / {} vs {}", rs[j], rk[j], ft[j]);
        assert!(
            it.estimate.experiments[0].errors_all.e_rel[j] < is.estimate.experiments[0].errors_all.e_rel[j],
            "joint {j}"
        );
        assert!(
            it.estimate.experiments[0].errors_all.e_rel[j] < ik.estimate.experiments[0].errors_all.e_rel[j],
            "joint {j}"
        );
    }
    assert!(zk > 10.0, "sign model on every row: max|z| {zk}");
    // q̈ from the logged q̇ through the 10 Hz low-pass misses the captures at the
    // start of a dwell: joint 1's standstill error is above the 40 Hz one's
    assert!(r10[0] > 1.2 * rt[0], "{} vs {}", r10[0], rt[0]);
    // and the velocity from the positions is the old failure
    assert!(zp > 10.0 && rp[0] > 3.0 * ft[0] && rp[2] > 3.0 * ft[2], "{zp} {rp:?}");
}

/// A three-joint run file with the columns `header` and `rows` rows of values `f(row, column)`.
fn write_csv(path: &Path, header: &[&str], rows: usize, f: impl Fn(usize, usize) -> String) {
    let mut s = header.join(",") + "\n";
    for k in 0..rows {
        let row: Vec<String> = (0..header.len())
            .map(|c| if c == 0 { format!("{}", 0.01 * k as f64) } else { f(k, c) })
            .collect();
        s += &(row.join(",") + "\n");
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn bad_logged_velocity_columns_are_errors_naming_file_row_and_column() {
    use idexp::ident::{Run, VelocityFrom, Weights};
    let tmp = tempfile::tempdir().unwrap();
    let base = ["t", "q1", "q2", "q3", "tau1", "tau2", "tau3"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> { base.iter().copied().chain(extra.iter().copied()).collect() };
    let val = |k: usize, c: usize| format!("{}", 0.1 * ((k * 7 + c * 3) % 11) as f64);
    let read = |name: &str, header: &[&str], f: &dyn Fn(usize, usize) -> String| {
        let p = tmp.path().join(name);
        write_csv(&p, header, 20, f);
        err_text(Run::read(std::slice::from_ref(&p), 3))
    };
    // a velocity column missing for one joint
    let e = read("partial.csv", &with(&["qd1", "qd3"]), &val);
    assert!(e.contains("partial.csv") && e.contains("qd2") && e.contains("every joint"), "{e}");
    // accelerations without velocities
    let e = read("acc.csv", &with(&["qdd1", "qdd2", "qdd3"]), &val);
    assert!(e.contains("acc.csv") && e.contains("qd1") && e.contains("without logged velocities"), "{e}");
    // NaN, infinite and non-number velocities: file, row and column
    for (bad, what) in [("NaN", "nan"), ("inf", "inf"), ("fast", "fast")] {
        let f = |k: usize, c: usize| if k == 6 && c == 8 { bad.to_string() } else { val(k, c) };
        let e = read("nan.csv", &with(&["qd1", "qd2", "qd3"]), &f);
        assert!(e.contains("nan.csv") && e.contains("qd2") && e.contains('7'), "{what}: {e}");
    }
    // a velocity column beyond the robot's joints
    let e = read("extra.csv", &with(&["qd1", "qd2", "qd3", "qd4"]), &val);
    assert!(e.contains("extra.csv") && e.contains("qd4"), "{e}");
    // velocities in one repetition but not in the other
    let (a, b) = (tmp.path().join("a.csv"), tmp.path().join("b.csv"));
    write_csv(&a, &with(&["qd1", "qd2", "qd3"]), 20, val);
    write_csv(&b, &base, 20, val);
    let e = err_text(Run::read(&[a.clone(), b.clone()], 3));
    assert!(e.contains("b.csv") && e.contains("qd1") && e.contains("same columns"), "{e}");
    // --velocity-from log on a run without velocities
    let r = robot::load(&root("tests/data/ident/rpr_drives_tanh.toml")).unwrap();
    let run = Run::read(std::slice::from_ref(&b), 3).unwrap();
    let torques = idexp::data::TorqueSource::logged_torques();
    let e = err_text(study(&r, run, torques, None, None, Weights::Sample, |d| {
        d.experiment[0].velocity_from = VelocityFrom::Log
    }));
    assert!(e.contains("b.csv") && e.contains("velocity_from") && e.contains("qd1..qd3"), "{e}");
    assert!("logged".parse::<VelocityFrom>().unwrap_err().to_string().contains("auto, log or positions"));
    // the design: velocity noise without logged velocities, negative noise
    let design = |extra: &str, noise: &str| {
        format!(
            "robot = {:?}\n{extra}\n[noise]\n{noise}\n[reference]\nkind = \"random_fourier\"\nn_h = 3\nfrequency = 0.2\namplitude = 0.3\nseed = 1\n",
            root("tests/data/ident/rpr_drives_tanh.toml").to_str().unwrap()
        )
    };
    for (extra, noise, what) in [
        ("", "velocity = 1e-5", "record_velocity = true"),
        ("record_velocity = true", "velocity = -1e-5", "-0.00001"),
        ("record_velocity = true", "velocity = [1e-5, 2e-5]", "one per joint"),
    ] {
        let d: idexp::sim::SimDesign = idexp::io::parse_toml(Path::new("vel.toml"), &design(extra, noise)).unwrap();
        let e = match d.validate("vel.toml") {
            Err(e) => e.to_string(),
            Ok(()) => err_text(idexp::sim::SimSetup::from_design(&d, &root(""), "vel.toml")),
        };
        assert!(e.contains("vel.toml") && e.contains("noise.velocity") && e.contains(what), "{e}");
    }
}
