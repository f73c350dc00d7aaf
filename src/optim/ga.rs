//! Real-coded genetic algorithm with feasibility-first selection (Deb 2000)
//! as an argmin [`Solver`]: binary tournaments, simulated binary crossover
//! (SBX) and polynomial mutation (Deb & Agrawal), elitism, box bounds, a
//! repair step inside the evaluation (Lamarckian: the repaired genes are
//! kept), population evaluated in parallel with rayon.
//!
//! Comparison of two individuals: a feasible one (violation 0) beats an
//! infeasible one; two infeasible ones compare by total violation; two
//! feasible ones by objective.
//!
//! One argmin iteration is one generation; argmin's `max_iters` is the number
//! of generations after the initial population (made in `init`). The
//! solver's `terminate` asks the [`Control`] first, so a stop request, the
//! deadline or the evaluation budget end the run between two generations
//! (one generation is one parallel evaluation of the population: with the
//! shipped designs well under 0.2 s). [`ArgminProgress`] forwards every
//! generation to the control's observer. [`run`] wires it all and maps
//! argmin's `TerminationReason` to [`GaStop`].
//!
//! Reproducibility: all random choices of generation g come from
//! `ChaCha8Rng::seed_from_u64(mix(seed, g, 1))` (the initial population from
//! `mix(seed, 0, 0)`) and are drawn sequentially; evaluations are pure
//! functions of the genes, run in parallel and collected in order, so the
//! result does not depend on the thread count.

use super::{Control, Termination};
use crate::error::{Error, Result};
use argmin::core::{observers::Observe, Executor, IterState, Problem, Solver, State, TerminationReason, TerminationStatus, KV};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One individual: genes, objective, constraint violation (0 = feasible).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Individual {
    /// Genes (design vector).
    pub x: Vec<f64>,
    /// Objective (lower is better).
    pub f: f64,
    /// Total constraint violation (sum of positive scaled constraint values).
    pub violation: f64,
}

impl Individual {
    /// No constraint violated.
    pub fn feasible(&self) -> bool {
        self.violation <= 0.0
    }
    /// Feasibility-first order: `Less` when `self` is better than `o`.
    pub fn cmp_fitness(&self, o: &Individual) -> std::cmp::Ordering {
        match (self.feasible(), o.feasible()) {
            (true, false) => std::cmp::Ordering::Less,
            (false, true) => std::cmp::Ordering::Greater,
            (false, false) => self.violation.total_cmp(&o.violation),
            (true, true) => self.f.total_cmp(&o.f),
        }
    }
}

/// `[ga]` of a design file: the settings of one GA run (the seed is the
/// design's, the deadline and the stop request come from the [`Control`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GaSpec {
    /// Population size.
    pub population: usize,
    /// Number of generations after the initial population.
    pub generations: usize,
    /// Individuals copied unchanged into the next generation.
    pub elite: usize,
    /// Crossover probability (SBX) per pair.
    pub crossover: f64,
    /// SBX distribution index.
    pub eta_crossover: f64,
    /// Per-gene mutation probability (0: 1/n_vars).
    pub mutation: f64,
    /// Polynomial-mutation distribution index.
    pub eta_mutation: f64,
    /// Fraction of the design's `time_limit` the GA may use.
    pub time_fraction: f64,
}

impl Default for GaSpec {
    fn default() -> Self {
        GaSpec {
            population: 40,
            generations: 30,
            elite: 2,
            crossover: 0.9,
            eta_crossover: 10.0,
            mutation: 0.0,
            eta_mutation: 20.0,
            time_fraction: 0.3,
        }
    }
}

impl GaSpec {
    /// Checks every value; `ctx` names the file in messages, fields are
    /// reported as `ga.<field>`.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let bad = |field: &str, msg: String| Err(Error::invalid(ctx, field, msg));
        let g = self;
        if g.population < 4 || g.population > 100_000 {
            return bad("ga.population", format!("expected 4..=100000, got {}", g.population));
        }
        if g.elite >= g.population {
            return bad(
                "ga.elite",
                format!("expected fewer elites than the population ({}), got {}", g.population, g.elite),
            );
        }
        if !(0.0..=1.0).contains(&g.crossover) || !(0.0..=1.0).contains(&g.mutation) {
            return bad("ga.crossover", "crossover and mutation are probabilities in [0, 1]".into());
        }
        if !(g.eta_crossover > 0.0 && g.eta_mutation > 0.0) {
            return bad("ga.eta_crossover", "distribution indices must be positive".into());
        }
        if !(g.time_fraction > 0.0 && g.time_fraction <= 1.0) {
            return bad("ga.time_fraction", format!("expected a fraction in (0, 1], got {}", g.time_fraction));
        }
        Ok(())
    }
}

/// Why the GA stopped (serialised as `generations`, `time_limit`, `interrupted`, `max_evaluations`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GaStop {
    /// All generations ran.
    Generations,
    /// The wall-clock budget ran out.
    TimeLimit,
    /// The user asked to stop (Ctrl-C).
    Interrupted,
    /// The evaluation budget of the control was used up.
    MaxEvaluations,
}

impl GaStop {
    /// The run-control word for this stop.
    pub fn termination(self) -> Termination {
        match self {
            GaStop::Generations => Termination::MaxIterations,
            GaStop::TimeLimit => Termination::TimeLimit,
            GaStop::Interrupted => Termination::Interrupted,
            GaStop::MaxEvaluations => Termination::MaxEvaluations,
        }
    }
}

/// Per-generation statistics.
#[derive(Debug, Clone, Serialize)]
pub struct GaGeneration {
    /// Generation (0 = initial population).
    pub generation: usize,
    /// Best objective among feasible individuals (∞ if none).
    pub best_feasible: f64,
    /// Smallest violation in the population.
    pub least_violation: f64,
    /// Number of feasible individuals.
    pub feasible: usize,
    /// Seconds from the start of the GA to the end of this generation.
    pub seconds: f64,
    /// Evaluations up to the end of this generation.
    pub evaluations: u64,
}

/// Result of a GA run.
#[derive(Debug, Clone, Serialize)]
pub struct GaResult {
    /// Final population, best first.
    pub population: Vec<Individual>,
    /// Generations completed.
    pub generations: usize,
    /// Evaluations made.
    pub evaluations: u64,
    /// Per-generation statistics.
    pub history: Vec<GaGeneration>,
    /// Stop reason.
    pub stop: GaStop,
    /// Wall time (s).
    pub seconds: f64,
}

/// The problem a GA minimises: a per-thread workspace and an evaluation
/// returning (objective, total violation ≥ 0) that may repair `x` in place.
pub trait GaProblem: Sync {
    /// Per-thread scratch memory.
    type Workspace: Send;
    /// A new workspace.
    fn workspace(&self) -> Self::Workspace;
    /// (objective, violation) of `x` (NaN counts as +∞); may repair `x`.
    fn evaluate(&self, ws: &mut Self::Workspace, x: &mut Vec<f64>) -> (f64, f64);
}

/// Closures as a [`GaProblem`]: `make_ws()` builds a workspace, `eval(ws, x)` evaluates.
pub struct FnProblem<M, E> {
    /// Workspace factory.
    pub make_ws: M,
    /// Evaluation.
    pub eval: E,
}

impl<W: Send, M: Fn() -> W + Sync, E: Fn(&mut W, &mut Vec<f64>) -> (f64, f64) + Sync> GaProblem for FnProblem<M, E> {
    type Workspace = W;
    fn workspace(&self) -> W {
        (self.make_ws)()
    }
    fn evaluate(&self, ws: &mut W, x: &mut Vec<f64>) -> (f64, f64) {
        (self.eval)(ws, x)
    }
}

pub use crate::rng::mix;

fn tournament<'a>(pop: &'a [Individual], rng: &mut ChaCha8Rng) -> &'a Individual {
    let a = &pop[rng.random_range(0..pop.len())];
    let b = &pop[rng.random_range(0..pop.len())];
    if b.cmp_fitness(a) == std::cmp::Ordering::Less {
        b
    } else {
        a
    }
}

/// SBX on one gene pair within [lo, hi] (bounded variant).
fn sbx(x1: f64, x2: f64, lo: f64, hi: f64, eta: f64, rng: &mut ChaCha8Rng) -> (f64, f64) {
    if (x1 - x2).abs() < 1e-14 || hi <= lo {
        return (x1, x2);
    }
    let (y1, y2) = if x1 < x2 { (x1, x2) } else { (x2, x1) };
    let u: f64 = rng.random_range(0.0..1.0);
    let child = |beta: f64| {
        let alpha = 2.0 - beta.powf(-(eta + 1.0));
        if u <= 1.0 / alpha {
            (u * alpha).powf(1.0 / (eta + 1.0))
        } else {
            (1.0 / (2.0 - u * alpha)).powf(1.0 / (eta + 1.0))
        }
    };
    let d = y2 - y1;
    let b1 = 1.0 + 2.0 * (y1 - lo) / d;
    let c1 = 0.5 * ((y1 + y2) - child(b1) * d);
    let b2 = 1.0 + 2.0 * (hi - y2) / d;
    let c2 = 0.5 * ((y1 + y2) + child(b2) * d);
    let (c1, c2) = (c1.clamp(lo, hi), c2.clamp(lo, hi));
    if rng.random_range(0.0..1.0) < 0.5 {
        (c2, c1)
    } else {
        (c1, c2)
    }
}

/// Polynomial mutation of one gene within [lo, hi].
fn poly_mutation(x: f64, lo: f64, hi: f64, eta: f64, rng: &mut ChaCha8Rng) -> f64 {
    let d = hi - lo;
    if d <= 0.0 {
        return x;
    }
    let u: f64 = rng.random_range(0.0..1.0);
    let (d1, d2) = ((x - lo) / d, (hi - x) / d);
    let p = 1.0 / (eta + 1.0);
    let dq = if u < 0.5 {
        let v = 2.0 * u + (1.0 - 2.0 * u) * (1.0 - d1).powf(eta + 1.0);
        v.powf(p) - 1.0
    } else {
        let v = 2.0 * (1.0 - u) + 2.0 * (u - 0.5) * (1.0 - d2).powf(eta + 1.0);
        1.0 - v.powf(p)
    };
    (x + dq * d).clamp(lo, hi)
}

/// The argmin state of the GA: param = genes of the best individual, cost =
/// its objective when feasible, else +∞.
pub type GaState = IterState<Vec<f64>, (), (), (), (), f64>;

/// The GA as an argmin solver (see the module docs). Holds the population.
pub struct Ga<'a> {
    spec: &'a GaSpec,
    seed: u64,
    lower: &'a [f64],
    upper: &'a [f64],
    centre: &'a [f64],
    initial: &'a [Vec<f64>],
    ctl: Control,
    /// Population, best first.
    pub population: Vec<Individual>,
    /// Per-generation statistics.
    pub history: Vec<GaGeneration>,
    /// Evaluations made.
    pub evaluations: u64,
    /// Generations completed.
    pub generations: usize,
    /// When the GA started (the history's clock).
    t0: Instant,
}

impl<'a> Ga<'a> {
    /// A GA on [lower, upper] with the settings `spec`, the random streams of
    /// `seed`, the shrink centre `centre` and `initial` individuals put first
    /// into the initial population; stopped by `ctl`.
    pub fn new(spec: &'a GaSpec, seed: u64, lower: &'a [f64], upper: &'a [f64], centre: &'a [f64], initial: &'a [Vec<f64>], ctl: &Control) -> Self {
        Ga {
            spec,
            seed,
            lower,
            upper,
            centre,
            initial,
            ctl: ctl.clone(),
            population: Vec::new(),
            history: Vec::new(),
            evaluations: 0,
            generations: 0,
            t0: Instant::now(),
        }
    }

    fn evaluate<P: GaProblem>(&self, p: &P, genes: Vec<Vec<f64>>) -> Vec<Individual> {
        let out: Vec<Individual> = genes
            .into_par_iter()
            .map_init(
                || p.workspace(),
                |ws, mut x| {
                    let (f, v) = p.evaluate(ws, &mut x);
                    let f = if f.is_nan() { f64::INFINITY } else { f };
                    let v = if v.is_nan() { f64::INFINITY } else { v };
                    Individual { x, f, violation: v }
                },
            )
            .collect();
        self.ctl.count(out.len() as u64);
        out
    }

    fn stats(&mut self, g: usize, state: GaState) -> (GaState, Option<KV>) {
        let pop = &self.population;
        self.history.push(GaGeneration {
            generation: g,
            best_feasible: pop.iter().filter(|i| i.feasible()).map(|i| i.f).fold(f64::INFINITY, f64::min),
            least_violation: pop.iter().map(|i| i.violation).fold(f64::INFINITY, f64::min),
            feasible: pop.iter().filter(|i| i.feasible()).count(),
            seconds: self.t0.elapsed().as_secs_f64(),
            evaluations: self.evaluations,
        });
        let b = &pop[0];
        let state = state.param(b.x.clone()).cost(if b.feasible() { b.f } else { f64::INFINITY });
        let kv = argmin::kv!("generation" => g as u64; "best" => b.f; "violation" => b.violation; "feasible" => b.feasible(););
        (state, Some(kv))
    }

    fn initial_genes(&self) -> Vec<Vec<f64>> {
        let (nv, np) = (self.lower.len(), self.spec.population);
        let (lower, upper) = (self.lower, self.upper);
        let mut rng = ChaCha8Rng::seed_from_u64(mix(self.seed, 0, 0));
        let mut genes: Vec<Vec<f64>> = self.initial.iter().take(np).cloned().collect();
        while genes.len() < np {
            let mut x: Vec<f64> = (0..nv)
                .map(|i| {
                    if upper[i] > lower[i] {
                        rng.random_range(lower[i]..upper[i])
                    } else {
                        lower[i]
                    }
                })
                .collect();
            if genes.len() % 2 == 1 {
                let u: f64 = rng.random_range(0.0..1.0);
                for (v, c) in x.iter_mut().zip(self.centre) {
                    *v = c + u * u * (*v - c);
                }
            }
            genes.push(x);
        }
        genes
    }

    fn children(&self, g: usize) -> Vec<Vec<f64>> {
        let s = self.spec;
        let (nv, np) = (self.lower.len(), s.population);
        let (lower, upper, pop) = (self.lower, self.upper, &self.population);
        let pm = if s.mutation > 0.0 { s.mutation } else { 1.0 / nv.max(1) as f64 };
        let mut rng = ChaCha8Rng::seed_from_u64(mix(self.seed, g as u64, 1));
        let n_child = np - s.elite;
        let mut children: Vec<Vec<f64>> = Vec::with_capacity(n_child + 1);
        while children.len() < n_child {
            let (mut c1, mut c2) = (tournament(pop, &mut rng).x.clone(), tournament(pop, &mut rng).x.clone());
            if rng.random_range(0.0..1.0) < s.crossover {
                for i in 0..nv {
                    if rng.random_range(0.0..1.0) < 0.5 {
                        let (a, b) = sbx(c1[i], c2[i], lower[i], upper[i], s.eta_crossover, &mut rng);
                        c1[i] = a;
                        c2[i] = b;
                    }
                }
            }
            for c in [&mut c1, &mut c2] {
                for i in 0..nv {
                    if rng.random_range(0.0..1.0) < pm {
                        c[i] = poly_mutation(c[i], lower[i], upper[i], s.eta_mutation, &mut rng);
                    }
                }
            }
            children.push(c1);
            if children.len() < n_child {
                children.push(c2);
            }
        }
        children
    }
}

impl<P: GaProblem> Solver<P, GaState> for Ga<'_> {
    fn name(&self) -> &str {
        "idexp GA"
    }

    fn init(&mut self, problem: &mut Problem<P>, state: GaState) -> std::result::Result<(GaState, Option<KV>), argmin::core::Error> {
        let genes = self.initial_genes();
        let p = problem.problem.as_ref().ok_or_else(|| argmin::core::Error::msg("GA without a problem"))?;
        let mut pop = self.evaluate(p, genes);
        self.evaluations = pop.len() as u64;
        pop.sort_by(|a, b| a.cmp_fitness(b));
        self.population = pop;
        Ok(self.stats(0, state))
    }

    fn next_iter(&mut self, problem: &mut Problem<P>, state: GaState) -> std::result::Result<(GaState, Option<KV>), argmin::core::Error> {
        let g = state.get_iter() as usize + 1;
        let children = self.children(g);
        let n_child = children.len();
        let p = problem.problem.as_ref().ok_or_else(|| argmin::core::Error::msg("GA without a problem"))?;
        let mut next: Vec<Individual> = self.population[..self.spec.elite].to_vec();
        next.extend(self.evaluate(p, children));
        self.evaluations += n_child as u64;
        next.sort_by(|a, b| a.cmp_fitness(b));
        self.population = next;
        self.generations = g;
        Ok(self.stats(g, state))
    }

    fn terminate(&mut self, state: &GaState) -> TerminationStatus {
        // all generations ran: the budget wins over a late stop request
        if state.get_iter() >= state.get_max_iters() {
            return TerminationStatus::Terminated(TerminationReason::MaxItersReached);
        }
        match self.ctl.check() {
            Some(Termination::Interrupted) => TerminationStatus::Terminated(TerminationReason::Interrupt),
            Some(Termination::TimeLimit) => TerminationStatus::Terminated(TerminationReason::Timeout),
            Some(t) => TerminationStatus::Terminated(TerminationReason::SolverExit(t.as_str().to_string())),
            None => TerminationStatus::NotTerminated,
        }
    }
}

/// An argmin observer that forwards every iteration to a [`Control`]'s
/// observer: `progress(iteration, msg)` where `msg` shows the best cost (or
/// the least violation while nothing is feasible).
pub struct ArgminProgress(pub Control);

impl<I: State> Observe<I> for ArgminProgress {
    fn observe_iter(&mut self, state: &I, kv: &KV) -> std::result::Result<(), argmin::core::Error> {
        let f = |k: &str| kv.get(k).and_then(|v| v.get_float());
        let feasible = kv.get("feasible").and_then(|v| v.get_bool()).unwrap_or(true);
        let msg = match (feasible, f("best"), f("violation")) {
            (true, Some(b), _) => format!("best {b:.4} (feasible)"),
            (false, _, Some(v)) => format!("violation {v:.3e} (none feasible yet)"),
            _ => String::new(),
        };
        self.0.observer().progress(state.get_iter() + 1, &msg);
        Ok(())
    }
}

/// Maps argmin's termination reason to the run-control word.
pub fn termination_of(reason: Option<&TerminationReason>) -> Termination {
    match reason {
        Some(TerminationReason::MaxItersReached) => Termination::MaxIterations,
        Some(TerminationReason::TargetCostReached | TerminationReason::SolverConverged) => Termination::Converged,
        Some(TerminationReason::Interrupt) => Termination::Interrupted,
        Some(TerminationReason::Timeout) => Termination::TimeLimit,
        Some(TerminationReason::SolverExit(s)) if s == "max_evaluations" => Termination::MaxEvaluations,
        Some(TerminationReason::SolverExit(s)) => Termination::Failed(s.clone()),
        None => Termination::Failed("not terminated".into()),
    }
}

/// The box a GA searches: bounds, the centre the mutation shrinks toward, and
/// individuals to seed the first population with (may be empty).
#[derive(Debug, Clone, Copy)]
pub struct SearchSpace<'a> {
    /// Lower bounds of the genes.
    pub lower: &'a [f64],
    /// Upper bounds of the genes.
    pub upper: &'a [f64],
    /// Centre of the box used by the repair step.
    pub centre: &'a [f64],
    /// Initial individuals (genes), placed first in the population.
    pub initial: &'a [Vec<f64>],
}

/// Runs the GA on `problem` (see the module docs) with argmin's executor.
/// The observer of `ctl` sees the phase `"GA"` with `spec.generations` steps.
pub fn run<P: GaProblem>(spec: &GaSpec, seed: u64, space: &SearchSpace, problem: P, ctl: &Control) -> Result<GaResult> {
    let t0 = Instant::now();
    let ga = Ga::new(spec, seed, space.lower, space.upper, space.centre, space.initial, ctl);
    let res = Executor::new(problem, ga)
        .configure(|s| s.max_iters(spec.generations as u64))
        .add_observer(ArgminProgress(ctl.clone()), argmin::core::observers::ObserverMode::Always)
        .run()
        .map_err(|e| Error::Numerical(format!("GA: {e}")))?;
    let stop = match termination_of(res.state.get_termination_reason()) {
        Termination::Interrupted => GaStop::Interrupted,
        Termination::TimeLimit => GaStop::TimeLimit,
        Termination::MaxEvaluations => GaStop::MaxEvaluations,
        Termination::MaxIterations | Termination::Converged => GaStop::Generations,
        Termination::Failed(m) => return Err(Error::Numerical(format!("GA: {m}"))),
    };
    let ga = res.solver;
    Ok(GaResult {
        population: ga.population,
        generations: ga.generations,
        evaluations: ga.evaluations,
        history: ga.history,
        stop,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    const SPACE: SearchSpace<'static> = SearchSpace {
        lower: &[-3.0, -3.0],
        upper: &[3.0, 3.0],
        centre: &[0.0, 0.0],
        initial: &[],
    };
    use super::*;

    fn spec() -> GaSpec {
        GaSpec {
            population: 40,
            generations: 80,
            elite: 2,
            crossover: 0.9,
            eta_crossover: 10.0,
            mutation: 0.0,
            eta_mutation: 20.0,
            time_fraction: 1.0,
        }
    }

    /// min (x0−1)² + (x1+0.5)² s.t. x0 + x1 ≥ 1  → optimum (1.25, −0.25)
    struct Quad;
    impl GaProblem for Quad {
        type Workspace = ();
        fn workspace(&self) {}
        fn evaluate(&self, _: &mut (), x: &mut Vec<f64>) -> (f64, f64) {
            ((x[0] - 1.0).powi(2) + (x[1] + 0.5).powi(2), (1.0 - x[0] - x[1]).max(0.0))
        }
    }

    fn quad() -> Quad {
        Quad
    }

    #[test]
    fn finds_the_constrained_minimum_of_a_quadratic_and_is_reproducible() {
        let s = spec();
        let c = Control::new();
        let r = run(&s, 7, &SPACE, quad(), &c).unwrap();
        assert_eq!(r.stop, GaStop::Generations);
        assert_eq!(r.generations, 80);
        assert_eq!(r.history.len(), 81);
        let b = &r.population[0];
        assert!(b.feasible());
        assert!((b.x[0] - 1.25).abs() < 0.05 && (b.x[1] + 0.25).abs() < 0.05, "{:?}", b.x);
        let r2 = run(&s, 7, &SPACE, quad(), &c).unwrap();
        assert_eq!(r.population, r2.population);
        assert_eq!(c.evaluations(), 2 * (40 + 80 * 38));
    }

    #[test]
    fn the_control_stops_it() {
        let s = spec();
        let c = Control::new();
        c.stop_flag().request();
        let r = run(&s, 7, &SPACE, quad(), &c).unwrap();
        assert_eq!(r.stop, GaStop::Interrupted);
        assert_eq!(r.generations, 0);
        assert_eq!(r.population.len(), 40);
        let c = Control::new().with_max_evals(Some(40 + 3 * 38));
        let r = run(&s, 7, &SPACE, quad(), &c).unwrap();
        assert_eq!((r.stop, r.generations), (GaStop::MaxEvaluations, 3));
        let c = Control::new().with_time_limit(Some(0.0));
        let r = run(&s, 7, &SPACE, quad(), &c).unwrap();
        assert_eq!(r.stop, GaStop::TimeLimit);
    }
}
