//! Rounding a relaxed design to whole experiments.
//!
//! * **Efficient rounding** (Pukelsheim & Rieder 1992, the "efficient design
//!   apportionment"): on the support S (l points) of w, m_i = ⌈(M − l/2) w_i⌉,
//!   then while Σm < M increase an m_j with the smallest m_j/w_j, while Σm > M
//!   decrease an m_k with the largest (m_k − 1)/w_k. Its efficiency loss is
//!   O(l/M).
//! * **Exchange**: then, repeatedly, the best single move of one experiment
//!   from candidate i to candidate j (among the support, the candidates with
//!   the largest sensitivities and those already used) that improves the
//!   criterion, until no move improves it.
//!
//! With per-candidate costs c_i and a budget B the plan must satisfy
//! Σ c_i m_i ≤ B: the relaxed weights are budget fractions u_i, the start is
//! m_i = ⌊B u_i / c_i⌋, the rest of the budget is filled greedily (best
//! criterion gain per cost), and the exchange moves keep the budget.
//!
//! The rounded plan's information is F_0 + Σ m_i F_i; its efficiency relative to
//! the relaxed optimum is reported on the normalised scale (÷ M, resp. ÷ B):
//! D: exp((log det M_r − log det M*)/p), A: tr M*⁻¹ / tr M_r⁻¹, E: λ_min(M_r)/λ_min(M*).

use super::problem::{Criterion, Problem};
use super::relax::Relaxed;
use crate::error::{Error, Result};
use crate::optim::Control;
use nalgebra::DMatrix;
use serde::Serialize;

/// An integer plan.
#[derive(Debug, Clone, Serialize)]
pub struct Rounded {
    /// Experiments per candidate.
    pub m: Vec<usize>,
    /// Total experiments Σ m_i.
    pub total: usize,
    /// Total cost Σ c_i m_i (= total without costs).
    pub cost: f64,
    /// Criterion value of the normalised plan (as the relaxed value).
    pub value: f64,
    /// Efficiency relative to the relaxed optimum (≤ 1 up to the relaxed certificate).
    pub efficiency: f64,
    /// Efficiency after efficient rounding, before the exchange step.
    pub efficiency_apportionment: f64,
    /// Exchange moves applied.
    pub exchanges: usize,
    /// Lower bound on the efficiency relative to the best possible relaxed design:
    /// `efficiency` × the relaxed certificate's bound.
    pub efficiency_bound: f64,
}

/// Efficient rounding of weights `w` (≥ 0) to `total` experiments; weights
/// below `1e-5·max w` are treated as zero.
pub fn efficient_rounding(w: &[f64], total: usize) -> Vec<usize> {
    let wmax = w.iter().cloned().fold(0.0, f64::max);
    let mut supp: Vec<usize> = (0..w.len()).filter(|&i| w[i] > 1e-5 * wmax && wmax > 0.0).collect();
    if supp.len() > total {
        // fewer experiments than support points: the `total` largest weights
        supp.sort_by(|&a, &b| w[b].total_cmp(&w[a]));
        supp.truncate(total);
        supp.sort_unstable();
    }
    let mut m = vec![0usize; w.len()];
    if supp.is_empty() || total == 0 {
        return m;
    }
    let s: f64 = supp.iter().map(|&i| w[i]).sum();
    let l = supp.len() as f64;
    let nn = total as f64;
    for &i in &supp {
        m[i] = ((nn - l / 2.0) * w[i] / s).ceil().max(0.0) as usize;
    }
    let mut sum: usize = m.iter().sum();
    while sum < total {
        let j = supp
            .iter()
            .copied()
            .min_by(|&a, &b| (m[a] as f64 / w[a]).total_cmp(&(m[b] as f64 / w[b])))
            .unwrap_or(supp[0]);
        m[j] += 1;
        sum += 1;
    }
    while sum > total {
        let k = supp
            .iter()
            .copied()
            .filter(|&i| m[i] > 0)
            .max_by(|&a, &b| ((m[a] as f64 - 1.0) / w[a]).total_cmp(&((m[b] as f64 - 1.0) / w[b])))
            .unwrap_or(supp[0]);
        m[k] -= 1;
        sum -= 1;
    }
    m
}

/// Criterion value of the information matrix `m` ("higher is better" form:
/// D log det, A −tr M⁻¹, E λ_min); −∞ when singular.
fn score(crit: Criterion, m: &DMatrix<f64>) -> f64 {
    match crit {
        Criterion::D => match m.clone().cholesky() {
            Some(c) => 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>(),
            None => f64::NEG_INFINITY,
        },
        Criterion::A => match m.clone().cholesky() {
            Some(c) => -c.inverse().trace(),
            None => f64::NEG_INFINITY,
        },
        Criterion::E => {
            let l = m.clone().symmetric_eigen().eigenvalues.min();
            if l > 0.0 {
                l
            } else {
                f64::NEG_INFINITY
            }
        }
    }
}

fn to_value(crit: Criterion, s: f64) -> f64 {
    match crit {
        Criterion::A => -s,
        _ => s,
    }
}

/// Efficiency of value `v` relative to the relaxed optimum `v_opt`.
pub fn efficiency(crit: Criterion, p: usize, v: f64, v_opt: f64) -> f64 {
    match crit {
        Criterion::D => ((v - v_opt) / p as f64).exp(),
        Criterion::A => v_opt / v,
        Criterion::E => v / v_opt,
    }
}

/// Rounds the relaxed design to whole experiments and improves it by exchange.
///
/// `pb` is the problem the relaxed design refers to (with costs: the
/// cost-divided problem, prior already divided by the budget); of `relaxed`
/// the weights, their sensitivities (to choose exchange candidates), the
/// relaxed value and the certificate's efficiency bound are used; `budget` is
/// the number of experiments M (or the budget B with `costs`).
pub fn round_design(pb: &Problem, crit: Criterion, relaxed: &Relaxed, budget: f64, costs: Option<&[f64]>, ctl: &Control) -> Result<Rounded> {
    let (w, sens) = (&relaxed.weights[..], &relaxed.sensitivities[..]);
    let (value, bound) = (relaxed.value, relaxed.certificate.efficiency_bound);
    let n = pb.n();
    if w.len() != n || sens.len() != n {
        return Err(Error::dim("weights of the relaxed design", n, w.len()));
    }
    if !(budget >= 1.0 && budget.is_finite()) {
        return Err(Error::invalid("positions", "experiments", "expected at least 1 experiment (or a budget ≥ 1)"));
    }
    let unit = vec![1.0; n];
    let c: &[f64] = costs.unwrap_or(&unit);
    // start
    let mut m = match costs {
        None => efficient_rounding(w, budget.round() as usize),
        Some(c) => (0..n).map(|i| (budget * w[i] / c[i] + 1e-9).floor().max(0.0) as usize).collect(),
    };
    // exchange pool: support, top sensitivities, used candidates
    let wmax = w.iter().cloned().fold(0.0, f64::max);
    let mut pool: Vec<usize> = (0..n).filter(|&i| w[i] > 1e-6 * wmax || m[i] > 0).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| sens[b].total_cmp(&sens[a]));
    let extra = if crit == Criterion::E { pb.p() } else { 3 * pb.p() };
    pool.extend(order.iter().take(extra.min(n)).copied());
    pool.sort_unstable();
    pool.dedup();
    // information of a plan, in the relaxed normalisation: u_i = c_i m_i / B on F_i/c_i
    let fmat: Vec<DMatrix<f64>> = pool.iter().map(|&i| pb.matrix(i) * (c[i] / budget)).collect();
    let plan_info = |m: &[usize]| {
        let mut u = vec![0.0; n];
        for i in 0..n {
            u[i] = c[i] * m[i] as f64 / budget;
        }
        pb.information(&u)
    };
    let spent = |m: &[usize]| (0..n).map(|i| c[i] * m[i] as f64).sum::<f64>();
    let mut info = plan_info(&m);
    // greedy fill of remaining budget (costs) — or of missing experiments
    loop {
        let slack = budget - spent(&m);
        let mut best: Option<(usize, f64)> = None;
        let cur = score(crit, &info);
        for (k, &j) in pool.iter().enumerate() {
            if c[j] <= slack + 1e-9 {
                let s = score(crit, &(&info + &fmat[k]));
                let gain = if cur.is_finite() { (s - cur) / c[j] } else { s };
                if best.map(|b| gain > b.1).unwrap_or(true) {
                    best = Some((k, gain));
                }
            }
        }
        match best {
            Some((k, _)) if costs.is_some() || m.iter().sum::<usize>() < budget.round() as usize => {
                m[pool[k]] += 1;
                info += &fmat[k];
            }
            _ => break,
        }
    }
    let v_app = to_value(crit, score(crit, &info));
    // exchange
    let mut exchanges = 0;
    for _ in 0..1000 {
        if ctl.interrupted() {
            break;
        }
        let cur = score(crit, &info);
        let slack = budget - spent(&m);
        let mut best: Option<(usize, usize, f64)> = None;
        for (ki, &i) in pool.iter().enumerate() {
            if m[i] == 0 {
                continue;
            }
            let base = &info - &fmat[ki];
            for (kj, &j) in pool.iter().enumerate() {
                if j == i || c[j] - c[i] > slack + 1e-9 {
                    continue;
                }
                let s = score(crit, &(&base + &fmat[kj]));
                let improves = if cur.is_finite() {
                    s > cur + 1e-12 * cur.abs().max(1.0)
                } else {
                    s.is_finite()
                };
                if improves && best.map(|b| s > b.2).unwrap_or(true) {
                    best = Some((ki, kj, s));
                }
            }
        }
        match best {
            Some((ki, kj, _)) => {
                m[pool[ki]] -= 1;
                m[pool[kj]] += 1;
                info = &info - &fmat[ki] + &fmat[kj];
                exchanges += 1;
            }
            None => break,
        }
    }
    let info = plan_info(&m);
    let v = to_value(crit, score(crit, &info));
    let p = pb.p();
    let eff = efficiency(crit, p, v, value);
    let eff_app = efficiency(crit, p, v_app, value);
    Ok(Rounded {
        total: m.iter().sum(),
        cost: spent(&m),
        m,
        value: v,
        efficiency: eff,
        efficiency_apportionment: eff_app,
        exchanges,
        efficiency_bound: eff * bound,
    })
}
