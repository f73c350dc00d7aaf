//! The closed-loop simulator: physics (noise-free tracking with the exact
//! model, recorded torques = inverse dynamics), reproducibility from the seed
//! whatever the thread count, references (Fourier, CSV with and without
//! derivatives, process motions, experiments), noise and quantisation, and
//! design-file errors.

mod ident_util;
use ident_util::*;
use idexp::robot::{mass_matrix, Workspace};
use idexp::sim::{perturb_params, SimDesign, SimSetup};
use idexp::trajectory::{differentiate, Reference};

fn fourier_design(extra: &str) -> SimDesign {
    design(&format!(
        r#"
robot = "tests/data/ident/rpr_drives.toml"
rate = 1000.0
repetitions = 2
seed = 4
{extra}
[reference]
kind = "random_fourier"
frequency = 0.2
amplitude = 0.6
seed = 2
"#
    ))
}

#[test]
fn noise_free_exact_model_tracks_the_reference_and_torques_are_inverse_dynamics() {
    let res = simulate(&fourier_design(""));
    // exact model feedforward, no noise: only the zero-order hold and RK4 errors remain
    let emax = res.status.max_tracking_error.iter().cloned().fold(0.0, f64::max);
    assert!(emax < 1e-3, "max tracking error {emax}");
    // the recorded torque drives the true plant: τ ≈ inverse dynamics at the reference state
    // (up to the feedback on the tiny tracking error)
    let setup = &res.setup;
    let f = setup.reference.fourier().unwrap();
    let robot = &setup.truth;
    let mut ws = Workspace::new(robot);
    let n = robot.dof();
    let (mut q, mut qd, mut qdd, mut tau) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let rep = &res.reps[0];
    let mut worst: f64 = 0.0;
    for k in (0..rep.len()).step_by(97) {
        f.eval(rep.t[k], &mut q, &mut qd, &mut qdd);
        idexp::robot::rnea(robot, &mut ws, &q, &qd, &qdd, &mut tau);
        for j in 0..n {
            let kp = setup.kp[j];
            worst = worst.max((rep.tau[k][j] - tau[j]).abs() / (1e-3 + kp * emax + setup.kd[j] * 10.0 * emax));
        }
    }
    assert!(
        worst < 1.0,
        "torque differs from inverse dynamics by more than the feedback on the tracking error: {worst}"
    );
}

#[test]
fn same_seed_same_data_whatever_the_thread_count() {
    let d = design(
        r#"
robot = "tests/data/ident/rpr_drives.toml"
rate = 1000.0
repetitions = 3
seed = 11
[noise]
torque = 0.1
position = 1e-4
disturbance = 0.05
[reference]
kind = "pick_and_place"
area_a = { center = [0.25, -0.38, 0.36], half_size = [0.04, 0.04, 0.01] }
area_b = { center = [-0.25, -0.38, 0.36], half_size = [0.04, 0.04, 0.01] }
cycles = 1
q_home = [0.0, 0.25, 0.0]
"#,
    );
    let setup = SimSetup::from_design(&d, &root(""), "t").unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| setup.run(&idexp::optim::Control::new()).unwrap());
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| setup.run(&idexp::optim::Control::new()).unwrap());
    assert_eq!(one.reps, two.reps);
    assert_ne!(one.reps[0], one.reps[1], "repetitions draw different noise");
    let again = simulate(&fourier_design("[noise]\ntorque = 0.1"));
    let again2 = simulate(&fourier_design("[noise]\ntorque = 0.1"));
    assert_eq!(again.reps, again2.reps);
}

#[test]
fn noise_levels_and_quantisation_are_as_designed() {
    let res = simulate(&fourier_design("[noise]\nencoder_counts = 1048576"));
    let quantum = std::f64::consts::TAU / 1048576.0;
    for row in &res.reps[0].q {
        for v in row {
            let k = v / quantum;
            assert!((k - k.round()).abs() < 1e-6, "position {v} not on the encoder grid");
        }
    }
    let res = simulate(&fourier_design("[noise]\ntorque = 0.2"));
    // torque noise: the difference of two repetitions has variance 2σ² (same periodic motion)
    let (a, b) = (&res.reps[0].tau, &res.reps[1].tau);
    let m = a.len();
    let var: f64 = (0..m).map(|k| (a[k][2] - b[k][2]).powi(2)).sum::<f64>() / m as f64 / 2.0;
    assert!((var.sqrt() - 0.2).abs() < 0.02, "torque noise σ {} (designed 0.2)", var.sqrt());
}

#[test]
fn perturbed_truth_is_physical_and_zero_perturbation_is_nominal() {
    let r = idexp::robot::load(&root("designs/robots/puma560.toml")).unwrap();
    assert_eq!(perturb_params(&r, 0.0, 3), r.nominal_params().as_slice().to_vec());
    let th = perturb_params(&r, 0.3, 3);
    assert_ne!(th, r.nominal_params().as_slice().to_vec());
    let t = r.with_params(&th).unwrap();
    let mut ws = Workspace::new(&t);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
    for _ in 0..20 {
        let q: Vec<f64> = (0..6).map(|_| rand::RngExt::random_range(&mut rng, -2.0..2.0)).collect();
        assert!(mass_matrix(&t, &mut ws, &q).cholesky().is_some(), "perturbed mass matrix not positive definite");
    }
}

#[test]
fn csv_references_with_and_without_derivatives() {
    let d = tempfile::tempdir().unwrap();
    let robot = idexp::robot::load(&root("tests/data/ident/rpr_drives.toml")).unwrap();
    let f = idexp::trajectory::reference::random_fourier(&robot, 3, 0.5, 0.5, None, 1, "t").unwrap();
    let s = f.sample(1000.0).unwrap();
    s.write(&d.path().join("full.csv")).unwrap();
    // positions only
    let header = "t,q1,q2,q3\n".to_string();
    let body: String =
        s.q.iter()
            .zip(s.t.as_ref().unwrap())
            .map(|(q, t)| format!("{t},{},{},{}\n", q[0], q[1], q[2]))
            .collect();
    std::fs::write(d.path().join("pos.csv"), header + &body).unwrap();
    let spec_full: idexp::trajectory::ReferenceSpec = toml::from_str("kind = \"states\"\nfile = \"full.csv\"").unwrap();
    let spec_pos: idexp::trajectory::ReferenceSpec = toml::from_str("kind = \"states\"\nfile = \"pos.csv\"").unwrap();
    let rf = spec_full.build(&robot, d.path(), 1000.0, "t").unwrap();
    let rp = spec_pos.build(&robot, d.path(), 1000.0, "t").unwrap();
    let (mut a, mut b, mut c) = (vec![0.0; 3], vec![0.0; 3], vec![0.0; 3]);
    let (mut a2, mut b2, mut c2) = (vec![0.0; 3], vec![0.0; 3], vec![0.0; 3]);
    for &t in &[0.1234, 0.9, 1.5] {
        f.eval(t, &mut a, &mut b, &mut c);
        rp.eval(t, &mut a2, &mut b2, &mut c2);
        for j in 0..3 {
            assert!((a[j] - a2[j]).abs() < 1e-6);
            assert!((b[j] - b2[j]).abs() < 1e-3 * (1.0 + b[j].abs()), "velocity by central differences");
            assert!((c[j] - c2[j]).abs() < 1e-2 * (1.0 + c[j].abs()), "acceleration by central differences");
        }
        rf.eval(t, &mut a2, &mut b2, &mut c2);
        for j in 0..3 {
            assert!((b[j] - b2[j]).abs() < 1e-5 * (1.0 + b[j].abs()), "given velocities interpolated");
        }
    }
    assert!(rp.periodic());
    // differentiation of a parabola is exact in the interior
    let q: Vec<Vec<f64>> = (0..10).map(|i| vec![(i as f64 * 0.1).powi(2)]).collect();
    let (v, acc) = differentiate(&q, 0.1, false);
    assert!((v[5][0] - 1.0).abs() < 1e-12 && (acc[5][0] - 2.0).abs() < 1e-9);
    // a non-uniform time column is rejected with the row
    std::fs::write(d.path().join("bad.csv"), "t,q1,q2,q3\n0,0,0,0\n0.1,0,0,0\n0.3,0,0,0\n0.4,0,0,0\n").unwrap();
    let spec_bad: idexp::trajectory::ReferenceSpec = toml::from_str("kind = \"states\"\nfile = \"bad.csv\"").unwrap();
    let e = spec_bad.build(&robot, d.path(), 1000.0, "t").unwrap_err().to_string();
    assert!(e.contains("bad.csv") && e.contains("column `t`") && e.contains("uniform"), "{e}");
}

#[test]
fn process_and_experiment_references_start_and_end_at_rest() {
    let robot = idexp::robot::load(&root("tests/data/ident/rpr_drives.toml")).unwrap();
    let specs = [
        "kind = \"pick_and_place\"\narea_a = { center = [0.25, -0.38, 0.36], half_size = [0.04, 0.04, 0.01] }\narea_b = { center = [-0.25, -0.38, 0.36], half_size = [0.04, 0.04, 0.01] }\nq_home = [0.0, 0.25, 0.0]",
        "kind = \"square\"\ncenter = [0.0, -0.4, 0.38]\nside = 0.1\nq_home = [0.0, 0.25, 0.0]",
        "kind = \"gravity_slopes\"\njoint = 1\nfrom = -1.0\nto = 1.0\nvelocity = 0.5\nq_rest = [0.0, 0.2, 0.0]",
        "kind = \"bang_bang\"\njoint = 3\nacceleration = 4.0\nvelocities = [0.5, 1.0]\nq_rest = [0.0, 0.2, 0.0]",
    ];
    for s in specs {
        let spec: idexp::trajectory::ReferenceSpec = toml::from_str(s).unwrap();
        spec.validate("t").unwrap();
        let r = spec.build(&robot, std::path::Path::new("."), 500.0, "t").unwrap();
        assert!(!r.periodic());
        let st = r.sample(500.0);
        let (first, last) = (&st.qd[0], st.qd.last().unwrap());
        assert!(first.iter().chain(last.iter()).all(|v| v.abs() < 1e-6), "{s}: not at rest at the ends");
        if let Reference::Sampled { q, .. } = &r {
            // the square keeps the end effector at its height
            if s.contains("square") {
                let mut ws = Workspace::new(&robot);
                let fr = robot.end_effector();
                let z: Vec<f64> = q[800..q.len() - 800]
                    .iter()
                    .map(|qq| idexp::robot::frame_pose(&robot, &mut ws, qq, &fr).translation.z)
                    .collect();
                assert!(z.iter().all(|v| (v - 0.38).abs() < 1e-4), "square height");
            }
        }
    }
    // an unreachable target is reported
    let spec: idexp::trajectory::ReferenceSpec =
        toml::from_str("kind = \"pick_and_place\"\narea_a = { center = [3.0, 0.0, 0.0], half_size = [0.0, 0.0, 0.0] }\narea_b = { center = [0.0, -0.4, 0.36], half_size = [0.0, 0.0, 0.0] }").unwrap();
    let e = spec.build(&robot, std::path::Path::new("."), 500.0, "t").unwrap_err().to_string();
    assert!(e.contains("out of reach"), "{e}");
}

#[test]
fn design_errors_name_the_field() {
    let bad = |text: &str, needle: &str| {
        let full = format!("robot = \"tests/data/ident/rpr_drives.toml\"\n{text}\n[reference]\nkind = \"random_fourier\"\n");
        let r: idexp::Result<SimDesign> = idexp::io::parse_toml(std::path::Path::new("d.toml"), &full).and_then(|d: SimDesign| d.validate("d.toml").map(|_| d));
        let e = r.unwrap_err().to_string();
        assert!(e.contains(needle), "{text}: {e}");
    };
    bad("rate = -1.0", "rate");
    bad("repetitions = 0", "repetitions");
    bad("ratee = 100.0", "ratee");
    bad("[truth]\nperturbation = 2.0", "truth.perturbation");
    bad("[controller]\nbandwidth = 500.0", "controller.bandwidth");
    bad("[noise]\ntorque = -1.0", "noise.torque");
    // unknown keys inside [reference] are caught too, also for the inline trajectory
    let r: Result<idexp::trajectory::ReferenceSpec, _> = toml::from_str("kind = \"random_fourier\"\nfoo = 1");
    assert!(r.unwrap_err().to_string().contains("foo"));
    let r: Result<idexp::trajectory::ReferenceSpec, _> = toml::from_str("kind = \"fourier_inline\"\nomega = 1.0\nq0 = [0.0]\na = [[0.1]]\nb = [[0.0]]\nzz = 3");
    assert!(r.unwrap_err().to_string().contains("zz"));
    // a period that is not a whole number of controller steps
    let d = design(
        "robot = \"tests/data/ident/rpr_drives.toml\"\nrate = 7.0\n[controller]\nbandwidth = 0.5\nvelocity_filter = 0.0\n[reference]\nkind = \"random_fourier\"\nfrequency = 0.3\n",
    );
    let e = SimSetup::from_design(&d, &root(""), "d.toml").unwrap_err().to_string();
    assert!(e.contains("rate"), "{e}");
    // a per-joint value of the wrong length
    let d = design("robot = \"tests/data/ident/rpr_drives.toml\"\n[noise]\ntorque = [0.1, 0.2]\n[reference]\nkind = \"random_fourier\"\n");
    let e = SimSetup::from_design(&d, &root(""), "d.toml").unwrap_err().to_string();
    assert!(e.contains("noise.torque"), "{e}");
}
