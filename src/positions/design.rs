//! The position-design file (`idexp positions designs/<file>.toml`) and the
//! library entry point [`run_design`] that turns it into a relaxed design and
//! an integer plan.
//!
//! ```toml
//! name = "positions_industrial6"
//! robot = "robots/industrial6.toml"   # relative to this file (needed for source = "rigid")
//! criterion = "d"                      # d | a | e
//! experiments = 15                     # M: whole experiments to allocate
//! seed = 1
//! # budget = 20.0                      # with costs: Σ c_i m_i ≤ budget (default: experiments)
//! # prior = "prior.json"               # p×p JSON array: information already available (one-experiment units)
//!
//! [information]
//! source = "rigid"                     # rigid | file | elastic (see [`super::elastic`])
//! parameters = "inertial"              # base parameters of the rigid body alone, or "all" (with drives/friction)
//! amplitude = 0.15                     # rad, one value or one per joint
//! period = 2.0                         # s
//! samples = 24                         # per period
//! noise = 1.0                          # N·m, one value or one per joint
//!
//! [candidates]
//! kind = "grid"                        # grid | random | file
//! joints = [2, 3, 5]                   # varied joints (1-based); the others stay at `fixed`
//! points = [7, 7, 5]
//! fixed = [0.0, -1.2, 1.0, 0.0, 0.5, 0.0]
//! [[candidates.workspace]]
//! shape = { type = "half_space", normal = [0, 0, 1], offset = 0.3 }
//!
//! [solver]                             # all optional, see relax::SolverOptions
//! tol = 1e-6
//! ```
//!
//! With `source = "elastic"` the `[information]` table names an elastic
//! design (`design = "elastic_industrial6.toml"`, optional `frequencies_hz`,
//! `noise`, `estimator`, `output`, `scale`), the robot is the elastic model's
//! (`robot` must be absent) and the candidates are its rigid joints.
//!
//! With `source = "file"` (see [`super::information`]) the candidates, their
//! joint values, costs and the prior come from the JSON file, and
//! `[candidates]` must be absent.

use super::candidates::CandidateSpec;
use super::elastic::{ElasticScale, ElasticSource};
use super::information::{InformationFile, InformationSource, RigidSource};
use super::problem::{Criterion, Problem};
use super::relax::{solve_relaxed, Relaxed, SolverOptions};
use super::rounding::{round_design, Rounded};
use crate::elastic::{Estimator, NoiseModel, Output};
use crate::error::{Error, Result};
use crate::optim::Control;
use crate::robot::{self, Robot, Workspace};
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One value for every joint, or one per joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerJoint {
    /// The same value for all joints.
    One(f64),
    /// One value per joint.
    Many(Vec<f64>),
}

impl PerJoint {
    /// The n values; errors unless positive and finite (or the wrong count).
    pub fn resolve(&self, n: usize, ctx: &str, field: &str) -> Result<Vec<f64>> {
        let v = match self {
            PerJoint::One(x) => vec![*x; n],
            PerJoint::Many(v) => v.clone(),
        };
        if v.len() != n {
            return Err(Error::invalid(
                ctx,
                field,
                format!("expected one value or {n} (one per joint), found {}", v.len()),
            ));
        }
        if v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(Error::invalid(ctx, field, "expected positive finite values"));
        }
        Ok(v)
    }
}

/// Which base parameters the rigid source estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum RigidParameters {
    /// Base parameters of the rigid-body (inertial) columns only.
    #[default]
    Inertial,
    /// All base parameters: inertial, rotor inertias, friction.
    All,
}

fn d_amp() -> PerJoint {
    PerJoint::One(0.1)
}
fn d_period() -> f64 {
    2.0
}
fn d_samples() -> usize {
    24
}
fn d_noise() -> PerJoint {
    PerJoint::One(1.0)
}

/// Where the information matrices come from (`[information]`, tag `source`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "source", rename_all = "lowercase", deny_unknown_fields)]
pub enum InformationSpec {
    /// A JSON information file (matrices or Jacobians), relative to the design file.
    File {
        /// The file.
        path: PathBuf,
    },
    /// The elastic gray-box model's FRF information (paper 001 eq. 5, see [`super::elastic`]).
    Elastic {
        /// Elastic design or model file holding a `[model]` table, relative to this file.
        design: PathBuf,
        /// Frequency lines (Hz). Default: the excited lines of the file's `[multisine]`
        /// (its defaults when the table is absent).
        #[serde(default)]
        frequencies_hz: Option<Vec<f64>>,
        /// Assumed noise on the FRF elements, e.g. `{ kind = "relative", rel = 0.02 }`.
        /// Default: relative, `[simulate].noise_rel` of the file, else 0.02.
        #[serde(default)]
        noise: Option<NoiseModel>,
        /// nls | lls | lls_magnitude. Default: `[fit].estimator` of the file, else lls.
        #[serde(default)]
        estimator: Option<Estimator>,
        /// FRF output: position | velocity | acceleration. Default: `[frf].output` of the file, else acceleration.
        #[serde(default)]
        output: Option<Output>,
        /// nominal (θ/θ_nom, default) | physical.
        #[serde(default)]
        scale: ElasticScale,
    },
    /// Rigid-body local excitation about each pose (see [`super::information`]).
    Rigid {
        /// inertial | all.
        #[serde(default)]
        parameters: RigidParameters,
        /// Amplitude per joint (rad or m).
        #[serde(default = "d_amp")]
        amplitude: PerJoint,
        /// Period (s).
        #[serde(default = "d_period")]
        period: f64,
        /// Samples per period.
        #[serde(default = "d_samples")]
        samples: usize,
        /// Torque noise standard deviation per joint.
        #[serde(default = "d_noise")]
        noise: PerJoint,
    },
}

fn d_experiments() -> usize {
    15
}
fn d_seed() -> u64 {
    1
}

/// A position-design file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionsDesign {
    /// Name (output folder `out/<name>`).
    pub name: String,
    /// Robot file, relative to the design file.
    #[serde(default)]
    pub robot: Option<PathBuf>,
    /// d | a | e.
    #[serde(default)]
    pub criterion: Criterion,
    /// Number of whole experiments M.
    #[serde(default = "d_experiments")]
    pub experiments: usize,
    /// Budget B for Σ c_i m_i ≤ B when candidates have costs (default: experiments).
    #[serde(default)]
    pub budget: Option<f64>,
    /// Seed of the random candidate sample.
    #[serde(default = "d_seed")]
    pub seed: u64,
    /// Prior information: JSON file holding a p×p array (one-experiment units).
    #[serde(default)]
    pub prior: Option<PathBuf>,
    /// Information source.
    pub information: InformationSpec,
    /// Candidate generation (not with source = "file").
    #[serde(default)]
    pub candidates: Option<CandidateSpec>,
    /// Solver options.
    #[serde(default)]
    pub solver: SolverOptions,
    /// Frame whose origin is plotted for the chosen poses (default: end effector).
    #[serde(default)]
    pub plot_frame: Option<String>,
}

impl PositionsDesign {
    /// Reads a design file.
    pub fn read(path: &Path) -> Result<PositionsDesign> {
        let d: PositionsDesign = crate::io::read_toml(path)?;
        d.validate(&path.display().to_string())?;
        if let Some(r) = &d.robot {
            crate::io::design_path(path, "robot", r)?;
        }
        Ok(d)
    }

    /// Checks the fields that do not need the robot, naming the field.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        if self.name.trim().is_empty() || self.name.contains(['/', '\\']) {
            return Err(Error::invalid(ctx, "name", "expected a non-empty name without path separators"));
        }
        if self.experiments == 0 {
            return Err(Error::invalid(ctx, "experiments", "expected at least 1"));
        }
        if let Some(b) = self.budget {
            if !(b.is_finite() && b >= 1.0) {
                return Err(Error::invalid(ctx, "budget", "expected a finite budget ≥ 1"));
            }
        }
        self.solver.validate(ctx)?;
        if self.solver.formulation == super::Formulation::Sdp && self.criterion != Criterion::D {
            return Err(Error::invalid(
                ctx,
                "solver.formulation",
                format!(
                    "formulation = \"sdp\" is the lifted log-det cone of the D criterion; criterion = \"{}\" is solved by its own formulation: remove `formulation` or use criterion = \"d\"",
                    match self.criterion {
                        Criterion::D => "d",
                        Criterion::A => "a",
                        Criterion::E => "e",
                    }
                ),
            ));
        }
        match &self.information {
            InformationSpec::File { .. } => {
                if self.candidates.is_some() {
                    return Err(Error::invalid(
                        ctx,
                        "candidates",
                        "with source = \"file\" the candidates come from the information file; remove [candidates]",
                    ));
                }
                if self.prior.is_some() {
                    return Err(Error::invalid(
                        ctx,
                        "prior",
                        "with source = \"file\" give the prior inside the information file",
                    ));
                }
            }
            InformationSpec::Elastic { frequencies_hz, noise, .. } => {
                if self.robot.is_some() {
                    return Err(Error::invalid(
                        ctx,
                        "robot",
                        "with source = \"elastic\" the robot is the elastic model's; remove `robot`",
                    ));
                }
                if self.candidates.is_none() {
                    return Err(Error::invalid(ctx, "candidates", "source = \"elastic\" needs a [candidates] section"));
                }
                if let Some(f) = frequencies_hz {
                    if f.is_empty() || f.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                        return Err(Error::invalid(
                            ctx,
                            "information.frequencies_hz",
                            "expected a non-empty list of positive frequencies (Hz)",
                        ));
                    }
                }
                if let Some(nm) = noise {
                    let (v, f) = match nm {
                        NoiseModel::Absolute { sigma } => (*sigma, "information.noise.sigma"),
                        NoiseModel::Relative { rel } => (*rel, "information.noise.rel"),
                    };
                    if !(v.is_finite() && v > 0.0) {
                        return Err(Error::invalid(ctx, f, format!("expected a positive finite noise level, found {v}")));
                    }
                }
            }
            InformationSpec::Rigid { period, samples, .. } => {
                if self.robot.is_none() {
                    return Err(Error::invalid(ctx, "robot", "source = \"rigid\" needs a robot file"));
                }
                if self.candidates.is_none() {
                    return Err(Error::invalid(ctx, "candidates", "source = \"rigid\" needs a [candidates] section"));
                }
                if !(period.is_finite() && *period > 0.0) {
                    return Err(Error::invalid(ctx, "information.period", "expected a positive period in seconds"));
                }
                if *samples < 2 || *samples > 10_000 {
                    return Err(Error::invalid(ctx, "information.samples", "expected 2..=10000 samples per period"));
                }
            }
        }
        Ok(())
    }
}

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct PositionsRun {
    /// The design as run (defaults filled in).
    pub design: PositionsDesign,
    /// The robot, if the design names one (shared with the information source).
    pub robot: Option<Arc<Robot>>,
    /// Parameter names (p).
    pub names: Vec<String>,
    /// Joint values per candidate (empty vectors when unknown).
    pub q: Vec<Vec<f64>>,
    /// Costs per candidate (None: all 1).
    pub costs: Option<Vec<f64>>,
    /// Rank of each candidate's information.
    pub ranks: Vec<usize>,
    /// Candidate generation counts: generated, rejected by limits, by workspace, by collision.
    pub generation: (usize, usize, usize, usize),
    /// The relaxed design.
    pub relaxed: Relaxed,
    /// The integer plan.
    pub rounded: Rounded,
    /// Budget used for rounding (M or B).
    pub budget: f64,
    /// Seconds spent computing information matrices.
    pub information_time: f64,
}

fn read_prior(path: &Path, p: usize) -> Result<DMatrix<f64>> {
    let text = crate::io::read_to_string(path)?;
    let rows: Vec<Vec<f64>> =
        serde_json::from_str(&text).map_err(|e| Error::parse(path, format!("line {}: {e} (expected a p×p array of numbers)", e.line())))?;
    let ctx = path.display().to_string();
    if rows.len() != p || rows.iter().any(|r| r.len() != p) {
        return Err(Error::invalid(ctx, "prior", format!("expected a {p}×{p} array (p = number of parameters)")));
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(Error::invalid(ctx, "prior", "expected finite numbers"));
    }
    let f0 = DMatrix::from_fn(p, p, |i, j| rows[i][j]);
    super::problem::psd_factor(&f0, &format!("{}: prior", path.display()))?;
    Ok(f0)
}

/// Runs a design: candidates, information, relaxed design, rounding.
/// `dir` is the folder of the design file (relative paths start there).
pub fn run_design(design: &PositionsDesign, dir: &Path, ctl: &Control) -> Result<PositionsRun> {
    let ctx = format!("positions design `{}` (files relative to {})", design.name, dir.display());
    design.validate(&ctx)?;
    let mut robot = match &design.robot {
        Some(r) => Some(Arc::new(robot::load(&dir.join(r))?)),
        None => None,
    };
    let t_info = std::time::Instant::now();
    let mut resolved = design.clone();
    let (names, q, factors, costs, prior, generation) = match &design.information {
        InformationSpec::File { path } => {
            let f = InformationFile::read(&dir.join(path))?;
            if let Some(r) = &robot {
                if let Some(q0) = f.q.first() {
                    if !q0.is_empty() && q0.len() != r.dof() {
                        return Err(Error::invalid(
                            f.path.display().to_string(),
                            "candidates[0].q",
                            format!("the robot has {} joints, the file gives {}", r.dof(), q0.len()),
                        ));
                    }
                }
            }
            let n = f.q.len();
            let costs = if f.has_costs { Some(f.costs.clone()) } else { None };
            (f.names.clone(), f.q.clone(), f.factors.clone(), costs, f.prior.clone(), (n, 0, 0, 0))
        }
        InformationSpec::Elastic {
            design: file,
            frequencies_hz,
            noise,
            estimator,
            output,
            scale,
        } => {
            let (model, set) = super::elastic::load_elastic(&dir.join(file), frequencies_hz.as_deref(), *noise, *estimator, *output)?;
            let spec = design
                .candidates
                .as_ref()
                .ok_or_else(|| Error::invalid(&ctx, "candidates", "source = \"elastic\" needs a [candidates] section"))?;
            // static positions: no margin to the joint limits
            let c = spec.generate(&model.rigid, &vec![0.0; model.n_motors()], design.seed, dir, &ctx)?;
            resolved.information = InformationSpec::Elastic {
                design: file.clone(),
                frequencies_hz: Some(set.frequencies_hz.clone()),
                noise: Some(set.noise),
                estimator: Some(set.estimator),
                output: Some(set.output),
                scale: *scale,
            };
            let omegas: Vec<f64> = set.frequencies_hz.iter().map(|f| 2.0 * std::f64::consts::PI * f).collect();
            // the source owns the model (its rigid robot is the run's robot, handed back below, not cloned)
            let src = ElasticSource::new(model, omegas, set.noise, set.estimator, set.output, *scale)?;
            let obs = ctl.observer();
            obs.phase("information", Some(c.q.len() as u64));
            let n_done = std::sync::atomic::AtomicU64::new(0);
            let factors: Vec<Result<DMatrix<f64>>> =
                c.q.par_iter()
                    .map_init(Vec::new, |buf, q| {
                        if ctl.interrupted() {
                            return Err(Error::Interrupted);
                        }
                        let h = src.factor_with(q, buf);
                        obs.progress(n_done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, "");
                        h
                    })
                    .collect();
            obs.phase_done();
            let factors = factors.into_iter().collect::<Result<Vec<_>>>()?;
            let prior = match &design.prior {
                Some(pp) => {
                    // the prior is given in physical units: F0_s = S F0 S
                    let f0 = read_prior(&dir.join(pp), src.n_params())?;
                    let s = &src.scaling;
                    Some(DMatrix::from_fn(f0.nrows(), f0.ncols(), |i, j| s[i] * f0[(i, j)] * s[j]))
                }
                None => None,
            };
            let names = src.names();
            robot = Some(Arc::new(src.model.rigid));
            (
                names,
                c.q,
                factors,
                c.costs,
                prior,
                (c.generated, c.rejected_limits, c.rejected_workspace, c.rejected_collision),
            )
        }
        InformationSpec::Rigid {
            parameters,
            amplitude,
            period,
            samples,
            noise,
        } => {
            // the source owns the robot while it computes; handed back below, not cloned
            let r = robot
                .take()
                .ok_or_else(|| Error::invalid(&ctx, "robot", "source = \"rigid\" needs a robot file"))?;
            let n = r.dof();
            let amp = amplitude.resolve(n, &ctx, "information.amplitude")?;
            let sig = noise.resolve(n, &ctx, "information.noise")?;
            let spec = design
                .candidates
                .as_ref()
                .ok_or_else(|| Error::invalid(&ctx, "candidates", "source = \"rigid\" needs a [candidates] section"))?;
            let c = spec.generate(&r, &amp, design.seed, dir, &ctx)?;
            let src = RigidSource::new(r, &c.q, *parameters == RigidParameters::Inertial, amp, *period, *samples, sig)?;
            let obs = ctl.observer();
            obs.phase("information", Some(c.q.len() as u64));
            let n_done = std::sync::atomic::AtomicU64::new(0);
            let factors: Vec<Result<DMatrix<f64>>> =
                c.q.par_iter()
                    .map_init(
                        || Workspace::new(&src.robot),
                        |ws, q| {
                            let h = src.factor_with(ws, q);
                            obs.progress(n_done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, "");
                            h
                        },
                    )
                    .collect();
            obs.phase_done();
            let factors = factors.into_iter().collect::<Result<Vec<_>>>()?;
            let prior = match &design.prior {
                Some(pp) => Some(read_prior(&dir.join(pp), src.n_params())?),
                None => None,
            };
            let names = src.names();
            robot = Some(src.robot);
            (
                names,
                c.q,
                factors,
                c.costs,
                prior,
                (c.generated, c.rejected_limits, c.rejected_workspace, c.rejected_collision),
            )
        }
    };
    let information_time = t_info.elapsed().as_secs_f64();
    if ctl.interrupted() {
        return Err(Error::Interrupted);
    }
    let p = names.len();
    let budget = design.budget.unwrap_or(design.experiments as f64);
    // the relaxed problem is normalised by the number of experiments (budget): F0/M + Σ w_i F_i
    let prior_n = prior.map(|f0| f0 / budget);
    let base = Problem::from_factors(p, &factors, prior_n.as_ref())?;
    let pb = match &costs {
        Some(c) => base.divided_by(c),
        None => base,
    };
    let ranks: Vec<usize> = (0..pb.n()).map(|i| pb.rank(i)).collect();
    identifiable(&ctx, &factors, prior_n.as_ref(), &names, &ranks, design.experiments, costs.is_some())?;
    let relaxed = solve_relaxed(&pb, design.criterion, &design.solver, ctl)?;
    let rounded = round_design(&pb, design.criterion, &relaxed, budget, costs.as_deref(), ctl)?;
    Ok(PositionsRun {
        design: resolved,
        robot,
        names,
        q,
        costs,
        ranks,
        generation,
        relaxed,
        rounded,
        budget,
        information_time,
    })
}

/// Refuses, before any solve, a problem no design can identify: the
/// information of all candidates together (Σ H_i H_iᵀ + prior, with the
/// parameters scaled to unit diagonal) of rank r < p, or, without a prior,
/// M experiments whose information can reach at most the sum of the M
/// largest candidate ranks < p.
fn identifiable(
    ctx: &str,
    factors: &[DMatrix<f64>],
    prior: Option<&DMatrix<f64>>,
    names: &[String],
    ranks: &[usize],
    experiments: usize,
    has_costs: bool,
) -> Result<()> {
    let p = names.len();
    if factors.is_empty() || p == 0 {
        return Ok(());
    }
    let mut g = DMatrix::<f64>::zeros(p, p);
    for h in factors {
        if h.nrows() == p {
            g += h * h.transpose();
        }
    }
    if let Some(f0) = prior {
        if f0.shape() == (p, p) {
            g += f0;
        }
    }
    if g.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(
            ctx,
            "information",
            "the candidates' information matrices hold non-finite values",
        ));
    }
    let d: Vec<f64> = (0..p).map(|i| g[(i, i)]).collect();
    if let Some(i) = d.iter().position(|v| v.is_nan() || *v <= 0.0) {
        return Err(Error::invalid(
            ctx,
            "information",
            format!(
                "no candidate carries information on parameter `{}`: no design can identify it (remove it, add candidates that excite it, or give a prior)",
                names[i]
            ),
        ));
    }
    let gs = DMatrix::from_fn(p, p, |i, j| g[(i, j)] / (d[i] * d[j]).sqrt());
    let ev = gs.symmetric_eigenvalues();
    let emax = ev.max();
    let rank = ev.iter().filter(|&&e| e > 1e-10 * emax).count();
    if rank < p {
        return Err(Error::invalid(
            ctx,
            "candidates",
            format!(
                "the information of all {} candidates together has rank {rank} < p = {p} parameters (candidate ranks {}): no design of them can identify every parameter; add candidates, a prior, or fewer parameters",
                factors.len(),
                summarize_ranks(ranks)
            ),
        ));
    }
    if prior.is_none() && !has_costs {
        let mut r: Vec<usize> = ranks.to_vec();
        r.sort_unstable_by(|a, b| b.cmp(a));
        let reach: usize = r.iter().take(experiments).sum();
        if reach < p {
            let need = {
                let mut acc = 0;
                r.iter()
                    .take_while(|&&x| {
                        let before = acc;
                        acc += x;
                        before < p
                    })
                    .count()
            };
            return Err(Error::invalid(
                ctx,
                "experiments",
                format!(
                    "{experiments} experiment(s) at candidates of rank ≤ {} reach an information of rank ≤ {reach} < p = {p}: every whole design would be singular (efficiency 0); expected experiments ≥ {need}",
                    r[0]
                ),
            ));
        }
    }
    Ok(())
}

/// "6 ×2, 3 ×10": the distinct candidate ranks with their counts.
fn summarize_ranks(ranks: &[usize]) -> String {
    let mut r = ranks.to_vec();
    r.sort_unstable_by(|a, b| b.cmp(a));
    r.dedup();
    r.iter()
        .map(|v| format!("{v} ×{}", ranks.iter().filter(|x| *x == v).count()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Convenience for library users: solve a relaxed design for matrices F_i.
pub fn design_from_matrices(mats: &[DMatrix<f64>], prior: Option<&DMatrix<f64>>, crit: Criterion, opts: &SolverOptions, ctl: &Control) -> Result<Relaxed> {
    let pb = Problem::from_matrices(mats, prior)?;
    solve_relaxed(&pb, crit, opts, ctl)
}
