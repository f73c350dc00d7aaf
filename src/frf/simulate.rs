//! Simulated measurements with known parameters, to rehearse and test every
//! step: the "true" parameters, and either block FRFs G_b = G(θ_true) ⊙ (1 +
//! ε_rel) + ε_abs from the linearised model (frequency method, ε circular
//! complex Gaussian) or closed-loop time-domain runs of the nonlinear model
//! ([`crate::elastic::sim`]) estimated like measured data (time method).

use super::design::{Design, SimMethod, SimulateSpec};
use super::estimate::{estimate_position, CMat, FrfData, FrfPosition, RunsManifest};
use super::multisine::{streams, sub_seed, Multisine};
use crate::data::MotorRecord;
use crate::elastic::{self, sim, ElasticModel, C64};
use crate::error::{Error, Result};
use crate::optim::Control;
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use std::collections::BTreeMap;
use std::path::Path;

/// True parameter values: all model parameters (`full`) and the unknowns (`theta`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Truth {
    /// Unknowns θ_true, model order.
    pub theta: Vec<f64>,
    /// Every parameter value.
    pub full: Vec<f64>,
    /// θ_true by name.
    pub by_name: BTreeMap<String, f64>,
}

/// θ_true: `truth` entries, the other unknowns nominal·exp(perturb·N(0,1)) (seeded).
pub fn truth(model: &ElasticModel, s: &SimulateSpec, seed: u64) -> Result<Truth> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sub_seed(seed, streams::TRUTH, 0));
    let mut theta = model.nominal_unknowns();
    for (k, &u) in model.unknowns.iter().enumerate() {
        let z: f64 = StandardNormal.sample(&mut rng);
        if let Some(v) = s.truth.get(&model.params[u].name) {
            theta[k] = *v;
        } else {
            theta[k] *= (s.perturb * z).exp();
        }
    }
    let mut full = model.full_values(&theta)?;
    for (name, v) in &s.truth {
        if let Some(i) = model.param_index(name) {
            full[i] = *v;
        }
    }
    let by_name = model.unknown_names().into_iter().zip(theta.iter().copied()).collect();
    Ok(Truth { theta, full, by_name })
}

fn cnormal(rng: &mut rand_chacha::ChaCha8Rng) -> C64 {
    let a: f64 = StandardNormal.sample(rng);
    let b: f64 = StandardNormal.sample(rng);
    C64::new(a, b) * std::f64::consts::FRAC_1_SQRT_2
}

/// The exact FRF of the linearised model with all parameter values `full` at `q0`.
pub fn true_frf(model: &ElasticModel, full: &[f64], q0: &[f64], omegas: &[f64], output: elastic::Output) -> Result<Vec<DMatrix<C64>>> {
    let op = model.operating_point(q0, full)?;
    let lin = model.linear_model(&op, full);
    let ker = elastic::FrfKernel::new(model);
    let mut dg = Vec::new();
    omegas.iter().map(|&w| ker.eval(&lin, &op, w, output, false, &mut dg)).collect()
}

/// Simulated FRF data of a design. Time method: runs are written to
/// `runs_dir` (`runs.json` + CSV per experiment) and estimated from there.
pub fn simulate(d: &Design, model: &ElasticModel, runs_dir: &Path, ctl: &Control) -> Result<(FrfData, Truth)> {
    let s = d.simulate.as_ref().ok_or_else(|| {
        Error::invalid(
            &d.name,
            "simulate",
            "the design has no [simulate] section: give one, or estimate from recorded runs (runs.json)",
        )
    })?;
    let t = truth(model, s, d.seed)?;
    let n = model.n_motors();
    let ms = Multisine::new(d, n);
    let freqs = ms.freqs_hz();
    let omegas: Vec<f64> = freqs.iter().map(|f| std::f64::consts::TAU * f).collect();
    let mut positions = Vec::new();
    match s.method {
        SimMethod::Frequency => {
            let obs = ctl.observer();
            obs.phase("simulate FRF", Some(d.positions.len() as u64));
            for (pi, q0) in d.positions.iter().enumerate() {
                if ctl.interrupted() {
                    return Err(Error::Interrupted);
                }
                let g = true_frf(model, &t.full, q0, &omegas, d.frf.output)?;
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sub_seed(d.seed, streams::NOISE, pi as u64));
                let gb: Vec<Vec<DMatrix<C64>>> = (0..d.multisine.blocks)
                    .map(|_| {
                        g.iter()
                            .map(|gk| gk.map(|v| v * (C64::new(1.0, 0.0) + cnormal(&mut rng) * s.noise_rel) + cnormal(&mut rng) * s.noise_abs))
                            .collect()
                    })
                    .collect();
                let (mean, var) = super::estimate::average_blocks(&gb)?;
                positions.push(FrfPosition {
                    q0: q0.clone(),
                    blocks: gb.len(),
                    g: mean.iter().map(CMat::from_mat).collect(),
                    var: var.iter().map(|v| (0..n * n).map(|r| v[(r / n, r % n)]).collect()).collect(),
                    distortion: None,
                });
                obs.progress(pi as u64 + 1, "");
            }
            obs.phase_done();
        }
        SimMethod::Time => {
            let mut manifest = RunsManifest {
                rate: ms.rate,
                samples: ms.samples,
                transient: d.multisine.transient,
                periods: d.multisine.periods,
                n,
                lines: ms.lines.clone(),
                even_lines: ms.even_lines.clone(),
                positions: d.positions.clone(),
                blocks: d.multisine.blocks,
                output: d.frf.output,
                zoh: d.frf.zoh,
                distortion_db: d.frf.distortion_db,
                files: Vec::new(),
            };
            let total = d.positions.len() * d.multisine.blocks * n;
            let obs = ctl.observer();
            obs.phase("simulate runs", Some(total as u64));
            let n_done = std::sync::atomic::AtomicU64::new(0);
            for (pi, q0) in d.positions.iter().enumerate() {
                let settings = sim::SimSettings {
                    rate: ms.rate,
                    substeps: 0,
                    coulomb: s.coulomb,
                    position_noise: s.position_noise,
                    torque_noise: s.torque_noise,
                    bandwidth_hz: s.bandwidth,
                };
                let plant = sim::ClosedLoop::new(model, &t.full, q0, &settings)?;
                let jobs: Vec<(usize, usize)> = (0..d.multisine.blocks).flat_map(|b| (0..n).map(move |e| (b, e))).collect();
                use rayon::prelude::*;
                let runs: Vec<Result<MotorRecord>> = jobs
                    .par_iter()
                    .map(|&(b, e)| {
                        if ctl.interrupted() {
                            return Err(Error::Interrupted);
                        }
                        let seed = sub_seed(d.seed, streams::NOISE, (pi * 100_000 + b * 1000 + e) as u64);
                        let r = plant.run(&ms.speed_and_position(b, e), d.multisine.transient + d.multisine.periods, seed);
                        obs.progress(n_done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, "");
                        r
                    })
                    .collect();
                let runs: Vec<MotorRecord> = runs.into_iter().collect::<Result<_>>()?;
                let mut files = Vec::new();
                let mut blocks: Vec<Vec<MotorRecord>> = Vec::new();
                for b in 0..d.multisine.blocks {
                    let mut fb = Vec::new();
                    let mut rb = Vec::new();
                    for e in 0..n {
                        let name = format!("pos{}_block{}_exp{}.csv", pi + 1, b + 1, e + 1);
                        let run = &runs[b * n + e];
                        run.write(&runs_dir.join(&name), ms.rate)?;
                        fb.push(name);
                        rb.push(run.clone());
                    }
                    files.push(fb);
                    blocks.push(rb);
                }
                manifest.files.push(files);
                let (pos, _) = estimate_position(&manifest, q0, &blocks, d.frf.distortion_db)?;
                positions.push(pos);
            }
            obs.phase_done();
            crate::io::write_json(&runs_dir.join("runs.json"), &manifest)?;
        }
    }
    Ok((
        FrfData {
            output: d.frf.output,
            n,
            freqs_hz: freqs,
            positions,
            source: format!("simulated ({:?} method) from design `{}`, seed {}", s.method, d.name, d.seed).to_lowercase(),
        },
        t,
    ))
}
