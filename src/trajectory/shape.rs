//! The trajectory-shape seam: what the excitation design needs from a
//! parameterised joint trajectory, whatever its basis.
//!
//! A [`TrajectoryShape`] maps a design vector x (length [`TrajectoryShape::n_vars`]) to a
//! [`Motion`] q(t; x) on [0, T] and gives
//!
//! * the box of x implied by the joint limits ([`TrajectoryShape::bounds`]);
//! * the Jacobian of the samples with respect to x, applied transposed to a
//!   gradient with respect to the state at one time ([`TrajectoryShape::pull_back`]):
//!   for a scalar c whose gradient with respect to (q, q̇, q̈)(t) is
//!   f·(g_q, g_q̇, g_q̈) ([`StateGradient`]),
//!
//!   ∂c/∂x = f · Σ_j [ g_q,j ∂q_j(t)/∂x + g_q̇,j ∂q̇_j(t)/∂x + g_q̈,j ∂q̈_j(t)/∂x ];
//!
//! * whether the motion is periodic (played between a lead-in and a
//!   lead-out) or starts and ends at rest ([`Ends`]).
//!
//! Two shapes implement it: the Fourier series ([`super::FourierLayout`] →
//! [`super::FourierTrajectory`], periodic) and clamped B-splines
//! ([`super::bspline::BSplineLayout`] → [`super::bspline::BSplineMotion`],
//! rest to rest).

use serde::Serialize;

/// How a motion begins and ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Ends {
    /// q(t + T) = q(t): one period of a motion played repeatedly, reached
    /// from rest and left to rest by a lead-in and a lead-out.
    Periodic,
    /// q̇ = q̈ = 0 at t = 0 and t = T: played as it is, no lead-in or lead-out.
    RestToRest,
}

/// The gradient of a scalar with respect to the state at one time t, as
/// `factor · (q, qd, qdd)` (n each): what [`TrajectoryShape::pull_back`] maps to x.
#[derive(Debug, Clone, PartialEq)]
pub struct StateGradient {
    /// Common factor f.
    pub factor: f64,
    /// ∂c/∂q_j (before the factor).
    pub q: Vec<f64>,
    /// ∂c/∂q̇_j (before the factor).
    pub qd: Vec<f64>,
    /// ∂c/∂q̈_j (before the factor).
    pub qdd: Vec<f64>,
}

impl StateGradient {
    /// A zero gradient for `n` joints (factor 0).
    pub fn zeros(n: usize) -> Self {
        StateGradient {
            factor: 0.0,
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        }
    }

    /// Sets q, qd and qdd to zero (the factor is kept).
    pub fn clear(&mut self) {
        for v in self.q.iter_mut().chain(self.qd.iter_mut()).chain(self.qdd.iter_mut()) {
            *v = 0.0;
        }
    }
}

/// A joint motion on [0, [`Motion::duration`]] (rad or m, s).
pub trait Motion {
    /// Number of joints n.
    fn n_joints(&self) -> usize;
    /// T (s): the period of a periodic motion, the whole motion of a rest-to-rest one.
    fn duration(&self) -> f64;
    /// Periodic or rest to rest.
    fn ends(&self) -> Ends;
    /// q, q̇, q̈ at time t (each slice of length n).
    fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]);
    /// The time derivatives of orders m, m + 1, m + 2 of q_j at t (order 0 is q_j).
    fn derivatives(&self, j: usize, m: usize, t: f64) -> [f64; 3];
}

/// The joint limits a shape's box of design variables is derived from (per
/// joint; infinite entries: no limit).
#[derive(Debug, Clone, Copy)]
pub struct JointBox<'a> {
    /// Allowed [lower, upper] position (rad or m).
    pub position: &'a [[f64; 2]],
    /// Velocity limit.
    pub velocity: &'a [f64],
    /// Acceleration limit.
    pub acceleration: &'a [f64],
}

/// A trajectory shape: design vector x → [`Motion`], with the box of x and
/// the Jacobian of the samples with respect to x.
pub trait TrajectoryShape {
    /// The motion of a design vector.
    type Motion: Motion;
    /// Per-thread buffers of [`TrajectoryShape::pull_back`] (so that it does not allocate).
    type Scratch: Default + Clone + std::fmt::Debug + Send;

    /// Length of x.
    fn n_vars(&self) -> usize;
    /// The motion q(t; x).
    fn motion(&self, x: &[f64]) -> Self::Motion;
    /// Lower and upper bounds of x from the joint limits: the box the global
    /// search samples and the refinement keeps.
    fn bounds(&self, limits: &JointBox) -> (Vec<f64>, Vec<f64>);
    /// `gx` (length [`TrajectoryShape::n_vars`], overwritten) = the gradient with
    /// respect to x of a scalar whose gradient with respect to the state of
    /// `m` at time t is `g` (the module's formula).
    fn pull_back(&self, m: &Self::Motion, t: f64, g: &StateGradient, scratch: &mut Self::Scratch, gx: &mut [f64]);

    /// The Jacobian of the state at t with respect to x, dense:
    /// `[∂q/∂x, ∂q̇/∂x, ∂q̈/∂x]`, each n rows of [`TrajectoryShape::n_vars`]
    /// (from [`TrajectoryShape::pull_back`] with unit gradients; for tests and reports).
    fn sample_jacobian(&self, x: &[f64], t: f64) -> [Vec<Vec<f64>>; 3] {
        let m = self.motion(x);
        let n = m.n_joints();
        let mut scratch = Self::Scratch::default();
        let mut g = StateGradient::zeros(n);
        g.factor = 1.0;
        let mut out: [Vec<Vec<f64>>; 3] = Default::default();
        for (order, rows) in out.iter_mut().enumerate() {
            for j in 0..n {
                g.clear();
                [&mut g.q, &mut g.qd, &mut g.qdd][order][j] = 1.0;
                let mut row = vec![0.0; self.n_vars()];
                self.pull_back(&m, t, &g, &mut scratch, &mut row);
                rows.push(row);
            }
        }
        out
    }
}
