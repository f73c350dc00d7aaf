//! The plan checked against simulated reality: each of N noise seeds
//! simulates every planned experiment with its planned repetitions (the
//! simulate design's own truth, the same for every seed; seed s of
//! experiment e draws its noise from seed 1 000 003·(s + 1) + e), identifies
//! them together with the study engine ([`crate::ident::study::run_study_with`]:
//! the candidates' `identify` keys, residual weights per experiment and joint,
//! the plan's `[consistent]` prior), and compares with the prediction:
//!
//! * per target, the **achieved σ** of each seed — the study's own
//!   covariance (Σ_LS of the base parameters; with the prior the posterior
//!   (KᵀΣ_LS⁻¹K + Λ)⁻¹) — and the fraction of seeds meeting every target;
//! * the **empirical spread** (standard deviation over the seeds) of each
//!   targeted estimate beside the predicted spread √(cᵀΦ⁻¹FΦ⁻¹c) (F = Φ − Λ:
//!   equal to the predicted σ without a prior), and the mean offset from the
//!   truth in predicted σ;
//! * per task, the **validation error** of each seed's estimate, the RMS
//!   over the task's rows of Y_task(β̂ − β_true), beside the predicted RMS.

use super::model::{given_of, simulate, Space, TargetKind};
use super::solve::Prepared;
use super::PlanRun;
use crate::error::{Error, Result};
use crate::ident::study::{run_study_with, Inputs, StudyDesign, WeightSource};
use crate::optim::Control;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// The rehearsal of a plan.
#[derive(Debug, Clone, Serialize)]
pub struct Rehearsal {
    /// Seeds run.
    pub seeds: usize,
    /// Repetitions rehearsed per experiment.
    pub repetitions: Vec<usize>,
    /// Seeds whose study met every target (by its own covariance).
    pub all_met: usize,
    /// Per target.
    pub targets: Vec<TargetRehearsal>,
}

/// One target's rehearsal.
#[derive(Debug, Clone, Serialize)]
pub struct TargetRehearsal {
    /// Label.
    pub label: String,
    /// The bound.
    pub bound: f64,
    /// Predicted σ (or RMS).
    pub predicted: f64,
    /// Predicted spread of the estimate over noise (= predicted without a prior).
    pub predicted_spread: f64,
    /// The study's own σ (or RMS), mean over seeds.
    pub achieved_mean: f64,
    /// Seeds whose study's own σ meets the bound.
    pub met: usize,
    /// Standard deviation of the estimate over the seeds (parameters), or
    /// the RMS over seeds of the task's validation error (tasks).
    pub empirical: f64,
    /// empirical / predicted spread.
    pub ratio: f64,
    /// Mean offset of the estimate from the truth, in predicted spreads (parameters).
    pub offset: f64,
}

/// One seed's numbers: per target (study's σ, estimate or error).
struct Seed {
    sigma: Vec<f64>,
    value: Vec<f64>,
}

/// Rehearses `run`'s plan (or `repetitions` instead) with `seeds` noise seeds;
/// `dir` is the plan file's folder.
pub fn rehearse(run: &PlanRun, repetitions: Option<&[usize]>, seeds: usize, dir: &Path, ctl: &Control) -> Result<Rehearsal> {
    let model = &run.model;
    let reps: Vec<usize> = repetitions.map_or_else(|| run.solution.repetitions.clone(), <[usize]>::to_vec);
    if reps.len() != model.candidates.len() {
        return Err(Error::dim("rehearsal: repetitions per experiment", model.candidates.len(), reps.len()));
    }
    if reps.iter().all(|&r| r == 0) {
        return Err(Error::invalid("plan", "rehearse", "the plan has no repetitions to rehearse"));
    }
    if seeds == 0 {
        return Err(Error::invalid("plan", "rehearse", "expected at least one seed"));
    }
    let pre = Prepared::new(model);
    let repf: Vec<f64> = reps.iter().map(|&x| x as f64).collect();
    let phi = pre.phi(&repf);
    let predicted = pre.values(&repf);
    let data = &phi - &pre.lambda;
    let cov = phi
        .clone()
        .try_inverse()
        .ok_or_else(|| Error::Numerical("the plan's information is singular".into()))?;
    let spread_cov = &cov * &data * &cov;
    let predicted_spread: Vec<f64> = pre.b.iter().map(|b| (b.transpose() * &spread_cov * b).trace().max(0.0).sqrt()).collect();
    // truth: the first planned experiment's simulate design's
    let first = reps.iter().position(|&r| r > 0).unwrap_or(0);
    let truth_spec = crate::sim::SimDesign::read(&model.candidates[first].simulate)?.truth;
    let truth_spec = crate::sim::TruthSpec {
        seed: Some(truth_spec.seed.unwrap_or(crate::sim::SimDesign::read(&model.candidates[first].simulate)?.seed)),
        ..truth_spec
    };
    let obs = ctl.observer();
    obs.phase("plan rehearse", Some(seeds as u64));
    let done = std::sync::atomic::AtomicU64::new(0);
    let results: Vec<Result<Seed>> = (0..seeds)
        .into_par_iter()
        .map(|s| {
            if ctl.interrupted() {
                return Err(Error::Interrupted);
            }
            let r = one_seed(run, &reps, s, &truth_spec, &pre, dir, ctl);
            let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            obs.progress(k, &format!("seed {k}/{seeds}"));
            r
        })
        .collect();
    obs.phase_done();
    let seeds_v: Vec<Seed> = results.into_iter().collect::<Result<_>>()?;
    let nt = model.targets.len();
    let truth_x = truth_in_space(run, &truth_spec)?;
    let mut targets = Vec::new();
    for i in 0..nt {
        let t = &model.targets[i];
        let sig: Vec<f64> = seeds_v.iter().map(|s| s.sigma[i]).collect();
        let met = sig.iter().filter(|&&v| v <= t.bound * (1.0 + 1e-9)).count();
        let vals: Vec<f64> = seeds_v.iter().map(|s| s.value[i]).collect();
        let nf = vals.len() as f64;
        let (empirical, offset) = match t.kind {
            TargetKind::Task { .. } => ((vals.iter().map(|v| v * v).sum::<f64>() / nf).sqrt(), 0.0),
            TargetKind::Parameter { .. } => {
                let mean = vals.iter().sum::<f64>() / nf;
                let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (nf - 1.0).max(1.0)).sqrt();
                let true_v = t.c.dot(&truth_x);
                (sd, (mean - true_v) / predicted_spread[i])
            }
        };
        let reference = if matches!(t.kind, TargetKind::Task { .. }) {
            predicted[i]
        } else {
            predicted_spread[i]
        };
        targets.push(TargetRehearsal {
            label: t.label.clone(),
            bound: t.bound,
            predicted: predicted[i],
            predicted_spread: predicted_spread[i],
            achieved_mean: sig.iter().sum::<f64>() / nf,
            met,
            empirical,
            ratio: empirical / reference,
            offset,
        });
    }
    let all_met = seeds_v
        .iter()
        .filter(|s| s.sigma.iter().zip(&model.targets).all(|(v, t)| *v <= t.bound * (1.0 + 1e-9)))
        .count();
    Ok(Rehearsal {
        seeds,
        repetitions: reps,
        all_met,
        targets,
    })
}

/// The truth in the plan's space (base or standard parameters).
fn truth_in_space(run: &PlanRun, truth: &crate::sim::TruthSpec) -> Result<DVector<f64>> {
    let model = &run.model;
    let first = &model.candidates[0];
    let (sim, _) = simulate(&first.simulate, 1, false, Some(0), Some(truth), &Control::new())?;
    let theta = DVector::from_vec(sim.truth()?.theta);
    Ok(match model.space {
        Space::Base => &model.base.k * theta,
        Space::Standard => theta,
    })
}

fn one_seed(run: &PlanRun, reps: &[usize], s: usize, truth: &crate::sim::TruthSpec, pre: &Prepared, dir: &Path, ctl: &Control) -> Result<Seed> {
    let model = &run.model;
    let quiet = Control::new().with_stop(ctl.stop_flag().clone());
    let mut inputs = Inputs {
        robot: Some(model.robot.clone()),
        ..Default::default()
    };
    let mut specs = Vec::new();
    for (e, c) in model.candidates.iter().enumerate() {
        if reps[e] == 0 {
            continue;
        }
        let seed = 1_000_003u64 * (s as u64 + 1) + e as u64;
        let (sim, _) = simulate(&c.simulate, reps[e], false, Some(seed), Some(truth), &quiet)?;
        if inputs.truth.is_none() {
            inputs.truth = Some(sim.truth()?);
        }
        inputs.entries.insert(c.name.clone(), given_of(&sim)?);
        specs.push(c.spec.clone());
    }
    let mut design = StudyDesign::one_experiment(&format!("{}_rehearse_{s}", run.design.name), run.design.robot.clone(), specs[0].clone());
    design.experiment = specs;
    design.weights = WeightSource::Residuals;
    design.consistent = run.design.consistent.clone();
    let res = run_study_with(&design, dir, &inputs, &quiet)?;
    let est = &res.estimate;
    let nb = model.base.n_base();
    let cov_ls = DMatrix::from_fn(nb, nb, |i, j| est.covariance.get(i).and_then(|r| r.get(j)).copied().unwrap_or(f64::NAN));
    // the study's own covariance in the plan's space
    let (cov, x_hat) = match model.space {
        Space::Base => (cov_ls, DVector::from_vec(est.theta.clone())),
        Space::Standard => {
            let c = est
                .consistent
                .as_ref()
                .ok_or_else(|| Error::Numerical("the rehearsal's study has no consistent estimate".into()))?;
            let info = cov_ls.try_inverse().map(|i| model.base.k.transpose() * i * &model.base.k + &pre.lambda);
            let post = info
                .and_then(|i| i.try_inverse())
                .unwrap_or_else(|| DMatrix::from_element(model.dim(), model.dim(), f64::INFINITY));
            (post, DVector::from_vec(c.standard.clone()))
        }
    };
    let truth_x = {
        let th = DVector::from_vec(inputs.truth.as_ref().map(|t| t.theta.clone()).unwrap_or_default());
        match model.space {
            Space::Base => &model.base.k * th,
            Space::Standard => th,
        }
    };
    let mut sigma = Vec::new();
    let mut value = Vec::new();
    for (i, t) in model.targets.iter().enumerate() {
        let b = &pre.b[i];
        sigma.push((b.transpose() * &cov * b).trace().max(0.0).sqrt());
        value.push(match t.kind {
            // RMS over the task's rows of Y(β̂ − β): √(dᵀ G d) = ‖Uᵀ d‖
            TargetKind::Task { .. } => (b.transpose() * (&x_hat - &truth_x)).norm(),
            TargetKind::Parameter { .. } => t.c.dot(&x_hat),
        });
    }
    Ok(Seed { sigma, value })
}
