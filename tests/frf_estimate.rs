//! Multisines (odd lines, RMS, orthogonality, crest factor), the FRF estimate
//! G = Y U⁻¹ on exactly periodic data from a known system, the block
//! covariance, and design-file errors.

use idexp::data::MotorRecord;
use idexp::elastic::{Output, C64};
use idexp::frf::estimate::{self, RunsManifest};
use idexp::frf::multisine::Multisine;
use idexp::frf::Design;
use nalgebra::DMatrix;
use rand::{RngExt, SeedableRng};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn shipped_text() -> String {
    let s = std::fs::read_to_string(root("designs/elastic_industrial6.toml")).unwrap();
    s.replace("robots/industrial6.toml", root("designs/robots/industrial6.toml").to_str().unwrap())
}

fn load(text: &str) -> idexp::Result<(Design, idexp::elastic::ElasticModel)> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("design.toml");
    std::fs::write(&p, text).unwrap();
    Design::load(&p)
}

fn dft(x: &[f64], k: usize) -> C64 {
    let n = x.len();
    x.iter()
        .enumerate()
        .map(|(t, v)| C64::from_polar(*v, -std::f64::consts::TAU * (k * t % n) as f64 / n as f64))
        .sum::<C64>()
        / n as f64
}

#[test]
fn multisine_is_odd_orthogonal_and_has_the_requested_rms() {
    let (d, m) = load(&shipped_text()).unwrap();
    let ms = Multisine::new(&d, m.n_motors());
    assert!(ms.lines.iter().all(|k| k % 2 == 1));
    assert_eq!(ms.lines.first(), Some(&3));
    assert_eq!(ms.lines.last(), Some(&149));
    let n = 6;
    for b in 0..2 {
        let refs: Vec<Vec<Vec<f64>>> = (0..n).map(|e| ms.reference(b, e)).collect();
        for e in 0..n {
            for i in 0..n {
                let r = &refs[e][i];
                let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
                assert!((rms - 0.05).abs() < 1e-9, "rms {rms}");
                // nothing on the even lines
                assert!(dft(r, 10).norm() < 1e-12 && dft(r, 2).norm() < 1e-12);
            }
        }
        // R(ω_k) = R_diag T: R Rᴴ = n·diag(|R_i|²), i.e. the n experiments are orthogonal
        for &k in &ms.lines[..5] {
            let r = DMatrix::from_fn(n, n, |i, e| dft(&refs[e][i], k));
            let rr = &r * r.adjoint();
            for i in 0..n {
                for j in 0..n {
                    let expect = if i == j { n as f64 * r[(i, 0)].norm_sqr() } else { 0.0 };
                    assert!((rr[(i, j)] - C64::new(expect, 0.0)).norm() < 1e-12, "R Rᴴ at line {k}");
                }
            }
        }
        // the position reference is the integral of the speed reference
        let p = ms.position_reference(b, 0);
        let k = ms.lines[3];
        let w = std::f64::consts::TAU * k as f64;
        assert!((dft(&p[0], k) * C64::new(0.0, w) - dft(&refs[0][0], k)).norm() < 1e-12);
    }
    // phases differ between blocks; crest factors are those of a random-phase multisine
    assert_ne!(ms.phases[0][0][0], ms.phases[1][0][0]);
    let cf = Multisine::crest_factor(&ms.reference(0, 0)[0]);
    assert!(cf > 2.0 && cf < 5.0, "crest factor {cf}");
    let c: Vec<f64> = (0..100).map(|t| (std::f64::consts::TAU * t as f64 / 100.0).cos()).collect();
    assert!((Multisine::crest_factor(&c) - 2f64.sqrt()).abs() < 1e-9);
}

/// Exactly periodic runs of a known system: y(t) = Σ_k 2 Re{G_k U_k e^{jω_k t}} per experiment.
#[test]
fn y_u_inverse_recovers_a_known_system_and_its_block_variance() {
    let n = 3;
    let np = 256;
    let lines = vec![3usize, 5, 7, 9, 11, 13];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let g: Vec<DMatrix<C64>> = lines
        .iter()
        .map(|_| DMatrix::from_fn(n, n, |_, _| C64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))))
        .collect();
    let m = RunsManifest {
        rate: 256.0,
        samples: np,
        transient: 1,
        periods: 2,
        n,
        lines: lines.clone(),
        even_lines: vec![4, 6],
        positions: vec![vec![0.0; n]],
        blocks: 3,
        output: Output::Position,
        zoh: false,
        distortion_db: 10.0,
        files: vec![],
    };
    let noise = 1e-3;
    let mut gb_expected: Vec<Vec<DMatrix<C64>>> = Vec::new();
    let runs: Vec<Vec<MotorRecord>> = (0..m.blocks)
        .map(|_| {
            let phases: Vec<Vec<f64>> = (0..n)
                .map(|_| lines.iter().map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect())
                .collect();
            // per-block output perturbation: G_b = G + noise·Δ_b (a block-dependent system, as nonlinear distortions are)
            let gbk: Vec<DMatrix<C64>> = g
                .iter()
                .map(|gk| gk + DMatrix::from_fn(n, n, |_, _| C64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)) * noise))
                .collect();
            gb_expected.push(gbk.clone());
            (0..n)
                .map(|e| {
                    let total = (m.transient + m.periods) * np;
                    let mut u = vec![vec![0.0; n]; total];
                    let mut y = vec![vec![0.0; n]; total];
                    for t in 0..total {
                        for (l, &k) in lines.iter().enumerate() {
                            let arg = std::f64::consts::TAU * (k * t % np) as f64 / np as f64;
                            let uk: Vec<C64> = (0..n)
                                .map(|i| C64::from_polar(1.0, phases[i][l] + std::f64::consts::TAU * (i * e) as f64 / n as f64))
                                .collect();
                            for i in 0..n {
                                u[t][i] += 2.0 * (uk[i] * C64::from_polar(1.0, arg)).re;
                                let yi: C64 = (0..n).map(|j| gbk[l][(i, j)] * uk[j]).sum();
                                y[t][i] += 2.0 * (yi * C64::from_polar(1.0, arg)).re;
                            }
                        }
                    }
                    MotorRecord { u, y }
                })
                .collect()
        })
        .collect();
    let (pos, gb) = estimate::estimate_position(&m, &[0.0; 3], &runs, 10.0).unwrap();
    for (l, gk) in gb_expected.iter().enumerate() {
        for k in 0..lines.len() {
            assert!((&gb[l][k] - &gk[k]).norm() < 1e-10, "block {l} line {k}");
        }
    }
    let (mean, var) = estimate::average_blocks(&gb_expected).unwrap();
    for k in 0..lines.len() {
        assert!((pos.g[k].to_mat(n) - &mean[k]).norm() < 1e-10);
        for a in 0..n {
            for b in 0..n {
                assert!((pos.var[k][a * n + b] - var[k][(a, b)]).abs() < 1e-14);
            }
        }
        // full covariance: its diagonal is the element variance (vec is column-stacked)
        let c = estimate::block_covariance(&gb_expected, k);
        assert!((c[(1, 1)].re - var[k][(1, 0)]).abs() < 1e-15);
    }
    // a linear noise-free system leaves the even lines empty
    let d = pos.distortion.unwrap();
    assert!(d.even_vs_odd_db.iter().all(|v| *v < -200.0), "{:?}", d.even_vs_odd_db);
    // zoh: magnitude sinc, phase −ωT/2
    let z = estimate::zoh(std::f64::consts::PI * 100.0, 1e-3);
    assert!(
        (z.arg() + 0.05 * std::f64::consts::PI).abs() < 1e-12 && (z.norm() - (0.05 * std::f64::consts::PI).sin() / (0.05 * std::f64::consts::PI)).abs() < 1e-12
    );
}

#[test]
fn design_errors_name_the_field() {
    let base = shipped_text();
    let cases = [
        ("rate = 1000.0", "rate = -1.0", "multisine.rate"),
        ("period = 1.0", "period = 0.0015", "multisine.period"),
        ("band = [2.0, 150.0]", "band = [2.0, 900.0]", "multisine.band"),
        ("amplitude = [0.05]", "amplitude = [0.05, 0.1]", "multisine.amplitude"),
        ("starts = 100", "starts = 0", "fit.starts"),
        ("reasonable = 1.5", "reasonable = 0.5", "fit.reasonable"),
        ("[0.0, -0.6, 0.4, 0.0, 0.9, 0.0],", "[0.0, -0.6, 0.4, 0.0, 0.9],", "positions[0]"),
        ("[0.0, -0.6, 0.4, 0.0, 0.9, 0.0],", "[0.0, -0.6, 0.4, 0.0, 9.0, 0.0],", "positions[0][4]"),
        ("perturb = 0.3", "perturb = -0.3", "simulate.perturb"),
        ("noise_rel = 0.02", "noise_rel = 0.02\ntruth = { k_a9 = 1.0 }", "simulate.truth.k_a9"),
        ("off_diagonal = 0.3", "off_diagonal = -0.3", "fit.user.off_diagonal"),
        ("estimator = \"lls\"", "estimator = \"lsq\"", "lsq"),
        ("max_iter = 200", "max_itr = 200", "max_itr"),
    ];
    for (from, to, field) in cases {
        assert!(base.contains(from), "{from}");
        let e = load(&base.replacen(from, to, 1)).unwrap_err().to_string();
        assert!(e.contains(field), "expected `{field}` in: {e}");
    }
}

#[test]
fn frf_files_round_trip_and_bad_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("d.toml");
    std::fs::write(&p, shipped_text().replace("band = [2.0, 150.0]", "band = [2.0, 20.0]")).unwrap();
    let (data, out) = idexp::frf::pipeline::frf(&p, Some(dir.path()), &idexp::optim::Control::new()).unwrap();
    let back = idexp::frf::FrfData::read(&out.join("frf.json")).unwrap();
    assert_eq!(back, data);
    for f in ["design.json", "status.json", "truth.json"] {
        assert!(out.join(f).exists(), "{f}");
    }
    // the figure only with the `plots` feature
    assert_eq!(out.join("frf.svg").exists(), cfg!(feature = "plots"));
    let text = std::fs::read_to_string(out.join("frf.json")).unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, text.replacen("\"n\": 6", "\"n\": 5", 1)).unwrap();
    let e = idexp::frf::FrfData::read(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.json") && e.contains("positions[0].g[0]"), "{e}");
    std::fs::write(&bad, "{ not json").unwrap();
    assert!(idexp::frf::FrfData::read(&bad).unwrap_err().to_string().contains("bad.json"));
    // a runs manifest naming a missing file
    let m = RunsManifest {
        rate: 100.0,
        samples: 100,
        transient: 0,
        periods: 1,
        n: 1,
        lines: vec![3],
        even_lines: vec![],
        positions: vec![vec![0.0]],
        blocks: 1,
        output: Output::Acceleration,
        zoh: true,
        distortion_db: 10.0,
        files: vec![vec![vec!["missing.csv".into()]]],
    };
    let mp = dir.path().join("runs.json");
    idexp::io::write_json(&mp, &m).unwrap();
    let e = idexp::frf::pipeline::frf(&mp, None, &idexp::optim::Control::new()).unwrap_err().to_string();
    assert!(e.contains("missing.csv"), "{e}");
}
