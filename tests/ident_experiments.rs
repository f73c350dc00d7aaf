//! The dedicated experiments of paper 002 §3.2 on the simulated PUMA 560:
//! gravity slopes (eq. 23) against the true gravity torque, and bang-bang
//! friction (eq. 2) against the true friction coefficients and inertia.

mod ident_util;
use ident_util::*;
use idexp::ident::experiments::{friction_experiment, gravity_experiment, GravityTerm};
use idexp::ident::{process, Filter};
use idexp::robot::{gravity, mass_matrix, Friction, Workspace};

const REST: &str = "[0.3, -0.5, 0.4, 0.0, 0.3, 0.0]";

fn puma(reference: &str) -> idexp::sim::SimDesign {
    design(&format!(
        r#"
robot = "designs/robots/puma560.toml"
rate = 1000.0
decimate = 5
repetitions = 3
seed = 5
[truth]
perturbation = 0.1
seed = 8
[controller]
bandwidth = 8.0
[noise]
torque = 0.05
position = 1e-5
[reference]
{reference}
q_rest = {REST}
"#
    ))
}

#[test]
fn gravity_slopes_recover_the_true_gravity_sinusoid() {
    let res = simulate(&puma(
        "kind = \"gravity_slopes\"\njoint = 2\nfrom = -1.2\nto = 0.8\nvelocity = 0.4\nacceleration = 2.0",
    ));
    let pr = process(&run_of(&res), &Filter::LowPass { cutoff: 10.0 }).unwrap();
    let g = gravity_experiment(&pr, 2).unwrap();
    // truth: gravity torque of joint 2 along the slope, fitted exactly by k sin(q + off)
    let truth = &res.setup.truth;
    let mut ws = Workspace::new(truth);
    let mut q: Vec<f64> = serde_json::from_str(REST).unwrap();
    let (mut a, mut b) = (nalgebra::DMatrix::zeros(50, 2), nalgebra::DVector::zeros(50));
    for i in 0..50 {
        q[1] = -1.2 + 2.0 * i as f64 / 49.0;
        let tg = gravity(truth, &mut ws, &q);
        a[(i, 0)] = q[1].sin();
        a[(i, 1)] = q[1].cos();
        b[i] = tg[1];
    }
    let x = a.clone().svd(true, true).solve(&b, 1e-12).unwrap();
    let (k, off) = (x[0].hypot(x[1]), x[1].atan2(x[0]));
    assert!((a * &x - b).amax() < 1e-9 * k, "gravity is exactly sinusoidal in q2");
    println!("k {} vs {k}, off {} vs {off}, c± {} {}", g.k, g.q_off, g.offset_pos, g.offset_neg);
    assert!((g.k - k).abs() < 0.01 * k, "k {} vs {k}", g.k);
    assert!((g.q_off - off).abs() < 0.01, "q_off {} vs {off}", g.q_off);
    // the offsets of the two directions hold friction at ±v: their half difference is Fc + Fv v
    let Friction::Symmetric { fc, fv, .. } = truth.drives[1].friction else {
        panic!()
    };
    let f = 0.5 * (g.offset_pos - g.offset_neg);
    assert!(
        (f - (fc + fv * g.speed)).abs() < 0.05 * (fc + fv * g.speed),
        "friction at speed {f} vs {}",
        fc + fv * g.speed
    );
}

#[test]
fn bang_bang_recovers_friction_and_inertia() {
    let res = simulate(&puma("kind = \"bang_bang\"\njoint = 2\nacceleration = 3.0\nvelocities = [0.3, 0.6, 1.0]"));
    let pr = process(&run_of(&res), &Filter::LowPass { cutoff: 10.0 }).unwrap();
    let res_g = simulate(&puma(
        "kind = \"gravity_slopes\"\njoint = 2\nfrom = -1.2\nto = 0.8\nvelocity = 0.4\nacceleration = 2.0",
    ));
    let g = gravity_experiment(&process(&run_of(&res_g), &Filter::LowPass { cutoff: 10.0 }).unwrap(), 2).unwrap();
    let f = friction_experiment(&pr, 2, GravityTerm::Given(&g), 0.05).unwrap();
    assert!(f.gravity_given);
    let truth = &res.setup.truth;
    let Friction::Symmetric { fc, fv, .. } = truth.drives[1].friction else {
        panic!()
    };
    let mut ws = Workspace::new(truth);
    let q: Vec<f64> = serde_json::from_str(REST).unwrap();
    let j22 = mass_matrix(truth, &mut ws, &q)[(1, 1)];
    println!("{f:?}\ntruth fc {fc} fv {fv} J {j22}");
    assert!((f.fc_pos - fc).abs() < 0.05 * fc, "Fc+ {} vs {fc}", f.fc_pos);
    assert!((f.fc_neg + fc).abs() < 0.05 * fc, "Fc- {} vs {}", f.fc_neg, -fc);
    assert!((f.fv_pos - fv).abs() < 0.1 * fv, "Fv+ {} vs {fv}", f.fv_pos);
    assert!((f.fv_neg - fv).abs() < 0.1 * fv, "Fv- {} vs {fv}", f.fv_neg);
    assert!((f.inertia - j22).abs() < 0.05 * j22, "J {} vs {j22}", f.inertia);
    // fitting gravity alongside over this 0.5 rad excursion is ill-posed, and the standard deviations say so
    let f2 = friction_experiment(&pr, 2, GravityTerm::Fit, 0.05).unwrap();
    assert!(f2.std[1] > 10.0 * f.std[1], "std of Fc+ {} vs {}", f2.std[1], f.std[1]);
    // joint 1 of the PUMA has a vertical axis: no gravity term
    let res1 = simulate(&puma("kind = \"bang_bang\"\njoint = 1\nacceleration = 3.0\nvelocities = [0.3, 0.6, 1.0]"));
    let pr1 = process(&run_of(&res1), &Filter::LowPass { cutoff: 10.0 }).unwrap();
    let f1 = friction_experiment(&pr1, 1, GravityTerm::Zero, 0.05).unwrap();
    let Friction::Symmetric { fc: fc1, .. } = truth.drives[0].friction else {
        panic!()
    };
    assert!((f1.fc_pos - fc1).abs() < 0.05 * fc1 && (f1.fc_neg + fc1).abs() < 0.05 * fc1, "{f1:?} vs {fc1}");
    // a joint number out of range is an input error
    assert!(friction_experiment(&pr, 7, GravityTerm::Zero, 0.05).is_err());
}

/// The dedicated fits as a study (every `[[experiment]]` with `joint`, the
/// friction entry taking its gravity from the gravity entry): the same
/// numbers as the fits called on the runs filtered by hand, to the bit; and
/// what such a study cannot mean is refused, naming the entry and the key.
#[test]
fn a_dedicated_study_is_the_fits_of_its_entries() {
    use idexp::ident::study::{run_dedicated, Given, Inputs, JointFit, StudyDesign};
    let res_g = simulate(&puma(
        "kind = \"gravity_slopes\"\njoint = 2\nfrom = -1.2\nto = 0.8\nvelocity = 0.4\nacceleration = 2.0",
    ));
    let res_f = simulate(&puma("kind = \"bang_bang\"\njoint = 2\nacceleration = 3.0\nvelocities = [0.3, 0.6, 1.0]"));
    let text = r#"
robot = "designs/robots/puma560.toml"
[[experiment]]
name = "friction_2"
kind = "friction"
joint = 2
files = []
gravity = "gravity_2"
min_speed = 0.05
[[experiment]]
name = "gravity_2"
kind = "gravity"
joint = 2
files = []
"#;
    let design: StudyDesign = toml::from_str(text).unwrap();
    let given = |res: &idexp::sim::SimResult| Given {
        run: run_of(res),
        trajectory: None,
        torque_source: idexp::data::TorqueSource::logged_torques(),
    };
    let inputs = Inputs {
        entries: [("gravity_2".to_string(), given(&res_g)), ("friction_2".to_string(), given(&res_f))].into(),
        ..Default::default()
    };
    let r = run_dedicated(&design, std::path::Path::new(""), &inputs, &idexp::optim::Control::new()).unwrap();
    let lowpass = Filter::LowPass { cutoff: 10.0 };
    let g = gravity_experiment(&process(&run_of(&res_g), &lowpass).unwrap(), 2).unwrap();
    let f = friction_experiment(&process(&run_of(&res_f), &lowpass).unwrap(), 2, GravityTerm::Given(&g), 0.05).unwrap();
    // the design's order, the gravity fitted first all the same
    assert_eq!(r.entries.iter().map(|e| e.name.as_str()).collect::<Vec<_>>(), ["friction_2", "gravity_2"]);
    match (&r.entries[0].fit, &r.entries[1].fit) {
        (JointFit::Friction { fit, gravity_source, .. }, JointFit::Gravity(gs)) => {
            assert_eq!(gs, &g);
            assert_eq!(fit, &f);
            assert!(gravity_source.contains("gravity_2"), "{gravity_source}");
        }
        other => panic!("{other:?}"),
    }
    // refusals, each naming the key
    let refused = |edit: &dyn Fn(&mut StudyDesign), key: &str| {
        let mut d: StudyDesign = toml::from_str(text).unwrap();
        edit(&mut d);
        let e = run_dedicated(&d, std::path::Path::new(""), &inputs, &idexp::optim::Control::new()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(&format!("`{key}`")) || msg.contains(&format!("{key}:")), "{key}: {msg}");
    };
    refused(&|d| d.experiment[1].kind = idexp::ident::study::ExperimentKind::Excitation, "joint");
    refused(&|d| d.experiment[0].gravity = Some("gravity_3".into()), "gravity");
    refused(&|d| d.experiment.iter_mut().for_each(|e| e.joint = Some(7)), "joint");
    refused(&|d| d.experiment[1].joint = Some(3), "gravity");
    refused(&|d| d.experiment[1].joint = None, "joint");
    refused(&|d| d.method = idexp::ident::Method::Ols, "method");
    refused(&|d| d.export = vec![idexp::ident::study::ExportFormat::Csv], "export");
}
