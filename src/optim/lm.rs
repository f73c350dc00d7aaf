//! Levenberg–Marquardt on a box as an argmin [`Solver`].
//!
//! Minimises V(z) = Σ rᵢ(z)² over a box in the solver's coordinates z (the
//! problem maps them to its physical parameters). At z the problem gives V,
//! g = Jᵀr (half the gradient) and H = JᵀJ (half the Gauss–Newton Hessian),
//! J = ∂r/∂z, so that V(z + s) ≈ V + 2gᵀs + sᵀHs; one iteration
//! solves (H + λ·diag(max(Hᵢᵢ, 10⁻¹² max Hⱼⱼ)))·s = −g by Cholesky, clamps
//! z + s to the box, and accepts it when V decreases and the gain ratio
//! ρ = (V − V(z+s)) / (−2gᵀs − sᵀHs) is positive; then λ ← λ·max(⅓, 1 − (2ρ−1)³)
//! and ν ← 2, else λ ← λν, ν ← 2ν until a step is accepted or λ > 10¹⁶
//! (stalled). Convergence: ‖g‖∞ ≤ 10⁻¹⁴ V (gradient), a relative decrease
//! below `ftol` with λ < 1 (cost), or ‖s‖∞ < `xtol` (step). λ starts at 10⁻³.
//!
//! One argmin iteration is one accepted step (with its rejected trials);
//! argmin's `max_iters` is the iteration budget. `terminate` asks the
//! [`Control`] whether the user stopped the run. [`run`] wires the
//! executor and maps argmin's `TerminationReason` to [`LmStatus`].

use super::Control;
use crate::error::Result;
use argmin::core::{Executor, IterState, Problem, Solver, State, TerminationReason, TerminationStatus, KV};
use nalgebra::{DMatrix, DVector};

/// A least-squares problem for [`Lm`], in the solver's coordinates z.
pub trait LmProblem {
    /// Number of unknowns.
    fn dim(&self) -> usize;
    /// (V, g = Jᵀr = ½ ∂V/∂z, H = JᵀJ) at `z`, J = ∂r/∂z; an error ends the fit.
    fn normal_equations(&self, z: &[f64]) -> Result<(f64, DVector<f64>, DMatrix<f64>)>;
    /// V at `z` (+∞ when it cannot be evaluated).
    fn cost(&self, z: &[f64]) -> f64;
    /// Coordinate `i` clamped to the box.
    fn clamp(&self, i: usize, zi: f64) -> f64;
}

/// How a Levenberg–Marquardt run ended (serialised in snake_case, e.g.
/// `"converged_ftol"`: the word the multistart logs carry).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LmStatus {
    /// Relative cost decrease below `ftol` (with λ < 1).
    ConvergedFtol,
    /// Step below `xtol`.
    ConvergedXtol,
    /// Gradient numerically zero.
    ConvergedGtol,
    /// Iteration limit reached.
    MaxIterations,
    /// No decreasing step found (λ grew past 10¹⁶), or the normal equations
    /// failed at an accepted point.
    Stalled,
    /// V could not be evaluated at the start point.
    Failed,
    /// Stopped through the control.
    Interrupted,
}

impl LmStatus {
    /// True for the three converged outcomes.
    pub fn converged(self) -> bool {
        matches!(self, LmStatus::ConvergedFtol | LmStatus::ConvergedXtol | LmStatus::ConvergedGtol)
    }
}

/// Tolerances of [`Lm`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmTolerances {
    /// Relative cost decrease that counts as converged.
    pub ftol: f64,
    /// Step (∞-norm, in z) that counts as converged.
    pub xtol: f64,
}

/// The argmin state of [`Lm`]: param = z, cost = V.
pub type LmState = IterState<Vec<f64>, (), (), (), (), f64>;

/// The Levenberg–Marquardt solver (see the module docs).
pub struct Lm {
    tol: LmTolerances,
    ctl: Control,
    lambda: f64,
    nu: f64,
    /// Current point.
    pub z: Vec<f64>,
    v: f64,
    g: DVector<f64>,
    h: DMatrix<f64>,
    /// Cost at the end (V(z); for a stall after an accepted step, V of that step).
    pub cost: f64,
    /// Cost evaluations (a normal-equation evaluation counts as one).
    pub evaluations: usize,
    /// How it ended (`MaxIterations` until something else happens).
    pub status: LmStatus,
}

impl Lm {
    /// A solver from `z0` with tolerances `tol`, stopped by `ctl`.
    pub fn new(z0: Vec<f64>, tol: LmTolerances, ctl: &Control) -> Lm {
        Lm {
            tol,
            ctl: ctl.clone(),
            lambda: 1e-3,
            nu: 2.0,
            z: z0,
            v: f64::INFINITY,
            g: DVector::zeros(0),
            h: DMatrix::zeros(0, 0),
            cost: f64::INFINITY,
            evaluations: 0,
            status: LmStatus::MaxIterations,
        }
    }

    fn end(&mut self, status: LmStatus, state: LmState) -> LmState {
        self.status = status;
        let reason = match status {
            LmStatus::ConvergedFtol | LmStatus::ConvergedXtol | LmStatus::ConvergedGtol => TerminationReason::SolverConverged,
            _ => TerminationReason::SolverExit(format!("{status:?}")),
        };
        state.terminate_with(reason)
    }
}

type Step = std::result::Result<(LmState, Option<KV>), argmin::core::Error>;

impl<P: LmProblem> Solver<P, LmState> for Lm {
    fn name(&self) -> &str {
        "idexp Levenberg-Marquardt"
    }

    fn init(&mut self, problem: &mut Problem<P>, state: LmState) -> Step {
        let p = problem.problem.as_ref().ok_or_else(|| argmin::core::Error::msg("LM without a problem"))?;
        let state = state.param(self.z.clone());
        match p.normal_equations(&self.z) {
            Ok((v, g, h)) => {
                (self.v, self.g, self.h, self.cost) = (v, g, h, v);
                self.evaluations = 1;
                Ok((state.cost(v), None))
            }
            Err(_) => {
                self.evaluations = 1;
                Ok((self.end(LmStatus::Failed, state), None))
            }
        }
    }

    fn next_iter(&mut self, problem: &mut Problem<P>, state: LmState) -> Step {
        let p = problem.problem.as_ref().ok_or_else(|| argmin::core::Error::msg("LM without a problem"))?;
        let np = p.dim();
        let (v, g, h) = (self.v, &self.g, &self.h);
        if g.amax() <= 1e-14 * v.max(f64::MIN_POSITIVE) {
            return Ok((self.end(LmStatus::ConvergedGtol, state), None));
        }
        let dmax = (0..np).map(|i| h[(i, i)]).fold(0.0, f64::max);
        loop {
            let mut a = h.clone();
            for i in 0..np {
                a[(i, i)] += self.lambda * h[(i, i)].max(1e-12 * dmax).max(f64::MIN_POSITIVE);
            }
            let step = match a.cholesky() {
                Some(c) => c.solve(&(-g)),
                None => {
                    self.lambda *= self.nu;
                    self.nu *= 2.0;
                    if self.lambda > 1e16 {
                        return Ok((self.end(LmStatus::Stalled, state), None));
                    }
                    continue;
                }
            };
            let pred = -(2.0 * g.dot(&step) + (step.transpose() * h * &step)[(0, 0)]);
            let zn: Vec<f64> = self.z.iter().zip(step.iter()).enumerate().map(|(i, (a, b))| p.clamp(i, a + b)).collect();
            let step = DVector::from_fn(np, |i, _| zn[i] - self.z[i]);
            self.evaluations += 1;
            let vn = p.cost(&zn);
            let rho = if pred > 0.0 { (v - vn) / pred } else { -1.0 };
            if vn < v && rho > 0.0 {
                let rel = (v - vn) / v.max(f64::MIN_POSITIVE);
                let snorm = step.amax();
                self.z = zn;
                self.lambda *= (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3));
                self.nu = 2.0;
                let state = state.param(self.z.clone());
                match p.normal_equations(&self.z) {
                    Ok((a, b, c)) => {
                        (self.v, self.g, self.h, self.cost) = (a, b, c, a);
                        self.evaluations += 1;
                    }
                    Err(_) => {
                        self.cost = vn;
                        return Ok((self.end(LmStatus::Stalled, state.cost(vn)), None));
                    }
                }
                let state = state.cost(self.v);
                // a tiny decrease only means convergence for a (near) Gauss–Newton step,
                // not for a short step forced by a large damping λ
                return Ok(if rel < self.tol.ftol && self.lambda < 1.0 {
                    (self.end(LmStatus::ConvergedFtol, state), None)
                } else if snorm < self.tol.xtol {
                    (self.end(LmStatus::ConvergedXtol, state), None)
                } else {
                    (state, None)
                });
            }
            self.lambda *= self.nu;
            self.nu *= 2.0;
            if self.lambda > 1e16 {
                return Ok((self.end(LmStatus::Stalled, state), None));
            }
        }
    }

    fn terminate(&mut self, state: &LmState) -> TerminationStatus {
        // the iteration budget wins over a late stop request
        if state.get_iter() >= state.get_max_iters() {
            return TerminationStatus::Terminated(TerminationReason::MaxItersReached);
        }
        if self.ctl.interrupted() {
            self.status = LmStatus::Interrupted;
            return TerminationStatus::Terminated(TerminationReason::Interrupt);
        }
        TerminationStatus::NotTerminated
    }
}

/// Result of [`run`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmOutcome {
    /// Final point z.
    pub z: Vec<f64>,
    /// Final cost.
    pub cost: f64,
    /// How it ended.
    pub status: LmStatus,
    /// Iterations (accepted steps, plus the last tried one).
    pub iterations: usize,
    /// Cost evaluations.
    pub evaluations: usize,
}

/// Runs [`Lm`] from `z0` for at most `max_iter` iterations with argmin's
/// executor. Errors only if argmin itself fails.
pub fn run<P: LmProblem>(problem: P, z0: Vec<f64>, max_iter: usize, tol: LmTolerances, ctl: &Control) -> Result<LmOutcome> {
    let res = Executor::new(problem, Lm::new(z0, tol, ctl))
        .configure(|s| s.max_iters(max_iter as u64))
        .run()
        .map_err(|e| crate::error::Error::Numerical(format!("Levenberg-Marquardt: {e}")))?;
    let iterations = res.state.get_iter() as usize;
    let lm = res.solver;
    Ok(LmOutcome {
        z: lm.z,
        cost: lm.cost,
        status: lm.status,
        iterations,
        evaluations: lm.evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// r = (10 (z1 − z0²), 1 − z0): Rosenbrock as least squares, minimum (1, 1), box [−2, 2]².
    struct Rosen;
    impl LmProblem for Rosen {
        fn dim(&self) -> usize {
            2
        }
        fn normal_equations(&self, z: &[f64]) -> Result<(f64, DVector<f64>, DMatrix<f64>)> {
            let r = DVector::from_vec(vec![10.0 * (z[1] - z[0] * z[0]), 1.0 - z[0]]);
            let j = DMatrix::from_row_slice(2, 2, &[-20.0 * z[0], 10.0, -1.0, 0.0]);
            Ok((r.norm_squared(), j.transpose() * &r, j.transpose() * &j))
        }
        fn cost(&self, z: &[f64]) -> f64 {
            (10.0 * (z[1] - z[0] * z[0])).powi(2) + (1.0 - z[0]).powi(2)
        }
        fn clamp(&self, _: usize, zi: f64) -> f64 {
            zi.clamp(-2.0, 2.0)
        }
    }

    const TOL: LmTolerances = LmTolerances { ftol: 1e-12, xtol: 1e-12 };

    #[test]
    fn finds_the_minimum_of_rosenbrock() {
        let o = run(Rosen, vec![-1.2, 1.0], 200, TOL, &Control::new()).unwrap();
        assert!(
            matches!(o.status, LmStatus::ConvergedFtol | LmStatus::ConvergedXtol | LmStatus::ConvergedGtol),
            "{o:?}"
        );
        assert!((o.z[0] - 1.0).abs() < 1e-6 && (o.z[1] - 1.0).abs() < 1e-6, "{o:?}");
        let o2 = run(Rosen, vec![-1.2, 1.0], 3, TOL, &Control::new()).unwrap();
        assert_eq!((o2.status, o2.iterations), (LmStatus::MaxIterations, 3));
    }

    #[test]
    fn a_stopped_control_returns_the_start() {
        let c = Control::new();
        c.stop_flag().request();
        let o = run(Rosen, vec![-1.2, 1.0], 200, TOL, &c).unwrap();
        assert_eq!((o.status, o.iterations, o.z.clone()), (LmStatus::Interrupted, 0, vec![-1.2, 1.0]));
        assert_eq!(o.cost, Rosen.cost(&[-1.2, 1.0]));
    }
}
