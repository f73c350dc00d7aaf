//! Sensitivity-based model reduction, paper 000 Algorithm 1.
//!
//! 1. **Rank check** of the design matrix C_0 (line 1): columns are taken in
//!    order of decreasing sensitivity c̄_i and a column is kept when its
//!    residual, after projection on the columns kept before it, exceeds
//!    `rank_tol` of its norm (unit-norm columns); the others are unidentifiable
//!    on this motion and removed before the reduction.
//! 2. WLS on the full model, errors e_{0,j}, e*_{0,j} (lines 2–3).
//! 3. Sets I (included: all) and E (essential: friction parameters when every
//!    joint moves, or a given list) (line 4).
//! 4. For k = 1, 2, …: the parameter i ∈ I \ E with the smallest sensitivity
//!    c̄_i = ‖c_i‖₁/(nN) (eq. 10) is removed, the model re-estimated by WLS and
//!    e*_{k,j} computed; if e*_{k,j}/e*_{0,j} − 1 > e_tol for some joint j the
//!    parameter is put back and added to E, otherwise it stays removed
//!    (lines 5–15). The paper's line 10 states the test as a ratio against
//!    e_tol; its text ("removed parameters are negligible since without them
//!    the model error did not increase by more than 5 %") is the relative growth
//!    used here. Each candidate is tested once, so at most |I| steps.
//!
//! Every step is reported: the parameter, its sensitivity, the decision, the
//! errors and the condition number (unit-norm columns) of the current model.

use super::estimate::{cond_normalized, errors, wls, Dataset, Errors, LsFit, Weights};
use crate::error::Result;
use crate::optim::Control;
use crate::params::BaseParams;
use crate::robot::Robot;
use serde::Serialize;

/// Which parameters may not be removed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Essential {
    /// Friction parameters when every joint moves (max |q̇_j| above `moving_speed`), else none (paper 000 §III-D).
    #[default]
    Auto,
    /// No essential parameters.
    None,
    /// All friction parameters.
    Friction,
    /// The named base parameters.
    Names(Vec<String>),
}

/// Options of the reduction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReduceOptions {
    /// Tolerance e_tol on the relative growth of e*_j.
    pub tol: f64,
    /// Rank tolerance (relative residual of a unit-norm column).
    pub rank_tol: f64,
    /// Essential set.
    pub essential: Essential,
    /// Joint speed above which a joint counts as moving (rad/s or m/s).
    pub moving_speed: f64,
    /// WLS weights.
    pub weights: Weights,
}

impl Default for ReduceOptions {
    fn default() -> Self {
        ReduceOptions {
            tol: 0.05,
            rank_tol: 1e-3,
            essential: Essential::Auto,
            moving_speed: 0.05,
            weights: Weights::Sample,
        }
    }
}

/// One step of Algorithm 1.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// Step k (1-based).
    pub k: usize,
    /// Parameter tried.
    pub parameter: String,
    /// Its sensitivity c̄_i (eq. 10).
    pub sensitivity: f64,
    /// `removed` or `kept`.
    pub decision: String,
    /// e*_{k,j} of the tried model.
    pub e_rel: Vec<f64>,
    /// max_j (e*_{k,j}/e*_{0,j} − 1).
    pub growth: f64,
    /// Condition number (unit-norm columns) of the tried model.
    pub cond: f64,
    /// Parameters in the model after the step.
    pub n_params: usize,
}

/// Result of the reduction.
#[derive(Debug, Clone, Serialize)]
pub struct Reduction {
    /// Options used.
    pub options: ReduceOptions,
    /// Parameters removed by the rank check (unidentifiable on this motion).
    pub rank_removed: Vec<String>,
    /// Essential parameters at the start.
    pub essential: Vec<String>,
    /// The full (rank-checked) model's parameter names.
    pub full_names: Vec<String>,
    /// Full-model fit.
    pub full: LsFit,
    /// Full-model errors e_0, e*_0.
    pub full_errors: Errors,
    /// Steps.
    pub steps: Vec<Step>,
    /// Column indices (into the base parameters) of the final model.
    pub kept: Vec<usize>,
    /// Final model's names.
    pub names: Vec<String>,
    /// Final fit.
    pub reduced: LsFit,
    /// Final errors.
    pub reduced_errors: Errors,
}

/// Sensitivity c̄_i = ‖c_i‖₁/(nN) of each column (eq. 10).
pub fn sensitivities(ds: &Dataset) -> Vec<f64> {
    let rows = ds.c.nrows() as f64;
    ds.c.column_iter().map(|c| c.iter().map(|v| v.abs()).sum::<f64>() / rows).collect()
}

fn growth(e: &Errors, e0: &Errors) -> f64 {
    e.e_rel
        .iter()
        .zip(&e0.e_rel)
        .map(|(a, b)| {
            if *b > 0.0 {
                a / b - 1.0
            } else if *a > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Runs Algorithm 1 on a dataset whose columns are the base parameters of `base`.
/// `moving[j]` tells whether joint j moves (for [`Essential::Auto`]).
pub fn reduce(robot: &Robot, base: &BaseParams, ds: &Dataset, moving: &[bool], opts: &ReduceOptions, ctl: &Control) -> Result<Reduction> {
    let sens = sensitivities(ds);
    let nb = ds.c.ncols();
    // 1. rank check, most sensitive columns first
    let mut order: Vec<usize> = (0..nb).collect();
    order.sort_by(|&a, &b| sens[b].total_cmp(&sens[a]));
    let mut basis: Vec<nalgebra::DVector<f64>> = Vec::new();
    let mut full: Vec<usize> = Vec::new();
    let mut rank_removed = Vec::new();
    for &c in &order {
        let col = ds.c.column(c);
        let nrm = col.norm();
        if nrm == 0.0 {
            rank_removed.push(c);
            continue;
        }
        let mut v = col / nrm;
        crate::linalg::orthogonalize(&basis, &mut v);
        let res = v.norm();
        if res > opts.rank_tol {
            basis.push(v / res);
            full.push(c);
        } else {
            rank_removed.push(c);
        }
    }
    full.sort_unstable();
    rank_removed.sort_unstable();
    // essential set
    let info = robot.params();
    let is_friction = |c: usize| info[base.independent[c]].kind.is_friction();
    let essential: Vec<usize> = match &opts.essential {
        Essential::None => vec![],
        Essential::Friction => full.iter().copied().filter(|&c| is_friction(c)).collect(),
        Essential::Auto => {
            if moving.iter().all(|&m| m) {
                full.iter().copied().filter(|&c| is_friction(c)).collect()
            } else {
                vec![]
            }
        }
        Essential::Names(names) => {
            let mut v = Vec::new();
            for nm in names {
                match ds.names.iter().position(|x| x == nm) {
                    Some(c) => v.push(c),
                    None => {
                        return Err(crate::Error::invalid(
                            "model reduction",
                            "essential",
                            format!("no base parameter named {nm:?}; the base parameters are {}", ds.names.join(", ")),
                        ))
                    }
                }
            }
            v.into_iter().filter(|c| full.contains(c)).collect()
        }
    };
    // 2. full model
    let dfull = ds.columns(&full);
    let fit0 = wls(&dfull, opts.weights)?;
    let e0 = errors(&dfull, &fit0.theta);
    // 4. backward stepwise
    let mut kept = full.clone();
    let mut ess = essential.clone();
    let mut steps = Vec::new();
    let mut tested: Vec<usize> = Vec::new();
    let mut k = 0;
    loop {
        if ctl.should_stop() {
            break;
        }
        let cand = kept
            .iter()
            .copied()
            .filter(|c| !ess.contains(c) && !tested.contains(c))
            .min_by(|&a, &b| sens[a].total_cmp(&sens[b]));
        let Some(i) = cand else { break };
        tested.push(i);
        if kept.len() == 1 {
            break;
        }
        k += 1;
        let trial: Vec<usize> = kept.iter().copied().filter(|&c| c != i).collect();
        let dt = ds.columns(&trial);
        let fit = wls(&dt, opts.weights)?;
        let e = errors(&dt, &fit.theta);
        let g = growth(&e, &e0);
        let removed = g <= opts.tol;
        if removed {
            kept = trial;
        } else {
            ess.push(i);
        }
        steps.push(Step {
            k,
            parameter: ds.names[i].clone(),
            sensitivity: sens[i],
            decision: if removed { "removed".into() } else { "kept".into() },
            e_rel: e.e_rel.clone(),
            growth: g,
            cond: cond_normalized(&dt.c)?,
            n_params: kept.len(),
        });
    }
    let dred = ds.columns(&kept);
    let reduced = wls(&dred, opts.weights)?;
    let reduced_errors = errors(&dred, &reduced.theta);
    Ok(Reduction {
        options: opts.clone(),
        rank_removed: rank_removed.iter().map(|&c| ds.names[c].clone()).collect(),
        essential: essential.iter().map(|&c| ds.names[c].clone()).collect(),
        full_names: full.iter().map(|&c| ds.names[c].clone()).collect(),
        full: fit0,
        full_errors: e0,
        steps,
        names: kept.iter().map(|&c| ds.names[c].clone()).collect(),
        kept,
        reduced,
        reduced_errors,
    })
}

impl Reduction {
    /// Text report: the steps and the table of full vs reduced estimates (paper 000 Table IV).
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "model reduction (paper 000 Algorithm 1), e_tol = {}", self.options.tol);
        if !self.rank_removed.is_empty() {
            let _ = writeln!(s, "rank check: unidentifiable on this motion, removed first: {}", self.rank_removed.join(" "));
        }
        let _ = writeln!(
            s,
            "essential: {}",
            if self.essential.is_empty() {
                "(none)".into()
            } else {
                self.essential.join(" ")
            }
        );
        let _ = writeln!(
            s,
            "full model: {} parameters, cond {:.3}, e* = [{}] %",
            self.full_names.len(),
            self.full.cond_normalized,
            pct(&self.full_errors.e_rel)
        );
        let _ = writeln!(
            s,
            "{:>4} {:<10} {:>11} {:>8} {:>9} {:>10} {:>4}  e*_k (%)",
            "k", "parameter", "sensitivity", "decision", "growth", "cond", "n"
        );
        for st in &self.steps {
            let _ = writeln!(
                s,
                "{:>4} {:<10} {:>11.4e} {:>8} {:>8.2}% {:>10.3} {:>4}  [{}]",
                st.k,
                st.parameter,
                st.sensitivity,
                st.decision,
                100.0 * st.growth,
                st.cond,
                st.n_params,
                pct(&st.e_rel)
            );
        }
        let _ = writeln!(
            s,
            "reduced model: {} parameters, cond {:.3} (full {:.3}, ratio {:.2}), e* = [{}] %",
            self.names.len(),
            self.reduced.cond_normalized,
            self.full.cond_normalized,
            self.full.cond_normalized / self.reduced.cond_normalized,
            pct(&self.reduced_errors.e_rel)
        );
        let _ = writeln!(s, "\n{:<10} {:>14} {:>14}", "parameter", "θ̂_0 (full)", "θ̂_r (reduced)");
        for (i, nm) in self.full_names.iter().enumerate() {
            let red = self
                .names
                .iter()
                .position(|x| x == nm)
                .map(|r| format!("{:.6}", self.reduced.theta[r]))
                .unwrap_or_else(|| "-".into());
            let _ = writeln!(s, "{:<10} {:>14.6} {:>14}", nm, self.full.theta[i], red);
        }
        s
    }
}

fn pct(v: &[f64]) -> String {
    v.iter().map(|x| format!("{:.3}", 100.0 * x)).collect::<Vec<_>>().join(", ")
}
