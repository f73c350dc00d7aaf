//! Fitting: the analytic gradient and Gauss–Newton matrix of every estimator
//! equal finite differences of the cost; the best LLS models recover the
//! springs within their theoretical uncertainty (eq. 5) on simulated 6-axis
//! data at several positions; eq. 5 agrees with the scatter of estimates over
//! noise realisations.

use idexp::elastic::Estimator;
use idexp::frf::pipeline::{self, FitOptions};
use idexp::frf::{design::WeightKind, fit, simulate, Design};
use std::path::{Path, PathBuf};

fn root(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The shipped design with its first `npos` positions, band up to `fmax` Hz, `edit` applied.
fn write_design(dir: &Path, npos: usize, fmax: f64, edit: &dyn Fn(String) -> String) -> PathBuf {
    let s = std::fs::read_to_string(root("designs/elastic_industrial6.toml")).unwrap();
    let s = s.replace("robots/industrial6.toml", root("designs/robots/industrial6.toml").to_str().unwrap());
    let i = s.find("positions = [\n").unwrap() + "positions = [\n".len();
    let j = i + s[i..].find("]\n\n").unwrap();
    let rows: Vec<&str> = s[i..j].lines().take(npos).collect();
    let s = format!("{}{}\n{}", &s[..i], rows.join("\n"), &s[j..]);
    let s = s
        .replace("band = [2.0, 150.0]", &format!("band = [2.0, {fmax}]"))
        .replace("band = [3.0, 150.0]", &format!("band = [3.0, {fmax}]"));
    let p = dir.join("d.toml");
    std::fs::write(&p, edit(s)).unwrap();
    p
}

fn frf_data(p: &Path, out: &Path) -> idexp::frf::FrfData {
    pipeline::frf(p, Some(out), &idexp::optim::Control::new()).unwrap().0
}

#[test]
fn gradients_equal_finite_differences() {
    let dir = tempfile::tempdir().unwrap();
    let p = write_design(dir.path(), 2, 60.0, &|s| s);
    let data = frf_data(&p, dir.path());
    let (d, m) = Design::load(&p).unwrap();
    let t = simulate::truth(&m, d.simulate.as_ref().unwrap(), d.seed).unwrap();
    for est in [Estimator::Lls, Estimator::LlsMagnitude, Estimator::Nls] {
        let w = fit::weights(&d, &data, est, WeightKind::User).unwrap();
        let prob = fit::FitProblem::new(&m, &data, est, w).unwrap();
        // a point away from the optimum: truth · 1.1^(±1)
        let theta: Vec<f64> = t.theta.iter().enumerate().map(|(i, v)| v * if i % 2 == 0 { 1.1 } else { 1.0 / 1.1 }).collect();
        let (v, g, h) = prob.normal_equations(&theta, true).unwrap();
        assert!((v - prob.cost(&theta).unwrap()).abs() < 1e-10 * v);
        let z = prob.to_z(&theta);
        for i in 0..z.len() {
            let hh = 1e-6;
            let mut zp = z.clone();
            zp[i] += hh;
            let mut zm = z.clone();
            zm[i] -= hh;
            let fd = (prob.cost(&prob.to_theta(&zp)).unwrap() - prob.cost(&prob.to_theta(&zm)).unwrap()) / (2.0 * hh);
            // dV/dz = 2 g
            let scale = g.amax().max(1e-12);
            assert!(
                (fd - 2.0 * g[i]).abs() < 1e-5 * 2.0 * scale,
                "{est:?} param {i}: fd {fd}, analytic {}",
                2.0 * g[i]
            );
        }
        // H is the Gauss–Newton matrix: PSD, symmetric
        assert!((&h - h.transpose()).abs().max() < 1e-12 * h.abs().max());
        assert!(h.clone().symmetric_eigen().eigenvalues.min() > -1e-9 * h.abs().max());
    }
}

#[test]
fn lls_recovers_the_springs_within_their_theoretical_uncertainty() {
    let dir = tempfile::tempdir().unwrap();
    // 3 positions, full band, 6 starts spread over ±0.3 decades
    let p = write_design(dir.path(), 3, 150.0, &|s| {
        s.replace("starts = 100", "starts = 6").replace("spread = 1.0", "spread = 0.3")
    });
    frf_data(&p, dir.path());
    let r = pipeline::fit(
        &p,
        &FitOptions {
            out: Some(dir.path().to_path_buf()),
            ..Default::default()
        },
        &idexp::optim::Control::new(),
    )
    .unwrap();
    let rep = r.report.unwrap();
    let e = rep.max_spring_error_sigma.expect("simulated data have a truth and the best model a covariance");
    assert!(e < 4.0, "springs of the best LLS model: max |θ̂ − θ_true|/std_th = {e}\n{}", rep.text());
    // every spring is determined to better than 1 % here, and the theoretical std is not absurdly small either
    for p in rep.params.iter().filter(|p| p.name.starts_with("k_")) {
        let s = p.std_th.unwrap();
        assert!(s / p.best < 0.01 && s > 0.0, "{}: std_th {s}", p.name);
    }
    assert!(rep.reasonable >= 1);
}

#[test]
fn eq5_covariance_matches_the_scatter_over_noise_realisations() {
    // LLS with user weights (sandwich form of eq. 5); 12 noise realisations, fits started at the truth
    let dir = tempfile::tempdir().unwrap();
    let mut est: Vec<Vec<f64>> = Vec::new();
    let mut std_th: Vec<f64> = Vec::new();
    let mut truth = Vec::new();
    for seed in 0..12 {
        let p = write_design(dir.path(), 2, 80.0, &|s| {
            s.replace("seed = 2026", &format!("seed = {}", 100 + seed))
                .replace("perturb = 0.3", "perturb = 0.0")
        });
        let data = frf_data(&p, &dir.path().join(format!("o{seed}")));
        let (d, m) = Design::load(&p).unwrap();
        let t = simulate::truth(&m, d.simulate.as_ref().unwrap(), d.seed).unwrap();
        let w = fit::weights(&d, &data, Estimator::Lls, WeightKind::User).unwrap();
        let prob = fit::FitProblem::new(&m, &data, Estimator::Lls, w).unwrap();
        let o = prob.solve(&t.theta, &d.fit, &idexp::optim::Control::new());
        assert!(o.status.converged(), "{:?}", o.status);
        if std_th.is_empty() {
            let c = prob.covariance(&o.theta).unwrap();
            std_th = (0..c.nrows()).map(|i| c[(i, i)].sqrt()).collect();
        }
        est.push(o.theta);
        truth = t.theta;
    }
    // ratio of the empirical RMS error to std_th, averaged over the 26 parameters
    let np = truth.len();
    let mut ratios = Vec::new();
    for i in 0..np {
        let rms = (est.iter().map(|e| (e[i] - truth[i]).powi(2)).sum::<f64>() / est.len() as f64).sqrt();
        ratios.push(rms / std_th[i]);
    }
    let mean = ratios.iter().sum::<f64>() / np as f64;
    assert!(mean > 0.7 && mean < 1.4, "RMS error / std_th averaged over parameters: {mean} ({ratios:?})");
}

#[test]
fn information_matrix_agrees_with_the_fit_covariance() {
    // ½ F⁻¹ from elastic::information_matrix (noise model) = eq. 5 covariance of the fit with optimal weights
    // from the estimated variances (20 blocks of 2 % relative noise: σ of the mean 2 %/√20)
    let dir = tempfile::tempdir().unwrap();
    let p = write_design(dir.path(), 2, 80.0, &|s| {
        s.replace("perturb = 0.3", "perturb = 0.0").replace("blocks = 4", "blocks = 20")
    });
    let data = frf_data(&p, dir.path());
    let (d, m) = Design::load(&p).unwrap();
    let theta = m.nominal_unknowns();
    for est in [Estimator::Lls, Estimator::Nls] {
        let w = fit::weights(&d, &data, est, WeightKind::Optimal).unwrap();
        let prob = fit::FitProblem::new(&m, &data, est, w).unwrap();
        let pc = prob.covariance(&theta).unwrap();
        let omegas: Vec<f64> = data.freqs_hz.iter().map(|f| std::f64::consts::TAU * f).collect();
        let noise = idexp::elastic::NoiseModel::Relative { rel: 0.02 / 20f64.sqrt() };
        let mut f = nalgebra::DMatrix::zeros(theta.len(), theta.len());
        for q0 in &d.positions {
            f += idexp::elastic::information_matrix(&m, q0, &omegas, &noise, est).unwrap();
        }
        let pf = f.try_inverse().unwrap() * 0.5;
        for i in 0..theta.len() {
            let r = (pc[(i, i)] / pf[(i, i)]).sqrt();
            assert!((r - 1.0).abs() < 0.15, "{est:?} {}: std from the fit / from F = {r}", m.unknown_names()[i]);
        }
    }
}
