//! Identification as a study: many experiments, many validation runs, a
//! prior, one design file ([`StudyDesign`], `idexp identify study.toml`).
//!
//! A commissioning has several experiments — different trajectories, days,
//! a gravity run, a friction run — not one trajectory repeated. A study
//! reads each experiment (its repetitions, irregular time stamps resampled
//! to a uniform grid, currents converted by the drives), processes it with
//! its own filter, decimation and standstill rule ([`crate::ident::prepare`]),
//! stacks the base-regressor rows of every experiment and estimates by
//! weighted least squares with weights per experiment and joint
//! ([`stack`]: from the repetitions where they exist, else from the
//! residuals, iterated). The report gives each experiment's residuals and
//! its share of the information, every validation run's errors e_j, e*_j
//! (paper 000 eq. 11–12) and their sums, and — with `[consistent]` — the
//! physically consistent estimate with a prior ([`crate::ident::prior`]),
//! per link beside the prior, with implausible values flagged and the
//! directions the prior decided.
//!
//! Files: [`design`] (the study file), `entry.rs` (one `[[experiment]]` or
//! `[[validation]]` entry and its checks), `load.rs` (one entry read and
//! processed: [`load_entry`]), [`dedicated`] (a study of dedicated one-joint
//! fits, paper 002 §3.2: [`run_dedicated`]),
//! [`stack`] (the weighted stack), this file (the study [`run_study`]),
//! `consistent.rs` (the consistent estimate with a prior), `result.rs`
//! (the records of [`StudyResult`]), [`report`] (its text), [`output`] (its
//! folder). Their items are re-exported here.

mod consistent;
pub mod dedicated;
pub mod design;
mod entry;
mod load;
pub mod output;
pub mod report;
mod result;
mod single;
pub mod stack;

pub use dedicated::{run_dedicated, DedicatedEntry, DedicatedResult, JointFit};
pub use design::{
    ConsistentSpec, EssentialRule, EssentialSpec, ExperimentKind, ExperimentSpec, ExportFormat, FilterName, GravityChoice, MlSpec, Prior, ProjectionSpec,
    ReduceSpec, StudyDesign, UnknownRule, UnknownSpec, WeightRule, WeightSpec,
};
pub use load::{load_entry, load_entry_with, EntryOptions, Given, Loaded};
pub use result::{ConsistentReport, Direction, Estimate, ExperimentReport, Flag, LinkPrior, StudyResult, UnknownParam, ValidationReport, ValidationTotal};
pub use stack::{Block, BlockWeight, StackOptions, Stacked, WeightSource};

use super::estimate::{errors, must_be_positive, Dataset};
use super::{EstimateStatus, Implausible, Method, TruthRow};
use crate::error::{Error, Result};
use crate::optim::Control;
use crate::params::{BaseOptions, BaseParams};
use crate::robot::Robot;
use consistent::consistent_with_prior;
use nalgebra::DVector;
use std::path::{Path, PathBuf};

/// The errors of the validation runs summed per joint, and the mean relative RMS.
fn validation_sum(sets: &[&Dataset], theta: &[f64]) -> Option<(ValidationTotal, f64)> {
    let n = sets.first()?.n;
    let (mut ae, mut am, mut sq, mut cnt) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0usize; n]);
    let mut rel = Vec::new();
    let th = DVector::from_column_slice(theta);
    for d in sets {
        let pred = &d.c * &th;
        let (mut r2, mut y2) = (vec![0.0; n], vec![0.0; n]);
        for (i, &j) in d.joint.iter().enumerate() {
            let e = d.y[i] - pred[i];
            ae[j] += e.abs();
            am[j] += d.y[i].abs();
            sq[j] += e * e;
            cnt[j] += 1;
            r2[j] += e * e;
            y2[j] += d.y[i] * d.y[i];
        }
        rel.extend((0..n).filter(|&j| y2[j] > 0.0).map(|j| (r2[j] / y2[j]).sqrt()));
    }
    let mean = rel.iter().sum::<f64>() / rel.len().max(1) as f64;
    let c = |j: usize| cnt[j].max(1) as f64;
    Some((
        ValidationTotal {
            e: (0..n).map(|j| ae[j] / c(j)).collect(),
            e_rel: (0..n).map(|j| if am[j] > 0.0 { ae[j] / am[j] } else { 0.0 }).collect(),
            rms: (0..n).map(|j| (sq[j] / c(j)).sqrt()).collect(),
            consistent_e_rel: None,
            mean_relative_rms: mean,
        },
        mean,
    ))
}

/// The estimate of either estimator: the stack or one experiment's.
struct Fit {
    theta: Vec<f64>,
    cov: nalgebra::DMatrix<f64>,
    rank: usize,
    cond: f64,
    cond_normalized: f64,
    chi2_dof: f64,
    iterations: usize,
    converged: bool,
}

/// Reads the study's robot, base parameters and prior robot.
fn setup(design: &StudyDesign, dir: &Path, given: Option<&Robot>) -> Result<(Robot, PathBuf, BaseParams, Option<Robot>)> {
    let robot_path = dir.join(&design.robot);
    let robot = match given {
        Some(r) => r.clone(),
        None => crate::robot::load(&robot_path)?,
    };
    if design.export.contains(&ExportFormat::Urdf) && given.is_none() {
        if let crate::robot::export::Source::Dh { toml } = crate::robot::export::source_of(&robot_path)? {
            return Err(Error::invalid(
                toml.display().to_string(),
                "export",
                "\"urdf\": this robot is a DH table, not a URDF: there is no URDF to copy the kinematics from; export \"toml\" (the DH table with the identified inertials and drive parameters) and \"csv\"",
            ));
        }
    }
    let base = if design.base_columns.is_empty() {
        BaseParams::compute(&robot, &BaseOptions::default())?
    } else {
        BaseParams::with_columns(&robot, &design.base_columns, &BaseOptions::default())?
    };
    let prior = match &design.consistent {
        Some(ConsistentSpec { prior: Prior::File(p), .. }) => Some(crate::robot::load(&dir.join(p))?),
        _ => None,
    };
    Ok((robot, robot_path, base, prior))
}

/// Runs a study whose relative paths are relative to `dir` (the study file's
/// folder). `ctl` stops it between experiments and between the prior's
/// candidate weights; what exists then is returned, marked interrupted.
pub fn run_study(design: &StudyDesign, dir: &Path, ctl: &Control) -> Result<StudyResult> {
    run_study_with(design, dir, &Inputs::default(), ctl)
}

/// What a study takes from memory instead of its files ([`run_study_with`]).
#[derive(Debug, Clone, Default)]
pub struct Inputs {
    /// The robot (its file `robot` is then only the source of exports).
    pub robot: Option<Robot>,
    /// Entries' data by entry name (their `files` may then be empty).
    pub entries: std::collections::BTreeMap<String, Given>,
    /// The true parameters of a simulated run (instead of `truth`).
    pub truth: Option<crate::data::Truth>,
}

/// [`run_study`] with what `inputs` gives taken from memory.
pub fn run_study_with(design: &StudyDesign, dir: &Path, inputs: &Inputs, ctl: &Control) -> Result<StudyResult> {
    let given = &inputs.entries;
    design.validate_with("study", given)?;
    let (robot, robot_path, base, prior_robot) = setup(design, dir, inputs.robot.as_ref())?;
    let obs = ctl.observer();
    let total = design.experiment.len() + design.validation.len();
    obs.phase("identify read", Some(total as u64));
    let mut experiments = Vec::new();
    let mut validations = Vec::new();
    for (i, spec) in design.experiment.iter().chain(&design.validation).enumerate() {
        if ctl.interrupted() {
            return Err(Error::Interrupted);
        }
        let o = load::EntryOptions {
            method: design.method,
            sample_limit: design.sample_limit,
            dead_band: design.dead_band,
            allow_incomplete: design.allow_incomplete,
            given: given.get(&spec.resolved_name()),
        };
        let l = load_entry_with(&robot, &base, spec, dir, &o)?;
        obs.progress(i as u64 + 1, &l.name);
        if i < design.experiment.len() {
            experiments.push(l);
        } else {
            validations.push(l);
        }
    }
    obs.phase_done();
    let single = match design.method {
        Method::Wls if design.reduce.is_none() => None,
        Method::Ols => None,
        _ => single::estimate(design, &robot, &base, &experiments[0], ctl)?,
    };
    // the reduction and ML return what they have when stopped: marked interrupted
    let stopped = single.is_some() && ctl.interrupted();
    // a reduced model: every dataset keeps the estimated columns only
    let cols: Vec<usize> = single.as_ref().map_or_else(|| (0..base.n_base()).collect(), |s| s.cols.clone());
    if cols.len() != base.n_base() {
        for l in experiments.iter_mut().chain(validations.iter_mut()) {
            l.prep.every = l.prep.every.columns(&cols);
            l.prep.full = l.prep.full.columns(&cols);
        }
    }
    let st = match &single {
        Some(_) => None,
        None => {
            let rows: Vec<stack::Rows> = experiments
                .iter()
                .map(|e| stack::Rows {
                    name: &e.name,
                    data: &e.prep.full,
                    n_reps: e.n_reps,
                })
                .collect();
            let so = StackOptions {
                weights: design.weights,
                repetition_weights: design.repetition_weights,
                ols: design.method == Method::Ols,
                max_iterations: design.irls_iterations,
                tol: design.irls_tol,
            };
            Some(stack::estimate(&rows, &so)?)
        }
    };
    let k = cols.len();
    let fit = match (&single, &st) {
        (Some(s), _) => Fit {
            theta: s.fit.theta.clone(),
            cov: s.fit.cov.clone(),
            rank: s.fit.rank,
            cond: s.fit.cond,
            cond_normalized: s.fit.cond_normalized,
            chi2_dof: s.fit.chi2_dof,
            iterations: 0,
            converged: true,
        },
        (None, Some(st)) => Fit {
            theta: st.theta.as_slice().to_vec(),
            cov: st.cov.clone(),
            rank: st.rank,
            cond: st.cond,
            cond_normalized: st.cond_normalized,
            chi2_dof: st.chi2_dof,
            iterations: st.iterations,
            converged: st.converged,
        },
        (None, None) => unreachable!("a study without a one-experiment estimator stacks its experiments"),
    };
    let theta = fit.theta.clone();
    let std: Vec<f64> = (0..k).map(|i| fit.cov[(i, i)].max(0.0).sqrt()).collect();
    let exp_reports: Vec<ExperimentReport> = match (&single, &st) {
        (Some(s), _) => vec![single::experiment_report(&experiments[0], s)],
        (None, Some(st)) => experiments.iter().enumerate().map(|(ei, e)| experiment_report(e, ei, st, &theta)).collect(),
        (None, None) => Vec::new(),
    };
    let val_reports: Vec<ValidationReport> = validations
        .iter()
        .map(|v| ValidationReport {
            name: v.name.clone(),
            kind: v.spec.kind,
            files: v.files.clone(),
            n_samples: v.prep.pr.len(),
            sampling: v.sampling.clone(),
            errors_all: errors(&v.prep.every, &theta),
            errors: errors(&v.prep.full, &theta),
            consistent_all: None,
        })
        .collect();
    let every_val: Vec<&Dataset> = validations.iter().map(|v| &v.prep.every).collect();
    let validation_total = validation_sum(&every_val, &theta).map(|t| t.0);
    let positive = must_be_positive(&robot, &base);
    let implausible = cols
        .iter()
        .enumerate()
        .filter(|&(i, &c)| positive[c] && theta[i] < 0.0)
        .map(|(i, &c)| Implausible {
            name: base.names[c].clone(),
            grouping: base.groupings[c].clone(),
            value: theta[i],
            std: std[i],
        })
        .collect();
    let mut warnings: Vec<String> = experiments
        .iter()
        .chain(&validations)
        .flat_map(|e| e.warnings().into_iter().map(move |w| format!("{}: {w}", e.name)))
        .collect();
    if !fit.converged {
        warnings.push(format!(
            "the residual weights did not settle within {} iterations (irls_iterations): the weights and the covariance are those of the last iteration",
            fit.iterations
        ));
    }
    warnings.extend(
        crate::robot::export::inertial_warnings(&robot)
            .into_iter()
            .map(|w| format!("nominal model: {w}")),
    );
    let status = match single.as_ref().and_then(|s| s.ml.as_ref()) {
        Some(m) => EstimateStatus::Ml(m.status),
        None if fit.rank < k => EstimateStatus::RankDeficient,
        None => EstimateStatus::Ok,
    };
    let (projection, ml, reduction) = match single {
        Some(s) => (s.projection, s.ml, s.reduction),
        None => (None, None, None),
    };
    let mut estimate = Estimate {
        name: design.name.clone(),
        robot: robot.name.clone(),
        status,
        method: design.method,
        weights: design.weights,
        dead_band: design.dead_band,
        names: cols.iter().map(|&c| base.names[c].clone()).collect(),
        groupings: cols.iter().map(|&c| base.groupings[c].clone()).collect(),
        covariance: fit.cov.row_iter().map(|r| r.iter().copied().collect()).collect(),
        rel_std: std
            .iter()
            .zip(&theta)
            .map(|(s, t)| if *t != 0.0 { s / t.abs() } else { f64::INFINITY })
            .collect(),
        std,
        theta,
        rank: fit.rank,
        cond: fit.cond,
        cond_normalized: fit.cond_normalized,
        chi2_dof: fit.chi2_dof,
        iterations: fit.iterations,
        converged: fit.converged,
        experiments: exp_reports,
        validation: val_reports,
        validation_total,
        consistent: None,
        implausible,
        standard_names: robot.param_names(),
        base_k: cols.iter().map(|&c| base.k.row(c).iter().copied().collect()).collect(),
        truth: None,
        warnings,
        projection,
        ml,
        reduction,
    };
    let mut interrupted = stopped;
    if let Some(cs) = &design.consistent {
        let st = st.as_ref().expect("the design allows [consistent] with the stacked least squares only");
        match consistent_with_prior(&robot, &base, prior_robot.as_ref(), cs, st, &experiments, &validations, ctl)? {
            Some(c) => {
                for (v, ve) in estimate.validation.iter_mut().zip(&validations) {
                    v.consistent_all = Some(errors(&ve.prep.every, &c.base));
                }
                if let Some(t) = &mut estimate.validation_total {
                    t.consistent_e_rel = validation_sum(&every_val, &c.base).map(|x| x.0.e_rel);
                }
                estimate.consistent = Some(c);
            }
            None => interrupted = true,
        }
    }
    let truth = match (&inputs.truth, &design.truth) {
        (Some(t), _) => Some(t.clone()),
        (None, Some(t)) => Some(crate::data::Truth::read(&dir.join(t))?),
        (None, None) => None,
    };
    if let Some(truth) = &truth {
        estimate.truth = Some(truth_rows(&estimate, truth)?);
    }
    Ok(StudyResult {
        design: design.clone(),
        estimate,
        experiments,
        validations,
        robot,
        robot_path,
        interrupted,
    })
}

fn truth_rows(e: &Estimate, truth: &crate::data::Truth) -> Result<Vec<TruthRow>> {
    e.names
        .iter()
        .enumerate()
        .map(|(i, nm)| {
            let k = truth.base_names.iter().position(|x| x == nm).ok_or_else(|| {
                Error::invalid(
                    "truth",
                    "base_names",
                    format!("the truth file has no base parameter {nm:?} (different robot or base columns?)"),
                )
            })?;
            Ok(TruthRow {
                name: nm.clone(),
                truth: truth.base[k],
                estimate: e.theta[i],
                z: (e.theta[i] - truth.base[k]) / e.std[i],
            })
        })
        .collect()
}

/// What an estimator says of one experiment's rows ([`experiment_report_of`]).
pub(super) struct RowStats {
    /// Per joint: how its rows are weighted.
    pub weights: Vec<BlockWeight>,
    /// Per joint: the torque noise σ the weights stand for (N·m).
    pub sigma: Vec<f64>,
    /// Weighted residual sum of squares per row.
    pub chi2_per_row: f64,
    /// Per base parameter, the experiment's share of its information.
    pub share: Vec<f64>,
    /// Rank and condition number of the experiment's own design.
    pub alone: (usize, f64),
}

/// The report of experiment `e` at the estimate `theta`.
pub(super) fn experiment_report_of(e: &Loaded, theta: &[f64], r: RowStats) -> ExperimentReport {
    let t = &e.prep.pr.t;
    ExperimentReport {
        name: e.name.clone(),
        kind: e.spec.kind,
        files: e.files.clone(),
        n_reps: e.n_reps,
        n_samples: e.prep.pr.len(),
        duration: t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0),
        sampling: e.sampling.clone(),
        filter: e.prep.filter.clone(),
        velocity: e.prep.pr.velocity,
        torque_source: e.torque_source.clone(),
        rows_used: e.prep.rows_used.clone(),
        weights: r.weights,
        sigma: r.sigma,
        chi2_per_row: r.chi2_per_row,
        errors: errors(&e.prep.full, theta),
        errors_all: errors(&e.prep.every, theta),
        information_share: r.share.iter().sum::<f64>() / r.share.len().max(1) as f64,
        information_share_per_parameter: r.share,
        rank_alone: r.alone.0,
        cond_alone: r.alone.1,
        warnings: e.warnings(),
    }
}

fn experiment_report(e: &Loaded, ei: usize, st: &Stacked, theta: &[f64]) -> ExperimentReport {
    let blocks: Vec<&Block> = st.blocks.iter().filter(|b| b.experiment == ei).collect();
    let n = e.prep.full.n;
    let mut weights = vec![BlockWeight::NoRows; n];
    let mut sigma = vec![0.0; n];
    for b in &blocks {
        weights[b.joint] = b.weight;
        sigma[b.joint] = b.sigma;
    }
    let rows: usize = blocks.iter().map(|b| b.rows).sum();
    let chi2: f64 = blocks.iter().map(|b| b.chi2).sum();
    let stats = RowStats {
        weights,
        sigma,
        chi2_per_row: chi2 / rows.max(1) as f64,
        share: st.share[ei].clone(),
        alone: st.alone[ei],
    };
    experiment_report_of(e, theta, stats)
}
