//! The elastic information source of `idexp positions`: F_i against paper 001
//! eq. 5 written out from `elastic::frf_jacobian`, the defaults taken from the
//! elastic design file, end to end on a small candidate set (certified
//! D-optimal, small support, checked again with independently computed
//! information), the shipped few-thousand-candidate design (ignored: long),
//! and design errors naming the field.

mod common;

use idexp::elastic::{self, ElasticModel, Estimator, NoiseModel, Output, C64};
use idexp::positions::design::InformationSpec;
use idexp::positions::elastic::{load_elastic, ElasticScale, ElasticSource};
#[cfg(feature = "cli")]
use idexp::positions::Status;
use idexp::positions::{run_design, InformationSource, PositionsDesign};
use nalgebra::DMatrix;
#[cfg(feature = "cli")]
use std::path::Path;
#[cfg(feature = "cli")]
use std::process::Command;

const ELASTIC: &str = "designs/elastic_industrial6.toml";

fn model() -> ElasticModel {
    ElasticModel::load(&common::root(ELASTIC)).unwrap()
}

/// Paper 001 eq. 5 written out: F = Σ_k Σ_ij λ_ij⁻¹ Re{conj(ψ_ij) ψ_ijᵀ}, ψ from
/// the FRF Jacobian in the estimator's domain, λ the noise variance there.
fn eq5(m: &ElasticModel, q0: &[f64], omegas: &[f64], noise: NoiseModel, est: Estimator, out: Output) -> DMatrix<f64> {
    let theta = m.nominal_unknowns();
    let vals = m.full_values(&theta).unwrap();
    let op = m.operating_point(q0, &vals).unwrap();
    let (g, dg) = elastic::frf_jacobian(m, &op, &theta, omegas, out).unwrap();
    let p = theta.len();
    let na = m.n_motors();
    let mut f = DMatrix::zeros(p, p);
    for k in 0..omegas.len() {
        for i in 0..na {
            for j in 0..na {
                let gij = g[k][(i, j)];
                let var_g = match noise {
                    NoiseModel::Absolute { sigma } => sigma * sigma,
                    NoiseModel::Relative { rel } => rel * rel * gij.norm_sqr(),
                };
                let psi: Vec<C64> = (0..p)
                    .map(|a| {
                        let d = dg[k][a][(i, j)];
                        match est {
                            Estimator::Nls => d,
                            Estimator::Lls => d / gij,
                            Estimator::LlsMagnitude => C64::new((d / gij).re, 0.0),
                        }
                    })
                    .collect();
                let lam = match est {
                    Estimator::Nls => var_g,
                    _ => var_g / gij.norm_sqr(),
                };
                for a in 0..p {
                    for b in 0..p {
                        f[(a, b)] += (psi[a].conj() * psi[b]).re / lam;
                    }
                }
            }
        }
    }
    f
}

fn rel_diff(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).norm() / b.norm()
}

#[test]
fn elastic_information_is_paper_eq5_from_the_frf_jacobian() {
    let m = model();
    let p = m.n_unknowns();
    assert_eq!(p, 26);
    let q0 = [0.3, -1.1, 0.7, 0.2, 0.9, -0.4];
    let omegas: Vec<f64> = [3.0, 11.0, 27.0, 55.0, 93.0, 141.0].iter().map(|f| 2.0 * std::f64::consts::PI * f).collect();
    let nominal = m.nominal_unknowns();
    for (noise, est, out) in [
        (NoiseModel::Relative { rel: 0.02 }, Estimator::Lls, Output::Acceleration),
        (NoiseModel::Relative { rel: 0.05 }, Estimator::Nls, Output::Acceleration),
        (NoiseModel::Absolute { sigma: 1e-3 }, Estimator::Nls, Output::Velocity),
        (NoiseModel::Absolute { sigma: 1e-3 }, Estimator::LlsMagnitude, Output::Acceleration),
    ] {
        let want = eq5(&m, &q0, &omegas, noise, est, out);
        // physical units
        let src = ElasticSource::new(m.clone(), omegas.clone(), noise, est, out, ElasticScale::Physical).unwrap();
        assert_eq!(src.n_params(), p);
        assert_eq!(src.names(), m.unknown_names());
        let f = src.information(&q0).unwrap();
        assert!(rel_diff(&f, &want) < 1e-10, "{est:?}/{out:?}: {}", rel_diff(&f, &want));
        // the thin factor: F = G Gᵀ
        let g = src.jacobian_factor(&q0).unwrap();
        assert_eq!(g.ncols(), src.n_rows());
        assert!(rel_diff(&(&g * g.transpose()), &want) < 1e-10);
        // scaled to θ/θ_nom: S F S, and the compressed factor reproduces it
        let srcn = ElasticSource::new(m.clone(), omegas.clone(), noise, est, out, ElasticScale::Nominal).unwrap();
        let wantn = DMatrix::from_fn(p, p, |a, b| nominal[a] * want[(a, b)] * nominal[b]);
        let fnom = srcn.information(&q0).unwrap();
        assert!(rel_diff(&fnom, &wantn) < 1e-10, "{est:?}: scaled {}", rel_diff(&fnom, &wantn));
        let h = srcn.factor(&q0).unwrap();
        assert!(h.ncols() <= p);
        assert!(rel_diff(&(&h * h.transpose()), &wantn) < 1e-9);
        assert!(srcn.names().iter().all(|n| n.ends_with("/nominal")));
    }
    // the elastic module's own accumulation agrees (acceleration output)
    let noise = NoiseModel::Relative { rel: 0.02 };
    let f_el = elastic::information_matrix(&m, &q0, &omegas, &noise, Estimator::Lls).unwrap();
    let src = ElasticSource::new(m.clone(), omegas.clone(), noise, Estimator::Lls, Output::Acceleration, ElasticScale::Physical).unwrap();
    assert!(rel_diff(&src.information(&q0).unwrap(), &f_el) < 1e-10);
    // a wrong number of joints is an error, not a panic
    assert!(src.information(&q0[..5]).is_err());
}

#[test]
fn defaults_come_from_the_elastic_design_file() {
    let (m, set) = load_elastic(&common::root(ELASTIC), None, None, None, None).unwrap();
    assert_eq!(m.n_unknowns(), 26);
    // [multisine] period 1 s, band 2..150 Hz: odd lines 3, 5, ..., 149 Hz
    let want: Vec<f64> = (3..=149).step_by(2).map(|k| k as f64).collect();
    assert_eq!(set.frequencies_hz, want);
    assert_eq!(set.noise, NoiseModel::Relative { rel: 0.02 });
    assert_eq!(set.estimator, Estimator::Lls);
    assert_eq!(set.output, Output::Acceleration);
    let (_, set2) = load_elastic(
        &common::root(ELASTIC),
        Some(&[5.0, 7.0]),
        Some(NoiseModel::Absolute { sigma: 0.1 }),
        Some(Estimator::Nls),
        Some(Output::Velocity),
    )
    .unwrap();
    assert_eq!(set2.frequencies_hz, vec![5.0, 7.0]);
    assert_eq!(set2.estimator, Estimator::Nls);
    assert_eq!(set2.output, Output::Velocity);
}

#[cfg(feature = "cli")]
fn run_cli(design: &str, out: &Path, threads: usize) -> serde_json::Value {
    let st = Command::new(env!("CARGO_BIN_EXE_idexp"))
        .args(["positions", design, "--out"])
        .arg(out)
        .env("IDEXP_NO_PROGRESS", "1")
        .env("RAYON_NUM_THREADS", threads.to_string())
        .current_dir(common::root(""))
        .output()
        .unwrap();
    assert!(st.status.success(), "{}", String::from_utf8_lossy(&st.stderr));
    for f in [
        "plan.csv",
        "plan.json",
        "candidates.csv",
        "report.json",
        "report.txt",
        "design.json",
        "status.json",
        "weights.svg",
        "poses.svg",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

#[cfg(feature = "cli")]
#[test]
fn small_elastic_design_is_certified_d_optimal_with_small_support() {
    let path = common::root("designs/positions_elastic6_small.toml");
    let design = PositionsDesign::read(&path).unwrap();
    let run = run_design(&design, path.parent().unwrap(), &idexp::optim::Control::new()).unwrap();
    let n = run.q.len();
    assert!((100..=300).contains(&n), "{n} candidates");
    assert_eq!(run.names.len(), 26);
    assert_eq!(run.relaxed.status, Status::Optimal);
    assert!(run.relaxed.certificate.holds);
    assert!(run.relaxed.certificate.max_sensitivity <= 26.0 * (1.0 + 1e-5));
    let support: Vec<usize> = (0..n).filter(|&i| run.relaxed.weights[i] > 1e-6).collect();
    assert!(!support.is_empty() && support.len() <= 30, "support {}", support.len());
    assert_eq!(run.rounded.m.iter().sum::<usize>(), 15);
    assert!(run.rounded.efficiency > 0.9 && run.rounded.efficiency <= 1.0 + 1e-9);
    // every candidate is a static pose of the model's rigid joints
    assert!(run.q.iter().all(|q| q.len() == 6));
    // Kiefer–Wolfowitz checked again with information computed independently
    // (eq. 5 from frf_jacobian, physical units then scaled by θ_nom in this
    // test: the D-optimal weights do not depend on the parameter scaling)
    let m = model();
    let omegas: Vec<f64> = (3..=149).step_by(2).map(|k| 2.0 * std::f64::consts::PI * k as f64).collect();
    let s = m.nominal_unknowns();
    let p = s.len();
    let noise = NoiseModel::Relative { rel: 0.02 };
    let fi = |q: &[f64]| {
        let f = eq5(&m, q, &omegas, noise, Estimator::Lls, Output::Acceleration);
        DMatrix::from_fn(p, p, |a, b| s[a] * f[(a, b)] * s[b])
    };
    let mut mw = DMatrix::zeros(p, p);
    for &i in &support {
        mw += fi(&run.q[i]) * run.relaxed.weights[i];
    }
    let minv = mw.clone().cholesky().expect("M(w) positive definite").inverse();
    // the support and a spread of other candidates
    let mut check: Vec<usize> = support.clone();
    check.extend((0..n).step_by(7));
    let mut dmax: f64 = 0.0;
    for &i in &check {
        let d = (&minv * fi(&run.q[i])).trace();
        dmax = dmax.max(d);
        if support.contains(&i) {
            assert!((d - 26.0).abs() < 1e-3, "support point {i}: d = {d}");
        }
    }
    assert!(dmax <= 26.0 * (1.0 + 1e-5), "max d = {dmax}");
    // physical units: the same D-optimal weights (congruence invariance)
    let mut phys = design.clone();
    if let InformationSpec::Elastic { scale, .. } = &mut phys.information {
        *scale = ElasticScale::Physical;
    }
    let run_p = run_design(&phys, path.parent().unwrap(), &idexp::optim::Control::new()).unwrap();
    assert_eq!(run_p.relaxed.status, Status::Optimal);
    let dw = run
        .relaxed
        .weights
        .iter()
        .zip(&run_p.relaxed.weights)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(dw < 1e-3, "weights differ by {dw}");
    // log det shifts by 2 Σ ln θ_nom
    let shift: f64 = s.iter().map(|v| 2.0 * v.ln()).sum();
    assert!(
        (run.relaxed.value - run_p.relaxed.value - shift).abs() < 1e-5 * run.relaxed.value.abs(),
        "log det"
    );
    assert_eq!(run.rounded.m, run_p.rounded.m);
    // and the CLI writes the outputs
    let dir = tempfile::tempdir().unwrap();
    let rep = run_cli("designs/positions_elastic6_small.toml", &dir.path().join("t2"), 2);
    assert_eq!(rep["status"], "optimal");
    assert_eq!(rep["certificate"]["holds"], true);
    assert_eq!(rep["parameters"], 26);
    // the resolved design names the settings taken from the elastic file
    let dj: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("t2/design.json")).unwrap()).unwrap();
    assert_eq!(dj["information"]["frequencies_hz"].as_array().map(|a| a.len()), Some(74));
    assert_eq!(dj["information"]["estimator"], "lls");
    // the same files whatever the thread count
    run_cli("designs/positions_elastic6_small.toml", &dir.path().join("t1"), 1);
    for f in ["plan.csv", "candidates.csv"] {
        let a = std::fs::read(dir.path().join("t1").join(f)).unwrap();
        let b = std::fs::read(dir.path().join("t2").join(f)).unwrap();
        assert!(a == b, "{f} differs between 1 and 2 threads");
    }
}

#[cfg(feature = "cli")]
/// The shipped design: a few thousand candidates, 26 unknowns.
/// `cargo test --release --test positions_elastic -- --ignored`
#[test]
#[ignore]
fn shipped_elastic_design_few_thousand_candidates() {
    let path = common::root("designs/positions_elastic6.toml");
    let design = PositionsDesign::read(&path).unwrap();
    let run = run_design(&design, path.parent().unwrap(), &idexp::optim::Control::new()).unwrap();
    assert!(run.q.len() >= 2000, "{} candidates", run.q.len());
    assert_eq!(run.names.len(), 26);
    assert_eq!(run.relaxed.status, Status::Optimal);
    assert!(run.relaxed.certificate.holds);
    let support = run.relaxed.weights.iter().filter(|&&w| w > 1e-6).count();
    assert!(support <= 40, "support {support}");
    assert_eq!(run.rounded.m.iter().sum::<usize>(), 15);
}

fn design_text(info: &str) -> String {
    let elastic = common::root(ELASTIC);
    format!(
        "name = \"bad\"\n[information]\nsource = \"elastic\"\ndesign = {:?}\n{info}\n[candidates]\nkind = \"grid\"\njoints = [2, 3]\npoints = [2, 2]\n",
        elastic.display().to_string()
    )
}

fn error_of(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("d.toml");
    std::fs::write(&p, text).unwrap();
    match PositionsDesign::read(&p) {
        Err(e) => e.to_string(),
        Ok(d) => match run_design(&d, dir.path(), &idexp::optim::Control::new()) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted: {text}"),
        },
    }
}

#[test]
fn bad_elastic_specs_name_the_field() {
    // a good one parses and has the elastic variant
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.toml");
    std::fs::write(&p, design_text("frequencies_hz = [5.0, 9.0]")).unwrap();
    let d = PositionsDesign::read(&p).unwrap();
    assert!(matches!(d.information, InformationSpec::Elastic { .. }));
    let run = run_design(&d, dir.path(), &idexp::optim::Control::new()).unwrap();
    assert_eq!(run.q.len(), 4);
    for (info, want) in [
        ("frequencies_hz = []", "information.frequencies_hz"),
        ("frequencies_hz = [5.0, -1.0]", "information.frequencies_hz"),
        ("noise = { kind = \"relative\", rel = -0.1 }", "information.noise.rel"),
        ("noise = { kind = \"absolute\", sigma = 0.0 }", "information.noise.sigma"),
        ("estimator = \"ml\"", "ml"),
        ("sample = 3", "sample"),
        ("scale = \"log\"", "log"),
    ] {
        let e = error_of(&design_text(info));
        assert!(e.contains(want), "{info}: {e}");
    }
    // the robot comes from the elastic model
    let e = error_of(&format!("robot = \"robots/industrial6.toml\"\n{}", design_text("")));
    assert!(e.contains("robot"), "{e}");
    // no candidates
    let text = design_text("");
    let e = error_of(&text[..text.find("[candidates]").unwrap()]);
    assert!(e.contains("candidates"), "{e}");
    // a missing elastic file names the file
    let e = error_of(&design_text("").replace("elastic_industrial6.toml", "no_such_elastic.toml"));
    assert!(e.contains("no_such_elastic.toml"), "{e}");
    // a file without [model]
    let e = error_of(&design_text("").replace("elastic_industrial6.toml", "positions_elastic6.toml"));
    assert!(e.contains("model"), "{e}");
}
