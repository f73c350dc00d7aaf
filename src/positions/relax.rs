//! The relaxed design: scaling, first-order warm start and pruning, Clarabel on
//! a small working set, and the optimality certificate on the full candidate set.
//!
//! Pipeline (see [`solve_relaxed`]):
//!
//! 1. **Scaling.** All information is multiplied by s = p / tr M(uniform), so
//!    the numbers are O(1). For D (and A, through K) the problem is also
//!    congruence-transformed, H_i → T H_i with T = L⁻¹, LLᵀ the information of
//!    the current design: the D-optimal weights do not change, log det shifts by
//!    2 ln|det T|, and the information the solver sees is close to the identity
//!    at the optimum (badly scaled parameters are what break interior-point
//!    solvers).
//! 2. **First order** on the full set (D: multiplicative algorithm, then
//!    Frank–Wolfe with away steps; A and E: the A multiplicative algorithm),
//!    with the equivalence-theorem pruning of [`super::firstorder`] for D.
//! 3. **Newton** (D, A; `newton = true`, the default): the active-set Newton
//!    method of [`firstorder::newton_simplex`] solves the working set to
//!    ε ≤ 10⁻³·tol, the certificate is checked on the full set, violators are
//!    added (column generation). When it certifies, no conic solve is needed:
//!    the Kiefer–Wolfowitz / A-equivalence bound below *is* the certificate.
//! 4. **Clarabel** ([`super::conic`]) on the pruned working set, for E, with
//!    `newton = false`, or when the Newton phase did not certify.
//! 5. **Certificate on the full set** ([`certify`]); candidates outside the
//!    working set that violate the optimality condition are added and the
//!    working set is solved again (at most `max_rounds` times).
//!
//! ## Certificates
//!
//! With t_0 the prior term (tr(M⁻¹F_0), tr(M⁻²F_0), tr(ZF_0)) and the maximum
//! taken over **all** candidates:
//!
//! * D: log det M* − log det M(w) ≤ p·ln(S/p), S = t_0 + max_i d_i, so the
//!   D-efficiency (det M(w)/det M*)^{1/p} ≥ p/S (AM–GM on the eigenvalues of
//!   M⁻¹M*, Atwood 1969). Without a prior this is p / max_i tr(M⁻¹F_i), the
//!   Kiefer–Wolfowitz check max_i d_i = p.
//! * A: tr M*⁻¹ ≥ tr M(w)⁻¹ − (max_i a_i − Σ_i w_i a_i) (convexity), so the
//!   A-efficiency tr M*⁻¹ / tr M(w)⁻¹ ≥ 1 − gap / tr M(w)⁻¹.
//! * E: for the unit-trace Z ⪰ 0 from the SDP dual, λ_min(M*) ≤ tr(ZF_0) +
//!   max_i tr(ZF_i) =: U, so the E-efficiency λ_min(M(w))/λ_min(M*) ≥ λ_min/U.
//!
//! The certificate holds when the efficiency bound is ≥ 1 − `tol`.

use super::conic::{self, Formulation};
use super::firstorder::{self, d_prune_threshold};
use super::problem::{evaluate_e_with, psd_unit_trace, Criterion, Evaluation, Problem};
use crate::error::{Error, Result};
use crate::optim::Control;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Options of the relaxed solver (the `[solver]` section of a design file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverOptions {
    /// Conic form of the D-optimal problem: "socp" (default) or "sdp".
    pub formulation: Formulation,
    /// Certificate tolerance: the efficiency lower bound must reach 1 − tol.
    pub tol: f64,
    /// Remove candidates ruled out by the equivalence theorem (D only).
    pub prune: bool,
    /// Iteration limit of the first-order warm start.
    pub first_order_iters: usize,
    /// Stop the first-order method when ε = max d − δ ≤ this · p (with
    /// `newton`, D stops at 0.1·p at the latest: the Newton phase finishes).
    pub first_order_eps: f64,
    /// Working-set rounds (Clarabel solves) at most.
    pub max_rounds: usize,
    /// Clarabel gap/feasibility tolerance for D (A and E use 1/100 of it: their
    /// certificates use gradients of the IPM answer, with no first-order polish).
    pub clarabel_tol: f64,
    /// Clarabel iteration limit.
    pub max_iter: u32,
    /// Clarabel time limit per solve, seconds (absent: none).
    pub time_limit: Option<f64>,
    /// Factor directions with eigenvalue ≤ this (in the whitened problem, where
    /// M ≈ I) are left out of the conic problem (D, A); the certificate always
    /// uses the exact matrices. 0 keeps everything.
    pub factor_tol: f64,
    /// Print Clarabel's iteration log.
    pub verbose: bool,
    /// D and A: solve the working set by the active-set Newton method
    /// ([`firstorder::newton_simplex`]) with column generation on all
    /// candidates, and call Clarabel only if that does not certify. false:
    /// Clarabel rounds straight after the first-order phase.
    pub newton: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            formulation: Formulation::Socp,
            tol: 1e-6,
            prune: true,
            first_order_iters: 3000,
            first_order_eps: 1e-5,
            max_rounds: 8,
            clarabel_tol: 1e-8,
            max_iter: 200,
            time_limit: None,
            factor_tol: 1e-9,
            verbose: false,
            newton: true,
        }
    }
}

impl SolverOptions {
    /// Checks ranges, naming the field.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let bad = |f: &str, m: &str| Err(Error::invalid(ctx, format!("solver.{f}"), m.to_string()));
        if !(self.tol > 0.0 && self.tol < 0.5) {
            return bad("tol", "expected 0 < tol < 0.5");
        }
        if !(self.first_order_eps > 0.0 && self.first_order_eps.is_finite()) {
            return bad("first_order_eps", "expected a positive number");
        }
        if self.max_rounds == 0 {
            return bad("max_rounds", "expected at least 1");
        }
        if !(self.clarabel_tol > 0.0 && self.clarabel_tol < 1e-3) {
            return bad("clarabel_tol", "expected 0 < clarabel_tol < 1e-3");
        }
        if !(self.factor_tol >= 0.0 && self.factor_tol < 1e-2) {
            return bad("factor_tol", "expected 0 ≤ factor_tol < 1e-2");
        }
        if self.max_iter == 0 {
            return bad("max_iter", "expected at least 1");
        }
        if let Some(t) = self.time_limit {
            if t.is_nan() || t <= 0.0 {
                return bad("time_limit", "expected a positive number of seconds");
            }
        }
        Ok(())
    }
}

/// The optimality certificate of a relaxed design, checked on the full candidate set.
#[derive(Debug, Clone, Serialize)]
pub struct Certificate {
    /// Criterion.
    pub criterion: Criterion,
    /// Criterion value at the design (original units; see [`Criterion::value_label`]).
    pub value: f64,
    /// max_i s_i(w) over all candidates (D: max_i tr(M⁻¹F_i)).
    pub max_sensitivity: f64,
    /// Candidate (0-based) attaining it.
    pub argmax: usize,
    /// What the maximum is compared with at an optimum (D: p − tr(M⁻¹F_0), i.e. p
    /// without prior; A: Σ w_i a_i; E: λ_min − tr(ZF_0)).
    pub reference: f64,
    /// The prior term t_0 (0 without prior).
    pub prior_term: f64,
    /// Upper bound on |Φ(optimum) − Φ(w)| in criterion units.
    pub gap_bound: f64,
    /// Lower bound on the efficiency relative to the true relaxed optimum.
    pub efficiency_bound: f64,
    /// The formula of the bound.
    pub formula: String,
    /// Tolerance used: holds ⇔ efficiency_bound ≥ 1 − tol.
    pub tol: f64,
    /// Whether the certificate holds.
    pub holds: bool,
    /// Number of candidates checked (all of them).
    pub candidates_checked: usize,
}

/// Computes the certificate of design `w` on `pb` (all candidates). For E,
/// `z` is the dual matrix (PSD, unit trace); without it, the projector on the
/// smallest eigenvector of M(w) is used.
pub fn certify(pb: &Problem, crit: Criterion, w: &[f64], z: Option<&DMatrix<f64>>, tol: f64) -> Result<(Certificate, Evaluation)> {
    let p = pb.p() as f64;
    let ev = match (crit, z) {
        (Criterion::E, Some(z)) => evaluate_e_with(pb, w, z),
        _ => pb.evaluate(crit, w)?,
    };
    let (argmax, mx) = ev.max_sens();
    let t0 = ev.prior_term;
    let (reference, gap, eff, formula) = match crit {
        Criterion::D => {
            let s = (t0 + mx).max(p);
            (
                p - t0,
                p * (s / p).ln(),
                p / s,
                "D-efficiency >= p / (tr(M^-1 F0) + max_i tr(M^-1 F_i)) (Atwood 1969; = p / max_i d_i without prior)".to_string(),
            )
        }
        Criterion::A => {
            let gap = (mx - ev.mean).max(0.0);
            (
                ev.mean,
                gap,
                (1.0 - gap / ev.value).max(0.0),
                "A-efficiency >= 1 - (max_i tr(M^-2 F_i) - sum_i w_i tr(M^-2 F_i)) / tr(M^-1)".to_string(),
            )
        }
        Criterion::E => {
            let u = t0 + mx;
            (
                ev.value - t0,
                (u - ev.value).max(0.0),
                if u > 0.0 { (ev.value / u).min(1.0) } else { 0.0 },
                "E-efficiency >= lambda_min(M) / (tr(Z F0) + max_i tr(Z F_i)), Z >= 0, tr Z = 1 (SDP dual)".to_string(),
            )
        }
    };
    let cert = Certificate {
        criterion: crit,
        value: ev.value,
        max_sensitivity: mx,
        argmax,
        reference,
        prior_term: t0,
        gap_bound: gap,
        efficiency_bound: eff,
        formula,
        tol,
        holds: eff >= 1.0 - tol,
        candidates_checked: pb.n(),
    };
    Ok((cert, ev))
}

/// How the relaxed solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// The certificate holds on the full set (the design came from the Newton
    /// phase or from Clarabel on the working set).
    Optimal,
    /// A design was found but the certificate does not reach 1 − tol (see its bound).
    NotCertified,
    /// Stopped by the user; the design is the best one so far, with its certificate.
    Interrupted,
}

/// One Clarabel solve on a working set.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    /// Candidates in the working set.
    pub working_set: usize,
    /// Clarabel status.
    pub clarabel_status: super::conic::ConicStatus,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Clarabel solve time (s).
    pub solve_time: f64,
    /// Variables and constraint rows of the conic problem.
    pub size: (usize, usize),
    /// Efficiency bound on the full set after this round.
    pub efficiency_bound: f64,
    /// Candidates added after this round (violators outside the working set).
    pub added: usize,
}

/// What the solver did and how long it took.
#[derive(Debug, Clone, Serialize, Default)]
pub struct SolveLog {
    /// Number of candidates.
    pub candidates: usize,
    /// Number of parameters p.
    pub parameters: usize,
    /// First-order iterations (all phases).
    pub first_order_iterations: usize,
    /// ε = max s − reference after the first-order phase.
    pub first_order_eps: f64,
    /// Candidates left after pruning (= first working set).
    pub pruned_to: usize,
    /// The Clarabel rounds.
    pub rounds: Vec<Round>,
    /// Polishing Frank–Wolfe iterations after Clarabel (D and A; 0 if not needed).
    pub polish_iterations: usize,
    /// Newton iterations (all working sets; 0 without the Newton phase).
    pub newton_iterations: usize,
    /// Working sets the Newton phase solved (column-generation rounds).
    pub newton_rounds: usize,
    /// Candidates in the last Newton working set.
    pub newton_working_set: usize,
    /// Whether the Newton phase alone certified the design (no Clarabel solve).
    pub newton_certified: bool,
    /// Wall time of the Newton phase (s).
    pub newton_time: f64,
    /// Wall time of the first-order phase (s).
    pub first_order_time: f64,
    /// Wall time inside Clarabel (s).
    pub clarabel_time: f64,
    /// Total wall time (s).
    pub total_time: f64,
}

/// A relaxed (approximate) design with its certificate.
#[derive(Debug, Clone, Serialize)]
pub struct Relaxed {
    /// Criterion.
    pub criterion: Criterion,
    /// Weight of every candidate (≥ 0, unit sum; with costs: fraction of the budget).
    pub weights: Vec<f64>,
    /// Criterion value (original units).
    pub value: f64,
    /// Sensitivity s_i of every candidate at the design (D: tr(M⁻¹F_i)).
    pub sensitivities: Vec<f64>,
    /// The certificate on the full set.
    pub certificate: Certificate,
    /// Outcome.
    pub status: Status,
    /// Solver log.
    pub log: SolveLog,
    /// For E: the unit-trace PSD matrix Z of the certificate (the SDP dual).
    #[serde(skip)]
    pub dual: Option<DMatrix<f64>>,
}

fn chol_inverse_factor(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let p = m.nrows();
    let c = m.clone().cholesky()?;
    c.l().solve_lower_triangular(&DMatrix::identity(p, p))
}

fn rank_of(m: &DMatrix<f64>) -> usize {
    let e = m.clone().symmetric_eigen();
    let mx = e.eigenvalues.max();
    e.eigenvalues.iter().filter(|&&v| v > 1e-10 * mx).count()
}

fn top_k(vals: &[f64], k: usize) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..vals.len()).collect();
    idx.sort_by(|&a, &b| vals[b].total_cmp(&vals[a]));
    idx.truncate(k);
    idx
}

/// Solves the relaxed allocation problem max/min Φ(M(w)) over the simplex and
/// certifies the answer on the full candidate set (see the module docs).
pub fn solve_relaxed(pb: &Problem, crit: Criterion, opts: &SolverOptions, ctl: &Control) -> Result<Relaxed> {
    let t_start = Instant::now();
    let (p, n) = (pb.p(), pb.n());
    let mut log = SolveLog {
        candidates: n,
        parameters: p,
        ..Default::default()
    };
    let pbs = scaled_problem(pb)?;
    let t_fo = Instant::now();
    // --- first order and initial working set
    let (ws, w_ws) = initial_working_set(&pbs, crit, opts, ctl, &mut log)?;
    log.first_order_time = t_fo.elapsed().as_secs_f64();
    log.pruned_to = ws.len();
    let phase = Phase {
        pb,
        pbs: &pbs,
        crit,
        opts,
        ctl,
    };
    // --- Newton on working sets (D, A): certified without a conic solve in the normal case
    let (ws, w_ws) = if opts.newton && crit != Criterion::E {
        let t_nt = Instant::now();
        let (ws, w_ws, done) = newton_phase(&phase, ws, w_ws, &mut log)?;
        log.newton_time = t_nt.elapsed().as_secs_f64();
        if let Some((w, cert, ev)) = done {
            log.newton_certified = true;
            log.total_time = t_start.elapsed().as_secs_f64();
            let status = if cert.holds { Status::Optimal } else { Status::Interrupted };
            return Ok(Relaxed {
                criterion: crit,
                value: cert.value,
                weights: w,
                sensitivities: ev.sens.clone(),
                certificate: cert,
                status,
                log,
                dual: None,
            });
        }
        (ws, w_ws)
    } else {
        (ws, w_ws)
    };
    // --- Clarabel rounds
    let (best, best_z, mut status, ws, w_ws) = clarabel_rounds(&phase, ws, w_ws, &mut log)?;
    let (mut w, mut cert, mut ev) = match best {
        Some(b) => b,
        None => {
            // stopped before any conic solve: the first-order design, certified
            let mut w_full = vec![0.0; n];
            for (k, &i) in ws.iter().enumerate() {
                w_full[i] = w_ws.get(k).copied().unwrap_or(0.0);
            }
            firstorder::normalise(&mut w_full);
            if w_full.iter().sum::<f64>() <= 0.0 {
                return Err(Error::Interrupted);
            }
            let (c, e) = certify(pb, crit, &w_full, None, opts.tol)?;
            status = Status::Interrupted;
            (w_full, c, e)
        }
    };
    // polish (D, A): Frank–Wolfe steps on the support neighbourhood if the
    // interior-point answer is not accurate enough for the certificate
    if crit != Criterion::E && !cert.holds && status != Status::Interrupted {
        if let Some((w2, c2, e2)) = polish(&phase, &w, &cert, &ev, &mut log)? {
            w = w2;
            cert = c2;
            ev = e2;
            if cert.holds {
                status = Status::Optimal;
            }
        }
    }
    if ctl.interrupted() && status != Status::Optimal {
        status = Status::Interrupted;
    }
    log.total_time = t_start.elapsed().as_secs_f64();
    Ok(Relaxed {
        criterion: crit,
        value: cert.value,
        weights: w,
        sensitivities: ev.sens.clone(),
        certificate: cert,
        status,
        log,
        dual: if crit == Criterion::E { best_z } else { None },
    })
}

/// The problem scaled so that the uniform design's information has trace p;
/// errors when the candidates cannot identify the parameters.
fn scaled_problem(pb: &Problem) -> Result<Problem> {
    let (p, n) = (pb.p(), pb.n());
    let uniform = vec![1.0 / n as f64; n];
    let mu = pb.information(&uniform);
    let tr = mu.trace();
    if !(tr > 0.0 && tr.is_finite()) {
        return Err(Error::Numerical("all candidate information matrices are zero".into()));
    }
    if mu.clone().cholesky().is_none() {
        return Err(Error::Numerical(format!(
            "the parameters are not identifiable from the candidate set: the information of all candidates together has rank {} < p = {}",
            rank_of(&mu),
            p
        )));
    }
    Ok(pb.scaled(p as f64 / tr))
}

/// Multiplicative iterations of the A-optimal warm start: at most this many,
/// in chunks of `A_CHUNK`, stopping once at most `A_SMALL_SET`·p candidates
/// keep a weight above 1e-4 of the largest (the first working set).
const A_FIRST_ORDER_ITERS: usize = 300;
const A_CHUNK: usize = 10;
const A_SMALL_SET: usize = 6;
/// With the Newton phase: the D warm start stops at ε ≤ this·p (or the
/// design's `first_order_eps` if larger), the A warm start after this many
/// multiplicative steps; Newton's column generation does the rest.
const NEWTON_WARM_EPS: f64 = 0.1;
const NEWTON_A_ITERS: usize = 30;

/// First-order warm start on the scaled problem `pbs` and the first working
/// set (candidate indices, their warm-start weights).
fn initial_working_set(pbs: &Problem, crit: Criterion, opts: &SolverOptions, ctl: &Control, log: &mut SolveLog) -> Result<(Vec<usize>, Vec<f64>)> {
    let (p, n) = (pbs.p(), pbs.n());
    let uniform = vec![1.0 / n as f64; n];
    Ok(match crit {
        Criterion::D => {
            let t = chol_inverse_factor(&pbs.information(&uniform))
                .ok_or_else(|| Error::Numerical("the uniform design's information is not positive definite after scaling".into()))?;
            // before Newton the first order only finds the neighbourhood of the support
            let eps = if opts.newton {
                opts.first_order_eps.max(NEWTON_WARM_EPS)
            } else {
                opts.first_order_eps
            };
            let ws0 = firstorder::d_warm_start(&pbs.transformed(&t), opts.prune, eps * p as f64, opts.first_order_iters, ctl)?;
            let (live, mut w, iters, eps) = (ws0.pool, ws0.w, ws0.iterations, ws0.eps);
            log.first_order_iterations = iters;
            log.first_order_eps = eps;
            if w.iter().sum::<f64>() <= 0.0 {
                w = vec![1.0; live.len()];
            }
            firstorder::normalise(&mut w);
            // first working set: the first-order support and the largest d_i of the pool
            let sub = pbs.subset(&live);
            let ev = sub.evaluate(Criterion::D, &w)?;
            let mut pick: Vec<usize> = (0..live.len()).filter(|&i| w[i] > 0.0).collect();
            pick.extend(top_k(&ev.sens, (p / 2).max(4)));
            pick.sort_unstable();
            pick.dedup();
            (pick.iter().map(|&i| live[i]).collect(), pick.iter().map(|&i| w[i]).collect())
        }
        Criterion::A | Criterion::E => {
            let mut w = uniform.clone();
            // A: enough multiplicative steps that the weights off the support
            // have decayed (they shrink geometrically), so the first working
            // set is small; E keeps its short A warm start
            let iters = if crit == Criterion::A && opts.newton {
                opts.first_order_iters.min(NEWTON_A_ITERS)
            } else if crit == Criterion::A {
                opts.first_order_iters.min(A_FIRST_ORDER_ITERS)
            } else {
                opts.first_order_iters.min(50)
            };
            let mut done = 0;
            let mut lg = firstorder::FirstOrderLog::default();
            while done < iters {
                let step = A_CHUNK.min(iters - done);
                lg = firstorder::multiplicative_a(pbs, &mut w, step, ctl)?;
                done += step;
                let wmax = w.iter().cloned().fold(0.0, f64::max);
                if crit == Criterion::A && w.iter().filter(|&&v| v > 1e-4 * wmax).count() <= A_SMALL_SET * p {
                    break;
                }
            }
            log.first_order_iterations = done;
            log.first_order_eps = lg.eps;
            let ev = pbs.evaluate(crit, &w)?;
            let wmax = w.iter().cloned().fold(0.0, f64::max);
            let mut set: Vec<usize> = (0..n).filter(|&i| w[i] > 1e-4 * wmax).collect();
            let k = (3 * p).max(2 * set.len()).min(n);
            set.extend(top_k(&ev.sens, k));
            if crit == Criterion::E {
                let eva = pbs.evaluate(Criterion::A, &w)?;
                set.extend(top_k(&eva.sens, k));
            }
            set.sort_unstable();
            set.dedup();
            let ww: Vec<f64> = set.iter().map(|&i| w[i]).collect();
            (set, ww)
        }
    })
}

/// Newton working-set rounds at most (each adds the violators of the full set).
const NEWTON_ROUNDS: usize = 30;
/// A first Newton working set larger than this many times p is cut to the
/// largest weights and sensitivities.
const NEWTON_SPARSE: usize = 6;
/// Newton iterations per working set at most.
const NEWTON_ITERS: usize = 200;

/// Column generation with the active-set Newton method: solve the working set
/// to ε ≤ 10⁻³·tol (relative), check all candidates, add the violators, until
/// the certificate holds on the full set. Returns the working set with its
/// weights (the warm start of the Clarabel rounds) and, when the certificate
/// holds (or the user stopped the run), the design with its certificate.
#[allow(clippy::type_complexity)]
fn newton_phase(
    cx: &Phase,
    mut ws: Vec<usize>,
    w_ws: Vec<f64>,
    log: &mut SolveLog,
) -> Result<(Vec<usize>, Vec<f64>, Option<(Vec<f64>, Certificate, Evaluation)>)> {
    let Phase { pb, pbs, crit, opts, ctl } = *cx;
    let (p, n) = (pb.p(), pb.n());
    let mut w_ws = w_ws;
    firstorder::normalise(&mut w_ws);
    if w_ws.iter().sum::<f64>() <= 0.0 {
        w_ws = vec![1.0 / ws.len() as f64; ws.len()];
    }
    // a small first working set: the warm start's main support and the
    // largest sensitivities (column generation adds what is missing)
    let newton_max = NEWTON_SPARSE * p;
    if ws.len() > newton_max {
        let sub = pbs.subset(&ws);
        if let Ok(ev) = sub.evaluate(crit, &w_ws) {
            let wmax = w_ws.iter().cloned().fold(0.0, f64::max);
            let mut keep: Vec<usize> = top_k(&w_ws, newton_max).into_iter().filter(|&k| w_ws[k] > 1e-3 * wmax).collect();
            keep.extend(top_k(&ev.sens, (2 * p).min(ws.len())));
            keep.sort_unstable();
            keep.dedup();
            w_ws = keep.iter().map(|&k| w_ws[k]).collect();
            ws = keep.iter().map(|&k| ws[k]).collect();
            firstorder::normalise(&mut w_ws);
        }
    }
    for _ in 0..NEWTON_ROUNDS {
        let sub = pbs.subset(&ws);
        // a working set that cannot identify the parameters: leave it to Clarabel
        let wmix: Vec<f64> = w_ws.iter().map(|v| 0.9 * v + 0.1 / ws.len() as f64).collect();
        let Some(t) = chol_inverse_factor(&sub.information(&wmix)) else {
            return Ok((ws, w_ws, None));
        };
        // D: whitened at the warm start (the weights do not change); A: as scaled
        let sub = if crit == Criterion::D { sub.transformed(&t) } else { sub };
        if sub.evaluate(crit, &w_ws).is_err() {
            w_ws = wmix;
        }
        let target = match crit {
            Criterion::D => 1e-3 * opts.tol * p as f64,
            _ => 1e-3 * opts.tol * sub.evaluate(crit, &w_ws).map(|e| e.value).unwrap_or(0.0),
        };
        let lg = firstorder::newton_simplex(&sub, crit, &mut w_ws, NEWTON_ITERS, target, ctl)?;
        log.newton_iterations += lg.iterations;
        log.newton_rounds += 1;
        log.newton_working_set = ws.len();
        let mut w_full = vec![0.0; n];
        for (k, &i) in ws.iter().enumerate() {
            w_full[i] = w_ws[k];
        }
        let (cert, ev) = certify(pb, crit, &w_full, None, opts.tol)?;
        if cert.holds || ctl.interrupted() {
            return Ok((ws, w_ws, Some((w_full, cert, ev))));
        }
        // violators outside the working set, largest first
        let thr = cert.reference + 1e-3 * opts.tol * cert.reference.abs();
        let in_ws: std::collections::HashSet<usize> = ws.iter().copied().collect();
        let mut viol: Vec<usize> = (0..n).filter(|i| !in_ws.contains(i) && ev.sens[*i] > thr).collect();
        if viol.is_empty() {
            // the working set is not solved accurately enough: Clarabel takes over
            return Ok((ws, w_ws, None));
        }
        viol.sort_by(|&a, &b| ev.sens[b].total_cmp(&ev.sens[a]));
        viol.truncate((2 * p).max(20));
        (ws, w_ws) = grow_working_set(&ws, &w_full, viol);
    }
    Ok((ws, w_ws, None))
}

/// One Clarabel solve on the working-set problem `sub` (congruence-scaled by
/// `t` when the warm start's information factors, objective-scaled so that
/// the warm-start criterion is O(1)).
fn conic_round(sub: &Problem, crit: Criterion, t: Option<&DMatrix<f64>>, wmix: &[f64], opts: &SolverOptions, ctl: &Control) -> conic::ConicResult {
    let p = sub.p();
    match (crit, t) {
        (Criterion::D, Some(t)) => conic::solve_d(&sub.transformed(t).truncated(opts.factor_tol), opts, ctl),
        (Criterion::D, None) => conic::solve_d(sub, opts, ctl),
        (Criterion::A, Some(t)) => {
            // tr(M⁻¹) = tr(Tᵀ M̃⁻¹ T); K = T/‖T‖_F makes the warm-start objective ≈ 1
            let k = t / t.norm().max(f64::MIN_POSITIVE);
            conic::solve_a(&sub.transformed(t).truncated(opts.factor_tol), &k, opts, ctl)
        }
        (Criterion::A, None) => conic::solve_a(sub, &DMatrix::identity(p, p), opts, ctl),
        (Criterion::E, _) => {
            let lmin = sub.information(wmix).symmetric_eigen().eigenvalues.min();
            let sc = if lmin > 0.0 && lmin.is_finite() { 1.0 / lmin } else { 1.0 };
            conic::solve_e(&sub.scaled(sc), opts, ctl)
        }
    }
}

/// The best design of the Clarabel rounds (weights, certificate, evaluation),
/// its PSD dual, the status, and the last working set with its weights.
/// What every phase of [`solve_relaxed`] works on: the problem, its scaled
/// copy, the criterion, the solver options and the run control.
#[derive(Clone, Copy)]
struct Phase<'a> {
    pb: &'a Problem,
    pbs: &'a Problem,
    crit: Criterion,
    opts: &'a SolverOptions,
    ctl: &'a Control,
}

type Rounds = (Option<(Vec<f64>, Certificate, Evaluation)>, Option<DMatrix<f64>>, Status, Vec<usize>, Vec<f64>);

/// Working-set rounds: solve on the working set, certify on all candidates,
/// add the violators, until the certificate holds or `opts.max_rounds`.
fn clarabel_rounds(cx: &Phase, mut ws: Vec<usize>, mut w_ws: Vec<f64>, log: &mut SolveLog) -> Result<Rounds> {
    let Phase { pb, pbs, crit, opts, ctl } = *cx;
    let (p, n) = (pb.p(), pb.n());
    let mut best: Option<(Vec<f64>, Certificate, Evaluation)> = None;
    let mut best_z: Option<DMatrix<f64>> = None;
    let mut status = Status::NotCertified;
    for _round in 0..opts.max_rounds {
        if ctl.interrupted() {
            status = Status::Interrupted;
            break;
        }
        let sub = pbs.subset(&ws);
        let mut w_sub0 = w_ws.clone();
        firstorder::normalise(&mut w_sub0);
        if w_sub0.iter().sum::<f64>() <= 0.0 {
            w_sub0 = vec![1.0 / ws.len() as f64; ws.len()];
        }
        // congruence scaling at the warm-start design (mixed with uniform to stay PD)
        let wmix: Vec<f64> = w_sub0.iter().map(|v| 0.9 * v + 0.1 / ws.len() as f64).collect();
        let t = chol_inverse_factor(&sub.information(&wmix));
        // objective-level scaling: O(1) criterion values at the warm start
        // (Clarabel's absolute tolerances then mean relative accuracy)
        let res = conic_round(&sub, crit, t.as_ref(), &wmix, opts, ctl);
        log.clarabel_time += res.solve_time;
        let mut w_full = vec![0.0; n];
        let use_w = if res.ok { &res.w } else { &w_sub0 };
        for (k, &i) in ws.iter().enumerate() {
            w_full[i] = use_w[k];
        }
        let z = res.dual.as_ref().and_then(psd_unit_trace);
        let (cert, ev) = certify(pb, crit, &w_full, z.as_ref(), opts.tol)?;
        let mut round = Round {
            working_set: ws.len(),
            clarabel_status: res.status.clone(),
            iterations: res.iterations,
            solve_time: res.solve_time,
            size: res.size,
            efficiency_bound: cert.efficiency_bound,
            added: 0,
        };
        let better = best.as_ref().map(|b| cert.efficiency_bound > b.1.efficiency_bound).unwrap_or(true);
        let holds = cert.holds;
        // violators outside the working set
        let thr = cert.reference + 0.1 * opts.tol * cert.reference.abs();
        let in_ws: std::collections::HashSet<usize> = ws.iter().copied().collect();
        let mut viol: Vec<usize> = (0..n).filter(|i| !in_ws.contains(i) && ev.sens[*i] > thr).collect();
        viol.sort_by(|&a, &b| ev.sens[b].total_cmp(&ev.sens[a]));
        viol.truncate((2 * p).max(20));
        if better {
            best = Some((w_full.clone(), cert, ev));
            best_z = z.clone();
        }
        if holds {
            status = Status::Optimal;
            log.rounds.push(round);
            break;
        }
        if viol.is_empty() {
            log.rounds.push(round);
            break;
        }
        round.added = viol.len();
        log.rounds.push(round);
        (ws, w_ws) = grow_working_set(&ws, &w_full, viol);
    }
    Ok((best, best_z, status, ws, w_ws))
}

/// The working set `ws` with the violators `viol` added (sorted by
/// candidate index), and its weights from `w_full` (0 for the new ones).
fn grow_working_set(ws: &[usize], w_full: &[f64], viol: Vec<usize>) -> (Vec<usize>, Vec<f64>) {
    let mut w_ws: Vec<f64> = ws.iter().map(|&i| w_full[i]).collect();
    let mut ws = ws.to_vec();
    ws.extend(viol);
    w_ws.resize(ws.len(), 0.0);
    let mut order: Vec<usize> = (0..ws.len()).collect();
    order.sort_by_key(|&k| ws[k]);
    (order.iter().map(|&k| ws[k]).collect(), order.iter().map(|&k| w_ws[k]).collect())
}

/// Frank–Wolfe polish of `w` on the support neighbourhood; the polished
/// design with its certificate when it certifies better.
fn polish(cx: &Phase, w: &[f64], cert: &Certificate, ev: &Evaluation, log: &mut SolveLog) -> Result<Option<(Vec<f64>, Certificate, Evaluation)>> {
    let Phase { pb, pbs, crit, opts, ctl } = *cx;
    let (p, n) = (pb.p(), pb.n());
    let set: Vec<usize> = if crit == Criterion::D {
        let thr = d_prune_threshold(p, cert.max_sensitivity, cert.prior_term);
        (0..n).filter(|&i| ev.sens[i] >= thr || w[i] > 0.0).collect()
    } else {
        let mut s: Vec<usize> = (0..n).filter(|&i| w[i] > 0.0).collect();
        s.extend(top_k(&ev.sens, (2 * p).min(n)));
        s.sort_unstable();
        s.dedup();
        s
    };
    let sub = pbs.subset(&set);
    let mut ws_w: Vec<f64> = set.iter().map(|&i| w[i]).collect();
    let target = match crit {
        Criterion::D => 0.1 * opts.tol * p as f64,
        _ => 0.1 * opts.tol * sub.evaluate(crit, &ws_w).map(|e| e.value).unwrap_or(0.0),
    };
    let lg = firstorder::fw_away(&sub, crit, &mut ws_w, 5000, target, ctl)?;
    log.polish_iterations = lg.iterations;
    let mut w2 = vec![0.0; n];
    for (k, &i) in set.iter().enumerate() {
        w2[i] = ws_w[k];
    }
    let (c2, e2) = certify(pb, crit, &w2, None, opts.tol)?;
    Ok((c2.efficiency_bound > cert.efficiency_bound).then_some((w2, c2, e2)))
}
