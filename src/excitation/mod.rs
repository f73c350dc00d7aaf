//! Excitation trajectory design (paper 000 §II-C, §III-B; paper 002 §2.3,
//! §3.3, eq. 17–20): the Fourier coefficients of a periodic joint trajectory
//! that make the base parameters identifiable, inside the joint, torque and
//! Cartesian limits of the cell.
//!
//! # The problem
//!
//! For joint j, q_j(t) = q0_j + Σ_{k=1..n_h} [a_kj/(kω) sin(kωt) − b_kj/(kω) cos(kωt)]
//! ([`crate::trajectory::FourierTrajectory`]; design vector x = (a, b[, q0]) by
//! [`crate::trajectory::FourierLayout`], optionally starting and ending at rest),
//! or, with `[trajectory] shape = "bspline"`, a clamped B-spline that starts
//! and ends at rest at q0 (x its free control points,
//! [`crate::trajectory::bspline`]). Everything below goes through the
//! trajectory-shape seam ([`crate::trajectory::TrajectoryShape`],
//! [`crate::trajectory::Shape`]).
//!
//! minimise J(C̃(x))  subject to  c_i(x) ≤ 0,  x in a box,
//!
//! J the criterion of the scaled stacked base regressor ([`objective`]:
//! cond by default, or −log det, 1/σ_min), c_i the joint position, velocity,
//! acceleration, torque and Cartesian constraints ([`constraints`]), checked
//! on the continuous trajectory or a fine grid and verified on a 1 kHz grid.
//!
//! # The method
//!
//! 1. A real-coded genetic algorithm ([`ga`]) over the box: feasibility-first
//!    selection, elitism, the joint limits repaired by scaling each joint's
//!    harmonics, population evaluated in parallel.
//! 2. Gradient refinement ([`refine`]) of the best distinct individuals with
//!    nlopt SLSQP or MMA, analytic gradients (dσ_i = u_iᵀ dC v_i through the
//!    regressor derivatives and the Fourier basis; envelope-theorem gradients
//!    of the constraint extrema); optionally (`refine.restarts`) restarts
//!    from perturbed copies of the best refined point (basin hopping; with
//!    `refine.elites = k`, of the k best distinct refined points in turn), and
//!    (`refine.bundle`) the epigraph form of the condition number over the
//!    eigenvalues at both ends of the spectrum ([`refine`]).
//! 3. The report ([`report`]): criterion, condition number, singular values,
//!    sensitivities c̄_i (paper 000 eq. 10), predicted relative standard
//!    deviations (eq. 13–14), the worst margin of every constraint on the
//!    verification grid, solver statistics; the trajectory at the controller
//!    rate, reloadable coefficients, SVG plots.
//!
//! Results depend only on the design (and its seed), not on the thread count,
//! unless a wall-clock `time_limit` cuts the search short (an evaluation
//! budget, `max_evaluations`, does not make them depend on the machine). The
//! refinements after the GA are one sequence that a budget only cuts, so with
//! a GA of fixed length a longer budget never gives a worse design;
//! [`ExciteResult::progress`] records when the best design improved.

pub mod constraints;
pub mod design;
pub mod execution;
pub mod forms;
/// The GA lives in the optimisation seam ([`crate::optim::ga`]); re-exported here.
pub use crate::optim::ga;
pub mod grid;
pub mod limits;
pub mod objective;
pub mod refine;
pub mod report;

use crate::error::{Error, Result};
use crate::optim::{Control, Termination};
use crate::params::{BaseOptions, BaseParams};
use crate::robot::Robot;
use crate::trajectory::{period_grid, Shape, ShapeMotion, TrajectoryShape};
use constraints::{Constraints, JointLimitSpec, Margin};
use design::{ExciteDesign, RefineAlgorithm};
use objective::{BaseColumns, Columns, Objective, Scoring, Spectrum};
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;

pub use design::{GaSpec, LimitsSpec, ObjectiveSpec, RefineSpec, TrajectorySpec};
pub use objective::{Criterion, Scaling};
pub use report::{assess, assess_delivered, Identifiability};

/// A design resolved against its robot: objective, constraints, bounds.
#[derive(Debug, Clone)]
pub struct Problem {
    /// The design (validated, robot path resolved).
    pub design: ExciteDesign,
    /// The robot (shared with the objective and the constraints).
    pub robot: Arc<Robot>,
    /// Base parameters (numerical, Gautier 1991).
    pub base: BaseParams,
    /// Nominal base-parameter values K θ_nominal.
    pub nominal_base: Vec<f64>,
    /// The trajectory shape: design vector ↔ motion.
    pub shape: Shape,
    /// The criterion.
    pub objective: Objective,
    /// The constraints.
    pub constraints: Constraints,
    /// The joint limits imposed.
    pub limits: JointLimitSpec,
    /// Every limit applied (or not imposed) per joint, with its source.
    pub applied_limits: Vec<limits::AppliedLimit>,
    /// Lower bounds of x.
    pub lower: Vec<f64>,
    /// Upper bounds of x.
    pub upper: Vec<f64>,
}

/// Outcome of a design run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Every constraint holds on the verification grid.
    Feasible,
    /// Some constraint is violated on the verification grid (see the margins).
    Infeasible,
}

/// What cut a design run short. Serialised as the sentence the reports
/// carry (`"time limit (during the GA)"`, `"interrupted (Ctrl-C)"`, ...).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoppedBy {
    /// Why the GA stopped early (`None`: it ran all its generations).
    pub ga: Option<Termination>,
    /// Why the refinement stopped early (`None`: not cut short).
    pub refine: Option<Termination>,
}

fn stop_words(t: &Termination) -> &'static str {
    match t {
        Termination::Interrupted => "interrupted (Ctrl-C)",
        Termination::MaxEvaluations => "evaluation budget",
        _ => "time limit",
    }
}

impl std::fmt::Display for StoppedBy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (&self.ga, &self.refine) {
            (_, Some(Termination::Interrupted)) => f.write_str("interrupted (Ctrl-C) during refinement"),
            (Some(Termination::Interrupted), _) => f.write_str("interrupted (Ctrl-C)"),
            (Some(g), Some(r)) => write!(f, "{} (during the GA) and {} (during refinement)", stop_words(g), stop_words(r)),
            (Some(g), None) => write!(f, "{} (during the GA)", stop_words(g)),
            (None, Some(r)) => write!(f, "{} (during refinement)", stop_words(r)),
            (None, None) => f.write_str("not stopped"),
        }
    }
}

impl Serialize for StoppedBy {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl ExciteResult {
    /// The delivered trajectory when it may be sent to the robot (the
    /// controller exports): the design is feasible and the delivered
    /// trajectory was not found colliding ([`execution::Safety`]). `Err`
    /// says why not.
    pub fn playable(&self) -> std::result::Result<&crate::trajectory::lead::Delivered, String> {
        match (&self.execution.delivered, self.status) {
            (Some(_), Status::Infeasible) | (None, _) => Err("the design is INFEASIBLE or not playable rest to rest: nothing safe to play".to_string()),
            (Some(_), _) if self.execution.safety.safe == Some(false) => Err(self.execution.safety.statement.clone()),
            (Some(d), _) => Ok(d),
        }
    }

    /// Why the best design found excites no usable set of parameters: its
    /// regressor is rank-deficient (condition number at [`objective::COND_CAP`]),
    /// typically because the limits leave too little motion (e.g. a tiny
    /// `limits.velocity`). `None` when the design's condition number is finite.
    pub fn unexcited(&self) -> Option<String> {
        if self.spectrum.cond < objective::COND_CAP {
            return None;
        }
        let s = &self.spectrum.singular_values;
        let ratio = match (s.first(), s.last()) {
            (Some(a), Some(b)) if *a > 0.0 => format!("{:.3e}", b / a),
            _ => "0".to_string(),
        };
        Some(format!(
            "no trajectory within these limits excites the {} base parameters: the best regressor found is \
             rank-deficient (sigma_min/sigma_max = {ratio}, condition number at the {:e} cap); \
             widen the limits (limits.position, limits.velocity, limits.acceleration) or the trajectory",
            s.len(),
            objective::COND_CAP
        ))
    }
}

/// Result of [`run`].
#[derive(Debug, Clone, Serialize)]
pub struct ExciteResult {
    /// Feasible or not (on the verification grid).
    pub status: Status,
    /// Whether the run was cut short (time limit, Ctrl-C) and by what.
    pub stopped_by: Option<StoppedBy>,
    /// The designed trajectory (a Fourier series, or a B-spline).
    pub trajectory: ShapeMotion,
    /// Its design vector.
    pub x: Vec<f64>,
    /// Criterion value.
    pub criterion: f64,
    /// Singular values and condition number of the scaled regressor.
    pub spectrum: Spectrum,
    /// Worst margin of every constraint on the verification grid.
    pub margins: Vec<Margin>,
    /// The violated constraints (empty when feasible), worst first.
    pub violated: Vec<Margin>,
    /// GA statistics.
    pub ga: GaSummary,
    /// One entry per refinement start.
    pub refinements: Vec<RefineSummary>,
    /// The search's best feasible criterion (on the design grid) each time
    /// it improved: the GA's generations, then the refinements in the order
    /// they ran (search_progress.svg).
    pub progress: Vec<ProgressPoint>,
    /// Where the final design came from (`ga` or `refine #k`).
    pub chosen: String,
    /// The trajectory as delivered to the robot (rest to rest, N periods;
    /// see [`execution`]) and its verification.
    pub execution: execution::Execution,
    /// Wall time of the search (s).
    pub seconds: f64,
    /// Worker threads used.
    pub threads: usize,
}

/// One improvement of the search's best feasible criterion (report.json
/// `result.progress`). The values are the search's, on the design grid
/// (`objective.sample_rate`); the design finally chosen is verified on the
/// check grid afterwards (result.criterion, result.chosen).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProgressPoint {
    /// Seconds from the start of the run when the point was known (the end
    /// of its GA generation, of its batch of refinements).
    pub seconds: f64,
    /// Criterion evaluations up to then: the GA's individuals and every
    /// refinement's objective evaluations.
    pub evaluations: u64,
    /// The best feasible criterion so far.
    pub best: f64,
    /// Where it came from: `GA generation g` or `refine #k` (as in `chosen`).
    pub from: String,
}

/// The improvements of the best feasible criterion: the GA history's
/// generations (at their own clock, `ga_offset` seconds after the run
/// started), then the refinements in order, refinement k known `ended[k]`
/// seconds after the start.
fn progress_of(ga_offset: f64, history: &[ga::GaGeneration], ga_evaluations: u64, refinements: &[refine::RefineOutcome], ended: &[f64]) -> Vec<ProgressPoint> {
    let mut out: Vec<ProgressPoint> = Vec::new();
    let mut best = f64::INFINITY;
    for g in history {
        if g.best_feasible < best {
            best = g.best_feasible;
            out.push(ProgressPoint {
                seconds: ga_offset + g.seconds,
                evaluations: g.evaluations,
                best,
                from: format!("GA generation {}", g.generation),
            });
        }
    }
    let mut evaluations = ga_evaluations;
    for (k, (r, &t)) in refinements.iter().zip(ended).enumerate() {
        evaluations += r.evaluations;
        if r.violation <= 0.0 && r.f < best {
            best = r.f;
            out.push(ProgressPoint {
                seconds: t,
                evaluations,
                best,
                from: format!("refine #{}", k + 1),
            });
        }
    }
    out
}

/// The best `k` distinct refined points, feasibility first then criterion
/// (two points are the same when every variable agrees to 1e-9 of its box).
fn elite_points(refinements: &[refine::RefineOutcome], k: usize, lower: &[f64], upper: &[f64]) -> Vec<ga::Individual> {
    let mut all: Vec<ga::Individual> = refinements
        .iter()
        .map(|r| ga::Individual {
            x: r.x.clone(),
            f: r.f,
            violation: r.violation,
        })
        .collect();
    all.sort_by(|a, b| a.cmp_fitness(b));
    let mut out: Vec<ga::Individual> = Vec::new();
    for c in all {
        if out.len() == k {
            break;
        }
        let same = |o: &ga::Individual| (0..c.x.len()).all(|i| (c.x[i] - o.x[i]).abs() <= 1e-9 * (upper[i] - lower[i]).max(1e-300));
        if !out.iter().any(same) {
            out.push(c);
        }
    }
    out
}

/// GA statistics in the report.
#[derive(Debug, Clone, Serialize)]
pub struct GaSummary {
    /// Generations completed.
    pub generations: usize,
    /// Evaluations.
    pub evaluations: u64,
    /// Wall time (s).
    pub seconds: f64,
    /// Stop reason.
    pub stop: ga::GaStop,
    /// Best criterion of the final population (feasible individuals; ∞ if none).
    pub best: f64,
    /// Smallest violation of the final population.
    pub least_violation: f64,
    /// Per-generation statistics.
    pub history: Vec<ga::GaGeneration>,
}

/// Refinement statistics in the report.
#[derive(Debug, Clone, Serialize)]
pub struct RefineSummary {
    /// Criterion at the start (the GA individual).
    pub start: f64,
    /// Criterion at the end.
    pub end: f64,
    /// Scaled violation at the end.
    pub violation: f64,
    /// nlopt status.
    pub status: refine::RefineStatus,
    /// Objective evaluations.
    pub evaluations: u64,
    /// Wall time (s).
    pub seconds: f64,
}

impl Problem {
    /// Loads a design file and its robot.
    pub fn from_file(path: &std::path::Path) -> Result<Problem> {
        let d = ExciteDesign::load(path)?;
        let robot = crate::robot::load(&d.robot)?;
        Problem::new(d, robot, &path.display().to_string())
    }

    /// Resolves a validated design against its robot.
    pub fn new(design: ExciteDesign, robot: Robot, ctx: &str) -> Result<Problem> {
        design.validate(ctx)?;
        design.validate_for(&robot, ctx)?;
        let n = robot.dof();
        let opts = BaseOptions {
            inertial_only: matches!(design.objective.columns, Columns::Inertial | Columns::Payload | Columns::Gains),
            ..BaseOptions::default()
        };
        let (robot, mount) = match &design.payload {
            Some(spec) => {
                let (mount, payload) = crate::robot::payload::resolve(&robot, spec, ctx, "payload")?;
                (mount.attach(&robot, &payload.params())?, Some((mount, payload)))
            }
            None => (robot, None),
        };
        let base = match (&design.objective.base_columns, &mount) {
            (_, Some((m, _))) if matches!(design.objective.columns, Columns::Payload | Columns::Gains) => {
                let o = robot.link_param_offset(m.link);
                let cols: Vec<usize> = (o..o + 10).collect();
                // the report lists the independent ones when fewer than ten are (a planar robot)
                BaseParams::of_columns(&robot, &cols, &opts)?
            }
            (Some(names), _) => {
                BaseParams::with_columns(&robot, names, &opts).map_err(|e| crate::Error::invalid(ctx, "objective.base_columns", e.to_string()))?
            }
            (None, _) => BaseParams::compute(&robot, &opts)?,
        };
        let theta = robot.nominal_params();
        let nominal_base: Vec<f64> = base.base_values(theta.as_slice()).iter().copied().collect();
        let (limits, applied_limits) = limits::resolve(&design.limits, &robot, &design.robot, ctx)?;
        let position = limits.position.clone();
        let tr = &design.trajectory;
        tr.check_poses(&position, ctx)?;
        let q0 = match &tr.q0 {
            Some(q) => q.clone(),
            None => position
                .iter()
                .map(|&[lo, hi]| if lo.is_finite() && hi.is_finite() { 0.5 * (lo + hi) } else { 0.0 })
                .collect(),
        };
        let shape = tr.shape(q0)?;
        if design.refine.perturb_joints > n {
            return Err(crate::Error::invalid(
                ctx,
                "refine.perturb_joints",
                format!(
                    "expected 0 (every variable) or 1..={n} joints of the robot, got {}",
                    design.refine.perturb_joints
                ),
            ));
        }
        let times = period_grid(tr.motion_duration(), design.objective.sample_rate)?;
        let robot = Arc::new(robot);
        let noise = design.objective.noise.clone().unwrap_or_else(|| vec![1.0; n]);
        let scoring = Scoring {
            criterion: design.objective.criterion,
            scaling: design.objective.scaling,
            noise: noise.clone(),
        };
        let objective = match &mount {
            Some((m, payload)) if design.objective.columns == Columns::Gains => {
                let (mixes, names, nominal) = objective::gains_columns(&robot, m, payload);
                Objective::mixed(Arc::clone(&robot), shape.clone(), mixes, names, nominal, times, scoring)?
            }
            _ => Objective::new(
                Arc::clone(&robot),
                shape.clone(),
                BaseColumns {
                    indices: base.independent.clone(),
                    names: base.names.clone(),
                    nominal: nominal_base.clone(),
                },
                times,
                scoring,
            )?,
        };
        let mut constraints = Constraints::new(Arc::clone(&robot), shape.clone(), &limits, &design.workspace, design.limits.grid_rate, ctx)?;
        if let Some(scene) = crate::robot::collision::CollisionScene::new(&robot, &design.collision, std::path::Path::new(""), ctx)? {
            if !scene.is_empty() {
                constraints = constraints.with_collision(scene);
            }
        }
        // the box of x: the shape's, from the joint limits
        let (lower, upper) = shape.bounds(&crate::trajectory::JointBox {
            position: &position,
            velocity: &limits.velocity,
            acceleration: &limits.acceleration,
        });
        Ok(Problem {
            design,
            robot,
            base,
            nominal_base,
            shape,
            objective,
            constraints,
            limits,
            applied_limits,
            lower,
            upper,
        })
    }

    /// Repairs the joint limits of x (in place), then returns (criterion,
    /// total violation) — the GA's evaluation.
    pub fn evaluate(&self, x: &mut [f64], ow: &mut objective::ObjectiveWorkspace, cw: &mut constraints::ConstraintWorkspace, c: &mut Vec<f64>) -> (f64, f64) {
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.clamp(self.lower[i], self.upper[i]);
        }
        self.constraints.repair_joints(x, &self.limits, 1e-6);
        c.resize(self.constraints.len(), 0.0);
        self.constraints.eval_selection(x, cw, c);
        let f = self.objective.value(x, ow);
        (f, Constraints::violation(c))
    }
}

/// A candidate design after verification on the check grid.
struct Finalised {
    x: Vec<f64>,
    trajectory: ShapeMotion,
    spectrum: Spectrum,
    margins: Vec<Margin>,
    violated: Vec<Margin>,
    shrink: f64,
}

impl Finalised {
    fn key(&self) -> ga::Individual {
        ga::Individual {
            x: Vec::new(),
            f: self.spectrum.criterion,
            violation: self.violated.iter().map(|m| -m.margin / scale_of(m)).sum(),
        }
    }
}

fn scale_of(m: &Margin) -> f64 {
    if m.limit != 0.0 {
        m.limit.abs()
    } else {
        1.0
    }
}

/// Factors tried, in order, to bring a slightly violating design inside its limits.
const SHRINK_STEPS: [f64; 9] = [0.9999, 0.9995, 0.999, 0.998, 0.995, 0.99, 0.98, 0.95, 0.9];

/// Verifies x on the check grid; if some constraint is violated there but
/// the rest pose at the centre is feasible, scales every joint's motion
/// about its centre ([`TrajectoryShape::joint_vars`]: the harmonics, the
/// B-spline's control points) by the first factor of [`SHRINK_STEPS`] that
/// meets every constraint (none below 0.9).
fn finalise(p: &Problem, x: &[f64]) -> Result<Finalised> {
    let rate = p.design.limits.check_rate;
    let n = p.robot.dof();
    let scaled = |s: f64| -> Vec<f64> {
        let mut y = x.to_vec();
        for j in 0..n {
            for v in &mut y[p.shape.joint_vars(j)] {
                *v *= s;
            }
        }
        y
    };
    let check = |y: &[f64]| -> Result<Vec<Margin>> { p.constraints.verify(&p.shape.motion(y), rate) };
    let feasible = |m: &[Margin]| m.iter().all(|m| m.margin >= 0.0);
    let mut margins = check(x)?;
    let mut xs = x.to_vec();
    let mut shrink = 1.0;
    if !feasible(&margins) && feasible(&check(&scaled(0.0))?) {
        for f in SHRINK_STEPS {
            let m = check(&scaled(f))?;
            if feasible(&m) {
                shrink = f;
                xs = scaled(f);
                margins = m;
                break;
            }
        }
    }
    let trajectory = p.shape.motion(&xs);
    let mut ow = p.objective.workspace();
    let spectrum = p.objective.spectrum(&trajectory, &mut ow)?;
    let mut violated: Vec<Margin> = margins.iter().filter(|m| m.margin < 0.0).cloned().collect();
    violated.sort_by(|a, b| (a.margin / scale_of(a)).total_cmp(&(b.margin / scale_of(b))));
    Ok(Finalised {
        x: xs,
        trajectory,
        spectrum,
        margins,
        violated,
        shrink,
    })
}

/// Restarts of the refinement perturbed from the same best point (`refine.restarts`).
const RESTART_ROUND: usize = 2;

/// The perturbation size of each refined point the restarts perturb
/// (`refine.perturb_adapt`; points known by their criterion's bits): a
/// round from a point that found a better one grows its size and hands the
/// grown size to the better point, a round that did not shrinks it.
struct PerturbSizes {
    base: f64,
    factor: f64,
    sizes: Vec<(u64, f64)>,
}

impl PerturbSizes {
    fn new(r: &design::RefineSpec) -> Self {
        PerturbSizes {
            base: r.perturb,
            factor: r.perturb_adapt,
            sizes: Vec::new(),
        }
    }

    /// The size to perturb the point of criterion `f` with.
    fn get(&self, f: f64) -> f64 {
        self.sizes.iter().find(|s| s.0 == f.to_bits()).map_or(self.base, |s| s.1)
    }

    fn set(&mut self, f: f64, size: f64) {
        let size = size.clamp(self.base / 10.0, (4.0 * self.base).min(1.0));
        match self.sizes.iter_mut().find(|s| s.0 == f.to_bits()) {
            Some(s) => s.1 = size,
            None => self.sizes.push((f.to_bits(), size)),
        }
    }

    /// After a round from the point of criterion `from` whose best point has
    /// criterion `to` (`better`: it is better than the start's point).
    fn after_round(&mut self, from: f64, to: f64, better: bool) {
        if self.factor == 1.0 {
            return;
        }
        let s = self.get(from);
        if better {
            self.set(from, s * self.factor);
            self.set(to, s * self.factor);
        } else {
            self.set(from, s / self.factor);
        }
    }
}

/// Runs the design: GA, refinement, verification (see the module docs).
///
/// `ctl` stops the run (stop request, deadline, evaluation budget); the
/// design's own `time_limit` is applied on top of it: the GA gets the
/// fraction `ga.time_fraction`, the refinement the rest up to 97 % (3 % are
/// left for the verification). Progress goes to `ctl.observer()` in three
/// phases, `"excite GA"`, `"excite refine"` and `"excite check"` (the
/// candidates on the check grid, then the delivered trajectory).
pub fn run(p: &Problem, ctl: &Control) -> Result<ExciteResult> {
    let t0 = Instant::now();
    let d = &p.design;
    // 3 % of the budget is left for the verification on the check grid
    let mut ctl_all = ctl.sub(d.time_limit.map(|t| 0.97 * t));
    if let Some(n) = d.max_evaluations {
        // the evaluations the caller's control already counted are not this run's
        let n = ctl.evaluations().saturating_add(n);
        ctl_all = ctl_all.with_max_evals(Some(ctl.max_evals().map_or(n, |m| m.min(n))));
    }
    let ctl_ga = ctl_all.sub(d.time_limit.map(|t| t * d.ga.time_fraction));
    let obs = ctl.observer();
    // shrink centre: the motion at rest at q0 (harmonics, control-point offsets zero)
    let centre = p.shape.rest_vars();
    obs.phase("excite GA", Some(d.ga.generations as u64));
    let problem = ga::FnProblem {
        make_ws: || (p.objective.workspace(), p.constraints.workspace(), Vec::new()),
        eval: |w: &mut (objective::ObjectiveWorkspace, constraints::ConstraintWorkspace, Vec<f64>), x: &mut Vec<f64>| {
            let (ow, cw, c) = w;
            p.evaluate(x, ow, cw, c)
        },
    };
    let gares_started = Instant::now();
    let gares = ga::run(
        &d.ga,
        d.seed,
        &ga::SearchSpace {
            lower: &p.lower,
            upper: &p.upper,
            centre: &centre,
            initial: &[],
        },
        problem,
        &ctl_ga,
    )?;
    obs.phase_done();
    let mut stopped_by = match gares.stop {
        ga::GaStop::Generations => None,
        s => Some(StoppedBy {
            ga: Some(s.termination()),
            refine: None,
        }),
    };
    // distinct individuals, best first: the first `starts` are refined; with a
    // time limit, further ones are refined in batches while time remains
    let mut starts: Vec<&ga::Individual> = Vec::new();
    for ind in &gares.population {
        let dup = starts
            .iter()
            .any(|s| s.x.iter().zip(&ind.x).all(|(a, b)| (a - b).abs() <= 1e-12 * (1.0 + a.abs())));
        if !dup {
            starts.push(ind);
        }
    }
    let mut refinements: Vec<refine::RefineOutcome> = Vec::new();
    // when each refinement was known (the end of its batch), seconds from t0
    let mut ended: Vec<f64> = Vec::new();
    let stamp = |ended: &mut Vec<f64>, n: usize| ended.resize(n, t0.elapsed().as_secs_f64());
    if d.refine.algorithm != RefineAlgorithm::None && gares.stop != ga::GaStop::Interrupted {
        let first = d.refine.starts.min(starts.len());
        obs.phase("excite refine", Some(first as u64));
        obs.note(&format!(
            "{first} {} start(s), analytic gradients",
            format!("{:?}", d.refine.algorithm).to_lowercase()
        ));
        // `refine.parallel` starts at a time (one: the gradient's per-sample
        // work is what runs in parallel); each start's result does not depend
        // on how many run beside it
        let batch = d.refine.parallel.max(1);
        let refine_batch = |xs: &[Vec<f64>]| -> Vec<refine::RefineOutcome> {
            let one = |x: &Vec<f64>| {
                let mut r = refine::refine(&p.objective, &p.constraints, x, &d.refine, &p.lower, &p.upper, &ctl_all);
                if d.refine.repair {
                    refine::repair_near(&mut r, &p.objective, &p.constraints, &p.limits, &ctl_all);
                }
                r
            };
            if xs.len() == 1 {
                vec![one(&xs[0])]
            } else {
                use rayon::prelude::*;
                xs.par_iter().map(one).collect()
            }
        };
        let ga_x: Vec<Vec<f64>> = starts.iter().map(|s| s.x.clone()).collect();
        for chunk in ga_x[..first].chunks(batch) {
            if ctl_all.should_stop() {
                break;
            }
            refinements.extend(refine_batch(chunk));
            stamp(&mut ended, refinements.len());
            obs.progress(refinements.len() as u64, "");
        }
        // `refine.restarts` perturbed copies of a centre, in rounds of
        // RESTART_ROUND from the centre before the round (so that the starts
        // do not depend on `refine.parallel`; seeded by the design's seed and
        // the restart index). The centre is the best refined point so far;
        // with `refine.stall = s > 0`, after s rounds without a better point
        // the next RESTART_ROUND GA individuals not yet refined are refined and
        // the better becomes the centre (a new basin); the best point over all
        // is kept. With `refine.elites = e > 1`, round r perturbs the
        // (r mod e)-th of the best e distinct refined points so far instead
        // (the stall rule then only brings the next GA individuals in)
        let fitness = |r: &refine::RefineOutcome| ga::Individual {
            x: r.x.clone(),
            f: r.f,
            violation: r.violation,
        };
        let mut next_ga = first;
        let mut sizes = PerturbSizes::new(&d.refine);
        let joint_vars: Vec<std::ops::Range<usize>> = (0..p.shape.n_joints()).map(|j| p.shape.joint_vars(j)).collect();
        let mut centre = refinements.iter().map(fitness).min_by(|a, b| a.cmp_fitness(b));
        let mut stalled = 0;
        let mut k = 0;
        while k < d.refine.restarts && !ctl_all.should_stop() {
            let Some(c) = centre.as_ref() else {
                break;
            };
            let from_elite = if d.refine.elites > 1 {
                let pool = elite_points(&refinements, d.refine.elites, &p.lower, &p.upper);
                pool.get((k / RESTART_ROUND) % pool.len().max(1)).cloned()
            } else {
                None
            };
            let around = from_elite.as_ref().unwrap_or(c);
            let scale = sizes.get(around.f);
            let xs: Vec<Vec<f64>> = (k..(k + RESTART_ROUND).min(d.refine.restarts))
                .map(|i| {
                    let seed = crate::rng::mix(d.seed, i as u64, 7);
                    let mut x = refine::perturb_joints(&around.x, &p.lower, &p.upper, scale, seed, d.refine.perturb_joints, &joint_vars);
                    p.constraints.repair_joints(&mut x, &p.limits, 1e-6);
                    x
                })
                .collect();
            k += xs.len();
            let from = refinements.len();
            for chunk in xs.chunks(batch) {
                if ctl_all.should_stop() {
                    break;
                }
                refinements.extend(refine_batch(chunk));
                stamp(&mut ended, refinements.len());
            }
            let round = refinements[from..].iter().map(fitness).min_by(|a, b| a.cmp_fitness(b));
            if let Some(r) = &round {
                let better = r.cmp_fitness(around) == std::cmp::Ordering::Less;
                sizes.after_round(around.f, r.f, better);
            }
            match round {
                Some(r) if r.cmp_fitness(c) == std::cmp::Ordering::Less => {
                    centre = Some(r);
                    stalled = 0;
                }
                _ => stalled += 1,
            }
            if d.refine.stall > 0 && stalled >= d.refine.stall && next_ga < ga_x.len() && !ctl_all.should_stop() {
                let to = (next_ga + RESTART_ROUND).min(ga_x.len());
                let from = refinements.len();
                for chunk in ga_x[next_ga..to].chunks(batch) {
                    if ctl_all.should_stop() {
                        break;
                    }
                    refinements.extend(refine_batch(chunk));
                    stamp(&mut ended, refinements.len());
                }
                next_ga = to;
                centre = refinements[from..].iter().map(fitness).min_by(|a, b| a.cmp_fitness(b));
                stalled = 0;
            }
            obs.progress(refinements.len() as u64, "");
        }
        if ctl_all.deadline().is_some() || ctl_all.max_evals().is_some() {
            for chunk in ga_x[next_ga..].chunks(batch) {
                if ctl_all.should_stop() {
                    break;
                }
                refinements.extend(refine_batch(chunk));
                stamp(&mut ended, refinements.len());
                obs.progress(refinements.len() as u64, "");
            }
        }
        obs.phase_done();
        if let Some(t) = ctl_all.check() {
            let ga = stopped_by.take().and_then(|s| s.ga);
            stopped_by = Some(StoppedBy { ga, refine: Some(t) });
        }
    }
    // verify every candidate on the check grid (shrinking it towards the rest
    // pose if the fine grid shows a small violation), then choose:
    // feasibility first, then criterion
    let best_ga = gares.population.first().ok_or_else(|| Error::Numerical("empty GA population".into()))?;
    let mut cands: Vec<(String, ga::Individual)> = vec![("ga".to_string(), best_ga.clone())];
    for (k, r) in refinements.iter().enumerate() {
        cands.push((
            format!("refine #{}", k + 1),
            ga::Individual {
                x: r.x.clone(),
                f: r.f,
                violation: r.violation,
            },
        ));
    }
    // best first by the search's own measure; the first candidate that passes
    // the check grid wins (later ones are worse), else the least violating
    cands.sort_by(|a, b| a.1.cmp_fitness(&b.1));
    // the checks take a while on a long trajectory: a phase of their own
    // (steps: the candidates tried, then the delivered trajectory)
    let rate = d.limits.check_rate;
    let checks = cands.len() as u64 + 1;
    obs.phase("excite check", Some(checks));
    let mut best: Option<(String, Finalised)> = None;
    for (k, (name, ind)) in cands.into_iter().enumerate() {
        obs.progress(k as u64, &format!("{name} on the {rate} Hz grid"));
        let f = finalise(p, &ind.x)?;
        let better = match &best {
            None => true,
            Some((_, b)) => f.key().cmp_fitness(&b.key()) == std::cmp::Ordering::Less,
        };
        let done = f.violated.is_empty();
        if better {
            best = Some((name, f));
        }
        if done {
            break;
        }
    }
    let (chosen_from, fin) = best.ok_or_else(|| Error::Numerical("no candidate design".into()))?;
    let Finalised {
        x,
        trajectory,
        spectrum,
        margins,
        violated,
        shrink,
    } = fin;
    let chosen_from = if shrink < 1.0 {
        format!("{chosen_from}, harmonics scaled by {shrink:.6} to meet the {} Hz check", d.limits.check_rate)
    } else {
        chosen_from
    };
    // the delivered trajectory: lead-in, periods, lead-out, every sample checked
    obs.progress(checks - 1, &format!("the delivered trajectory at {rate} Hz"));
    let execution = execution::deliver(p, &trajectory)?;
    obs.progress(checks, "");
    obs.phase_done();
    // a regressor at the condition-number cap does not excite every base
    // parameter: not a usable design, whatever the constraints say
    let status = if violated.is_empty() && execution.verified && spectrum.cond < objective::COND_CAP {
        Status::Feasible
    } else {
        Status::Infeasible
    };
    let last = gares.history.last();
    // the GA started when the run did (its clock is its own: the offset is the setup before it, ~0)
    let ga_offset = (gares_started - t0).as_secs_f64();
    let progress = progress_of(ga_offset, &gares.history, gares.evaluations, &refinements, &ended);
    Ok(ExciteResult {
        progress,
        status,
        stopped_by,
        x,
        criterion: spectrum.criterion,
        spectrum,
        margins,
        violated,
        ga: GaSummary {
            generations: gares.generations,
            evaluations: gares.evaluations,
            seconds: gares.seconds,
            stop: gares.stop,
            best: last.map_or(f64::INFINITY, |h| h.best_feasible),
            least_violation: last.map_or(f64::INFINITY, |h| h.least_violation),
            history: gares.history.clone(),
        },
        refinements: refinements
            .iter()
            .map(|r| RefineSummary {
                start: r.start_f,
                end: r.f,
                violation: r.violation,
                status: r.status.clone(),
                evaluations: r.evaluations,
                seconds: r.seconds,
            })
            .collect(),
        chosen: chosen_from,
        execution,
        trajectory,
        seconds: t0.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
    })
}
