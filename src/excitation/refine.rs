//! Constrained gradient refinement with nlopt (SLSQP or MMA) using the
//! analytic gradients of the objective and of [`Constraints::eval`].
//!
//! What each stage minimises (ln J, the smooth surrogate, the epigraph form
//! over the eigenvalue bundle) is the objective's choice
//! ([`Objective::refinement_forms`], [`super::forms`]); this module runs the
//! stages under the design's constraints. Box bounds are the GA's. The best feasible point met during the
//! run is kept (SLSQP may end on a slightly infeasible iterate); wall-clock
//! budgets map to nlopt's `maxtime`; Ctrl-C makes the callbacks return a zero
//! gradient so the solver ends at once (both through the nlopt bridge,
//! [`crate::optim::nlopt`]).

use super::constraints::{Constraints, JointLimitSpec};
use super::design::{RefineAlgorithm, RefineSpec};
use super::forms::{Epigraph, Form, Plain};
use super::objective::Objective;
use crate::optim::nlopt::{Algorithm, Problem};
use crate::optim::Control;
use serde::Serialize;
use std::cell::{Cell, RefCell};
use std::time::Instant;

/// The nlopt problem of a refinement stage over the box [lower, upper]:
/// the spec's algorithm, evaluation budget and relative tolerances (when
/// positive), stopped by `ctl` (the bridge hands its deadline to nlopt).
fn problem<'c>(s: &RefineSpec, lower: Vec<f64>, upper: Vec<f64>, max_evals: u32, ctl: &'c Control, halt: &'c Cell<bool>) -> Problem<'c> {
    let alg = match s.algorithm {
        RefineAlgorithm::Mma => Algorithm::Mma,
        _ => Algorithm::Slsqp,
    };
    Problem::new(alg, lower, upper, ctl)
        .max_evals(max_evals)
        .xtol_rel(s.xtol_rel)
        .ftol_rel(s.ftol_rel)
        .halt_on(halt)
}

/// Feasibility tolerance of nlopt on the scaled constraints; the
/// constraints are imposed as c + 2·tol ≤ 0, so accepted points have c < 0.
const TOL: f64 = 1e-9;

/// What one nlopt stage ended with (serialised as nlopt's own word, e.g.
/// `FtolReached`, `MaxEvalReached`, `Failure`).
pub use crate::optim::GradientStatus as NloptWord;

/// How a refinement ended: the nlopt result of the smooth stage (if any) and
/// of the main stage, and whether the run-control asked to stop. Serialised
/// as one string, as in the reports so far: `"XtolReached (smooth stage),
/// FtolReached (interrupted)"`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RefineStatus {
    /// Result of the smooth first stage.
    pub smooth: Option<NloptWord>,
    /// Result of the main stage.
    pub main: NloptWord,
    /// The control stopped the run (Ctrl-C).
    pub interrupted: bool,
    /// A stage ended for want of progress (`refine.patience`).
    pub stalled: bool,
    /// The result is the repaired near-feasible point ([`repair_near`]).
    pub repaired: bool,
}

impl std::fmt::Display for RefineStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(s) = &self.smooth {
            write!(f, "{s} (smooth stage), ")?;
        }
        f.write_str(self.main.as_str())?;
        if self.stalled {
            f.write_str(" (stalled)")?;
        }
        if self.repaired {
            f.write_str(" (repaired)")?;
        }
        if self.interrupted {
            f.write_str(" (interrupted)")?;
        }
        Ok(())
    }
}

impl Serialize for RefineStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Outcome of one refinement.
#[derive(Debug, Clone, Serialize)]
pub struct RefineOutcome {
    /// Final design vector (best feasible point met, else the last iterate).
    pub x: Vec<f64>,
    /// Criterion J at x.
    pub f: f64,
    /// Total scaled violation at x.
    pub violation: f64,
    /// Criterion at the start.
    pub start_f: f64,
    /// nlopt status.
    pub status: RefineStatus,
    /// Objective evaluations.
    pub evaluations: u64,
    /// Wall time (s).
    pub seconds: f64,
    /// The infeasible point with the lowest criterion met, among those
    /// within [`NEAR`] of every constraint, if its criterion is below `f`:
    /// what [`repair_near`] repairs.
    #[serde(skip)]
    pub near: Option<(Vec<f64>, f64)>,
}

/// Largest scaled violation c_i (a fraction of the constraint's scale: the
/// half range of a position, the limit of a velocity) of a point kept for
/// [`repair_near`].
pub const NEAR: f64 = 0.05;

struct Tracker {
    last_x: Vec<f64>,
    last_f: f64,
    best: Option<(Vec<f64>, f64)>,
    /// The lowest-criterion infeasible point within [`NEAR`] of feasibility.
    near: Option<(Vec<f64>, f64)>,
    /// Evaluations since the best feasible value last fell below `mark`.
    stale: u32,
    /// The best feasible value when `stale` was last reset.
    mark: f64,
}

/// Relative fall of the best feasible value that counts as progress for
/// `refine.patience`.
const PROGRESS: f64 = 1e-4;

impl Tracker {
    fn new() -> Self {
        Tracker {
            last_x: Vec::new(),
            last_f: f64::INFINITY,
            best: None,
            near: None,
            stale: 0,
            mark: f64::INFINITY,
        }
    }

    /// Keeps (x, f) if it is the best feasible point so far.
    fn offer(&mut self, x: &[f64], f: f64) {
        if f.is_finite() && self.best.as_ref().is_none_or(|b| f < b.1) {
            self.best = Some((x.to_vec(), f));
            if f < self.mark - PROGRESS * self.mark.abs() || !self.mark.is_finite() {
                self.mark = f;
                self.stale = 0;
            }
        }
    }

    /// Keeps (x, f) if x is infeasible, its worst scaled constraint at
    /// most [`NEAR`], and f the lowest of such points so far.
    fn offer_near(&mut self, x: &[f64], f: f64, worst: f64) {
        if f.is_finite() && worst <= NEAR && self.near.as_ref().is_none_or(|b| f < b.1) {
            self.near = Some((x.to_vec(), f));
        }
    }

    /// Sets `halt` once `patience` (> 0) evaluations passed without
    /// progress (each evaluation counted before its point is offered).
    fn check(&self, patience: u32, halt: &Cell<bool>) {
        if patience > 0 && self.stale >= patience {
            halt.set(true);
        }
    }
}

/// The settings of a refinement as the stages see them.
struct Bounds<'a> {
    spec: &'a RefineSpec,
    lower: &'a [f64],
    upper: &'a [f64],
    ctl: &'a Control,
}

/// What a stage ended with.
struct StageResult {
    /// The last iterate.
    last: Vec<f64>,
    /// The best feasible point met and its criterion.
    best: Option<(Vec<f64>, f64)>,
    /// The best near-feasible infeasible point met ([`Tracker::offer_near`]).
    near: Option<(Vec<f64>, f64)>,
    status: NloptWord,
    evaluations: u64,
    /// Ended for want of progress (`refine.patience`).
    halted: bool,
}

impl StageResult {
    fn new(last: Vec<f64>, t: Tracker, status: NloptWord, evaluations: u64, halted: bool) -> Self {
        StageResult {
            last,
            best: t.best,
            near: t.near,
            status,
            evaluations,
            halted,
        }
    }
}

/// The point of lower criterion of two optional (point, criterion) pairs.
fn lower_of(a: Option<(Vec<f64>, f64)>, b: Option<(Vec<f64>, f64)>) -> Option<(Vec<f64>, f64)> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.1 < a.1 { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// One nlopt run from x0 on the plain form `form` of the criterion:
/// returns (last iterate, best feasible point met with its tracked value,
/// nlopt status, evaluations). Once the control says stop, the bridge calls
/// neither callback (a flat objective and constraints that hold, with zero
/// gradients), which ends SLSQP's iteration at its next step: nothing more
/// is evaluated or recorded.
fn stage(obj: &Objective, cons: &Constraints, x0: &[f64], b: &Bounds, form: Plain, max_evals: u32) -> StageResult {
    let nv = x0.len();
    let m = cons.len();
    let tracker = RefCell::new(Tracker::new());
    let halt = Cell::new(false);
    let patience = b.spec.patience;
    // SLSQP asks for the objective and then the constraints at the same
    // point, both with gradients: the objective's callback computes the
    // constraints beside it (rayon::join: the two parallel workloads share
    // the threads instead of each waiting on its slowest part) and keeps them
    // for the constraints' callback, which takes them when the point and the
    // request match bit for bit. The constraint values do not depend on the
    // thread that computes them, so the result is the same as computing them
    // in their own callback.
    let ahead = RefCell::new(Ahead {
        cw: cons.workspace(),
        x: Vec::new(),
        c: vec![0.0; m],
        jac: vec![0.0; m * nv],
    });
    let f_cb = |x: &[f64], grad: Option<&mut [f64]>, w: &mut super::objective::ObjectiveWorkspace| -> f64 {
        let (j, v) = match grad {
            Some(g) if m > 0 => {
                let mut a = ahead.borrow_mut();
                let a = &mut *a;
                // no point held while the constraints are computed
                a.x.clear();
                let (jv, ()) = rayon::join(|| obj.plain_value(form, x, w, Some(g)), || cons.eval(x, &mut a.cw, &mut a.c, Some(&mut a.jac)));
                a.x.extend_from_slice(x);
                jv
            }
            g => obj.plain_value(form, x, w, g),
        };
        let mut t = tracker.borrow_mut();
        t.last_x.clear();
        t.last_x.extend_from_slice(x);
        t.last_f = j;
        t.stale = t.stale.saturating_add(1);
        if m == 0 {
            t.offer(x, j);
            t.check(patience, &halt);
        }
        v
    };
    let pb = problem(b.spec, b.lower.to_vec(), b.upper.to_vec(), max_evals, b.ctl, &halt);
    let mut x = x0.to_vec();
    let run = if m > 0 {
        let c_cb = |res: &mut [f64], x: &[f64], grad: Option<&mut [f64]>, cw: &mut super::constraints::ConstraintWorkspace| {
            let a = ahead.borrow();
            if a.x.len() == x.len() && a.x.iter().zip(x).all(|(p, q)| p.to_bits() == q.to_bits()) {
                res.copy_from_slice(&a.c);
                if let Some(g) = grad {
                    g.copy_from_slice(&a.jac);
                }
            } else {
                drop(a);
                cons.eval(x, cw, res, grad);
            }
            // shifted by 2·tol so that a point accepted within nlopt's tolerance is strictly feasible
            res.iter_mut().for_each(|v| *v += 2.0 * TOL);
            let feasible = res.iter().all(|v| *v <= TOL);
            let mut t = tracker.borrow_mut();
            if t.last_x.as_slice() == x {
                let f = t.last_f;
                if feasible {
                    t.offer(x, f);
                } else {
                    t.offer_near(x, f, res.iter().fold(f64::NEG_INFINITY, |a, v| a.max(*v)));
                }
            }
            t.check(patience, &halt);
        };
        pb.minimise_constrained(&mut x, f_cb, obj.workspace(), m, TOL, c_cb, cons.workspace())
    } else {
        pb.minimise(&mut x, f_cb, obj.workspace())
    };
    StageResult::new(x, tracker.into_inner(), run.status, run.evaluations, halt.get())
}

/// The constraints computed beside the objective at its last point
/// ([`stage`]), for the constraints' callback at the same point (`x`
/// empty: none held).
struct Ahead {
    cw: super::constraints::ConstraintWorkspace,
    x: Vec<f64>,
    c: Vec<f64>,
    jac: Vec<f64>,
}

/// Buffers of the epigraph stage's constraint callback.
struct EpiBuffers {
    ow: super::objective::ObjectiveWorkspace,
    cw: super::constraints::ConstraintWorkspace,
    c: Vec<f64>,
    jac: Vec<f64>,
    vals: Vec<f64>,
    grads: Vec<f64>,
}

/// The epigraph form `e` of the criterion ([`super::forms`]) from x0, under
/// the design's constraints c(x) ≤ 0 beside the bundle's. The best point is
/// chosen on the exact criterion J(x), which every constraint call
/// evaluates. Returns the x part of the last iterate.
fn stage_epigraph(obj: &Objective, cons: &Constraints, x0: &[f64], b: &Bounds, e: &Epigraph, max_evals: u32) -> StageResult {
    let ctl = b.ctl;
    let nv = x0.len();
    let mc = cons.len();
    let nt = e.n_rows();
    // z = (x, u, l)
    let nz = nv + 2;
    let mut buf = EpiBuffers {
        ow: obj.workspace(),
        cw: cons.workspace(),
        c: vec![0.0; mc],
        jac: vec![0.0; mc * nv],
        vals: vec![0.0; nt],
        grads: vec![0.0; nt * nv],
    };
    let j0 = e.bundle(obj, x0, &mut buf.ow, &mut buf.vals, None);
    ctl.count(1);
    let tracker = RefCell::new(Tracker::new());
    let halt = Cell::new(false);
    let patience = b.spec.patience;
    if !j0.is_finite() {
        return StageResult::new(x0.to_vec(), Tracker::new(), NloptWord::Failure, 1, false);
    }
    cons.eval(x0, &mut buf.cw, &mut buf.c, None);
    if buf.c.iter().all(|v| *v + 2.0 * TOL <= TOL) {
        tracker.borrow_mut().offer(x0, j0);
    }
    let mut z = x0.to_vec();
    z.extend(e.start(&buf.vals));
    // SLSQP starts from the identity as its Hessian: the weight of the linear
    // objective sets the length of the first steps against it
    let f_cb = |z: &[f64], grad: Option<&mut [f64]>, _: &mut ()| -> f64 {
        match grad {
            Some(g) => {
                g[..nv].iter_mut().for_each(|v| *v = 0.0);
                e.value(&z[nv..], Some(&mut g[nv..]))
            }
            None => e.value(&z[nv..], None),
        }
    };
    let (lo, hi) = e.bounds();
    let mut lower = b.lower.to_vec();
    let mut upper = b.upper.to_vec();
    lower.extend(lo);
    upper.extend(hi);
    // the constraints evaluate the criterion: their calls are the evaluations
    let pb = problem(b.spec, lower, upper, max_evals, ctl, &halt).count_constraint_calls();
    let c_cb = |res: &mut [f64], z: &[f64], grad: Option<&mut [f64]>, eb: &mut EpiBuffers| {
        let x = &z[..nv];
        let want = grad.is_some();
        // the design's constraints beside the eigenvalues (rayon::join, as
        // in `stage`: each is parallel inside and leaves a thread idle at its
        // end; neither result depends on the thread that computes it); the
        // gradients only when SLSQP asks for them (not in its line search)
        let EpiBuffers { ow, cw, c, jac, vals, grads } = eb;
        let ((), j) = rayon::join(
            || cons.eval(x, cw, c, if want { Some(jac) } else { None }),
            || e.bundle(obj, x, ow, vals, if want { Some(grads) } else { None }),
        );
        // the design's constraints, shifted by 2·tol as in the direct stage
        let (res_c, res_b) = res.split_at_mut(mc);
        for i in 0..mc {
            res_c[i] = eb.c[i] + 2.0 * TOL;
        }
        let feasible = res_c.iter().all(|v| *v <= TOL);
        match grad {
            Some(g) => {
                let (g_c, g_b) = g.split_at_mut(mc * nz);
                g_c.iter_mut().for_each(|v| *v = 0.0);
                if j.is_finite() {
                    for i in 0..mc {
                        g_c[i * nz..i * nz + nv].copy_from_slice(&eb.jac[i * nv..(i + 1) * nv]);
                    }
                }
                e.rows(j, &eb.vals, &eb.grads, z, res_b, Some(g_b));
            }
            None => e.rows(j, &eb.vals, &eb.grads, z, res_b, None),
        }
        let mut t = tracker.borrow_mut();
        t.last_x.clear();
        t.last_x.extend_from_slice(x);
        t.last_f = j;
        t.stale = t.stale.saturating_add(1);
        if feasible {
            t.offer(x, j);
        } else {
            t.offer_near(x, j, res_c.iter().fold(f64::NEG_INFINITY, |a, v| a.max(*v)));
        }
        t.check(patience, &halt);
    };
    let run = pb.minimise_constrained(&mut z, f_cb, (), mc + nt, TOL, c_cb, buf);
    z.truncate(nv);
    // the start's evaluation and the constraint calls
    StageResult::new(z, tracker.into_inner(), run.status, 1 + run.evaluations, halt.get())
}

/// Refines `x0` (see the module docs) on the objective's forms
/// ([`Objective::refinement_forms`]): a first stage, if the objective has
/// one (the smooth surrogate of the condition number, `spec.smooth` > 0),
/// on 60 % of the evaluations, then the main stage (the direct form, or the
/// epigraph form with `spec.bundle` > 0) from the best feasible point of the
/// first.
///
/// `spec` gives the algorithm, the evaluation budget and the tolerances,
/// [lower, upper] the box; `ctl` stops it (deadline → nlopt's `maxtime`;
/// once a stop request, the deadline or the evaluation budget stops it, the
/// callbacks return at once, flat and feasible with zero gradients, so that
/// nlopt ends at its next step; every objective evaluation is counted on
/// `ctl`).
pub fn refine(obj: &Objective, cons: &Constraints, x0: &[f64], spec: &RefineSpec, lower: &[f64], upper: &[f64], ctl: &Control) -> RefineOutcome {
    let b = Bounds { spec, lower, upper, ctl };
    let s = spec;
    let forms = obj.refinement_forms(s.smooth, s.bundle, s.bundle_weight);
    let t0 = Instant::now();
    let m = cons.len();
    let mut ow = obj.workspace();
    let start_f = obj.value(x0, &mut ow);
    let mut evals = 0;
    let mut x_start = x0.to_vec();
    let mut status_soft = None;
    let mut stalled = false;
    let mut near = None;
    if let Some(first) = forms.first {
        let budget = (s.max_evals as f64 * 0.6) as u32;
        let r = stage(obj, cons, x0, &b, first, budget);
        evals += r.evaluations;
        stalled |= r.halted;
        status_soft = Some(r.status);
        near = r.near;
        x_start = r.best.map(|b| b.0).unwrap_or(r.last);
    }
    let left = s.max_evals.saturating_sub(evals as u32).max(1);
    let r = match &forms.main {
        Form::Epigraph(e) => stage_epigraph(obj, cons, &x_start, &b, e, left),
        Form::Plain(p) => stage(obj, cons, &x_start, &b, *p, left),
    };
    let (mut x, mut best, status) = (r.last, r.best, r.status);
    evals += r.evaluations;
    stalled |= r.halted;
    near = lower_of(near, r.near);
    if s.polish > 0 && s.algorithm == RefineAlgorithm::Slsqp && !ctl.should_stop() {
        // MMA from where SLSQP ended (module docs of RefineSpec::polish)
        let mma = RefineSpec {
            algorithm: RefineAlgorithm::Mma,
            ..s.clone()
        };
        let bm = Bounds { spec: &mma, lower, upper, ctl };
        let rm = stage(obj, cons, &x, &bm, Plain::Direct, s.polish);
        let (xm, bestm) = (rm.last, rm.best);
        evals += rm.evaluations;
        near = lower_of(near, rm.near);
        if let Some((bx, bf)) = bestm {
            if best.as_ref().is_none_or(|b| bf < b.1) {
                best = Some((bx, bf));
            }
        } else if best.is_none() {
            x = xm;
        }
    }
    let status = RefineStatus {
        smooth: status_soft,
        main: status,
        interrupted: ctl.interrupted(),
        stalled,
        repaired: false,
    };
    // final candidate: the best feasible point met, else the last iterate
    let mut cw = cons.workspace();
    let mut c = vec![0.0; m];
    let (xf, ff) = match best {
        Some((bx, bf)) => (bx, bf),
        None => {
            let f = obj.value(&x, &mut ow);
            (x, f)
        }
    };
    cons.eval(&xf, &mut cw, &mut c, None);
    let violation = Constraints::violation(&c);
    RefineOutcome {
        near: near.filter(|n| n.1 < ff || violation > 0.0),
        x: xf,
        f: ff,
        violation,
        start_f,
        status,
        evaluations: evals,
        seconds: t0.elapsed().as_secs_f64(),
    }
}

/// `refine.repair`: SLSQP crosses infeasible regions and may spend its
/// whole budget there, ending where it started (the best feasible point met)
/// although it met near-feasible points of a much lower criterion. The
/// lowest of them (`out.near`) is repaired by [`Constraints::repair_joints`]
/// (each joint's motion scaled about its centre into its position, velocity
/// and acceleration limits, as the GA repairs), evaluated (one criterion
/// evaluation, counted on `ctl`) and taken if it is feasible and better than
/// the refinement's result. Nothing is done once `ctl` says stop.
pub fn repair_near(out: &mut RefineOutcome, obj: &Objective, cons: &Constraints, limits: &JointLimitSpec, ctl: &Control) {
    let Some((mut y, _)) = out.near.take() else {
        return;
    };
    if ctl.should_stop() {
        return;
    }
    cons.repair_joints(&mut y, limits, 1e-6);
    let t0 = Instant::now();
    let f = obj.value(&y, &mut obj.workspace());
    ctl.count(1);
    out.evaluations += 1;
    let mut c = vec![0.0; cons.len()];
    cons.eval(&y, &mut cons.workspace(), &mut c, None);
    // as the stages accept a point: c + 2·tol ≤ tol
    if f.is_finite() && c.iter().all(|v| *v + TOL <= 0.0) && (f < out.f || out.violation > 0.0) {
        out.x = y;
        out.f = f;
        out.violation = 0.0;
        out.status.repaired = true;
    }
    out.seconds += t0.elapsed().as_secs_f64();
}

/// A perturbed copy of x: each variable moved by a uniform draw in
/// ±`scale`·(upper − lower)/2 (ChaCha8 seeded with `seed`), clamped to the
/// box. The start of a restart of the refinement (`refine.restarts`).
pub fn perturb(x: &[f64], lower: &[f64], upper: &[f64], scale: f64, seed: u64) -> Vec<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    x.iter()
        .zip(lower.iter().zip(upper))
        .map(|(&v, (&lo, &hi))| {
            let r: f64 = rng.random_range(-1.0..=1.0);
            (v + r * scale * 0.5 * (hi - lo)).clamp(lo, hi)
        })
        .collect()
}

/// As [`perturb`], but only the variables of `k` joints move (`k` > 0 and
/// less than the number of joints): the joints are drawn without
/// replacement by ChaCha8 seeded with `seed`, each variable in
/// `joint_vars(j)` of a drawn joint moved as in [`perturb`] (its own stream
/// seeded with `seed`), the others kept. `k` = 0 or ≥ the number of joints:
/// [`perturb`] itself.
pub fn perturb_joints(x: &[f64], lower: &[f64], upper: &[f64], scale: f64, seed: u64, k: usize, joint_vars: &[std::ops::Range<usize>]) -> Vec<f64> {
    use rand::{RngExt, SeedableRng};
    let n = joint_vars.len();
    if k == 0 || k >= n {
        return perturb(x, lower, upper, scale, seed);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    // a partial Fisher-Yates shuffle: the first k of `order` are the drawn joints
    let mut order: Vec<usize> = (0..n).collect();
    for i in 0..k {
        let j = rng.random_range(i..n);
        order.swap(i, j);
    }
    let moved = perturb(x, lower, upper, scale, seed);
    let mut y = x.to_vec();
    for &j in &order[..k] {
        for v in joint_vars[j].clone() {
            y[v] = moved[v];
        }
    }
    y
}
