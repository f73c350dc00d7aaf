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

pub mod design;
pub mod output;
pub mod report;
pub mod stack;

pub use design::{ConsistentSpec, ExperimentKind, ExperimentSpec, ExportFormat, FilterName, StudyDesign, StudyMethod, WeightRule, WeightSpec};
pub use stack::{Block, BlockWeight, StackOptions, Stacked, WeightSource};

use super::consistent::{kinds_of, Active, ConsistentStatus, Kind};
use super::estimate::{errors, must_be_positive, Dataset, Errors};
use super::prior::{PriorMetric, PriorProblem};
use super::{
    in_joint_coordinates, prepare, resolve_filter, run_trajectory, EstimateStatus, Filter, FilterChoice, IdentOptions, Implausible, Method, Prepared, RowsUsed,
    TruthRow, VelocitySource,
};
use crate::data::{Run, Sampling, SamplingOptions, TorqueSource};
use crate::error::{Error, Result};
use crate::optim::Control;
use crate::params::{BaseOptions, BaseParams};
use crate::robot::Robot;
use crate::trajectory::FourierTrajectory;
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// One experiment or validation run, read and processed.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// Its name.
    pub name: String,
    /// Its entry.
    pub spec: ExperimentSpec,
    /// The files read.
    pub files: Vec<PathBuf>,
    /// Repetitions.
    pub n_reps: usize,
    /// How the torques were obtained.
    pub torque_source: TorqueSource,
    /// What was done with the time stamps.
    pub sampling: Sampling,
    /// The processed run and its datasets.
    pub prep: Prepared,
}

/// Reads and processes one entry of a study (paths relative to `dir`).
pub fn load_entry(robot: &Robot, base: &BaseParams, spec: &ExperimentSpec, dir: &Path, method: StudyMethod, sample_limit: usize) -> Result<Loaded> {
    let name = spec.resolved_name();
    let paths: Vec<PathBuf> = spec.files.iter().map(|f| dir.join(f)).collect();
    for p in &paths {
        crate::io::status::require_complete(p, false)?;
    }
    let (run, torque_source, sampling) = match &spec.log {
        Some(l) => {
            let (run, src, sampling, _) = crate::data::logs::read_run(&paths, robot, l, spec.resample, sample_limit)?;
            (run, src, sampling)
        }
        None => {
            let (run, src, sampling) = Run::read_drives_sampled(
                &paths,
                robot,
                spec.repetitions,
                spec.torque_from,
                spec.current_tolerance,
                Some(SamplingOptions {
                    rate: spec.resample,
                    limit: sample_limit,
                }),
            )?;
            let sampling = sampling.unwrap_or_else(|| unreachable_sampling(&run));
            (run, src, sampling)
        }
    };
    let run = in_joint_coordinates(robot, &run, spec.coordinates)?.into_owned();
    let traj: Option<FourierTrajectory> = match &spec.trajectory {
        Some(p) => {
            let p = dir.join(p);
            let t = FourierTrajectory::load(&p)?;
            if t.n_joints() != robot.dof() {
                return Err(Error::invalid(
                    p.display().to_string(),
                    "trajectory",
                    format!(
                        "{} joints in the trajectory, {} in robot {}: expected the experiment's own trajectory",
                        t.n_joints(),
                        robot.dof(),
                        robot.name
                    ),
                ));
            }
            Some(t)
        }
        None => run_trajectory(&run)?,
    };
    let lowpass = FilterChoice::Given(Filter::LowPass { cutoff: spec.cutoff });
    let filter = match spec.filter {
        FilterName::Auto if traj.is_some() && spec.kind == ExperimentKind::Excitation => FilterChoice::Auto,
        FilterName::Auto => lowpass,
        FilterName::Fourier => match &traj {
            Some(t) => FilterChoice::Given(resolve_filter(&FilterChoice::Auto, Some(t), None)),
            None => {
                return Err(Error::invalid(
                    format!("experiment `{name}`"),
                    "filter",
                    "\"fourier\" needs the Fourier trajectory: give `trajectory` or put trajectory.json beside the run",
                ))
            }
        },
        FilterName::Lowpass => lowpass,
        FilterName::None => FilterChoice::Given(Filter::None),
    };
    let opts = IdentOptions {
        method: match method {
            StudyMethod::Wls => Method::Wls,
            StudyMethod::Ols => Method::Ols,
        },
        filter,
        harmonics: spec.harmonics,
        decimate: spec.decimate,
        slow_ratio: spec.slow_ratio,
        min_speed: spec.min_speed,
        standstill: spec.standstill.unwrap_or(spec.kind.default_standstill()),
        velocity_from: spec.velocity_from,
        ..Default::default()
    };
    let prep = prepare(robot, base, &run, traj.as_ref(), &opts, false).map_err(|e| match e {
        Error::Invalid { context, field, msg } => Error::Invalid {
            context: format!("experiment `{name}` ({context})"),
            field,
            msg,
        },
        e => e,
    })?;
    Ok(Loaded {
        name,
        spec: spec.clone(),
        files: run.files.clone(),
        n_reps: run.n_reps(),
        torque_source,
        sampling,
        prep,
    })
}

/// The sampling record of a run read without resampling (not reached: the
/// study always reads with sampling options; kept total for safety).
fn unreachable_sampling(run: &Run) -> Sampling {
    let (a, m, b) = crate::data::resample::step_stats(&run.reps[0].t);
    Sampling {
        irregular: false,
        min_step: a,
        median_step: m,
        max_step: b,
        resampled_to: None,
        samples: (run.reps[0].len(), run.reps[0].len()),
    }
}

/// One experiment in the report.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentReport {
    /// Name.
    pub name: String,
    /// Kind.
    pub kind: ExperimentKind,
    /// Files read.
    pub files: Vec<PathBuf>,
    /// Repetitions.
    pub n_reps: usize,
    /// Samples per joint after processing.
    pub n_samples: usize,
    /// Duration (s).
    pub duration: f64,
    /// Time stamps: uniform, or resampled.
    pub sampling: Sampling,
    /// Filter used.
    pub filter: Filter,
    /// Velocity source.
    pub velocity: VelocitySource,
    /// Torques from torques or currents.
    pub torque_source: TorqueSource,
    /// Rows used per joint.
    pub rows_used: Vec<RowsUsed>,
    /// Per joint: how the rows are weighted.
    pub weights: Vec<BlockWeight>,
    /// Per joint: the torque noise σ the weights stand for (N·m).
    pub sigma: Vec<f64>,
    /// Weighted residual sum of squares of its rows per row.
    pub chi2_per_row: f64,
    /// Errors on its rows used.
    pub errors: Errors,
    /// Errors on every sample.
    pub errors_all: Errors,
    /// Its share of the information, tr((CᵀWC)⁻¹F_e)/k.
    pub information_share: f64,
    /// Per base parameter, its share of that parameter's information.
    pub information_share_per_parameter: Vec<f64>,
    /// Rank of its own weighted design (of k).
    pub rank_alone: usize,
    /// Condition number of its own weighted design (∞ when rank deficient).
    pub cond_alone: f64,
    /// Warnings of its processing.
    pub warnings: Vec<String>,
}

/// One validation run in the report.
#[derive(Debug, Clone, Serialize)]
pub struct ValidationReport {
    /// Name.
    pub name: String,
    /// Kind.
    pub kind: ExperimentKind,
    /// Files read.
    pub files: Vec<PathBuf>,
    /// Samples per joint.
    pub n_samples: usize,
    /// Time stamps.
    pub sampling: Sampling,
    /// Errors of the least-squares estimate on every sample.
    pub errors_all: Errors,
    /// The same on the rows selected like the estimate's.
    pub errors: Errors,
    /// Errors of the consistent estimate on every sample.
    pub consistent_all: Option<Errors>,
}

/// Validation errors summed over the runs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ValidationTotal {
    /// Per joint e_j over every sample of every validation run (N·m).
    pub e: Vec<f64>,
    /// Per joint e*_j = Σ|τ − τ̂| / Σ|τ| over every sample of every run.
    pub e_rel: Vec<f64>,
    /// Per joint RMS over every sample of every run (N·m).
    pub rms: Vec<f64>,
    /// The same for the consistent estimate.
    pub consistent_e_rel: Option<Vec<f64>>,
    /// Mean over runs and joints of the relative RMS error (the criterion of `weight = "validation"`).
    pub mean_relative_rms: f64,
}

/// A link of the consistent estimate beside the prior.
#[derive(Debug, Clone, Serialize)]
pub struct LinkPrior {
    /// Link name.
    pub link: String,
    /// Mass (kg): estimate, prior.
    pub mass: [f64; 2],
    /// Centre of mass (m, link frame): estimate, prior.
    pub com: [[f64; 3]; 2],
    /// Trace of the inertia about the centre of mass (kg·m²): estimate, prior.
    pub inertia_trace: [f64; 2],
    /// Entropic divergence D(J, J₀) of the link's pseudo-inertia from the prior's.
    pub divergence: f64,
}

/// A value physically possible but implausible next to the prior.
#[derive(Debug, Clone, Serialize)]
pub struct Flag {
    /// Link or parameter.
    pub what: String,
    /// Estimate.
    pub value: f64,
    /// Prior.
    pub prior: f64,
    /// Why.
    pub reason: String,
}

/// A direction of the standard parameters the data do not decide.
#[derive(Debug, Clone, Serialize)]
pub struct Direction {
    /// The fit's curvature along it (in prior-scale units; 0: not seen at all).
    pub curvature: f64,
    /// Its largest components (parameter, weight), largest first.
    pub components: Vec<(String, f64)>,
    /// The estimate's coordinate along it, in prior scales (0: the prior's value).
    pub offset: f64,
}

/// The consistent estimate with its prior.
#[derive(Debug, Clone, Serialize)]
pub struct ConsistentReport {
    /// How the fit ended.
    pub status: ConsistentStatus,
    /// `nominal` or the prior robot file.
    pub prior: String,
    /// Metric.
    pub metric: PriorMetric,
    /// Weight used.
    pub weight: f64,
    /// Per candidate weight (weight = "validation"): (weight, mean relative RMS on the validation runs, extra cost).
    pub weight_curve: Vec<(f64, f64, f64)>,
    /// Relative scale of the prior.
    pub scale: f64,
    /// Margin ε.
    pub margin: f64,
    /// Standard parameter names.
    pub standard_names: Vec<String>,
    /// Consistent standard parameters θ.
    pub standard: Vec<f64>,
    /// The prior θ₀.
    pub prior_standard: Vec<f64>,
    /// The prior's scales s.
    pub prior_scale: Vec<f64>,
    /// Base parameters K θ.
    pub base: Vec<f64>,
    /// Increase of the weighted residual sum of squares over WLS.
    pub extra_cost: f64,
    /// Weighted residual sum of squares per degree of freedom.
    pub chi2_dof: f64,
    /// Smallest pseudo-inertia eigenvalue per link (kg·m²).
    pub min_eigenvalue: Vec<f64>,
    /// Constraints at their bound.
    pub active: Vec<Active>,
    /// Per link: the estimate beside the prior.
    pub links: Vec<LinkPrior>,
    /// Implausible values.
    pub flags: Vec<Flag>,
    /// Directions the data do not see at all (decided by the prior alone): their number.
    pub unidentifiable: usize,
    /// Directions the fit sees less than the prior (curvature below the weight), weakest first, at most 12 listed.
    pub prior_decided: Vec<Direction>,
    /// Their number.
    pub n_prior_decided: usize,
    /// Per experiment, the consistent estimate's errors on every sample.
    pub experiments: Vec<Errors>,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Solver time (s).
    pub solve_time: f64,
}

/// The result of a study (written as `estimate.json`).
#[derive(Debug, Clone, Serialize)]
pub struct StudyEstimate {
    /// Study name.
    pub name: String,
    /// Robot.
    pub robot: String,
    /// How the estimate ended.
    pub status: EstimateStatus,
    /// Estimator.
    pub method: StudyMethod,
    /// Weight source.
    pub weights: WeightSource,
    /// Base parameter names.
    pub names: Vec<String>,
    /// Their groupings.
    pub groupings: Vec<String>,
    /// Estimates.
    pub theta: Vec<f64>,
    /// Standard deviations.
    pub std: Vec<f64>,
    /// Relative standard deviations.
    pub rel_std: Vec<f64>,
    /// Covariance (rows).
    pub covariance: Vec<Vec<f64>>,
    /// Rank of the weighted design.
    pub rank: usize,
    /// Condition number of the weighted design √W C.
    pub cond: f64,
    /// The same with unit-norm columns.
    pub cond_normalized: f64,
    /// χ²/dof.
    pub chi2_dof: f64,
    /// Reweighting iterations.
    pub iterations: usize,
    /// True when the reweighting converged.
    pub converged: bool,
    /// The experiments.
    pub experiments: Vec<ExperimentReport>,
    /// The validation runs.
    pub validation: Vec<ValidationReport>,
    /// Their totals (None without validation runs).
    pub validation_total: Option<ValidationTotal>,
    /// The consistent estimate with a prior.
    pub consistent: Option<ConsistentReport>,
    /// Base parameters that must be positive but are negative.
    pub implausible: Vec<Implausible>,
    /// Standard parameter names (columns of `base_k`).
    pub standard_names: Vec<String>,
    /// θ_base = K θ_standard.
    pub base_k: Vec<Vec<f64>>,
    /// Comparison with the truth.
    pub truth: Option<Vec<TruthRow>>,
    /// Warnings.
    pub warnings: Vec<String>,
}

/// A study's result with the data behind it (for the plots and files).
#[derive(Debug, Clone)]
pub struct StudyResult {
    /// The resolved design.
    pub design: StudyDesign,
    /// The estimate.
    pub estimate: StudyEstimate,
    /// The experiments.
    pub experiments: Vec<Loaded>,
    /// The validation runs.
    pub validations: Vec<Loaded>,
    /// The robot.
    pub robot: Robot,
    /// The robot file's path.
    pub robot_path: PathBuf,
    /// True when a Ctrl-C stopped it (what exists is written and marked so).
    pub interrupted: bool,
}

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

/// Reads the study's robot, base parameters and prior robot.
fn setup(design: &StudyDesign, dir: &Path) -> Result<(Robot, PathBuf, BaseParams, Option<Robot>)> {
    let robot_path = dir.join(&design.robot);
    let robot = crate::robot::load(&robot_path)?;
    let base = if design.base_columns.is_empty() {
        BaseParams::compute(&robot, &BaseOptions::default())?
    } else {
        BaseParams::with_columns(&robot, &design.base_columns, &BaseOptions::default())?
    };
    let prior = match &design.consistent {
        Some(c) if c.prior != "nominal" => Some(crate::robot::load(&dir.join(&c.prior))?),
        _ => None,
    };
    Ok((robot, robot_path, base, prior))
}

/// Runs a study whose relative paths are relative to `dir` (the study file's
/// folder). `ctl` stops it between experiments and between the prior's
/// candidate weights; what exists then is returned, marked interrupted.
pub fn run_study(design: &StudyDesign, dir: &Path, ctl: &Control) -> Result<StudyResult> {
    design.validate("study")?;
    let (robot, robot_path, base, prior_robot) = setup(design, dir)?;
    let obs = ctl.observer();
    let total = design.experiment.len() + design.validation.len();
    obs.phase("identify read", Some(total as u64));
    let mut experiments = Vec::new();
    let mut validations = Vec::new();
    for (i, spec) in design.experiment.iter().chain(&design.validation).enumerate() {
        if ctl.interrupted() {
            return Err(Error::Interrupted);
        }
        let l = load_entry(&robot, &base, spec, dir, design.method, design.sample_limit)?;
        obs.progress(i as u64 + 1, &l.name);
        if i < design.experiment.len() {
            experiments.push(l);
        } else {
            validations.push(l);
        }
    }
    obs.phase_done();
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
        ols: design.method == StudyMethod::Ols,
        max_iterations: design.irls_iterations,
        tol: design.irls_tol,
    };
    let st = stack::estimate(&rows, &so)?;
    let k = base.n_base();
    let theta: Vec<f64> = st.theta.as_slice().to_vec();
    let std: Vec<f64> = (0..k).map(|i| st.cov[(i, i)].max(0.0).sqrt()).collect();
    let exp_reports: Vec<ExperimentReport> = experiments.iter().enumerate().map(|(ei, e)| experiment_report(e, ei, &st, &theta)).collect();
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
    let implausible = (0..k)
        .filter(|&i| positive[i] && theta[i] < 0.0)
        .map(|i| Implausible {
            name: base.names[i].clone(),
            grouping: base.groupings[i].clone(),
            value: theta[i],
            std: std[i],
        })
        .collect();
    let mut warnings: Vec<String> = experiments
        .iter()
        .chain(&validations)
        .flat_map(|e| super::filter_warnings(&e.prep.pr).into_iter().map(move |w| format!("{}: {w}", e.name)))
        .collect();
    if !st.converged {
        warnings.push(format!(
            "the residual weights did not settle within {} iterations (irls_iterations): the weights and the covariance are those of the last iteration",
            st.iterations
        ));
    }
    warnings.extend(
        crate::robot::export::inertial_warnings(&robot)
            .into_iter()
            .map(|w| format!("nominal model: {w}")),
    );
    let status = if st.rank < k { EstimateStatus::RankDeficient } else { EstimateStatus::Ok };
    let mut estimate = StudyEstimate {
        name: design.name.clone(),
        robot: robot.name.clone(),
        status,
        method: design.method,
        weights: design.weights,
        names: base.names.clone(),
        groupings: base.groupings.clone(),
        covariance: st.cov.row_iter().map(|r| r.iter().copied().collect()).collect(),
        rel_std: std
            .iter()
            .zip(&theta)
            .map(|(s, t)| if *t != 0.0 { s / t.abs() } else { f64::INFINITY })
            .collect(),
        std,
        theta,
        rank: st.rank,
        cond: st.cond,
        cond_normalized: st.cond_normalized,
        chi2_dof: st.chi2_dof,
        iterations: st.iterations,
        converged: st.converged,
        experiments: exp_reports,
        validation: val_reports,
        validation_total,
        consistent: None,
        implausible,
        standard_names: robot.param_names(),
        base_k: base.k.row_iter().map(|r| r.iter().copied().collect()).collect(),
        truth: None,
        warnings,
    };
    let mut interrupted = false;
    if let Some(cs) = &design.consistent {
        match consistent_with_prior(&robot, &base, prior_robot.as_ref(), cs, &st, &experiments, &validations, ctl)? {
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
    if let Some(t) = &design.truth {
        let truth = crate::data::Truth::read(&dir.join(t))?;
        estimate.truth = Some(truth_rows(&estimate, &truth)?);
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

fn truth_rows(e: &StudyEstimate, truth: &crate::data::Truth) -> Result<Vec<TruthRow>> {
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
    let share = &st.share[ei];
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
        weights,
        sigma,
        chi2_per_row: chi2 / rows.max(1) as f64,
        errors: errors(&e.prep.full, theta),
        errors_all: errors(&e.prep.every, theta),
        information_share: share.iter().sum::<f64>() / share.len().max(1) as f64,
        information_share_per_parameter: share.clone(),
        rank_alone: st.alone[ei].0,
        cond_alone: st.alone[ei].1,
        warnings: super::filter_warnings(&e.prep.pr),
    }
}

/// The consistent estimate with a prior; None when interrupted.
#[allow(clippy::too_many_arguments)] // the study's parts, each needed once
fn consistent_with_prior(
    robot: &Robot,
    base: &BaseParams,
    prior_robot: Option<&Robot>,
    cs: &ConsistentSpec,
    st: &Stacked,
    experiments: &[Loaded],
    validations: &[Loaded],
    ctl: &Control,
) -> Result<Option<ConsistentReport>> {
    let (kinds, links) = kinds_of(robot);
    let (theta0, scale) = super::prior::prior_of(robot, prior_robot, cs.scale)?;
    let link_names: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
    let pb = PriorProblem {
        r: &st.r,
        theta_b: &st.theta,
        k: &base.k,
        links: &links,
        link_names: &link_names,
        kinds: &kinds,
        prior: &theta0,
        scale: &scale,
    };
    let every_val: Vec<&Dataset> = validations.iter().map(|v| &v.prep.every).collect();
    let (weight, curve, sol) = match cs.weight {
        WeightSpec::Value(w) => (w, Vec::new(), super::prior::solve(&pb, cs.metric, w, cs.margin, ctl)?),
        WeightSpec::Rule(WeightRule::Validation) => {
            let obs = ctl.observer();
            obs.phase("identify prior weight", Some(cs.weight_grid.len() as u64));
            let mut best: Option<(f64, f64, super::consistent::Solution)> = None;
            let mut curve = Vec::new();
            for (i, &w) in cs.weight_grid.iter().enumerate() {
                if ctl.interrupted() {
                    obs.phase_done();
                    return Ok(None);
                }
                let sol = super::prior::solve(&pb, cs.metric, w, cs.margin, ctl)?;
                let ok = ConsistentStatus::of(&sol.status).is_ok();
                let score = if ok {
                    validation_sum(&every_val, sol.base.as_slice()).map_or(f64::INFINITY, |t| t.1)
                } else {
                    f64::INFINITY
                };
                curve.push((w, score, sol.extra_cost));
                obs.progress(i as u64 + 1, &format!("weight {w:e}: validation {score:.4}"));
                if best.as_ref().is_none_or(|b| score < b.1) {
                    best = Some((w, score, sol));
                }
            }
            obs.phase_done();
            let (w, _, sol) = best.ok_or_else(|| Error::invalid("consistent", "weight_grid", "no candidate weight"))?;
            (w, curve, sol)
        }
    };
    let status = ConsistentStatus::of(&sol.status);
    let names = robot.param_names();
    let th = sol.theta.as_slice();
    let active = super::consistent::active_constraints(robot, &kinds, &links, &sol, cs.margin, &scale);
    let mut flags = Vec::new();
    let [lo, hi] = cs.plausible;
    let ratio_flag = |flags: &mut Vec<Flag>, what: String, v: f64, p: f64, unit: &str| {
        if p > 0.0 && (v < lo * p || v > hi * p) {
            flags.push(Flag {
                what,
                value: v,
                prior: p,
                reason: format!("{:.3}× the prior's {p:.4e} {unit} (plausible: {lo}–{hi}×)", v / p),
            });
        }
    };
    let mut link_rows = Vec::new();
    for (i, &l) in links.iter().enumerate() {
        let (b, b0) = (&th[l..l + 10], &theta0.as_slice()[l..l + 10]);
        let com = |b: &[f64]| if b[9] > 0.0 { [b[6] / b[9], b[7] / b[9], b[8] / b[9]] } else { [0.0; 3] };
        // tr(I_c) = tr(I_o) − 2 m |c|²
        let trc = |b: &[f64]| {
            let c = com(b);
            b[0] + b[3] + b[5] - 2.0 * b[9] * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
        };
        let name = &link_names[i];
        ratio_flag(&mut flags, format!("{name} mass"), b[9], b0[9], "kg");
        ratio_flag(&mut flags, format!("{name} inertia about the COM (trace)"), trc(b), trc(b0), "kg·m²");
        link_rows.push(LinkPrior {
            link: name.clone(),
            mass: [b[9], b0[9]],
            com: [com(b), com(b0)],
            inertia_trace: [trc(b), trc(b0)],
            divergence: super::prior::divergence(b, b0),
        });
    }
    for (j, kd) in kinds.iter().enumerate() {
        if matches!(kd, Kind::NonNegative | Kind::NonPositive) {
            ratio_flag(&mut flags, names[j].clone(), th[j].abs(), theta0[j].abs(), "");
        }
    }
    let (unidentifiable, prior_decided, n_prior_decided) = directions(&st.r, &base.k, &scale, &sol.theta, &theta0, weight, &names);
    let consistent_experiments = experiments.iter().map(|e| errors(&e.prep.every, sol.base.as_slice())).collect();
    let total: usize = experiments.iter().map(|e| e.prep.full.y.len()).sum();
    let ssr_wls: f64 = st.blocks.iter().map(|b| b.chi2).sum();
    Ok(Some(ConsistentReport {
        status,
        prior: cs.prior.clone(),
        metric: cs.metric,
        weight,
        weight_curve: curve,
        scale: cs.scale,
        margin: cs.margin,
        standard_names: names,
        standard: th.to_vec(),
        prior_standard: theta0.as_slice().to_vec(),
        prior_scale: scale.as_slice().to_vec(),
        base: sol.base.as_slice().to_vec(),
        extra_cost: sol.extra_cost,
        chi2_dof: (ssr_wls + sol.extra_cost) / total.saturating_sub(st.rank).max(1) as f64,
        min_eigenvalue: sol.min_eig.clone(),
        active,
        links: link_rows,
        flags,
        unidentifiable,
        prior_decided,
        n_prior_decided,
        experiments: consistent_experiments,
        iterations: sol.iterations,
        solve_time: sol.solve_time,
    }))
}

/// The directions of the standard parameters (in prior scales) that the fit
/// does not see (curvature ≤ 1e-10 of the largest) and those it sees less
/// than the prior (curvature below `weight`): (count unseen, weakest listed, count weak).
fn directions(
    r: &DMatrix<f64>,
    k: &DMatrix<f64>,
    scale: &DVector<f64>,
    theta: &DVector<f64>,
    theta0: &DVector<f64>,
    weight: f64,
    names: &[String],
) -> (usize, Vec<Direction>, usize) {
    let a = r * k * DMatrix::from_diagonal(scale);
    let h = a.transpose() * &a;
    let eig = SymmetricEigen::new(h);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let x = (theta - theta0).component_div(scale);
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let unseen = order.iter().filter(|&&i| eig.eigenvalues[i] <= 1e-10 * lmax).count();
    let weak: Vec<usize> = order.iter().copied().filter(|&i| eig.eigenvalues[i] < weight).collect();
    let listed = weak
        .iter()
        .take(12)
        .map(|&i| {
            let v = eig.eigenvectors.column(i);
            let mut comp: Vec<(usize, f64)> = v.iter().copied().enumerate().collect();
            comp.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            Direction {
                curvature: eig.eigenvalues[i].max(0.0),
                components: comp.iter().take(3).map(|&(j, c)| (names[j].clone(), c)).collect(),
                offset: v.dot(&x),
            }
        })
        .collect();
    (unseen, listed, weak.len())
}
