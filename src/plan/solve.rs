//! The cheapest integer repetitions meeting every target: a semidefinite
//! relaxation on Clarabel, then rounding by enumeration around it.
//!
//! **Relaxation.** With Φ(r) = Λ + Σ_e r_e M_e (the information of
//! [`super::model`]), target i bounds σ_i² = c_iᵀΦ⁻¹c_i ≤ t_i², and a task
//! bounds its mean squared prediction error tr(G Φ⁻¹) = tr(UᵀΦ⁻¹U) ≤ t²
//! (G = UUᵀ). With B = [c_1/t_1 … c_m/t_m, U_1/t_1 …] all of them are one
//! linear matrix inequality (Schur complement):
//!
//! ```text
//! min Σ_e cost_e r_e   s.t.  [ Z   Bᵀ  ]
//!                            [ B   Φ(r)] ⪰ 0,   Z_ii ≤ 1 (parameters),  Σ_{k ∈ task} Z_kk ≤ 1,
//!                            0 ≤ r_e ≤ r_max,e
//! ```
//!
//! exact for real r (Z ⪰ BᵀΦ⁻¹B, so each bound holds iff some Z meets it):
//! [`relax_sdp`]. Clarabel's PSD block is dense in the svec dimension, so
//! [`relax`] solves the same convex problem by **supporting hyperplanes**:
//! each g_i(r) = value_i²/t_i² is convex in r (a matrix-fractional function
//! of the affine Φ(r)), with ∂g_i/∂r_e = −tr(B_iᵀΦ⁻¹M_eΦ⁻¹B_i)/t_i²; its tangent
//! planes bound the feasible set from outside, an LP over them (Clarabel)
//! gives a lower bound, and the boundary point toward r_max a feasible upper
//! bound (tests: both agree with the SDP). The lower bound is a lower bound
//! on every integer plan's cost.
//!
//! **Rounding.** ⌈r*⌉ is feasible (Φ grows with every r_e). Every integer
//! vector within ±`window` of r* (clipped to [0, r_max]) is then evaluated by
//! Cholesky factorisation of Φ and the cheapest feasible one kept (ties: the
//! largest margin); beyond [`ENUMERATION_LIMIT`] vectors, ⌈r*⌉ is trimmed
//! greedily instead (the most expensive repetition whose removal keeps every
//! target, repeatedly). The report gives both costs and the gap.
//!
//! **Refusal.** Before any of this the targets are evaluated with every
//! experiment at its largest repetitions: a target missed there is
//! unreachable, with the reason (not a function of the base parameters; not
//! seen by any candidate; below what the noise allows) and the best value.

use super::model::{Model, Space, TargetKind};
use crate::error::Result;
use crate::optim::conic::{self as bridge, svec_index, svec_scale, Cone, ConicStatus, Entries, Program, Settings};
use crate::optim::Control;
use nalgebra::DMatrix;
use serde::Serialize;

/// Integer vectors enumerated around the relaxed solution at most.
pub const ENUMERATION_LIMIT: usize = 200_000;

/// The matrices of the problem in the plan's space, ready for evaluation.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// M_e per candidate.
    pub m: Vec<DMatrix<f64>>,
    /// Λ (zero without a prior).
    pub lambda: DMatrix<f64>,
    /// c_i of the parameter targets (columns), in target order; task targets hold U.
    pub b: Vec<DMatrix<f64>>,
    /// Whether each target is a task (its value is an RMS: √tr(UᵀΦ⁻¹U)).
    pub is_task: Vec<bool>,
    /// The bounds planned for: each target's bound / (1 + margin).
    pub bound: Vec<f64>,
    /// Costs per repetition (s).
    pub cost: Vec<f64>,
    /// Setup costs (s), paid once by an experiment with at least one repetition.
    pub setup: Vec<f64>,
    /// Largest repetitions.
    pub rmax: Vec<usize>,
}

impl Prepared {
    /// From a model.
    pub fn new(model: &Model) -> Prepared {
        let p = model.dim();
        let m = (0..model.candidates.len()).map(|e| model.info(e)).collect();
        let lambda = match &model.prior {
            Some(l) => DMatrix::from_diagonal(l),
            None => DMatrix::zeros(p, p),
        };
        let mut b = Vec::new();
        let mut is_task = Vec::new();
        for t in &model.targets {
            match t.kind {
                TargetKind::Task { task } => {
                    let g = model.task_gram(task);
                    let eig = g.symmetric_eigen();
                    let top = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
                    let keep: Vec<usize> = (0..p).filter(|&k| eig.eigenvalues[k] > 1e-12 * top).collect();
                    let mut u = DMatrix::zeros(p, keep.len());
                    for (c, &k) in keep.iter().enumerate() {
                        u.set_column(c, &(eig.eigenvectors.column(k) * eig.eigenvalues[k].sqrt()));
                    }
                    b.push(u);
                    is_task.push(true);
                }
                TargetKind::Parameter { .. } => {
                    b.push(DMatrix::from_column_slice(p, 1, t.c.as_slice()));
                    is_task.push(false);
                }
            }
        }
        Prepared {
            m,
            lambda,
            b,
            is_task,
            bound: model.targets.iter().map(|t| t.bound / (1.0 + model.margin)).collect(),
            cost: model.candidates.iter().map(|c| c.cost).collect(),
            setup: model.candidates.iter().map(|c| c.setup).collect(),
            rmax: model.candidates.iter().map(|c| c.max_repetitions).collect(),
        }
    }

    /// Φ(r).
    pub fn phi(&self, r: &[f64]) -> DMatrix<f64> {
        let mut f = self.lambda.clone();
        for (e, &x) in r.iter().enumerate() {
            if x != 0.0 {
                f += &self.m[e] * x;
            }
        }
        f
    }

    /// Every target's value (σ or RMS) for repetitions `r`; infinite where Φ is singular.
    pub fn values(&self, r: &[f64]) -> Vec<f64> {
        values_of(&self.phi(r), &self.b)
    }

    /// Cost of `r` (s): the repetitions' and the setups of the experiments used.
    pub fn cost_of(&self, r: &[usize]) -> f64 {
        r.iter()
            .zip(self.cost.iter().zip(&self.setup))
            .map(|(&x, (c, su))| if x > 0 { x as f64 * c + su } else { 0.0 })
            .sum()
    }

    /// The same problem with only the experiments in `used` (a bit mask) allowed.
    pub fn restricted(&self, used: u32) -> Prepared {
        let mut p = self.clone();
        for (e, m) in p.rmax.iter_mut().enumerate() {
            if used & (1 << e) == 0 {
                *m = 0;
            }
        }
        p
    }

    /// The same problem with every bound multiplied by `s`.
    pub fn scaled(&self, s: f64) -> Prepared {
        let mut p = self.clone();
        for b in &mut p.bound {
            *b *= s;
        }
        p
    }

    /// The setup paid when every experiment in `used` is used (s).
    pub fn setup_of(&self, used: u32) -> f64 {
        (0..self.setup.len()).filter(|e| used & (1 << e) != 0).map(|e| self.setup[e]).sum()
    }

    /// Largest value/bound ratio (≤ 1: every target met).
    pub fn worst_ratio(&self, r: &[usize]) -> f64 {
        let rf: Vec<f64> = r.iter().map(|&x| x as f64).collect();
        self.values(&rf).iter().zip(&self.bound).map(|(v, b)| v / b).fold(0.0, f64::max)
    }
}

/// √(diag or trace of BᵀΦ⁻¹B) per block; infinite where Φ is not positive definite.
pub fn values_of(phi: &DMatrix<f64>, b: &[DMatrix<f64>]) -> Vec<f64> {
    let p = phi.nrows();
    // a relative jitter-free check: Cholesky must succeed and the pivots stay above 1e-13 of the diagonal
    let dmax = phi.diagonal().iter().cloned().fold(0.0, f64::max);
    let chol = phi.clone().cholesky().filter(|c| (0..p).all(|i| c.l_dirty()[(i, i)].powi(2) > 1e-13 * dmax));
    match chol {
        None => vec![f64::INFINITY; b.len()],
        Some(c) => b
            .iter()
            .map(|bi| {
                let mut x = bi.clone();
                c.l().solve_lower_triangular_mut(&mut x);
                x.iter().map(|v| v * v).sum::<f64>().sqrt()
            })
            .collect(),
    }
}

/// How the plan was found.
#[derive(Debug, Clone, Serialize)]
pub struct Solution {
    /// `planned`, `unreachable`, `over_budget`, `interrupted` or `failed`.
    pub status: PlanStatus,
    /// Relaxed repetitions r*.
    pub relaxed: Vec<f64>,
    /// Lower bound on the relaxed cost (s, setups included): a lower bound on every plan's.
    pub relaxed_cost: f64,
    /// Cost of the relaxed r* (s): the relaxation solved to `relaxed_upper − relaxed_cost`.
    pub relaxed_upper: f64,
    /// Clarabel's status of the relaxation.
    pub solver_status: String,
    /// Interior-point iterations.
    pub iterations: u32,
    /// The integer plan.
    pub repetitions: Vec<usize>,
    /// Its cost (s): repetitions and the setups of the experiments used.
    pub cost: f64,
    /// cost − relaxed_cost (s).
    pub gap: f64,
    /// How the rounding searched.
    pub rounding: String,
    /// Integer vectors evaluated.
    pub evaluated: usize,
    /// Every target's value for the plan (the cheapest meeting every target, also when over the budget).
    pub values: Vec<f64>,
    /// Every target's value with every experiment at its largest repetitions.
    pub best: Vec<f64>,
    /// The unreachable targets and why.
    pub refused: Vec<Refusal>,
    /// The total robot time available (s), if the design sets one.
    pub budget: Option<f64>,
    /// `over_budget`: the best plan within the budget and the targets it misses.
    pub within_budget: Option<super::budget::WithinBudget>,
}

/// How planning ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlanStatus {
    /// Every target met by the plan.
    Planned,
    /// Some target cannot be met by any combination.
    Unreachable,
    /// Every target can be met, but not within the budget (`within_budget` has the best plan that fits).
    OverBudget,
    /// Ctrl-C stopped the relaxation.
    Interrupted,
    /// The relaxation failed (its status says how).
    Failed,
}

impl PlanStatus {
    /// The name in plan.json (`planned`, `unreachable`, `over_budget`, `interrupted`, `failed`).
    pub fn name(self) -> &'static str {
        match self {
            PlanStatus::Planned => "planned",
            PlanStatus::Unreachable => "unreachable",
            PlanStatus::OverBudget => "over_budget",
            PlanStatus::Interrupted => "interrupted",
            PlanStatus::Failed => "failed",
        }
    }
}

/// A target no combination meets.
#[derive(Debug, Clone, Serialize)]
pub struct Refusal {
    /// Target index.
    pub target: usize,
    /// Its label.
    pub label: String,
    /// Why.
    pub reason: String,
    /// The best reachable value (every experiment at its largest repetitions; infinite: none).
    pub best: f64,
    /// The bound asked for.
    pub bound: f64,
}

/// Plans `model` (see the module documentation and [`super::budget`]);
/// `window` is the enumeration's half-width around the relaxed solution.
pub fn plan(model: &Model, window: usize, ctl: &Control) -> Result<Solution> {
    let pre = Prepared::new(model);
    let ne = pre.cost.len();
    let rmax_f: Vec<f64> = pre.rmax.iter().map(|&x| x as f64).collect();
    let best = pre.values(&rmax_f);
    let mut sol = Solution {
        status: PlanStatus::Planned,
        relaxed: vec![0.0; ne],
        relaxed_cost: 0.0,
        relaxed_upper: 0.0,
        solver_status: String::new(),
        iterations: 0,
        repetitions: pre.rmax.clone(),
        cost: pre.cost_of(&pre.rmax),
        gap: 0.0,
        rounding: String::new(),
        evaluated: 0,
        values: best.clone(),
        best: best.clone(),
        refused: Vec::new(),
        budget: model.budget,
        within_budget: None,
    };
    sol.refused = refusals(model, &pre, &best);
    if !sol.refused.is_empty() {
        sol.status = PlanStatus::Unreachable;
        return Ok(sol);
    }
    let found = super::budget::cheapest(&pre, window, ctl);
    sol.solver_status = found.status.to_string();
    sol.iterations = found.iterations;
    if !found.status.is_solved() {
        sol.status = if ctl.interrupted() { PlanStatus::Interrupted } else { PlanStatus::Failed };
        return Ok(sol);
    }
    sol.relaxed_cost = found.lower;
    sol.relaxed_upper = found.upper;
    sol.relaxed = found.r;
    sol.repetitions = found.repetitions;
    sol.rounding = found.rounding;
    sol.evaluated = found.evaluated;
    set_plan(&mut sol, &pre);
    if let Some(budget) = model.budget {
        if sol.cost > budget + 1e-9 {
            let (r, ratio, lower, n) = match super::budget::within(&pre, budget, window, ctl) {
                Ok(x) => x,
                Err(crate::error::Error::Interrupted) => {
                    sol.status = PlanStatus::Interrupted;
                    return Ok(sol);
                }
                Err(e) => return Err(e),
            };
            sol.evaluated += n;
            if ratio <= 1.0 + 1e-9 {
                // the rounding missed a cheaper plan that the budget's search found
                sol.repetitions = r;
                sol.rounding += "; a cheaper plan within the budget found by the budget's search";
                set_plan(&mut sol, &pre);
            } else {
                let k = 1.0 + model.margin;
                let values = pre.values(&r.iter().map(|&x| x as f64).collect::<Vec<_>>());
                let missed = model
                    .targets
                    .iter()
                    .enumerate()
                    .filter(|(i, t)| values[*i] > t.bound * (1.0 + 1e-9))
                    .map(|(i, t)| super::budget::Miss {
                        target: i,
                        label: t.label.clone(),
                        bound: t.bound,
                        value: values[i],
                        ratio: values[i] / t.bound,
                    })
                    .collect();
                sol.within_budget = Some(super::budget::WithinBudget {
                    cost: pre.cost_of(&r),
                    repetitions: r,
                    values,
                    worst_ratio: ratio / k,
                    lower_bound: lower / k,
                    missed,
                    evaluated: n,
                });
                sol.status = PlanStatus::OverBudget;
            }
        }
    }
    Ok(sol)
}

/// Cost, gap and values of `sol.repetitions`.
fn set_plan(sol: &mut Solution, pre: &Prepared) {
    sol.cost = pre.cost_of(&sol.repetitions);
    sol.gap = sol.cost - sol.relaxed_cost;
    sol.values = pre.values(&sol.repetitions.iter().map(|&x| x as f64).collect::<Vec<_>>());
}

/// The targets missed with every experiment at its largest repetitions, and why.
fn refusals(model: &Model, pre: &Prepared, best: &[f64]) -> Vec<Refusal> {
    let data_only = {
        let mut f = DMatrix::zeros(model.dim(), model.dim());
        for (e, m) in pre.m.iter().enumerate() {
            f += m * pre.rmax[e] as f64;
        }
        f
    };
    let rank = super::model::rank_of(&data_only);
    let mut out = Vec::new();
    for (i, t) in model.targets.iter().enumerate() {
        let never = model.space == Space::Base && matches!(t.kind, TargetKind::Parameter { identifiable: false, .. });
        if !never && best[i] <= pre.bound[i] * (1.0 + 1e-9) {
            continue;
        }
        let reason = match &t.kind {
            TargetKind::Parameter { name, identifiable: false, .. } => match model.space {
                Space::Base => format!("structurally unidentifiable: `{name}` is not a function of the base parameters (it never appears in the torques alone, only in groupings): no experiment estimates it; target a base parameter that contains it, or add a [consistent] prior"),
                Space::Standard => format!("structurally unidentifiable: `{name}` is not a function of the base parameters; only the prior speaks about it (its σ with the prior alone is {:.4e})", best[i]),
            },
            _ if !best[i].is_finite() => format!(
                "the candidates together see only {rank} of {} directions of the base parameters: the study without a prior cannot estimate this; add an experiment that excites the rest, or a [consistent] prior",
                model.base.n_base()
            ),
            TargetKind::Parameter { .. } => format!(
                "below what the noise allows: with every experiment at its largest repetitions σ = {:.4e} > {:.4e} (the bound {:.4e} / (1 + margin {})); allow more repetitions or add a quieter or richer experiment",
                best[i], pre.bound[i], t.bound, model.margin
            ),
            TargetKind::Task { .. } => format!(
                "below what the noise allows: with every experiment at its largest repetitions the RMS prediction error is {:.4e} N·m > {:.4e} (the bound {:.4e} / (1 + margin {}))",
                best[i], pre.bound[i], t.bound, model.margin
            ),
        };
        out.push(Refusal {
            target: i,
            label: t.label.clone(),
            reason,
            best: if never { f64::INFINITY } else { best[i] },
            bound: t.bound,
        });
    }
    out
}

/// The relaxation as one semidefinite program (module docs): r*, the status
/// and the iterations. Exact, but Clarabel's PSD block is dense in the
/// svec dimension ((m + p)(m + p + 1)/2 rows): for checks on small problems;
/// [`relax`] solves the same problem by supporting hyperplanes.
pub fn relax_sdp(pre: &Prepared, ctl: &Control) -> (Vec<f64>, ConicStatus, u32) {
    let ne = pre.cost.len();
    let p = pre.lambda.nrows();
    // scaling: Φ(r_max) with a unit diagonal
    let rmax_f: Vec<f64> = pre.rmax.iter().map(|&x| x as f64).collect();
    let full = pre.phi(&rmax_f);
    let d: Vec<f64> = (0..p).map(|i| if full[(i, i)] > 0.0 { 1.0 / full[(i, i)].sqrt() } else { 1.0 }).collect();
    // B columns, scaled by D and by 1 / bound
    let mut cols: Vec<Vec<f64>> = Vec::new();
    let mut blocks: Vec<(usize, usize, bool)> = Vec::new(); // (first column, columns, task)
    for (k, bk) in pre.b.iter().enumerate() {
        blocks.push((cols.len(), bk.ncols(), pre.is_task[k]));
        for c in 0..bk.ncols() {
            cols.push((0..p).map(|i| d[i] * bk[(i, c)] / pre.bound[k]).collect());
        }
    }
    let m = cols.len();
    let nz = m * (m + 1) / 2;
    let zvar = |a: usize, b: usize| ne + svec_index(a, b);
    let n_var = ne + nz;
    let cmax = pre.cost.iter().cloned().fold(0.0, f64::max);
    let mut q = vec![0.0; n_var];
    for e in 0..ne {
        q[e] = pre.cost[e] / cmax;
    }
    let mut a = Entries::new();
    let mut b = Vec::new();
    let mut cones = Vec::new();
    // 0 ≤ r_e ≤ r_max, the target rows
    let nn = 2 * ne + blocks.len();
    let r0 = a.rows(nn);
    for e in 0..ne {
        a.push(r0 + e, e, -1.0);
        b.push(0.0);
    }
    for e in 0..ne {
        a.push(r0 + ne + e, e, 1.0);
        b.push(rmax_f[e]);
    }
    for (k, &(c0, nc, _)) in blocks.iter().enumerate() {
        for c in c0..c0 + nc {
            a.push(r0 + 2 * ne + k, zvar(c, c), 1.0);
        }
        b.push(1.0);
    }
    cones.push(Cone::Nonnegative(nn));
    // the LMI [[Z, Bᵀ], [B, Φ(r)]] ⪰ 0
    let n = m + p;
    let nsv = n * (n + 1) / 2;
    let rs = a.rows(nsv);
    let mut bb = vec![0.0; nsv];
    for j in 0..m {
        for i in 0..=j {
            a.push(rs + svec_index(i, j), zvar(i, j), -svec_scale(i, j));
        }
    }
    for (c, col) in cols.iter().enumerate() {
        for i in 0..p {
            bb[svec_index(c, m + i)] = col[i] * svec_scale(c, m + i);
        }
    }
    for j in 0..p {
        for i in 0..=j {
            let s = svec_scale(i, j);
            let row = svec_index(m + i, m + j);
            bb[row] = pre.lambda[(i, j)] * d[i] * d[j] * s;
            for e in 0..ne {
                let v = pre.m[e][(i, j)] * d[i] * d[j];
                if v != 0.0 {
                    a.push(rs + row, e, -v * s);
                }
            }
        }
    }
    b.extend_from_slice(&bb);
    cones.push(Cone::PsdTriangle(n));
    let prog = Program {
        n_var,
        p: None,
        q,
        a,
        b,
        cones,
    };
    let set = Settings {
        tol: Some(1e-9),
        max_iter: Some(200),
        ..Default::default()
    };
    let s = bridge::solve(prog, &set, ctl);
    let r = if s.x.len() >= ne { s.x[..ne].to_vec() } else { vec![0.0; ne] };
    (r, s.status, s.iterations)
}

/// The relaxation's result.
#[derive(Debug, Clone)]
pub struct Relaxed {
    /// The best feasible real r found (its cost is `upper`).
    pub r: Vec<f64>,
    /// A lower bound on the relaxed (and so on every integer plan's) cost (s).
    pub lower: f64,
    /// The cost of `r` (s).
    pub upper: f64,
    /// The last LP's status (`Solved` when the bounds met).
    pub status: ConicStatus,
    /// Outer iterations (LPs solved).
    pub iterations: u32,
    /// Cuts added.
    pub cuts: usize,
}

/// Every target's g_i = value²/bound² and its gradient in r, at `r` (None: Φ singular).
fn ratios_and_gradients(pre: &Prepared, r: &[f64]) -> Option<(Vec<f64>, Vec<Vec<f64>>)> {
    let phi = pre.phi(r);
    let p = phi.nrows();
    let dmax = phi.diagonal().iter().cloned().fold(0.0, f64::max);
    let chol = phi.cholesky().filter(|c| (0..p).all(|i| c.l_dirty()[(i, i)].powi(2) > 1e-13 * dmax))?;
    let mut g = Vec::with_capacity(pre.b.len());
    let mut grad = Vec::with_capacity(pre.b.len());
    for (i, bi) in pre.b.iter().enumerate() {
        let w = chol.solve(bi); // Φ⁻¹ B_i
        let t2 = pre.bound[i] * pre.bound[i];
        g.push(bi.iter().zip(w.iter()).map(|(a, b)| a * b).sum::<f64>() / t2);
        grad.push(pre.m.iter().map(|me| -(w.transpose() * me * &w).trace() / t2).collect());
    }
    Some((g, grad))
}

/// The relaxation by supporting hyperplanes (Veinott): g_i(r) ≤ 1 are
/// convex, so their tangent planes at any point bound the feasible set from
/// outside. Each LP (Clarabel) over the planes gives a lower bound and a
/// point r_k; the boundary point on the segment from the interior point
/// r_max to r_k (bisection on max_i g_i = 1) is feasible (an upper bound)
/// and adds the tangent planes of the targets near their bound there.
/// Stops when the bounds agree to 1e-7 (relative) or after 400 LPs.
pub fn relax(pre: &Prepared, ctl: &Control) -> Relaxed {
    let ne = pre.cost.len();
    let rmax: Vec<f64> = pre.rmax.iter().map(|&x| x as f64).collect();
    let cost = |r: &[f64]| r.iter().zip(&pre.cost).map(|(a, c)| a * c).sum::<f64>();
    let worst = |r: &[f64]| ratios_and_gradients(pre, r).map_or(f64::INFINITY, |(g, _)| g.iter().cloned().fold(0.0, f64::max));
    let mut cuts: Vec<(Vec<f64>, f64)> = Vec::new(); // a·r ≤ b
    let add_cuts = |at: &[f64], cuts: &mut Vec<(Vec<f64>, f64)>| {
        if let Some((g, grad)) = ratios_and_gradients(pre, at) {
            let top = g.iter().cloned().fold(0.0, f64::max);
            for (gi, di) in g.iter().zip(&grad) {
                if *gi >= 0.9 * top {
                    let rhs = 1.0 - gi + di.iter().zip(at).map(|(a, b)| a * b).sum::<f64>();
                    cuts.push((di.clone(), rhs));
                }
            }
        }
    };
    let mut best = rmax.clone();
    let mut upper = cost(&best);
    add_cuts(&best, &mut cuts);
    let cmax = pre.cost.iter().cloned().fold(0.0, f64::max);
    let mut lower = 0.0;
    let mut status = ConicStatus::Solver(bridge::SolverStatus::Unsolved);
    let mut iterations = 0;
    while iterations < 400 {
        if ctl.interrupted() {
            status = ConicStatus::Solver(bridge::SolverStatus::CallbackTerminated);
            break;
        }
        // the LP: min cost·r over the cuts and the box
        let mut a = Entries::new();
        let mut b = Vec::new();
        let nrow = 2 * ne + cuts.len();
        let r0 = a.rows(nrow);
        for e in 0..ne {
            a.push(r0 + e, e, -1.0);
            b.push(0.0);
            a.push(r0 + ne + e, e, 1.0);
        }
        b.extend_from_slice(&rmax);
        for (k, (d, rhs)) in cuts.iter().enumerate() {
            // scale each row to a unit gradient
            let nrm = d.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300);
            for e in 0..ne {
                a.push(r0 + 2 * ne + k, e, d[e] / nrm);
            }
            b.push(rhs / nrm);
        }
        let prog = Program {
            n_var: ne,
            p: None,
            q: pre.cost.iter().map(|c| c / cmax).collect(),
            a,
            b,
            cones: vec![Cone::Nonnegative(nrow)],
        };
        let s = bridge::solve(
            prog,
            &Settings {
                tol: Some(1e-10),
                ..Default::default()
            },
            ctl,
        );
        iterations += 1;
        status = s.status.clone();
        if !s.status.is_solved() || s.x.len() < ne {
            break;
        }
        let rk: Vec<f64> = s.x.iter().zip(&rmax).map(|(x, m)| x.clamp(0.0, *m)).collect();
        lower = cost(&rk).max(lower);
        // the boundary point between r_max (feasible) and r_k
        let (mut lo, mut hi) = (0.0f64, 1.0f64); // fraction toward r_max
        let at = |f: f64| -> Vec<f64> { rk.iter().zip(&rmax).map(|(a, m)| a + f * (m - a)).collect() };
        if worst(&rk) > 1.0 {
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if worst(&at(mid)) <= 1.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
        } else {
            hi = 0.0;
        }
        let pk = at(hi);
        if cost(&pk) < upper {
            upper = cost(&pk);
            best = pk.clone();
        }
        if upper - lower <= 1e-7 * upper.max(1e-300) {
            break;
        }
        add_cuts(&pk, &mut cuts);
    }
    Relaxed {
        r: best,
        lower,
        upper,
        status,
        iterations,
        cuts: cuts.len(),
    }
}

/// Rounds r* (module docs): the plan, how, and the vectors evaluated.
pub fn round(pre: &Prepared, r: &[f64], window: usize) -> (Vec<usize>, String, usize) {
    let ne = r.len();
    let ok = |x: &[usize]| pre.worst_ratio(x) <= 1.0 + 1e-9;
    // ⌈r*⌉ (feasible up to the solver's tolerance), repaired greedily if not
    let mut start: Vec<usize> = r.iter().zip(&pre.rmax).map(|(x, &m)| ((x - 1e-7).ceil().max(0.0) as usize).min(m)).collect();
    let mut evaluated = 1;
    while !ok(&start) {
        // add the repetition that lowers the worst ratio most per second
        let base = pre.worst_ratio(&start);
        let pick = (0..ne)
            .filter(|&e| start[e] < pre.rmax[e])
            .map(|e| {
                let mut t = start.clone();
                t[e] += 1;
                evaluated += 1;
                (e, (base - pre.worst_ratio(&t)) / pre.cost[e])
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match pick {
            Some((e, _)) => start[e] += 1,
            None => break,
        }
    }
    let lo: Vec<usize> = r.iter().map(|x| (x.floor() as usize).saturating_sub(window)).collect();
    let hi: Vec<usize> = r
        .iter()
        .zip(&pre.rmax)
        .zip(&start)
        .map(|((x, &m), &s)| ((x.ceil() as usize) + window).min(m).max(s))
        .collect();
    let count = lo.iter().zip(&hi).try_fold(1usize, |acc, (l, h)| acc.checked_mul(h - l + 1));
    match count {
        Some(c) if c <= ENUMERATION_LIMIT => {
            let mut best = start.clone();
            let (mut best_cost, mut best_ratio) = (pre.cost_of(&best), pre.worst_ratio(&best));
            let mut cur = lo.clone();
            loop {
                let cost = pre.cost_of(&cur);
                if cost <= best_cost + 1e-9 {
                    evaluated += 1;
                    let ratio = pre.worst_ratio(&cur);
                    if ratio <= 1.0 + 1e-9 && (cost < best_cost - 1e-9 || ratio < best_ratio) {
                        best = cur.clone();
                        best_cost = cost;
                        best_ratio = ratio;
                    }
                }
                if !next_in_box(&mut cur, &lo, &hi) {
                    return (best, format!("every integer vector within ±{window} of r* ({c} vectors)"), evaluated);
                }
            }
        }
        _ => {
            // greedy trim: drop the most expensive repetition that keeps every target
            let mut cur = start;
            loop {
                let mut order: Vec<usize> = (0..ne).filter(|&e| cur[e] > 0).collect();
                order.sort_by(|&a, &b| pre.cost[b].total_cmp(&pre.cost[a]));
                let mut changed = false;
                for e in order {
                    cur[e] -= 1;
                    evaluated += 1;
                    if ok(&cur) {
                        changed = true;
                        break;
                    }
                    cur[e] += 1;
                }
                if !changed {
                    return (cur, "⌈r*⌉ trimmed greedily (too many vectors to enumerate)".into(), evaluated);
                }
            }
        }
    }
}

/// Steps `cur` to the next integer vector of the box [lo, hi] (the first
/// coordinate fastest); false after the last.
pub fn next_in_box(cur: &mut [usize], lo: &[usize], hi: &[usize]) -> bool {
    for k in 0..cur.len() {
        if cur[k] < hi[k] {
            cur[k] += 1;
            return true;
        }
        cur[k] = lo[k];
    }
    false
}

/// σ of every coordinate of the plan's space, and of every base parameter, for repetitions `r`.
pub fn parameter_sigmas(model: &Model, pre: &Prepared, r: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let phi = pre.phi(&r.iter().map(|&x| x as f64).collect::<Vec<_>>());
    let p = model.dim();
    let cov = phi.clone().try_inverse().filter(|_| phi.clone().cholesky().is_some());
    match cov {
        None => (vec![f64::INFINITY; p], vec![f64::INFINITY; model.base.n_base()]),
        Some(c) => {
            let own: Vec<f64> = (0..p).map(|i| c[(i, i)].max(0.0).sqrt()).collect();
            let base = match model.space {
                Space::Base => own.clone(),
                Space::Standard => {
                    let kb = &model.base.k * &c * model.base.k.transpose();
                    (0..kb.nrows()).map(|i| kb[(i, i)].max(0.0).sqrt()).collect()
                }
            };
            (own, base)
        }
    }
}

/// A value of every target along repetitions of experiment `e` (others at `r`).
pub fn curve(pre: &Prepared, r: &[usize], e: usize, upto: usize) -> Vec<(usize, Vec<f64>)> {
    (0..=upto)
        .map(|k| {
            let mut x: Vec<f64> = r.iter().map(|&v| v as f64).collect();
            x[e] = k as f64;
            (k, pre.values(&x))
        })
        .collect()
}
