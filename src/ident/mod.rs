//! Identification from measured runs (paper 000 §II-B, §III-C, §III-D, §IV;
//! paper 002 §2.2, §3.2–3.5).
//!
//! Pipeline ([`identify`]): read the repetitions ([`Run`]), average them and
//! filter the positions ([`process()`]: Fourier filtering with analytic
//! derivatives for Fourier references, else zero-phase low-pass and central
//! differences), stack the base-parameter regressor ([`estimate::Dataset`]),
//! estimate by OLS, WLS (paper 000 eq. 5, 8–9), the projection method or
//! maximum likelihood ([`closed_loop`], paper 002 eq. 10–16), with covariances
//! and relative standard deviations (eq. 13–14), prediction errors e_j, e*_j
//! on the identification and a validation run (eq. 11–12), the condition
//! number, physical-plausibility flags, and optionally the sensitivity-based
//! model reduction ([`reduce`], Algorithm 1). The dedicated gravity and
//! friction experiments of paper 002 §3.2 are in [`experiments`].

pub mod closed_loop;
pub mod consistent;
pub mod estimate;
pub mod experiments;
pub mod output;
pub mod prior;
pub mod process;
pub mod reduce;
pub mod study;

pub use crate::data::{Coordinates, Repetition, Run, TorqueFrom, TorqueSource, CURRENT_TOLERANCE};
pub use closed_loop::{MlOptions, ProjectionOptions};
pub use consistent::{Consistent, ConsistentOptions, ConsistentStatus};
pub use estimate::{Dataset, Errors, LsFit, Weights};
pub use process::{process, process_with, Filter, Processed, VelocityFrom, VelocitySource};
pub use reduce::{Essential, ReduceOptions, Reduction};

use crate::error::{Error, Result};
use crate::io::status::RunState;
use crate::params::BaseParams;
use crate::robot::Robot;
use crate::trajectory::FourierTrajectory;
use nalgebra::DVector;
use serde::Serialize;

/// Estimator (`--method`: `ols`, `wls`, `projection`, `ml`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Ordinary least squares.
    Ols,
    /// Weighted least squares with sample-variance weights (paper 000).
    #[default]
    Wls,
    /// Projection method for closed-loop data (paper 002 eq. 10–12).
    Projection,
    /// Maximum likelihood with noisy positions and torques (paper 002 eq. 13–16).
    Ml,
}

impl Method {
    /// Every method, in the order of the command line's help.
    pub const ALL: [Method; 4] = [Method::Ols, Method::Wls, Method::Projection, Method::Ml];

    /// The name on the command line and in files (`ols`, `wls`, `projection`, `ml`).
    pub fn name(self) -> &'static str {
        match self {
            Method::Ols => "ols",
            Method::Wls => "wls",
            Method::Projection => "projection",
            Method::Ml => "ml",
        }
    }

    /// Human words for reports ("weighted least squares", ...).
    pub fn words(self) -> &'static str {
        match self {
            Method::Ols => "ordinary least squares",
            Method::Wls => "weighted least squares",
            Method::Projection => "projection method",
            Method::Ml => "maximum likelihood",
        }
    }
}

/// The name of [`Method::name`].
impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Parses [`Method::name`]; the error lists the allowed values.
impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| Error::invalid("--method", "method", format!("expected ols, wls, projection or ml, found `{s}`")))
    }
}

/// How positions are filtered.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum FilterChoice {
    /// Fourier filtering when the run's Fourier trajectory is known, else a low-pass at 10 Hz.
    #[default]
    Auto,
    /// This filter.
    Given(Filter),
}

/// Which slow rows (standstill, |q̇_j| below `slow_ratio`·max|q̇_j| or
/// `min_speed`) identification leaves out (`--standstill`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Standstill {
    /// Follow the model: drop the slow rows of joints whose friction is
    /// discontinuous at rest (Coulomb shape `sign`: the measured velocity at
    /// standstill is encoder noise and sign(q̇) flips between ±Fc), keep them
    /// for smooth shapes (`tanh`, `stribeck`) and joints without friction.
    #[default]
    Auto,
    /// Drop the slow rows of every joint (the former default rule).
    Drop,
    /// Keep every row of every joint.
    Keep,
}

impl Standstill {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Standstill::Auto => "auto",
            Standstill::Drop => "drop",
            Standstill::Keep => "keep",
        }
    }
}

impl std::str::FromStr for Standstill {
    type Err = Error;
    fn from_str(s: &str) -> Result<Standstill> {
        match s {
            "auto" => Ok(Standstill::Auto),
            "drop" => Ok(Standstill::Drop),
            "keep" => Ok(Standstill::Keep),
            _ => Err(Error::invalid(
                "--standstill",
                "standstill",
                format!("expected auto, drop or keep, found `{s}`"),
            )),
        }
    }
}

/// The rows of one joint used for the estimate and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RowsUsed {
    /// Joint name.
    pub joint: String,
    /// Rows of this joint in the estimate.
    pub used: usize,
    /// Rows of this joint in the run (after decimation).
    pub total: usize,
    /// True when slow rows were left out.
    pub slow_dropped: bool,
    /// The rule in words.
    pub reason: String,
}

/// Options of [`identify`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentOptions {
    /// Estimator.
    pub method: Method,
    /// WLS weights.
    pub weights: Weights,
    /// Filter of the identification run.
    pub filter: FilterChoice,
    /// Harmonics kept by Fourier filtering (default: the trajectory's n_h, the
    /// excited ones as in paper 000 §III-C). More harmonics keep the part of the
    /// closed-loop response above the excitation band (tracking errors of a
    /// nonlinear plant) that filtering at n_h would remove from q̈.
    pub harmonics: Option<usize>,
    /// Keep every k-th processed sample.
    pub decimate: usize,
    /// Rows of joint j where |q̇_j| is below this fraction of the joint's largest
    /// speed in the run are left out (see [`Dataset::new`]). Not applied by the
    /// projection method, which needs every sample.
    pub slow_ratio: f64,
    /// Rows of a joint slower than this speed are left out too (rad/s or m/s).
    pub min_speed: f64,
    /// Which joints the slow-row rule applies to ([`Standstill`]; default:
    /// those with a `sign` Coulomb term).
    pub standstill: Standstill,
    /// Velocities from the logged `qd*` columns or from the positions
    /// ([`VelocityFrom`]; default: logged when present), for the
    /// identification and the validation run alike.
    pub velocity_from: VelocityFrom,
    /// Model reduction (WLS only).
    pub reduce: Option<ReduceOptions>,
    /// Projection-method options.
    pub projection: ProjectionOptions,
    /// ML options.
    pub ml: MlOptions,
    /// Coordinates of the runs' positions (motor-side runs are mapped through the coupling).
    pub coordinates: Coordinates,
    /// Physically consistent fit after WLS/OLS ([`consistent`]).
    pub consistent: Option<ConsistentOptions>,
}

impl Default for IdentOptions {
    fn default() -> Self {
        IdentOptions {
            method: Method::Wls,
            weights: Weights::Sample,
            filter: FilterChoice::Auto,
            harmonics: None,
            decimate: 1,
            slow_ratio: 0.1,
            min_speed: 0.01,
            standstill: Standstill::Auto,
            velocity_from: VelocityFrom::Auto,
            reduce: None,
            projection: ProjectionOptions::default(),
            ml: MlOptions::default(),
            coordinates: Coordinates::Joint,
            consistent: None,
        }
    }
}

/// How an estimate ended (`status` in estimate.json: `ok`, `rank_deficient`,
/// or nlopt's word for the maximum-likelihood stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimateStatus {
    /// Full rank, estimated.
    Ok,
    /// The design matrix is rank deficient: the minimum-norm solution is not an estimate.
    RankDeficient,
    /// The maximum-likelihood stage ended with this nlopt status.
    Ml(crate::optim::nlopt::NloptStatus),
}

impl EstimateStatus {
    /// The word written in estimate.json and reports.
    pub fn as_str(self) -> &'static str {
        match self {
            EstimateStatus::Ok => "ok",
            EstimateStatus::RankDeficient => "rank_deficient",
            EstimateStatus::Ml(s) => s.as_str(),
        }
    }

    /// What status.json says of a run that ended so: a rank-deficient design
    /// or an ML failure is not usable, a forced stop is an interruption.
    pub fn state(self) -> RunState {
        use crate::optim::nlopt::NloptStatus as N;
        match self {
            EstimateStatus::RankDeficient => RunState::Failed,
            EstimateStatus::Ml(N::Failure | N::InvalidArgs | N::OutOfMemory | N::RoundoffLimited) => RunState::Failed,
            EstimateStatus::Ml(N::ForcedStop) => RunState::Interrupted,
            _ => RunState::Complete,
        }
    }
}

impl std::fmt::Display for EstimateStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for EstimateStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

/// A base parameter that must be positive but was estimated negative.
#[derive(Debug, Clone, Serialize)]
pub struct Implausible {
    /// Base parameter name.
    pub name: String,
    /// Its combination of standard parameters.
    pub grouping: String,
    /// Estimate.
    pub value: f64,
    /// Standard deviation.
    pub std: f64,
}

/// Comparison with known true parameters (simulated runs).
#[derive(Debug, Clone, Serialize)]
pub struct TruthRow {
    /// Name.
    pub name: String,
    /// True base value.
    pub truth: f64,
    /// Estimate.
    pub estimate: f64,
    /// (estimate − truth)/σ.
    pub z: f64,
}

/// The result of an identification (written as `estimate.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    /// How the estimate ended.
    pub status: EstimateStatus,
    /// Estimator.
    pub method: Method,
    /// Names of the estimated base parameters.
    pub names: Vec<String>,
    /// Their combinations of standard parameters.
    pub groupings: Vec<String>,
    /// Estimates θ̂.
    pub theta: Vec<f64>,
    /// Standard deviations σ_i.
    pub std: Vec<f64>,
    /// Relative standard deviations σ*_i (eq. 14).
    pub rel_std: Vec<f64>,
    /// Covariance matrix (rows).
    pub covariance: Vec<Vec<f64>>,
    /// Rank of the design matrix.
    pub rank: usize,
    /// Condition number of C.
    pub cond: f64,
    /// Condition number of C with unit-norm columns.
    pub cond_normalized: f64,
    /// Weighted residual sum of squares per degree of freedom.
    pub chi2_dof: f64,
    /// Errors (eq. 11–12) on the rows of the identification run used for the
    /// estimate (fast enough for friction: `slow_ratio`, `min_speed`).
    pub errors: Errors,
    /// Errors on the same kind of rows of the validation run.
    pub validation: Option<Errors>,
    /// Errors on every sample of the identification run (paper 000's
    /// definition), with the same model (friction shape) as the estimate.
    pub errors_all: Errors,
    /// Per joint: the rows used for the estimate and the standstill rule applied.
    pub rows_used: Vec<RowsUsed>,
    /// How the joint torques were obtained when the run logged motor
    /// currents ([`crate::data::Run::read_drives`]); set by the caller.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torque_source: Option<crate::data::TorqueSource>,
    /// Errors on every sample of the validation run.
    pub validation_all: Option<Errors>,
    /// Names of the standard parameters (columns of `base_k`).
    pub standard_names: Vec<String>,
    /// K restricted to the estimated base parameters: θ_base = K θ_standard (rows: `names`).
    pub base_k: Vec<Vec<f64>>,
    /// Coordinates the run's positions were logged in.
    pub coordinates: Coordinates,
    /// True when the run was one averaged file with variance columns.
    pub averaged: bool,
    /// The physically consistent estimate, if asked for.
    pub consistent: Option<Consistent>,
    /// Base parameters that must be positive but are negative.
    pub implausible: Vec<Implausible>,
    /// Repetitions averaged.
    pub n_reps: usize,
    /// Samples per joint used.
    pub n_samples: usize,
    /// Filter used.
    pub filter: Filter,
    /// Where q̇ and q̈ came from (logged `qd*`/`qdd*` or the positions).
    pub velocity: VelocitySource,
    /// Per joint: RMS of (averaged − filtered) positions and the noise RMS of
    /// the averaged positions ([`Processed::filter_residual`]).
    pub filter_residual: Vec<(f64, Option<f64>)>,
    /// Warnings about the data processing (e.g. motion removed by the filter).
    pub warnings: Vec<String>,
    /// Projection-method details.
    pub projection: Option<closed_loop::ProjectionInfo>,
    /// ML details.
    pub ml: Option<closed_loop::MlInfo>,
    /// Model reduction.
    pub reduction: Option<Reduction>,
    /// Comparison with the truth.
    pub truth: Option<Vec<TruthRow>>,
}

/// An identification with the data behind it (for plots).
#[derive(Debug, Clone)]
pub struct Identification {
    /// The estimate.
    pub estimate: Estimate,
    /// Processed identification data.
    pub processed: Processed,
    /// Its dataset (columns of the estimated parameters).
    pub dataset: Dataset,
    /// Validation dataset, if any.
    pub validation: Option<Dataset>,
}

/// Chooses the filter: a given one, or Fourier filtering at the trajectory's
/// ω and n_h when known, else a 10 Hz low-pass.
pub fn resolve_filter(choice: &FilterChoice, trajectory: Option<&FourierTrajectory>, harmonics: Option<usize>) -> Filter {
    match (choice, trajectory) {
        (FilterChoice::Given(Filter::Fourier { omega, n_h }), _) => Filter::Fourier {
            omega: *omega,
            n_h: harmonics.unwrap_or(*n_h),
        },
        (FilterChoice::Given(f), _) => f.clone(),
        (FilterChoice::Auto, Some(t)) => Filter::Fourier {
            omega: t.omega,
            n_h: harmonics.unwrap_or(t.n_harmonics()),
        },
        (FilterChoice::Auto, None) => Filter::LowPass { cutoff: 10.0 },
    }
}

/// The Fourier trajectory stored next to a run (`trajectory.json` in its folder), if any.
pub fn run_trajectory(run: &Run) -> Result<Option<FourierTrajectory>> {
    match run.folder().map(|d| d.join("trajectory.json")) {
        Some(p) if p.exists() => Ok(Some(FourierTrajectory::load(&p)?)),
        _ => Ok(None),
    }
}

/// Identifies the base parameters of `robot` from `run` (validated on
/// `validation`, each with its Fourier trajectory if known). `ctl` stops the
/// model reduction and the maximum-likelihood stage (they return what they
/// have, marked as interrupted).
pub fn identify(
    robot: &Robot,
    base: &BaseParams,
    run: &Run,
    trajectory: Option<&FourierTrajectory>,
    validation: Option<(&Run, Option<&FourierTrajectory>)>,
    opts: &IdentOptions,
    ctl: &crate::optim::Control,
) -> Result<Identification> {
    if run.n_joints() != robot.dof() {
        return Err(Error::dim("joints in the run", robot.dof(), run.n_joints()));
    }
    if opts.decimate == 0 {
        return Err(Error::invalid("identify", "decimate", "expected ≥ 1"));
    }
    if opts.consistent.is_some() && (opts.reduce.is_some() || !matches!(opts.method, Method::Wls | Method::Ols)) {
        return Err(Error::invalid(
            "identify",
            "--consistent",
            "the physically consistent fit uses the least-squares fit of every base parameter: run it with method wls or ols and without --reduce",
        ));
    }
    let run = &*in_joint_coordinates(robot, run, opts.coordinates)?;
    if opts.reduce.is_some() && !matches!(opts.method, Method::Wls) {
        return Err(Error::invalid(
            "identify",
            "reduce",
            "model reduction (paper 000 Algorithm 1) uses WLS: run it with method wls",
        ));
    }
    let uses_sample_weights = matches!(opts.method, Method::Wls | Method::Ml) && opts.weights == Weights::Sample;
    let Prepared {
        pr,
        filter,
        every,
        full,
        drop,
        rows_used,
        slow,
        vmin,
    } = prepare(robot, base, run, trajectory, opts, uses_sample_weights)?;
    let moving: Vec<bool> = (0..robot.dof())
        .map(|j| pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max) > opts.reduce.as_ref().map_or(0.05, |r| r.moving_speed))
        .collect();
    let mut projection = None;
    let mut ml = None;
    let mut reduction = None;
    let (cols, fit): (Vec<usize>, LsFit) = match opts.method {
        Method::Ols => ((0..base.n_base()).collect(), estimate::ols(&full)?),
        Method::Wls => match &opts.reduce {
            None => ((0..base.n_base()).collect(), estimate::wls(&full, opts.weights)?),
            Some(ro) => {
                let red = reduce::reduce(robot, base, &full, &moving, ro, ctl)?;
                let out = (red.kept.clone(), red.reduced.clone());
                reduction = Some(red);
                out
            }
        },
        Method::Projection => {
            let (f, info) = closed_loop::projection(&full, &pr, run, opts.decimate, &opts.projection)?;
            projection = Some(info);
            ((0..base.n_base()).collect(), f)
        }
        Method::Ml => {
            let start = estimate::wls(&full, opts.weights)?;
            let cols: Vec<usize> = (0..base.n_base()).collect();
            let (f, info) = closed_loop::ml(
                robot,
                base,
                &pr,
                closed_loop::MlStart {
                    cols: &cols,
                    theta: &start.theta,
                    scale: &start.std,
                },
                &opts.ml,
                ctl,
            )?;
            ml = Some(info);
            (cols, f)
        }
    };
    let ds = full.columns(&cols);
    let errors = estimate::errors(&ds, &fit.theta);
    let every_ds = every.columns(&cols);
    let errors_all = estimate::errors(&every_ds, &fit.theta);
    let mut val_every = None;
    let val_ds = match validation {
        Some((vrun, vtraj)) => {
            if vrun.n_joints() != robot.dof() {
                return Err(Error::dim("joints in the validation run", robot.dof(), vrun.n_joints()));
            }
            let vrun = &*in_joint_coordinates(robot, vrun, opts.coordinates)?;
            let vf = match (&opts.filter, vtraj) {
                (FilterChoice::Given(f), _) if !matches!(f, Filter::Fourier { .. }) => f.clone(),
                (_, Some(t)) => resolve_filter(&FilterChoice::Auto, Some(t), opts.harmonics),
                (_, None) => resolve_filter(&FilterChoice::Auto, None, None),
            };
            let vp = process_with(vrun, &vf, opts.velocity_from)?.decimated(opts.decimate);
            let ve = Dataset::every_row(robot, base, &vp).columns(&cols);
            let vd = ve.moving_rows_of(&vp, slow, vmin, &drop);
            val_every = Some(ve);
            Some(vd)
        }
        None => None,
    };
    let val_errors = val_ds.as_ref().map(|d| estimate::errors(d, &fit.theta));
    let val_errors_all = val_every.as_ref().map(|d| estimate::errors(d, &fit.theta));
    let consistent = match &opts.consistent {
        None => None,
        Some(co) => {
            let sw = match opts.method {
                Method::Wls => estimate::row_variances(&full, opts.weights)?.map(|v| 1.0 / v.sqrt()),
                _ => DVector::from_element(full.y.len(), 1.0),
            };
            let (mut c, sol) = consistent::fit(robot, base, &full, &sw, &fit.theta, co, ctl)?;
            let th = sol.base.as_slice();
            c.errors = estimate::errors(&ds, th);
            c.errors_all = estimate::errors(&every_ds, th);
            c.validation = val_ds.as_ref().map(|d| estimate::errors(d, th));
            c.validation_all = val_every.as_ref().map(|d| estimate::errors(d, th));
            Some(c)
        }
    };
    let positive = estimate::must_be_positive(robot, base);
    let implausible = cols
        .iter()
        .enumerate()
        .filter(|(i, &c)| positive[c] && fit.theta[*i] < 0.0)
        .map(|(i, &c)| Implausible {
            name: base.names[c].clone(),
            grouping: base.groupings[c].clone(),
            value: fit.theta[i],
            std: fit.std[i],
        })
        .collect();
    let status = if let Some(m) = &ml {
        EstimateStatus::Ml(m.status)
    } else if fit.rank < cols.len() {
        EstimateStatus::RankDeficient
    } else {
        EstimateStatus::Ok
    };
    let estimate = Estimate {
        status,
        method: opts.method,
        names: cols.iter().map(|&c| base.names[c].clone()).collect(),
        groupings: cols.iter().map(|&c| base.groupings[c].clone()).collect(),
        covariance: fit.cov.row_iter().map(|r| r.iter().copied().collect()).collect(),
        theta: fit.theta.clone(),
        std: fit.std.clone(),
        rel_std: fit.rel_std.clone(),
        rank: fit.rank,
        cond: fit.cond,
        cond_normalized: fit.cond_normalized,
        chi2_dof: fit.chi2_dof,
        errors,
        validation: val_errors,
        errors_all,
        rows_used,
        torque_source: None,
        validation_all: val_errors_all,
        standard_names: robot.param_names(),
        base_k: cols.iter().map(|&c| base.k.row(c).iter().copied().collect()).collect(),
        coordinates: opts.coordinates,
        averaged: run.averaged.is_some(),
        consistent,
        implausible,
        n_reps: pr.n_reps,
        n_samples: pr.len(),
        warnings: filter_warnings(&pr)
            .into_iter()
            .chain(
                crate::robot::export::inertial_warnings(robot)
                    .into_iter()
                    .map(|w| format!("nominal model: {w}")),
            )
            .collect(),
        filter_residual: pr.filter_residual.clone(),
        velocity: pr.velocity,
        filter,
        projection,
        ml,
        reduction,
        truth: None,
    };
    Ok(Identification {
        estimate,
        processed: pr,
        dataset: ds,
        validation: val_ds,
    })
}

/// A run in joint coordinates (runs logged motor-side mapped through the coupling).
pub fn in_joint_coordinates<'a>(robot: &Robot, run: &'a Run, coordinates: Coordinates) -> Result<std::borrow::Cow<'a, Run>> {
    Ok(match coordinates {
        Coordinates::Joint => std::borrow::Cow::Borrowed(run),
        Coordinates::Motor => {
            let mut r = run.clone();
            r.to_joint_coordinates(&robot.coupling_matrix())?;
            std::borrow::Cow::Owned(r)
        }
    })
}

/// A run ready for estimation ([`prepare`]).
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The processed (averaged, filtered, decimated) run.
    pub pr: Processed,
    /// The filter used.
    pub filter: Filter,
    /// Every sample's rows (every base column).
    pub every: Dataset,
    /// The rows the standstill rule keeps.
    pub full: Dataset,
    /// Per joint: the standstill rule drops its slow rows.
    pub drop: Vec<bool>,
    /// Per joint: the rows used and why.
    pub rows_used: Vec<RowsUsed>,
    /// Slow-row fraction applied.
    pub slow: f64,
    /// Slow-row speed applied.
    pub vmin: f64,
}

/// Processes a run (in joint coordinates) as `opts` says — filter, decimation,
/// standstill rule — and stacks its base regressor. With
/// `needs_sample_weights`, a run without repetitions or variances is an error
/// that names the alternatives.
pub fn prepare(
    robot: &Robot,
    base: &BaseParams,
    run: &Run,
    trajectory: Option<&FourierTrajectory>,
    opts: &IdentOptions,
    needs_sample_weights: bool,
) -> Result<Prepared> {
    let filter = resolve_filter(&opts.filter, trajectory, opts.harmonics);
    let pr = process_with(run, &filter, opts.velocity_from)?.decimated(opts.decimate);
    if !(opts.slow_ratio.is_finite() && (0.0..1.0).contains(&opts.slow_ratio)) {
        return Err(Error::invalid("identify", "slow_ratio", "expected a fraction in [0, 1)"));
    }
    if !(opts.min_speed.is_finite() && opts.min_speed >= 0.0) {
        return Err(Error::invalid("identify", "min_speed", "expected a speed ≥ 0"));
    }
    let (slow, vmin) = if matches!(opts.method, Method::Projection) {
        (0.0, 0.0)
    } else {
        (opts.slow_ratio, opts.min_speed)
    };
    if needs_sample_weights && pr.tau_var.is_none() {
        let file = run.files.first().map(|f| f.display().to_string()).unwrap_or_else(|| "run".into());
        return Err(Error::invalid(
            file,
            "--weights",
            format!(
                "the run has {} repetition and no variance columns, so sample weights (paper 000 eq. 7–9) are not possible; use --weights joint (per-joint residual variance of an OLS fit), --method ols, more repetitions, or an averaged run with var_tau1..var_tau{} columns and --repetitions N",
                run.reps.len(),
                robot.dof()
            ),
        ));
    }
    let drop: Vec<bool> = robot
        .drives
        .iter()
        .map(|d| match opts.standstill {
            Standstill::Auto => d.discontinuous_at_rest(),
            Standstill::Drop => true,
            Standstill::Keep => false,
        })
        .collect();
    let every = Dataset::every_row(robot, base, &pr);
    let full = every.moving_rows_of(&pr, slow, vmin, &drop);
    if full.c.nrows() <= full.c.ncols() && every.c.nrows() > every.c.ncols() {
        let vmax: Vec<String> = (0..robot.dof())
            .map(|j| format!("{:.3e}", pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max)))
            .collect();
        return Err(Error::invalid(run.files.first().map_or_else(|| "identify".to_string(), |f| f.display().to_string()), "min_speed", format!("no row is fast enough: {} of {} rows left after the speed rule |q̇_j| ≥ max({slow} · max |q̇_j|, {vmin} rad/s) (--slow-ratio, --min-speed), more than {} needed; largest |q̇_j| of the run: [{}] rad/s", full.c.nrows(), every.c.nrows(), full.c.ncols(), vmax.join(", "))));
    }
    let rows_used = rows_used(robot, &full, pr.len(), &drop, slow, vmin, opts);
    Ok(Prepared {
        pr,
        filter,
        every,
        full,
        drop,
        rows_used,
        slow,
        vmin,
    })
}

/// The rows of each joint in `full` and the standstill rule that chose them.
fn rows_used(robot: &Robot, full: &Dataset, total: usize, drop: &[bool], slow: f64, vmin: f64, opts: &IdentOptions) -> Vec<RowsUsed> {
    (0..robot.dof())
        .map(|j| {
            let used = full.joint.iter().filter(|&&k| k == j).count();
            let d = &robot.drives[j];
            let shape = if matches!(d.friction, crate::robot::Friction::None) {
                "no friction".to_string()
            } else {
                format!("Coulomb {}", d.coulomb.describe())
            };
            let reason = if matches!(opts.method, Method::Projection) {
                "every row kept: the projection method needs every sample".to_string()
            } else if slow <= 0.0 && vmin <= 0.0 {
                "every row kept: --slow-ratio 0 and --min-speed 0".to_string()
            } else if drop[j] {
                let why = match opts.standstill {
                    Standstill::Drop => "--standstill drop".to_string(),
                    _ => format!("{shape} is discontinuous at rest"),
                };
                format!("rows with |q̇| < max({slow}·max|q̇|, {vmin}) left out: {why}")
            } else {
                let why = match opts.standstill {
                    Standstill::Keep => "--standstill keep".to_string(),
                    _ => format!("{shape} is continuous at rest"),
                };
                format!("every row kept, standstill included: {why}")
            };
            RowsUsed {
                joint: robot.joints[j].name.clone(),
                used,
                total,
                slow_dropped: used < total,
                reason,
            }
        })
        .collect()
}

/// Joints whose filter residual exceeds 3× the noise of the averaged positions.
pub(crate) fn filter_warnings(pr: &Processed) -> Vec<String> {
    let mut w = Vec::new();
    for (j, (res, noise)) in pr.filter_residual.iter().enumerate() {
        if let Some(nz) = noise {
            if *res > 3.0 * nz && *res > 0.0 {
                let hint = match pr.filter {
                    Filter::Fourier { n_h, .. } => format!(
                        "the closed-loop response has harmonics above the {n_h} kept (tracking errors of a nonlinear plant); dropping them biases q̈: consider --harmonics {}",
                        4 * n_h
                    ),
                    Filter::LowPass { cutoff } => format!("the low-pass at {cutoff} Hz removes motion: consider a higher --cutoff"),
                    Filter::None => String::new(),
                };
                w.push(format!(
                    "joint {}: the filter removes {res:.3e} rad RMS from the averaged positions, {:.1}× their noise ({nz:.3e}); {hint}",
                    j + 1,
                    res / nz
                ));
            }
        }
    }
    w
}

/// The report's table of the estimated base parameters (one-run and study reports).
pub(crate) fn parameter_table(names: &[String], theta: &[f64], std: &[f64], rel_std: &[f64], groupings: &[String]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "\n{:>3} {:<10} {:>14} {:>12} {:>9}  grouping", "i", "parameter", "estimate", "std", "σ* (%)");
    for i in 0..names.len() {
        let _ = writeln!(
            s,
            "{:>3} {:<10} {:>14.6} {:>12.4e} {:>9.3}  {}",
            i + 1,
            names[i],
            theta[i],
            std[i],
            100.0 * rel_std[i],
            groupings[i]
        );
    }
    s
}

/// The report's blocks on negative base parameters that must be positive and
/// on the comparison with the truth (shared by one-run and study reports).
pub(crate) fn plausibility_and_truth_text(implausible: &[Implausible], truth: Option<&[TruthRow]>) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if implausible.is_empty() {
        let _ = writeln!(s, "\nphysical plausibility: every base parameter that must be positive is positive");
    } else {
        let _ = writeln!(s, "\nphysical plausibility: NEGATIVE estimates of parameters that must be positive:");
        for p in implausible {
            let _ = writeln!(s, "  {} = {:.6} (σ {:.3e}): {}", p.name, p.value, p.std, p.grouping);
        }
    }
    if let Some(t) = truth {
        let _ = writeln!(s, "\ncomparison with the true base parameters");
        let _ = writeln!(s, "{:<10} {:>14} {:>14} {:>8}", "parameter", "truth", "estimate", "z");
        for r in t {
            let _ = writeln!(s, "{:<10} {:>14.6} {:>14.6} {:>8.2}", r.name, r.truth, r.estimate, r.z);
        }
        let zmax = t.iter().map(|r| r.z.abs()).fold(0.0, f64::max);
        let _ = writeln!(s, "max |z| = {zmax:.2}");
    }
    s
}

impl Estimate {
    /// Adds the comparison with true base parameters (names must match the base parameters).
    pub fn compare_truth(&mut self, base_names: &[String], base_truth: &[f64]) -> Result<()> {
        let mut rows = Vec::new();
        for (i, nm) in self.names.iter().enumerate() {
            let k = base_names.iter().position(|x| x == nm).ok_or_else(|| {
                Error::invalid(
                    "truth",
                    "base_names",
                    format!("the truth file has no base parameter {nm:?} (different robot or base-parameter options?)"),
                )
            })?;
            rows.push(TruthRow {
                name: nm.clone(),
                truth: base_truth[k],
                estimate: self.theta[i],
                z: (self.theta[i] - base_truth[k]) / self.std[i],
            });
        }
        self.truth = Some(rows);
        Ok(())
    }

    /// The consistent block of the text report.
    fn consistent_text(&self, c: &Consistent) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "\nphysically consistent estimate (pseudo-inertias ⪰ {} I, drive signs; closest-to-nominal weight {}): {}",
            c.options.margin, c.options.regularization, c.status
        );
        let _ = writeln!(
            s,
            "  Clarabel: {} iterations, {:.1} ms; weighted SSR + {:.4e} over {} ({:.3} %); χ²/dof {:.4} (unconstrained {:.4})",
            c.iterations,
            1e3 * c.solve_time,
            c.extra_cost,
            self.method,
            100.0 * c.extra_cost_rel,
            c.chi2_dof,
            self.chi2_dof
        );
        let e_row = |s: &mut String, title: &str, a: &Errors, b: &Errors| {
            let _ = writeln!(s, "  {title}");
            let _ = writeln!(
                s,
                "  {:>5} {:>14} {:>14} {:>14} {:>14}",
                "joint", "e*_j uncons.", "e*_j consist.", "e_j uncons.", "e_j consist."
            );
            for j in 0..a.e.len().min(b.e.len()) {
                let _ = writeln!(
                    s,
                    "  {:>5} {:>13.3}% {:>13.3}% {:>14.4e} {:>14.4e}",
                    j + 1,
                    100.0 * a.e_rel[j],
                    100.0 * b.e_rel[j],
                    a.e[j],
                    b.e[j]
                );
            }
        };
        e_row(&mut s, "every sample of the identification run:", &self.errors_all, &c.errors_all);
        if let (Some(a), Some(b)) = (&self.validation_all, &c.validation_all) {
            e_row(&mut s, "every sample of the validation run:", a, b);
        }
        if c.active.is_empty() {
            let _ = writeln!(s, "  active constraints: none (the unconstrained estimate is consistent)");
        } else {
            let _ = writeln!(s, "  active constraints:");
            for a in &c.active {
                let what = if a.constraint == "pseudo_inertia" {
                    format!("pseudo-inertia of link `{}` (smallest eigenvalue − margin {:.3e})", a.what, a.value)
                } else {
                    format!("{} = {:.3e} at its sign bound", a.what, a.value)
                };
                let _ = writeln!(s, "    {what}");
            }
        }
        let _ = writeln!(
            s,
            "  smallest pseudo-inertia eigenvalues (kg·m²): [{}]",
            c.min_eigenvalue.iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>().join(", ")
        );
        let _ = writeln!(s, "  {:<10} {:>14} {:>14} {:>10}", "base", "unconstrained", "consistent", "Δ/σ");
        for i in 0..self.names.len() {
            let d = (c.base[i] - self.theta[i]) / self.std[i].max(1e-300);
            let _ = writeln!(s, "  {:<10} {:>14.6} {:>14.6} {:>10.2}", self.names[i], self.theta[i], c.base[i], d);
        }
        s
    }

    /// The text report (`report.txt`).
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "identification: method {}, status {}", self.method.words(), self.status);
        let _ = writeln!(
            s,
            "data: {} repetitions {}, {} samples per joint, {} coordinates, filter {}",
            self.n_reps,
            if self.averaged {
                "(averaged upstream, per-sample variances given)"
            } else {
                "averaged"
            },
            self.n_samples,
            self.coordinates,
            match &self.filter {
                Filter::Fourier { omega, n_h } => format!("Fourier (ω = {omega:.6} rad/s, {n_h} harmonics)"),
                Filter::LowPass { cutoff } => format!("zero-phase low-pass {cutoff} Hz + central differences"),
                Filter::None => "none (central differences)".into(),
            }
        );
        let _ = writeln!(s, "velocities: {}", self.velocity.words(&self.filter));
        for w in &self.warnings {
            let _ = writeln!(s, "WARNING: {w}");
        }
        if let Some(t) = &self.torque_source {
            let _ = writeln!(s, "{}", t.text());
        }
        let _ = writeln!(s, "rows used for the estimate (standstill rule):");
        for r in &self.rows_used {
            let _ = writeln!(s, "  {:<12} {:>7} of {:>7}  {}", r.joint, r.used, r.total, r.reason);
        }
        let _ = writeln!(
            s,
            "design matrix: {} parameters, rank {}, cond {:.4e} (unit-norm columns {:.4}), χ²/dof {:.4}",
            self.names.len(),
            self.rank,
            self.cond,
            self.cond_normalized,
            self.chi2_dof
        );
        if let Some(p) = &self.projection {
            let _ = writeln!(
                s,
                "projection method: FIR lags M1 = {}, M2 = {} ({}), instrument rank {}, corr(û, ũ) = [{}], explained = [{}]",
                p.m1,
                p.m2,
                p.rule,
                p.instrument_rank,
                p.corr.iter().map(|x| format!("{x:.1e}")).collect::<Vec<_>>().join(", "),
                p.explained.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", ")
            );
        }
        if let Some(m) = &self.ml {
            let _ = writeln!(
                s,
                "maximum likelihood: {} after {} evaluations, cost {:.6e} → {:.6e}",
                m.status, m.evaluations, m.cost_start, m.cost_end
            );
        }
        s.push_str(&parameter_table(&self.names, &self.theta, &self.std, &self.rel_std, &self.groupings));
        let err_block = |s: &mut String, title: &str, e: &Errors| {
            let _ = writeln!(s, "\n{title}");
            let _ = writeln!(
                s,
                "{:>5} {:>12} {:>9} {:>12} {:>12}",
                "joint", "e_j (N·m)", "e*_j (%)", "rms (N·m)", "noise floor"
            );
            for j in 0..e.e.len() {
                let nf = e.noise_floor.as_ref().map(|v| format!("{:.4e}", v[j])).unwrap_or_else(|| "-".into());
                let _ = writeln!(s, "{:>5} {:>12.4e} {:>9.3} {:>12.4e} {:>12}", j + 1, e.e[j], 100.0 * e.e_rel[j], e.rms[j], nf);
            }
        };
        err_block(
            &mut s,
            "prediction errors on every sample of the identification run (eq. 11–12)",
            &self.errors_all,
        );
        err_block(
            &mut s,
            "prediction errors on the rows used for the estimate (identification run, rows chosen by the standstill rule above)",
            &self.errors,
        );
        if let Some(v) = &self.validation_all {
            err_block(&mut s, "prediction errors on every sample of the validation run", v);
        }
        if let Some(v) = &self.validation {
            err_block(&mut s, "prediction errors on the validation run's rows selected like the estimate's", v);
        }
        if let Some(c) = &self.consistent {
            s.push_str(&self.consistent_text(c));
        }
        s.push_str(&plausibility_and_truth_text(&self.implausible, self.truth.as_deref()));
        if let Some(r) = &self.reduction {
            let _ = writeln!(s);
            s.push_str(&r.text());
        }
        s
    }
}

impl Identification {
    /// What status.json says of this identification: the estimate's state,
    /// failed when the consistent fit failed, interrupted when `interrupted`.
    pub fn state(&self, interrupted: bool) -> RunState {
        let e = &self.estimate;
        if interrupted {
            RunState::Interrupted
        } else if e.consistent.as_ref().is_some_and(|c| !c.status.is_ok()) {
            RunState::Failed
        } else {
            e.status.state()
        }
    }

    /// Why the result is not usable (None when it is): the words of the
    /// command line's exit-3 message.
    pub fn unusable_reason(&self) -> Option<String> {
        let e = &self.estimate;
        match e.consistent.as_ref().map(|c| &c.status) {
            Some(s) if !s.is_ok() => Some(format!("the consistent fit ended with status `{s}`")),
            _ if e.status.state() == RunState::Failed => Some(format!("the {} estimate ended with status `{}`", e.method.words(), e.status)),
            _ => None,
        }
    }

    /// Writes `status.json` into `dir` (command `identify`) with the state of
    /// [`Identification::state`]; `options` is what the run was asked
    /// (fingerprinted). Returns the state written.
    pub fn write_status(
        &self,
        dir: &std::path::Path,
        started: Option<std::time::SystemTime>,
        options: &serde_json::Value,
        interrupted: bool,
    ) -> Result<RunState> {
        let e = &self.estimate;
        let state = self.state(interrupted);
        let detail = format!("{}: {}", e.method.words(), e.status);
        let summary = serde_json::json!({ "method": e.method, "estimate_status": e.status });
        crate::io::status::write_status(dir, "identify", state, detail, started, crate::io::status::fingerprint_of(options)?, summary)?;
        Ok(state)
    }

    /// Writes `estimate.json`, `report.txt`, `torques.svg`, `residuals.svg`,
    /// `params.svg` (and `validation.svg`, `reduction.csv` and `reduction.svg`
    /// when present) into `dir`.
    pub fn write(&self, dir: &std::path::Path) -> Result<()> {
        use crate::io::plot::write_svg;
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        crate::io::write_json(&dir.join("estimate.json"), &self.estimate)?;
        crate::io::write_atomic(&dir.join("report.txt"), self.estimate.text().as_bytes())?;
        let th: &[f64] = &self.estimate.theta;
        let torque_panels = |ds: &Dataset, t: &[f64], resid: bool| output::torque_panels(ds, t, &[("predicted", th)], resid);
        let t = &self.processed.t;
        write_svg(
            &dir.join("torques.svg"),
            "measured vs predicted torque",
            &torque_panels(&self.dataset, t, false),
            2,
        )?;
        write_svg(&dir.join("residuals.svg"), "torque residuals", &torque_panels(&self.dataset, t, true), 2)?;
        if let Some(v) = &self.validation {
            let tv: Vec<f64> = (0..v.n_samples).map(|k| k as f64).collect();
            let mut panels = torque_panels(v, &tv, false);
            for p in &mut panels {
                p.x_label = "sample".into();
            }
            write_svg(&dir.join("validation.svg"), "validation run: measured vs predicted torque", &panels, 2)?;
        }
        let panels = output::params_panels(&self.estimate);
        write_svg(&dir.join("params.svg"), "identified base parameters", &panels, 1)?;
        if let Some(r) = &self.estimate.reduction {
            let mut csv = format!(
                "k,parameter,sensitivity,decision,growth,cond,n_params,{}\n",
                (1..=self.dataset.n).map(|j| format!("e_rel{j}")).collect::<Vec<_>>().join(",")
            );
            for st in &r.steps {
                csv.push_str(&format!(
                    "{},{},{},{},{},{},{},{}\n",
                    st.k,
                    st.parameter,
                    st.sensitivity,
                    st.decision,
                    st.growth,
                    st.cond,
                    st.n_params,
                    st.e_rel.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",")
                ));
            }
            crate::io::write_atomic(&dir.join("reduction.csv"), csv.as_bytes())?;
            let panels = output::reduction_panels(r);
            write_svg(&dir.join("reduction.svg"), "model reduction (Algorithm 1)", &panels, 2)?;
        }
        Ok(())
    }
}
