//! The information of one repetition of each candidate, the prior's, the
//! task's Gram matrix and the targets as vectors, in one parameter space.
//!
//! **One repetition's information.** The candidate's simulate design is run
//! once without noise (nominal parameters, one repetition) and processed
//! exactly as the study will process it ([`crate::ident::study::load_entry_with`]
//! with the candidate's `identify` keys: its filter, decimation and standstill
//! rule). The study filters the *positions* (to get q, q̇, q̈) but not the
//! torques, and averages the repetitions sample by sample: each kept row i of
//! the base regressor, c_iᵀ (joint j_i), is one independent torque sample of
//! variance σ²_{j_i}/r after r repetitions. The effective number of samples
//! is therefore the rows the study keeps (after decimation and the
//! standstill rule), stated per experiment, and
//!
//! F_e = Σ_i c_i c_iᵀ / σ²_{j_i}   (n_b × n_b, per repetition),
//!
//! so r_e repetitions carry r_e F_e. Position noise reaches the rows only
//! through the filtered q, q̇, q̈ (an error-in-variables term the plan
//! neglects; the rehearsal measures it).
//!
//! **The space.** Without a prior the plan works on the base parameters β:
//! Φ(r) = Σ r_e F_e; a standard parameter is a target only if it is
//! estimable (e_j = Kᵀa for some a: then its σ is that of aᵀβ). With the
//! study's Euclidean prior it works on the standard parameters θ, as the
//! consistent fit does (min ‖R(Kθ − β̂)‖² + w Σ u_j((θ_j − θ₀,j)/s_j)², u_j =
//! [`crate::ident::prior::UNKNOWN_PULL`] for an unknown drive parameter,
//! else 1): Φ(r) = Kᵀ(Σ r_e F_e)K + Λ, Λ = diag(w u_j / s_j²), the posterior
//! information (active consistency constraints are not modelled).

use super::design::{CandidateNoise, CandidateSpec, PlanDesign, TargetSpec};
use crate::error::{Error, Result};
use crate::ident::study::{load_entry_with, EntryOptions, ExperimentSpec, Given, Prior, UnknownRule, UnknownSpec, WeightSpec};
use crate::ident::{Method, Run};
use crate::optim::Control;
use crate::params::{BaseOptions, BaseParams};
use crate::robot::Robot;
use crate::sim::{NoiseSpec, SimDesign, SimResult, SimSetup, TruthSpec};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The parameter space the plan works in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Space {
    /// Base parameters (no prior).
    Base,
    /// Standard parameters (with the prior).
    Standard,
}

/// One candidate experiment, modelled.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// Name.
    pub name: String,
    /// Seconds per repetition.
    pub cost: f64,
    /// Seconds paid once if it is used at all.
    pub setup: f64,
    /// Largest repetitions.
    pub max_repetitions: usize,
    /// σ per joint of one repetition's torque rows (N·m): the equation error the study sees.
    pub sigma: Vec<f64>,
    /// Where σ comes from: `given`, or the residuals of one simulated repetition.
    pub noise_source: String,
    /// Per joint, the RMS residual of the noise-free run's least-squares fit
    /// (N·m): what the model does not explain even without noise, the same in
    /// every repetition — averaging cannot lower it (a bias, not a spread).
    pub repeatable: Vec<f64>,
    /// Duration of one recorded repetition (s).
    pub duration: f64,
    /// Samples per joint of one repetition as recorded.
    pub samples: usize,
    /// Rows the study keeps per repetition (all joints): the effective number of samples.
    pub rows: usize,
    /// Rank of its own information.
    pub rank: usize,
    /// The simulate design (resolved path).
    pub simulate: PathBuf,
    /// How the study processes it (name set, files empty).
    pub spec: ExperimentSpec,
    /// One repetition's information F_e in the base parameters (n_b × n_b).
    #[serde(skip)]
    pub info: DMatrix<f64>,
}

/// A task trajectory, modelled.
#[derive(Debug, Clone, Serialize)]
pub struct Task {
    /// The simulate design (resolved path).
    pub simulate: PathBuf,
    /// Rows (samples × joints).
    pub rows: usize,
    /// YᵀY / rows (n_b × n_b): the mean squared prediction error is tr(G Σ_β).
    #[serde(skip)]
    pub gram: DMatrix<f64>,
}

/// What a target bounds.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TargetKind {
    /// σ of one linear function cᵀx of the plan's parameters.
    Parameter {
        /// Its name.
        name: String,
        /// `base` or `standard`.
        of: String,
        /// Its nominal value.
        nominal: f64,
        /// Whether the data can see it at all (estimable from some experiment set).
        identifiable: bool,
    },
    /// RMS torque-prediction error on a task.
    Task {
        /// Index into [`Model::tasks`].
        task: usize,
    },
}

/// One target, resolved.
#[derive(Debug, Clone, Serialize)]
pub struct Target {
    /// Label in reports (`σ(ZZ2)`, `rms(task)`).
    pub label: String,
    /// What it bounds.
    pub kind: TargetKind,
    /// The bound (σ in the parameter's unit, or N·m RMS).
    pub bound: f64,
    /// For a parameter target: c in the plan's space (σ² = cᵀΦ⁻¹c).
    #[serde(skip)]
    pub c: DVector<f64>,
}

/// The planning problem.
#[derive(Debug, Clone)]
pub struct Model {
    /// The robot.
    pub robot: Robot,
    /// Its base parameters.
    pub base: BaseParams,
    /// The space.
    pub space: Space,
    /// Parameter names of the space.
    pub names: Vec<String>,
    /// Nominal values in the space.
    pub nominal: DVector<f64>,
    /// The candidates.
    pub candidates: Vec<Candidate>,
    /// The tasks.
    pub tasks: Vec<Task>,
    /// The targets.
    pub targets: Vec<Target>,
    /// Prior information Λ (diagonal, in the standard space), if any.
    pub prior: Option<DVector<f64>>,
    /// Notes for the report.
    pub notes: Vec<String>,
    /// Targets are planned at bound / (1 + margin).
    pub margin: f64,
    /// Total robot time available (s), if any.
    pub budget: Option<f64>,
}

impl Model {
    /// Dimension of the space.
    pub fn dim(&self) -> usize {
        self.names.len()
    }

    /// One repetition's information of candidate `e` in the plan's space.
    pub fn info(&self, e: usize) -> DMatrix<f64> {
        let f = &self.candidates[e].info;
        match self.space {
            Space::Base => f.clone(),
            Space::Standard => self.base.k.transpose() * f * &self.base.k,
        }
    }

    /// The task's Gram matrix in the plan's space.
    pub fn task_gram(&self, t: usize) -> DMatrix<f64> {
        let g = &self.tasks[t].gram;
        match self.space {
            Space::Base => g.clone(),
            Space::Standard => self.base.k.transpose() * g * &self.base.k,
        }
    }
}

/// Runs a simulate design with `repetitions` repetitions; `noise_free` zeroes
/// its noise (the plan's model; the truth stays); `seed` replaces its seed
/// (the noise) and `truth` its true parameters (by default the design's
/// truth, kept when the seed changes).
pub fn simulate(
    path: &Path,
    repetitions: usize,
    noise_free: bool,
    seed: Option<u64>,
    truth: Option<&TruthSpec>,
    ctl: &Control,
) -> Result<(SimResult, SimDesign)> {
    let mut d = SimDesign::read(path)?;
    d.repetitions = repetitions;
    if let Some(t) = truth {
        d.truth = t.clone();
    }
    if noise_free {
        d.noise = NoiseSpec::default();
    }
    if let Some(s) = seed {
        d.truth.seed = Some(d.truth.seed.unwrap_or(d.seed));
        d.seed = s;
    }
    let ctx = path.display().to_string();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let setup = SimSetup::from_design(&d, &dir, &ctx)?;
    Ok((setup.run(ctl)?, d))
}

/// [`Candidate::noise_source`] of the default: σ from the study's residuals on one simulated repetition.
pub const SIMULATED_NOISE: &str = "the residuals of one simulated repetition";

/// The effective noise per joint of one repetition: the study's own
/// residual σ (per joint, [`crate::ident::study::ExperimentReport::sigma`])
/// when it identifies one simulated repetition (the design's seed and truth,
/// with its noise). It holds the sensor noise and everything else the
/// filtered regressor does not explain — above all the controller's torque
/// reaction to position noise (k_d times the differentiated noise), often
/// far above the torque sensor's σ.
fn effective_sigma(robot: &Robot, design: &PlanDesign, c: &CandidateSpec, path: &Path, dir: &Path, ctl: &Control) -> Result<Vec<f64>> {
    let (sim, _) = simulate(path, 1, false, None, None, ctl)?;
    let mut study = crate::ident::study::StudyDesign::one_experiment("noise", design.robot.clone(), spec_of(c));
    study.weights = crate::ident::study::WeightSource::Residuals;
    let mut inputs = crate::ident::study::Inputs {
        robot: Some(robot.clone()),
        ..Default::default()
    };
    inputs.entries.insert(c.name.clone(), given_of(&sim)?);
    let quiet = Control::new().with_stop(ctl.stop_flag().clone());
    let r = crate::ident::study::run_study_with(&study, dir, &inputs, &quiet)?;
    Ok(r.estimate.experiments[0].sigma.clone())
}

/// σ per joint of one repetition from a finished study's estimate.json:
/// `experiments[k].sigma` (the residual σ per joint of its averaged rows,
/// the torque noise its weights stand for) × √`experiments[k].n_reps` (the
/// study averages its repetitions sample by sample). Experiment k is
/// `experiment`, else the one named `candidate`, else the only one. A joint
/// without rows there (`weights` `no_rows`) keeps σ = 0 (an error later if
/// the candidate has rows on it); every other σ must be positive. Also
/// returns where σ comes from, for the report.
pub fn sigma_from_estimate(file: &Path, experiment: Option<&str>, candidate: &str, n: usize) -> Result<(Vec<f64>, String)> {
    let ctx = file.display().to_string();
    let v: serde_json::Value = serde_json::from_str(&crate::io::read_to_string(file)?)
        .map_err(|e| Error::parse(file, format!("not JSON ({e}): expected a study's estimate.json (`idexp identify` writes it)")))?;
    let exps = v.get("experiments").and_then(|x| x.as_array()).ok_or_else(|| {
        Error::invalid(
            &ctx,
            "experiments",
            "missing: expected a study's estimate.json (`idexp identify` writes it), with an `experiments` list",
        )
    })?;
    let name_of = |e: &serde_json::Value| e.get("name").and_then(|x| x.as_str()).unwrap_or("").to_string();
    let names: Vec<String> = exps.iter().map(name_of).collect();
    let k = match experiment {
        Some(want) => names
            .iter()
            .position(|x| x == want)
            .ok_or_else(|| Error::invalid(&ctx, "experiments", format!("no experiment named `{want}` (it has: {})", names.join(", "))))?,
        None => match names.iter().position(|x| x == candidate) {
            Some(k) => k,
            None if names.len() == 1 => 0,
            None => {
                return Err(Error::invalid(
                    &ctx,
                    "experiments",
                    format!(
                        "{} experiments ({}) and none named `{candidate}`: say which, noise = {{ from = \"…\", experiment = \"<name>\" }}",
                        names.len(),
                        names.join(", ")
                    ),
                ))
            }
        },
    };
    let e = &exps[k];
    let field = |f: &str| format!("experiments[{k}].{f}");
    let sigma: Vec<f64> = e
        .get("sigma")
        .and_then(|x| x.as_array())
        .ok_or_else(|| Error::invalid(&ctx, field("sigma"), "missing: expected the residual σ per joint (N·m)"))?
        .iter()
        .map(|x| x.as_f64().unwrap_or(f64::NAN))
        .collect();
    if sigma.len() != n {
        return Err(Error::invalid(
            &ctx,
            field("sigma"),
            format!("has {} values, the plan's robot has {n} joints: a study of another robot?", sigma.len()),
        ));
    }
    let weights: Vec<String> = e
        .get("weights")
        .and_then(|x| x.as_array())
        .map(|a| a.iter().map(|w| w.as_str().unwrap_or("").to_string()).collect())
        .unwrap_or_default();
    if let Some(j) = weights.iter().position(|w| w == "unit") {
        return Err(Error::invalid(
            &ctx,
            field(&format!("weights[{j}]")),
            "`unit`: the study used ordinary least squares, its σ is not a noise estimate; plan from a weighted study (weights = \"auto\" or \"residuals\")",
        ));
    }
    let reps = e
        .get("n_reps")
        .and_then(|x| x.as_u64())
        .filter(|&r| r >= 1)
        .ok_or_else(|| Error::invalid(&ctx, field("n_reps"), "missing or below 1: expected the study's number of averaged repetitions"))?;
    for (j, &s) in sigma.iter().enumerate() {
        let no_rows = weights.get(j).is_some_and(|w| w == "no_rows");
        if !(s.is_finite() && (s > 0.0 || (no_rows && s == 0.0))) {
            return Err(Error::invalid(
                &ctx,
                field(&format!("sigma[{j}]")),
                format!("σ of joint {} is {s}: expected a positive number of N·m", j + 1),
            ));
        }
    }
    let f = (reps as f64).sqrt();
    Ok((
        sigma.iter().map(|s| s * f).collect(),
        format!(
            "{ctx} experiments[{k}] (`{}`): the study's residual σ of {reps} averaged repetition(s) × √{reps}",
            names[k]
        ),
    ))
}

/// The study's in-memory form of a simulated run.
pub fn given_of(sim: &SimResult) -> Result<Given> {
    Ok(Given {
        run: Run::new(vec![], sim.reps.clone())?,
        trajectory: sim.setup.reference.fourier().cloned(),
        torque_source: crate::data::TorqueSource::logged_torques(),
    })
}

/// The study's experiment entry of a candidate (its `identify` keys, its name).
pub fn spec_of(c: &CandidateSpec) -> ExperimentSpec {
    let mut s = c.identify.clone().unwrap_or_else(|| ExperimentSpec::new(vec![]));
    s.name = c.name.clone();
    s
}

fn processed(robot: &Robot, base: &BaseParams, spec: &ExperimentSpec, sim: &SimResult, dir: &Path) -> Result<crate::ident::Prepared> {
    let given = given_of(sim)?;
    let o = EntryOptions {
        method: Method::Wls,
        sample_limit: 5_000_000,
        dead_band: crate::ident::DEAD_BAND,
        allow_incomplete: false,
        given: Some(&given),
    };
    Ok(load_entry_with(robot, base, spec, dir, &o)?.prep)
}

/// Builds the planning problem of `design` (paths relative to `dir`).
pub fn build(design: &PlanDesign, dir: &Path, ctl: &Control) -> Result<Model> {
    let robot = crate::robot::load(&crate::io::path_in("plan", dir, "robot", &design.robot)?)?;
    let base = BaseParams::compute(&robot, &BaseOptions::default())?;
    let n = robot.dof();
    let nb = base.n_base();
    let mut notes = Vec::new();
    let mut candidates = Vec::new();
    for (i, c) in design.experiment.iter().enumerate() {
        let at = format!("plan: experiment {} ({})", i + 1, c.name);
        let path = crate::io::path_in(&at, dir, "simulate", &c.simulate)?;
        let d = SimDesign::read(&path)?;
        let (sigma, noise_source) = match &c.noise {
            Some(CandidateNoise::Given(p)) => (p.resolve(n, &at, "noise")?, "given".to_string()),
            Some(CandidateNoise::From(f)) => {
                let file = crate::io::path_in(&at, dir, "noise.from", &f.from)?;
                sigma_from_estimate(&file, f.experiment.as_deref(), &c.name, n)?
            }
            None => (
                effective_sigma(&robot, design, c, &path, dir, ctl)
                    .map_err(|e| Error::invalid(&at, "noise", format!("cannot estimate the effective noise from one simulated repetition: {e}")))?,
                SIMULATED_NOISE.to_string(),
            ),
        };
        if d.robot.file_name() != design.robot.file_name() {
            notes.push(format!("experiment {}: its simulate design's robot {} is not the plan's robot file {} (the motion is simulated with the former, identified with the latter)", c.name, d.robot.display(), design.robot.display()));
        }
        let (sim, _) = simulate(&path, 1, true, None, None, ctl)?;
        let spec = spec_of(c);
        let prep = processed(&robot, &base, &spec, &sim, dir)
            .map_err(|e| Error::invalid(&at, "identify", format!("the study cannot process its simulated run: {e}")))?;
        let ds = &prep.full;
        if let Some(j) = (0..n).find(|&j| ds.joint.contains(&j) && !(sigma[j].is_finite() && sigma[j] > 0.0)) {
            return Err(Error::invalid(
                &at,
                "noise",
                format!(
                    "σ of joint {} is {} ({}): an experiment without noise would carry infinite information; give noise = σ (N·m) per joint",
                    j + 1,
                    sigma[j],
                    noise_source
                ),
            ));
        }
        let mut info = DMatrix::zeros(nb, nb);
        for (r, &j) in ds.joint.iter().enumerate() {
            let row = ds.c.row(r);
            info.ger(1.0 / (sigma[j] * sigma[j]), &row.transpose(), &row.transpose(), 1.0);
        }
        let rank = rank_of(&info);
        let repeatable = repeatable_residual(ds, n);
        let t = &sim.reps[0].t;
        candidates.push(Candidate {
            name: c.name.clone(),
            cost: c.cost,
            setup: c.setup,
            max_repetitions: c.max_repetitions.unwrap_or(design.max_repetitions),
            sigma,
            noise_source,
            repeatable,
            duration: t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0),
            samples: t.len(),
            rows: ds.c.nrows(),
            rank,
            simulate: path,
            spec,
            info,
        });
    }
    // the prior
    let (space, prior) = match &design.consistent {
        None => (Space::Base, None),
        Some(cs) => {
            let prior_robot = match &cs.prior {
                Prior::Nominal => None,
                Prior::File(p) => Some(crate::robot::load(&crate::io::path_in("plan: [consistent]", dir, "prior", p)?)?),
            };
            let (theta0, s) = crate::ident::prior::prior_of(&robot, prior_robot.as_ref(), cs.scale)?;
            let w = match cs.weight {
                WeightSpec::Value(w) => w,
                _ => return Err(Error::invalid("plan: [consistent]", "weight", "expected a positive number")),
            };
            let unknown = unknown_flags(&robot, &theta0, &cs.unknown)?;
            let lambda = DVector::from_iterator(
                theta0.len(),
                (0..theta0.len()).map(|j| w * if unknown[j] { crate::ident::prior::UNKNOWN_PULL } else { 1.0 } / (s[j] * s[j])),
            );
            (Space::Standard, Some(lambda))
        }
    };
    let std_names = robot.param_names();
    let theta_nom = robot.nominal_params();
    let (names, nominal) = match space {
        Space::Base => (base.names.clone(), &base.k * &theta_nom),
        Space::Standard => (std_names.clone(), theta_nom.clone()),
    };
    // tasks and targets
    let mut tasks: Vec<Task> = Vec::new();
    let mut targets = Vec::new();
    let kt = base.k.transpose();
    for (i, t) in design.target.iter().enumerate() {
        let at = format!("plan: target {}", i + 1);
        targets.push(resolve_target(t, &at, dir, &robot, &base, space, &std_names, &theta_nom, &kt, &mut tasks, ctl)?);
    }
    Ok(Model {
        robot,
        base,
        space,
        names,
        nominal,
        candidates,
        tasks,
        targets,
        prior,
        notes,
        margin: design.margin,
        budget: design.budget,
    })
}

#[allow(clippy::too_many_arguments)]
fn resolve_target(
    t: &TargetSpec,
    at: &str,
    dir: &Path,
    robot: &Robot,
    base: &BaseParams,
    space: Space,
    std_names: &[String],
    theta_nom: &DVector<f64>,
    kt: &DMatrix<f64>,
    tasks: &mut Vec<Task>,
    ctl: &Control,
) -> Result<Target> {
    let nb = base.n_base();
    if let (Some(task), Some(rms)) = (&t.task, t.rms) {
        let path = crate::io::path_in(at, dir, "task", task)?;
        let idx = match tasks.iter().position(|x| x.simulate == path) {
            Some(k) => k,
            None => {
                let (sim, _) = simulate(&path, 1, true, None, None, ctl)?;
                let mut spec = ExperimentSpec::new(vec![]);
                spec.name = "task".into();
                let prep = processed(robot, base, &spec, &sim, dir)
                    .map_err(|e| Error::invalid(at, "task", format!("cannot process the task's simulated run: {e}")))?;
                let y = &prep.every.c;
                let rows = y.nrows().max(1);
                tasks.push(Task {
                    simulate: path.clone(),
                    rows: y.nrows(),
                    gram: y.transpose() * y / rows as f64,
                });
                tasks.len() - 1
            }
        };
        let stem = path.file_stem().map_or_else(|| "task".into(), |s| s.to_string_lossy().into_owned());
        return Ok(Target {
            label: format!("rms({stem})"),
            kind: TargetKind::Task { task: idx },
            bound: rms,
            c: DVector::zeros(0),
        });
    }
    let name = t.parameter.clone().unwrap_or_default();
    // a base parameter, then a standard one
    let (of, a_base, std_j) = if let Some(i) = base.names.iter().position(|x| *x == name) {
        let mut a = DVector::zeros(nb);
        a[i] = 1.0;
        ("base", Some(a), None)
    } else if let Some(j) = std_names.iter().position(|x| *x == name) {
        // estimable iff e_j = Kᵀ a for some a
        let mut e = DVector::zeros(std_names.len());
        e[j] = 1.0;
        let svd = kt.clone().svd(true, true);
        let a = svd.solve(&e, 1e-10).map_err(|m| Error::Numerical(m.to_string()))?;
        let ok = (kt * &a - &e).norm() < 1e-8;
        ("standard", ok.then_some(a), Some(j))
    } else {
        return Err(Error::invalid(
            at,
            "parameter",
            format!(
                "`{name}` is neither a base parameter ({}) nor a standard parameter of robot {}",
                base.names.join(", "),
                robot.name
            ),
        ));
    };
    let nominal = match (a_base.as_ref(), std_j) {
        (_, Some(j)) => theta_nom[j],
        (Some(a), None) => a.dot(&(&base.k * theta_nom)),
        _ => 0.0,
    };
    let bound = match (t.sigma, t.relative) {
        (Some(s), _) => s,
        (None, Some(r)) => {
            if nominal == 0.0 {
                return Err(Error::invalid(
                    at,
                    "relative",
                    format!("`{name}`'s nominal value is 0: give an absolute `sigma`"),
                ));
            }
            r * nominal.abs()
        }
        _ => unreachable!("validated"),
    };
    let identifiable = a_base.is_some();
    let c = match space {
        Space::Base => match &a_base {
            Some(a) => a.clone(),
            None => DVector::zeros(nb),
        },
        Space::Standard => match (std_j, &a_base) {
            (Some(j), _) => {
                let mut e = DVector::zeros(std_names.len());
                e[j] = 1.0;
                e
            }
            (None, Some(a)) => kt * a,
            _ => unreachable!(),
        },
    };
    Ok(Target {
        label: format!("σ({name})"),
        kind: TargetKind::Parameter {
            name,
            of: of.into(),
            nominal,
            identifiable,
        },
        bound,
        c,
    })
}

/// Per joint, the RMS residual of the least-squares fit of the rows (0 for a joint without rows).
fn repeatable_residual(ds: &crate::ident::Dataset, n: usize) -> Vec<f64> {
    let svd = ds.c.clone().svd(true, true);
    let theta = match svd.solve(&ds.y, 1e-12) {
        Ok(t) => t,
        Err(_) => return vec![f64::NAN; n],
    };
    let res = &ds.y - &ds.c * theta;
    let (mut sq, mut cnt) = (vec![0.0; n], vec![0usize; n]);
    for (i, &j) in ds.joint.iter().enumerate() {
        sq[j] += res[i] * res[i];
        cnt[j] += 1;
    }
    (0..n).map(|j| if cnt[j] > 0 { (sq[j] / cnt[j] as f64).sqrt() } else { 0.0 }).collect()
}

/// Rank of a symmetric positive semidefinite matrix (eigenvalues above 1e-10 of the largest).
pub fn rank_of(m: &DMatrix<f64>) -> usize {
    let ev = m.clone().symmetric_eigen().eigenvalues;
    let top = ev.iter().cloned().fold(0.0, f64::max);
    ev.iter().filter(|&&v| v > 1e-10 * top && top > 0.0).count()
}

/// Per standard parameter: a drive parameter without a known value (the study's rule).
fn unknown_flags(robot: &Robot, theta0: &DVector<f64>, spec: &UnknownSpec) -> Result<Vec<bool>> {
    let params = robot.params();
    let drive = |j: usize| !params[j].kind.is_inertial();
    Ok(match spec {
        UnknownSpec::Rule(UnknownRule::None) => vec![false; params.len()],
        UnknownSpec::Rule(UnknownRule::Zeros) => (0..params.len()).map(|j| drive(j) && theta0[j] == 0.0).collect(),
        UnknownSpec::Names(list) => {
            let mut out = vec![false; params.len()];
            for n in list {
                match params.iter().position(|p| p.name == *n) {
                    Some(j) if drive(j) => out[j] = true,
                    _ => {
                        return Err(Error::invalid(
                            "plan: [consistent]",
                            "unknown",
                            format!("`{n}` is not a drive parameter of robot {}", robot.name),
                        ))
                    }
                }
            }
            out
        }
    })
}
