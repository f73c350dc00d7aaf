//! The nlopt bridge: one place that owns an nlopt problem (algorithm, box,
//! stopping rules, constraints), its run-control and its result.
//!
//! nlopt's algorithms (SLSQP, MMA, L-BFGS) run their own loop inside C, so
//! they cannot be argmin solvers: argmin's `Executor` drives a solver one
//! `next_iter` at a time, while `nlopt_optimize` returns only at the end.
//! The seam is therefore the callbacks, which [`Problem`] wraps:
//!
//! - before each call, the [`Control`] is asked; once it says stop (Ctrl-C,
//!   deadline, evaluation budget), the callback is not called: the objective
//!   answers the last value it returned (a flat objective, with a zero
//!   gradient) and the constraints hold (−1, zero gradients), so that nlopt
//!   takes the point as converged and ends at its next step;
//! - after an evaluation that the control would now stop, the gradient is
//!   zeroed for the same reason (the value is kept);
//! - each evaluated call of the counted callback (the objective's, or the
//!   constraints' when they carry the expensive evaluation:
//!   [`Problem::count_constraint_calls`]) is counted on the control and in
//!   [`Run::evaluations`];
//! - the control's deadline is handed to nlopt as `maxtime`, beside the
//!   problem's own evaluation budget and relative tolerances.
//!
//! The nlopt result is mapped here to idexp's [`GradientStatus`] (serialised
//! as nlopt's own word, e.g. `FtolReached`; its `termination()` is the
//! run-control word); no file outside `src/optim/` names the `nlopt` crate
//! (`tests/module_graph.rs`).

use super::{Control, GradientStatus};
use std::cell::Cell;

/// The nlopt algorithms idexp uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Algorithm {
    /// Sequential quadratic programming (box and inequality constraints).
    Slsqp,
    /// Method of moving asymptotes (box and inequality constraints).
    Mma,
    /// Limited-memory BFGS (box constraints only).
    Lbfgs,
}

impl Algorithm {
    fn nlopt(self) -> nlopt::Algorithm {
        match self {
            Algorithm::Slsqp => nlopt::Algorithm::Slsqp,
            Algorithm::Mma => nlopt::Algorithm::Mma,
            Algorithm::Lbfgs => nlopt::Algorithm::Lbfgs,
        }
    }
}

/// Which callback's calls are the counted evaluations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Counted {
    Objective,
    Constraints,
}

/// One nlopt minimisation: algorithm, box, stopping rules and run-control.
///
/// ```
/// use idexp::optim::{nlopt::{Algorithm, Problem}, Control};
/// let ctl = Control::new();
/// let mut x = vec![3.0, -2.0];
/// let run = Problem::new(Algorithm::Lbfgs, vec![-10.0; 2], vec![10.0; 2], &ctl)
///     .max_evals(200)
///     .ftol_rel(1e-14)
///     .minimise(
///         &mut x,
///         |x: &[f64], g: Option<&mut [f64]>, _: &mut ()| {
///             if let Some(g) = g {
///                 g[0] = 2.0 * (x[0] - 1.0);
///                 g[1] = 2.0 * x[1];
///             }
///             (x[0] - 1.0).powi(2) + x[1] * x[1]
///         },
///         (),
///     );
/// assert_eq!(run.status.termination(), idexp::optim::Termination::Converged);
/// assert!((x[0] - 1.0).abs() < 1e-6 && x[1].abs() < 1e-6);
/// assert_eq!(run.evaluations, ctl.evaluations());
/// ```
#[derive(Debug, Clone)]
pub struct Problem<'c> {
    algorithm: Algorithm,
    lower: Vec<f64>,
    upper: Vec<f64>,
    max_evals: Option<u32>,
    xtol_rel: Option<f64>,
    ftol_rel: Option<f64>,
    counted: Counted,
    ctl: &'c Control,
    halt: Option<&'c Cell<bool>>,
}

/// How one nlopt run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run {
    /// How it ended.
    pub status: GradientStatus,
    /// Evaluated calls of the counted callback (calls skipped on a stop are not counted).
    pub evaluations: u64,
}

impl<'c> Problem<'c> {
    /// `algorithm` over the box [lower, upper], stopped by `ctl` (its stop
    /// flag, deadline and evaluation budget). No evaluation budget or
    /// tolerance of its own until set.
    pub fn new(algorithm: Algorithm, lower: Vec<f64>, upper: Vec<f64>, ctl: &'c Control) -> Self {
        Problem {
            algorithm,
            lower,
            upper,
            max_evals: None,
            xtol_rel: None,
            ftol_rel: None,
            counted: Counted::Objective,
            ctl,
            halt: None,
        }
    }
    /// nlopt's own evaluation budget (`maxeval`, at least 1).
    pub fn max_evals(mut self, n: u32) -> Self {
        self.max_evals = Some(n.max(1));
        self
    }
    /// Relative tolerance on x (`xtol_rel`; ignored unless positive).
    pub fn xtol_rel(mut self, tol: f64) -> Self {
        self.xtol_rel = (tol > 0.0).then_some(tol);
        self
    }
    /// Relative tolerance on the objective (`ftol_rel`; ignored unless positive).
    pub fn ftol_rel(mut self, tol: f64) -> Self {
        self.ftol_rel = (tol > 0.0).then_some(tol);
        self
    }
    /// Ends the run as a stop request of the control does (flat callbacks,
    /// nothing more evaluated or counted) once `flag` is set, e.g. by the
    /// callbacks themselves when the run stopped making progress.
    pub fn halt_on(mut self, flag: &'c Cell<bool>) -> Self {
        self.halt = Some(flag);
        self
    }
    /// Counts the constraint callback's calls as the evaluations instead of
    /// the objective's (an epigraph form, whose objective is a cheap linear
    /// function and whose constraints evaluate the criterion).
    pub fn count_constraint_calls(mut self) -> Self {
        self.counted = Counted::Constraints;
        self
    }

    /// Minimises `f` (value; gradient into the slice when nlopt asks for it;
    /// `data` is its per-run buffer) from `x`, which receives nlopt's last point.
    pub fn minimise<U>(&self, x: &mut [f64], f: impl Fn(&[f64], Option<&mut [f64]>, &mut U) -> f64, data: U) -> Run {
        self.run(x, f, data, None::<(usize, f64, fn(&mut [f64], &[f64], Option<&mut [f64]>, &mut ()), ())>)
    }

    /// Minimises `f` subject to the `m` inequality constraints c(x) ≤ `tol`
    /// computed by `c` (values into the first slice; the m × n Jacobian,
    /// row-major, into the second when nlopt asks for it; `cdata` its buffer).
    #[allow(clippy::too_many_arguments)]
    pub fn minimise_constrained<U, V>(
        &self,
        x: &mut [f64],
        f: impl Fn(&[f64], Option<&mut [f64]>, &mut U) -> f64,
        data: U,
        m: usize,
        tol: f64,
        c: impl Fn(&mut [f64], &[f64], Option<&mut [f64]>, &mut V),
        cdata: V,
    ) -> Run {
        self.run(x, f, data, Some((m, tol, c, cdata)))
    }

    fn run<U, V, C>(&self, x: &mut [f64], f: impl Fn(&[f64], Option<&mut [f64]>, &mut U) -> f64, data: U, cons: Option<(usize, f64, C, V)>) -> Run
    where
        C: Fn(&mut [f64], &[f64], Option<&mut [f64]>, &mut V),
    {
        let ctl = self.ctl;
        let halt = self.halt;
        let stop = move || ctl.should_stop() || halt.is_some_and(Cell::get);
        let evals = Cell::new(0u64);
        let last = Cell::new(STOPPED_F);
        let count = |which: Counted| {
            if which == self.counted {
                evals.set(evals.get() + 1);
                ctl.count(1);
            }
        };
        let f_cb = |x: &[f64], grad: Option<&mut [f64]>, u: &mut U| -> f64 {
            let mut grad = grad;
            if stop() {
                zero(grad);
                return last.get();
            }
            let v = f(x, grad.as_deref_mut(), u);
            count(Counted::Objective);
            if stop() {
                zero(grad);
            }
            last.set(v);
            v
        };
        let mut opt = nlopt::Nlopt::new(self.algorithm.nlopt(), x.len(), f_cb, nlopt::Target::Minimize, data);
        let _ = opt.set_lower_bounds(&self.lower);
        let _ = opt.set_upper_bounds(&self.upper);
        if let Some(n) = self.max_evals {
            let _ = opt.set_maxeval(n);
        }
        if let Some(t) = self.xtol_rel {
            let _ = opt.set_xtol_rel(t);
        }
        if let Some(t) = self.ftol_rel {
            let _ = opt.set_ftol_rel(t);
        }
        if let Some(d) = ctl.remaining() {
            let _ = opt.set_maxtime(d.as_secs_f64().max(1e-3));
        }
        if let Some((m, tol, c, cdata)) = cons {
            let c_cb = move |res: &mut [f64], x: &[f64], grad: Option<&mut [f64]>, v: &mut V| {
                let mut grad = grad;
                if stop() {
                    res.iter_mut().for_each(|r| *r = -1.0);
                    zero(grad);
                    return;
                }
                c(res, x, grad.as_deref_mut(), v);
                count(Counted::Constraints);
                if stop() {
                    zero(grad);
                }
            };
            let _ = opt.add_inequality_mconstraint(m, c_cb, cdata, &vec![tol; m]);
        }
        let status = status_of(&opt.optimize(x));
        drop(opt);
        Run {
            status,
            evaluations: evals.get(),
        }
    }
}

/// What the objective answers when stopped before its first evaluation.
const STOPPED_F: f64 = 0.0;

fn zero(g: Option<&mut [f64]>) {
    if let Some(g) = g {
        g.iter_mut().for_each(|v| *v = 0.0);
    }
}

/// nlopt's `optimize` result as idexp's [`GradientStatus`] (the only place
/// that reads nlopt's result codes).
fn status_of<T>(r: &Result<(nlopt::SuccessState, T), (nlopt::FailState, T)>) -> GradientStatus {
    use nlopt::{FailState as F, SuccessState as S};
    match r {
        Ok((S::Success, _)) => GradientStatus::Success,
        Ok((S::StopValReached, _)) => GradientStatus::StopValReached,
        Ok((S::FtolReached, _)) => GradientStatus::FtolReached,
        Ok((S::XtolReached, _)) => GradientStatus::XtolReached,
        Ok((S::MaxEvalReached, _)) => GradientStatus::MaxEvalReached,
        Ok((S::MaxTimeReached, _)) => GradientStatus::MaxTimeReached,
        Err((F::Failure, _)) => GradientStatus::Failure,
        Err((F::InvalidArgs, _)) => GradientStatus::InvalidArgs,
        Err((F::OutOfMemory, _)) => GradientStatus::OutOfMemory,
        Err((F::RoundoffLimited, _)) => GradientStatus::RoundoffLimited,
        Err((F::ForcedStop, _)) => GradientStatus::ForcedStop,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::optim::Termination;

    /// Every nlopt result maps to the status written with nlopt's own name for it.
    #[test]
    fn words_match_nlopts_debug_names() {
        use nlopt::{FailState as F, SuccessState as S};
        for s in [
            S::Success,
            S::StopValReached,
            S::FtolReached,
            S::XtolReached,
            S::MaxEvalReached,
            S::MaxTimeReached,
        ] {
            let ours = status_of::<f64>(&Ok((s, 0.0)));
            assert_eq!(ours.as_str(), format!("{s:?}"));
            assert_eq!(serde_json::to_string(&ours).unwrap(), format!("\"{s:?}\""));
        }
        for f in [F::Failure, F::InvalidArgs, F::OutOfMemory, F::RoundoffLimited, F::ForcedStop] {
            let ours = status_of::<f64>(&Err((f, 0.0)));
            assert_eq!(ours.to_string(), format!("{f:?}"));
            assert_eq!(serde_json::to_string(&ours).unwrap(), format!("\"{f:?}\""));
        }
        assert_eq!(GradientStatus::MaxTimeReached.termination(), Termination::TimeLimit);
    }

    fn bowl(x: &[f64], g: Option<&mut [f64]>, _: &mut ()) -> f64 {
        if let Some(g) = g {
            for (gi, xi) in g.iter_mut().zip(x) {
                *gi = 2.0 * (xi - 1.0);
            }
        }
        x.iter().map(|v| (v - 1.0).powi(2)).sum()
    }

    #[test]
    fn a_stopped_control_ends_the_run_without_more_evaluations() {
        for alg in [Algorithm::Slsqp, Algorithm::Mma, Algorithm::Lbfgs] {
            let ctl = Control::new().with_max_evals(Some(3));
            let mut x = vec![-4.0, 3.0, 7.0];
            let run = Problem::new(alg, vec![-10.0; 3], vec![10.0; 3], &ctl).max_evals(500).minimise(&mut x, bowl, ());
            assert_eq!(run.evaluations, 3, "{alg:?}: {run:?}");
            assert_eq!(ctl.evaluations(), 3, "{alg:?}");
            // a stop flag set before the start: nothing evaluated at all
            let ctl = Control::new();
            ctl.stop_flag().request();
            let calls = Cell::new(0);
            let f = |x: &[f64], g: Option<&mut [f64]>, u: &mut ()| {
                calls.set(calls.get() + 1);
                bowl(x, g, u)
            };
            let run = Problem::new(alg, vec![-10.0; 3], vec![10.0; 3], &ctl)
                .max_evals(500)
                .minimise(&mut [0.5; 3], f, ());
            assert_eq!((run.evaluations, calls.get()), (0, 0), "{alg:?}: {run:?}");
        }
    }

    #[test]
    fn constraints_are_counted_when_asked_and_the_minimum_is_found() {
        // min ‖x − 1‖² s.t. x_0 + x_1 ≤ 1: the minimum at (½, ½)
        let ctl = Control::new();
        let calls = Cell::new(0u64);
        let c = |res: &mut [f64], x: &[f64], g: Option<&mut [f64]>, _: &mut ()| {
            calls.set(calls.get() + 1);
            res[0] = x[0] + x[1] - 1.0;
            if let Some(g) = g {
                g.copy_from_slice(&[1.0, 1.0]);
            }
        };
        let mut x = vec![0.0, 0.0];
        let run = Problem::new(Algorithm::Slsqp, vec![-5.0; 2], vec![5.0; 2], &ctl)
            .max_evals(200)
            .xtol_rel(1e-12)
            .count_constraint_calls()
            .minimise_constrained(&mut x, bowl, (), 1, 1e-12, c, ());
        assert_eq!(run.status.termination(), Termination::Converged, "{run:?}");
        approx::assert_abs_diff_eq!(x.as_slice(), [0.5, 0.5].as_slice(), epsilon = 1e-6);
        assert_eq!(run.evaluations, calls.get());
        assert_eq!(ctl.evaluations(), calls.get());
    }

    #[test]
    fn the_deadline_is_nlopts_maxtime() {
        // Rosenbrock in 10 variables at 2 ms an evaluation takes hundreds of
        // evaluations; a 50 ms deadline ends it after about 25
        let ctl = Control::new().with_time_limit(Some(0.05));
        let f = |x: &[f64], g: Option<&mut [f64]>, _: &mut ()| {
            std::thread::sleep(std::time::Duration::from_millis(2));
            let n = x.len();
            let mut v = 0.0;
            let mut gr = vec![0.0; n];
            for i in 0..n - 1 {
                let (a, b) = (x[i + 1] - x[i] * x[i], 1.0 - x[i]);
                v += 100.0 * a * a + b * b;
                gr[i] += -400.0 * a * x[i] - 2.0 * b;
                gr[i + 1] += 200.0 * a;
            }
            if let Some(g) = g {
                g.copy_from_slice(&gr);
            }
            v
        };
        let run = Problem::new(Algorithm::Lbfgs, vec![-5.0; 10], vec![5.0; 10], &ctl).minimise(&mut [-1.5; 10], f, ());
        assert!(run.evaluations >= 5 && run.evaluations <= 60, "{run:?}");
        assert!(matches!(run.status.termination(), Termination::TimeLimit | Termination::Converged), "{run:?}");
    }
}
