//! Real-coded genetic algorithm with feasibility-first selection (Deb 2000):
//! binary tournaments, simulated binary crossover (SBX) and polynomial
//! mutation (Deb & Agrawal), elitism, box bounds, a repair step inside the
//! evaluation (Lamarckian: the repaired genes are kept), population evaluated
//! in parallel with rayon.
//!
//! Comparison of two individuals: a feasible one (violation 0) beats an
//! infeasible one; two infeasible ones compare by total violation; two
//! feasible ones by objective.
//!
//! Reproducibility: all random choices of generation g come from
//! `ChaCha8Rng::seed_from_u64(mix(seed, g))` and are drawn sequentially;
//! evaluations are pure functions of the genes, run in parallel and collected
//! in order, so the result does not depend on the thread count.

use crate::rng::mix;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
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
    /// True if feasible.
    pub fn feasible(&self) -> bool {
        self.violation <= 0.0
    }
    /// Feasibility-first ordering (Less = better).
    pub fn cmp_fitness(&self, o: &Individual) -> std::cmp::Ordering {
        match (self.feasible(), o.feasible()) {
            (true, false) => std::cmp::Ordering::Less,
            (false, true) => std::cmp::Ordering::Greater,
            (false, false) => self.violation.total_cmp(&o.violation),
            (true, true) => self.f.total_cmp(&o.f),
        }
    }
}

/// Settings of one GA run.
#[derive(Debug, Clone)]
pub struct GaSettings {
    /// Population size.
    pub population: usize,
    /// Generations after the initial population.
    pub generations: usize,
    /// Elites kept.
    pub elite: usize,
    /// SBX probability per pair.
    pub crossover: f64,
    /// SBX distribution index.
    pub eta_crossover: f64,
    /// Per-gene mutation probability (0: 1/n).
    pub mutation: f64,
    /// Polynomial mutation distribution index.
    pub eta_mutation: f64,
    /// Seed.
    pub seed: u64,
    /// Stop after this instant (checked between generations).
    pub deadline: Option<Instant>,
}

/// Why the GA stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GaStop {
    /// All generations ran.
    Generations,
    /// The wall-clock budget ran out.
    TimeLimit,
    /// The user asked to stop (Ctrl-C).
    Interrupted,
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

/// Runs the GA. `initial` individuals (genes) are put first into the
/// initial population, the rest drawn uniformly in [lower, upper] and then,
/// for every other one, shrunk towards `centre` by a factor u², u ~ U(0, 1)
/// (small-amplitude individuals near a feasible rest point keep tight
/// workspace constraints satisfiable from the start).
/// `eval(ws, x)` returns (objective, violation) and may repair x in place.
/// `observe(gen, best)` is called after each generation (progress bars).
#[allow(clippy::too_many_arguments)] // bounds, start points and the three callbacks; part B replaces this loop with a solver
pub fn run<W, M, E, O>(s: &GaSettings, lower: &[f64], upper: &[f64], centre: &[f64], initial: &[Vec<f64>], make_ws: M, eval: E, mut observe: O) -> GaResult
where
    M: Fn() -> W + Sync + Send,
    E: Fn(&mut W, &mut Vec<f64>) -> (f64, f64) + Sync + Send,
    O: FnMut(usize, &Individual),
{
    let t0 = Instant::now();
    let nv = lower.len();
    let np = s.population;
    let evaluate = |genes: Vec<Vec<f64>>| -> Vec<Individual> {
        genes
            .into_par_iter()
            .map_init(&make_ws, |ws, mut x| {
                let (f, v) = eval(ws, &mut x);
                let f = if f.is_nan() { f64::INFINITY } else { f };
                let v = if v.is_nan() { f64::INFINITY } else { v };
                Individual { x, f, violation: v }
            })
            .collect()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(mix(s.seed, 0, 0));
    let mut genes: Vec<Vec<f64>> = initial.iter().take(np).cloned().collect();
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
            for (v, c) in x.iter_mut().zip(centre) {
                *v = c + u * u * (*v - c);
            }
        }
        genes.push(x);
    }
    let mut pop = evaluate(genes);
    let mut evaluations = np as u64;
    pop.sort_by(|a, b| a.cmp_fitness(b));
    let stats = |g: usize, pop: &[Individual]| GaGeneration {
        generation: g,
        best_feasible: pop.iter().filter(|i| i.feasible()).map(|i| i.f).fold(f64::INFINITY, f64::min),
        least_violation: pop.iter().map(|i| i.violation).fold(f64::INFINITY, f64::min),
        feasible: pop.iter().filter(|i| i.feasible()).count(),
    };
    let mut history = vec![stats(0, &pop)];
    observe(0, &pop[0]);
    let pm = if s.mutation > 0.0 { s.mutation } else { 1.0 / nv.max(1) as f64 };
    let mut stop = GaStop::Generations;
    let mut done = 0;
    for g in 1..=s.generations {
        if crate::io::stop::requested() {
            stop = GaStop::Interrupted;
            break;
        }
        if s.deadline.is_some_and(|d| Instant::now() >= d) {
            stop = GaStop::TimeLimit;
            break;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(mix(s.seed, g as u64, 1));
        let n_child = np - s.elite;
        let mut children: Vec<Vec<f64>> = Vec::with_capacity(n_child + 1);
        while children.len() < n_child {
            let p1 = tournament(&pop, &mut rng).x.clone();
            let p2 = tournament(&pop, &mut rng).x.clone();
            let (mut c1, mut c2) = (p1, p2);
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
        let mut next: Vec<Individual> = pop[..s.elite].to_vec();
        next.extend(evaluate(children));
        evaluations += n_child as u64;
        next.sort_by(|a, b| a.cmp_fitness(b));
        pop = next;
        history.push(stats(g, &pop));
        observe(g, &pop[0]);
        done = g;
    }
    GaResult {
        population: pop,
        generations: done,
        evaluations,
        history,
        stop,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_constrained_minimum_of_a_quadratic_and_is_reproducible() {
        // min (x0−1)² + (x1+0.5)² s.t. x0 + x1 ≥ 1  → optimum (1.25, −0.25)
        let s = GaSettings {
            population: 40,
            generations: 80,
            elite: 2,
            crossover: 0.9,
            eta_crossover: 10.0,
            mutation: 0.0,
            eta_mutation: 20.0,
            seed: 7,
            deadline: None,
        };
        let ev = |_: &mut (), x: &mut Vec<f64>| ((x[0] - 1.0).powi(2) + (x[1] + 0.5).powi(2), (1.0 - x[0] - x[1]).max(0.0));
        let r = run(&s, &[-3.0, -3.0], &[3.0, 3.0], &[0.0, 0.0], &[], || (), ev, |_, _| {});
        let b = &r.population[0];
        assert!(b.feasible());
        assert!((b.x[0] - 1.25).abs() < 0.05 && (b.x[1] + 0.25).abs() < 0.05, "{:?}", b.x);
        let r2 = run(&s, &[-3.0, -3.0], &[3.0, 3.0], &[0.0, 0.0], &[], || (), ev, |_, _| {});
        assert_eq!(r.population, r2.population);
    }
}
