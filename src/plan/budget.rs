//! Setup costs and the total-time budget.
//!
//! **Setup costs** (s, paid once by an experiment with at least one
//! repetition: mounting a payload, a recalibration) make the cost
//! Σ_e cost_e r_e + Σ_{e used} setup_e mixed-integer. [`cheapest`] enumerates
//! the subsets S of used experiments (2^n − 1; `design` allows at most
//! [`super::design::MAX_CANDIDATES_WITH_SETUP`] candidates with setups), each
//! with the relaxation of [`super::solve::relax`] over r_e = 0 outside S:
//! every integer plan r is feasible for the relaxation of its own used set
//! U, so cost(r) ≥ lower_U + setup_U ≥ min_S (lower_S + setup_S) — the
//! reported relaxed bound is a true lower bound. Each subset is rounded as
//! without setups (cost with the setups of the experiments the vector
//! really uses) and the cheapest plan over the subsets kept; a subset whose
//! setup or bound already reaches the best plan's cost is pruned (it cannot
//! be cheaper). Without setup costs only the full set is relaxed (the
//! relaxation over all candidates bounds every subset's).
//!
//! **The budget.** When the cheapest plan meeting every target costs more
//! than `budget`, [`within`] finds the best plan within it: the smallest
//! worst value/bound ratio s over the targets. Per subset, the smallest s
//! whose relaxation (every bound × s) fits the budget is found by bisection
//! (the relaxation's lower bound above the budget certifies that no plan of
//! that subset reaches s: the reported **lower bound** on the ratio); the
//! integer vectors within ±window of the relaxed r* there and within the
//! budget (⌊r*⌋ always is) are enumerated and the smallest worst ratio kept.

use super::solve::{next_in_box, relax, round, Prepared, Relaxed, ENUMERATION_LIMIT};
use crate::error::{Error, Result};
use crate::optim::conic::ConicStatus;
use crate::optim::Control;
use serde::Serialize;

/// The cheapest plan over the subsets of used experiments.
#[derive(Debug, Clone)]
pub struct Cheapest {
    /// The relaxed r* of the subset giving the bound.
    pub r: Vec<f64>,
    /// min over subsets of (relaxed lower bound + setup) (s).
    pub lower: f64,
    /// That subset's relaxed upper bound + setup (s).
    pub upper: f64,
    /// The status of the last relaxation (not solved: every plan is void).
    pub status: ConicStatus,
    /// LPs solved in all.
    pub iterations: u32,
    /// The integer plan.
    pub repetitions: Vec<usize>,
    /// How it was rounded.
    pub rounding: String,
    /// Integer vectors evaluated.
    pub evaluated: usize,
}

/// The subsets to relax: only the full set without setup costs (it bounds
/// every subset), else every nonempty subset, cheapest setup first.
fn subsets(pre: &Prepared) -> Vec<Option<u32>> {
    let ne = pre.cost.len();
    if pre.setup.iter().all(|&s| s == 0.0) {
        return vec![None];
    }
    let mut m: Vec<u32> = (1..(1u32 << ne)).collect();
    m.sort_by(|&a, &b| {
        pre.setup_of(a)
            .total_cmp(&pre.setup_of(b))
            .then(b.count_ones().cmp(&a.count_ones()))
            .then(a.cmp(&b))
    });
    m.into_iter().map(Some).collect()
}

/// The cheapest plan meeting every target (module docs); `window` is the
/// rounding's half-width.
pub fn cheapest(pre: &Prepared, window: usize, ctl: &Control) -> Cheapest {
    let ne = pre.cost.len();
    let list = subsets(pre);
    let mut out = Cheapest {
        r: vec![0.0; ne],
        lower: f64::INFINITY,
        upper: f64::INFINITY,
        status: ConicStatus::Solver(crate::optim::conic::SolverStatus::Unsolved),
        iterations: 0,
        repetitions: pre.rmax.clone(),
        rounding: String::new(),
        evaluated: 0,
    };
    let (mut best_cost, mut best_ratio) = (f64::INFINITY, f64::INFINITY);
    let (mut relaxed, mut pruned, mut unreachable) = (0usize, 0usize, 0usize);
    for used in &list {
        let (p, setup) = match used {
            None => (pre.clone(), 0.0),
            Some(u) => (pre.restricted(*u), pre.setup_of(*u)),
        };
        if used.is_some() && p.worst_ratio(&p.rmax) > 1.0 + 1e-9 {
            unreachable += 1;
            continue;
        }
        if setup >= best_cost - 1e-9 {
            pruned += 1;
            continue;
        }
        let rel: Relaxed = relax(&p, ctl);
        out.iterations += rel.iterations;
        out.status = rel.status.clone();
        if !rel.status.is_solved() {
            return out;
        }
        relaxed += 1;
        let lb = rel.lower + setup;
        if lb < out.lower {
            out.lower = lb;
            out.upper = rel.upper + setup;
            out.r = rel.r.clone();
        }
        if lb >= best_cost - 1e-9 {
            pruned += 1;
            continue;
        }
        let (reps, how, n) = round(&p, &rel.r, window);
        out.evaluated += n;
        let (c, ratio) = (pre.cost_of(&reps), pre.worst_ratio(&reps));
        if ratio <= 1.0 + 1e-9 && (c < best_cost - 1e-9 || (c <= best_cost + 1e-9 && ratio < best_ratio)) {
            best_cost = c;
            best_ratio = ratio;
            out.repetitions = reps;
            out.rounding = match used {
                None => how,
                Some(u) => format!("{how}, with {} of {ne} experiments allowed", u.count_ones()),
            };
        }
    }
    if list[0].is_some() {
        out.rounding = format!(
            "{}; setup costs: {} subsets of used experiments, {relaxed} relaxed, {pruned} pruned by their bound, {unreachable} cannot meet the targets",
            out.rounding,
            list.len()
        );
    }
    out
}

/// A target the best plan within the budget misses.
#[derive(Debug, Clone, Serialize)]
pub struct Miss {
    /// Target index.
    pub target: usize,
    /// Its label.
    pub label: String,
    /// The bound asked for.
    pub bound: f64,
    /// The value the plan within the budget reaches.
    pub value: f64,
    /// value / bound (> 1).
    pub ratio: f64,
}

/// The best plan within the budget when the cheapest plan meeting every target exceeds it.
#[derive(Debug, Clone, Serialize)]
pub struct WithinBudget {
    /// Repetitions per candidate.
    pub repetitions: Vec<usize>,
    /// Its robot time (s), ≤ the budget.
    pub cost: f64,
    /// Every target's value.
    pub values: Vec<f64>,
    /// Its worst value / asked bound over the targets (the quantity minimised).
    pub worst_ratio: f64,
    /// No plan within the budget has a worst value / asked bound below this (the relaxation's certificate).
    pub lower_bound: f64,
    /// The targets it misses, and by how much.
    pub missed: Vec<Miss>,
    /// Integer vectors evaluated.
    pub evaluated: usize,
}

/// Largest bisection steps on the ratio per subset.
const BISECTION_STEPS: usize = 40;

/// The best plan within `budget` s (module docs): the smallest worst
/// value/bound ratio. Values and ratios refer to `pre`'s bounds (with the
/// margin); the caller converts. `Err(Interrupted)` on Ctrl-C.
pub fn within(pre: &Prepared, budget: f64, window: usize, ctl: &Control) -> Result<(Vec<usize>, f64, f64, usize)> {
    let ne = pre.cost.len();
    let mut best: Option<(Vec<usize>, f64, f64)> = None; // (r, ratio, cost)
    let mut lower = f64::INFINITY;
    let mut evaluated = 0;
    for used in subsets(pre) {
        if ctl.interrupted() {
            return Err(Error::Interrupted);
        }
        let (p, setup) = match used {
            None => (pre.clone(), 0.0),
            Some(u) => (pre.restricted(u), pre.setup_of(u)),
        };
        let avail = budget - setup;
        if avail <= 0.0 {
            continue;
        }
        let rmax: Vec<f64> = p.rmax.iter().map(|&x| x as f64).collect();
        let s_lo = p.worst_ratio(&p.rmax);
        if !s_lo.is_finite() {
            continue;
        }
        let best_ratio = best.as_ref().map_or(f64::INFINITY, |b| b.1);
        if s_lo >= best_ratio {
            lower = lower.min(s_lo);
            continue;
        }
        let lin: f64 = rmax.iter().zip(&p.cost).map(|(r, c)| r * c).sum();
        let (lo, r_hi) = if lin <= avail {
            (s_lo, rmax.clone())
        } else {
            let fit: Vec<f64> = rmax.iter().map(|r| r * avail / lin).collect();
            let s_hi = p.values(&fit).iter().zip(&p.bound).map(|(v, b)| v / b).fold(0.0, f64::max);
            if !s_hi.is_finite() {
                // the budget's share of every allowed experiment does not see every target: only the bound counts
                lower = lower.min(s_lo);
                continue;
            }
            let (mut lo, mut hi, mut r_hi) = (s_lo, s_hi, fit);
            for _ in 0..BISECTION_STEPS {
                if hi / lo - 1.0 < 1e-4 {
                    break;
                }
                let mid = (lo * hi).sqrt();
                let rel = relax(&p.scaled(mid), ctl);
                if ctl.interrupted() {
                    return Err(Error::Interrupted);
                }
                if !rel.status.is_solved() {
                    break;
                }
                if rel.lower > avail {
                    lo = mid;
                } else if rel.upper <= avail {
                    hi = mid;
                    r_hi = rel.r;
                } else {
                    break;
                }
            }
            (lo, r_hi)
        };
        lower = lower.min(lo);
        let (r, ratio, n) = best_integer_within(&p, &r_hi, budget, window);
        evaluated += n;
        let c = pre.cost_of(&r);
        if best.as_ref().is_none_or(|b| ratio < b.1 - 1e-12 || (ratio <= b.1 + 1e-12 && c < b.2)) {
            best = Some((r, ratio, c));
        }
    }
    match best {
        Some((r, ratio, _)) => Ok((r, ratio, lower.min(ratio), evaluated)),
        None => Ok((vec![0; ne], f64::INFINITY, lower, evaluated)),
    }
}

/// The integer vector within ±`window` of `r` (in `p`'s box) and within
/// `budget` with the smallest worst ratio; beyond the enumeration limit ⌊r⌋
/// grown greedily (the repetition lowering the worst ratio most per second
/// that still fits). Returns (vector, worst ratio, vectors evaluated).
fn best_integer_within(p: &Prepared, r: &[f64], budget: f64, window: usize) -> (Vec<usize>, f64, usize) {
    let ne = r.len();
    let floor: Vec<usize> = r.iter().zip(&p.rmax).map(|(x, &m)| ((x + 1e-9).floor().max(0.0) as usize).min(m)).collect();
    let lo: Vec<usize> = floor.iter().map(|x| x.saturating_sub(window)).collect();
    let hi: Vec<usize> = r.iter().zip(&p.rmax).map(|(x, &m)| ((x.ceil() as usize) + window).min(m)).collect();
    let mut best = (floor.clone(), p.worst_ratio(&floor));
    let mut evaluated = 1;
    let count = lo.iter().zip(&hi).try_fold(1usize, |acc, (l, h)| acc.checked_mul(h - l + 1));
    match count {
        Some(c) if c <= ENUMERATION_LIMIT => {
            let mut cur = lo.clone();
            loop {
                if p.cost_of(&cur) <= budget + 1e-9 {
                    evaluated += 1;
                    let ratio = p.worst_ratio(&cur);
                    if ratio < best.1 - 1e-12 || (ratio <= best.1 + 1e-12 && p.cost_of(&cur) < p.cost_of(&best.0)) {
                        best = (cur.clone(), ratio);
                    }
                }
                if !next_in_box(&mut cur, &lo, &hi) {
                    return (best.0, best.1, evaluated);
                }
            }
        }
        _ => {
            let mut cur = floor;
            loop {
                let base = p.worst_ratio(&cur);
                let pick = (0..ne)
                    .filter(|&e| cur[e] < p.rmax[e])
                    .filter_map(|e| {
                        let mut t = cur.clone();
                        t[e] += 1;
                        (p.cost_of(&t) <= budget + 1e-9).then(|| {
                            evaluated += 1;
                            (e, (base - p.worst_ratio(&t)) / p.cost[e])
                        })
                    })
                    .filter(|x| x.1 > 0.0)
                    .max_by(|a, b| a.1.total_cmp(&b.1));
                match pick {
                    Some((e, _)) => cur[e] += 1,
                    None => {
                        let ratio = p.worst_ratio(&cur);
                        return (cur, ratio, evaluated);
                    }
                }
            }
        }
    }
}
