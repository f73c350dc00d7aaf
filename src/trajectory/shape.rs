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
//! The excitation design evaluates a motion on fixed time grids (the
//! criterion's samples, the constraint grid, the extremum scan): a shape
//! prepares such a grid once ([`TrajectoryShape::grid`]) and may precompute
//! what it needs there (the Fourier series its sin/cos table,
//! [`super::TrigGrid`]); the defaults evaluate [`Motion::eval`] at the grid's
//! times and pull gradients back one sample at a time.
//!
//! Two shapes implement it: the Fourier series ([`super::FourierLayout`] →
//! [`super::FourierTrajectory`], periodic) and clamped B-splines
//! ([`super::bspline::BSplineLayout`] → [`super::bspline::BSplineMotion`],
//! rest to rest). A design names one of them: [`super::shapes::Shape`], one
//! variant per shape.

use crate::io::States;
use serde::Serialize;
use std::ops::Range;

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
    /// The pose the motion is played from and back to by default (the
    /// home of [`super::lead::Delivered`]): q0 of a Fourier series, the
    /// start (= end) pose of a rest-to-rest motion.
    fn rest_pose(&self) -> Vec<f64>;

    /// The motion at the given times.
    fn sample_at(&self, times: &[f64]) -> States {
        let n = self.n_joints();
        let mut s = States {
            t: Some(times.to_vec()),
            q: Vec::with_capacity(times.len()),
            qd: Vec::with_capacity(times.len()),
            qdd: Vec::with_capacity(times.len()),
        };
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for &t in times {
            self.eval(t, &mut q, &mut qd, &mut qdd);
            s.q.push(q.clone());
            s.qd.push(qd.clone());
            s.qdd.push(qdd.clone());
        }
        s
    }
}

/// Fixed sample times with whatever a shape precomputes for them.
pub trait TimeGrid {
    /// The times (s).
    fn times(&self) -> &[f64];
    /// Number of times.
    fn len(&self) -> usize {
        self.times().len()
    }
    /// True without times.
    fn is_empty(&self) -> bool {
        self.times().is_empty()
    }
}

/// A grid that is its times only (shapes that precompute nothing).
#[derive(Debug, Clone, PartialEq)]
pub struct PlainGrid {
    /// Times (s).
    pub times: Vec<f64>,
}

impl TimeGrid for PlainGrid {
    fn times(&self) -> &[f64] {
        &self.times
    }
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
    /// A fixed time grid with what the shape precomputes there ([`TrajectoryShape::grid`]).
    type Grid: TimeGrid + Clone + std::fmt::Debug + Send + Sync;

    /// Length of x.
    fn n_vars(&self) -> usize;
    /// Number of joints n.
    fn n_joints(&self) -> usize;
    /// T (s): [`Motion::duration`] of every motion of the shape.
    fn duration(&self) -> f64;
    /// Periodic or rest to rest ([`Motion::ends`] of every motion).
    fn ends(&self) -> Ends;
    /// The motion q(t; x).
    fn motion(&self, x: &[f64]) -> Self::Motion;
    /// The design vector of the motion at rest at its centre pose (the GA's
    /// shrink centre; every [`TrajectoryShape::joint_vars`] entry zero).
    fn rest_vars(&self) -> Vec<f64>;
    /// The entries of x that move joint j about its centre c_j
    /// ([`TrajectoryShape::centre`]): scaling them by s scales q_j(t) − c_j,
    /// q̇_j and q̈_j by s (the GA's repair and the final shrink).
    fn joint_vars(&self, j: usize) -> Range<usize>;
    /// The centre c_j of joint j for design vector x.
    fn centre(&self, x: &[f64], j: usize) -> f64;
    /// Moves design variables that place a centre into the allowed position
    /// range `position` (per joint), keeping a small pad (default: none do).
    fn clamp_centre(&self, _x: &mut [f64], _position: &[[f64; 2]]) {}
    /// Times over [0, T) that bracket every extremum of q_j, q̇_j, q̈_j
    /// (the scan before the Newton steps of the joint-limit constraints).
    fn scan_times(&self) -> Vec<f64>;
    /// Prepares a grid of fixed times.
    fn grid(&self, times: Vec<f64>) -> Self::Grid;
    /// q, q̇, q̈ of motion `m` at grid time i (default [`Motion::eval`]).
    fn grid_state(&self, grid: &Self::Grid, m: &Self::Motion, i: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        m.eval(grid.times()[i], q, qd, qdd)
    }
    /// The `order`-th time derivative of q_j of `m` at grid time i.
    fn grid_derivative(&self, grid: &Self::Grid, m: &Self::Motion, j: usize, order: usize, i: usize) -> f64 {
        m.derivatives(j, order, grid.times()[i])[0]
    }
    /// [`TrajectoryShape::grid_derivative`] at every grid time into `out`
    /// (resized to the grid's length): the same values, for a shape that
    /// can share work between the times.
    fn grid_series(&self, grid: &Self::Grid, m: &Self::Motion, j: usize, order: usize, out: &mut Vec<f64>) {
        out.clear();
        out.extend((0..grid.times().len()).map(|i| self.grid_derivative(grid, m, j, order, i)));
    }
    /// Length of the per-gradient accumulator of [`TrajectoryShape::grid_accumulate`].
    fn acc_len(&self) -> usize {
        self.n_vars()
    }
    /// Adds the contributions of grid time i to `acc` (one block of
    /// [`TrajectoryShape::acc_len`] per gradient) from `g`, one block of 3n
    /// values (∂c/∂q, ∂c/∂q̇, ∂c/∂q̈ at t_i) per gradient; the sum over the
    /// grid is turned into ∂c/∂x by [`TrajectoryShape::grid_finish`].
    /// The default pulls each block back through [`TrajectoryShape::pull_back`]
    /// (allocating its buffers); shapes on a hot path override it.
    fn grid_accumulate(&self, grid: &Self::Grid, m: &Self::Motion, i: usize, g: &[f64], scratch: &mut Self::Scratch, acc: &mut [f64]) {
        let (n, len) = (self.n_joints(), self.acc_len());
        let mut sg = StateGradient::zeros(n);
        sg.factor = 1.0;
        let mut gx = vec![0.0; self.n_vars()];
        for (gt, at) in g.chunks_exact(3 * n).zip(acc.chunks_exact_mut(len)) {
            sg.q.copy_from_slice(&gt[..n]);
            sg.qd.copy_from_slice(&gt[n..2 * n]);
            sg.qdd.copy_from_slice(&gt[2 * n..]);
            self.pull_back(m, grid.times()[i], &sg, scratch, &mut gx);
            at.iter_mut().zip(&gx).for_each(|(a, v)| *a += v);
        }
    }
    /// ∂c/∂x (`gx`, length [`TrajectoryShape::n_vars`]) from one summed
    /// accumulator of [`TrajectoryShape::grid_accumulate`] (default: a copy).
    fn grid_finish(&self, acc: &[f64], gx: &mut [f64]) {
        gx.copy_from_slice(acc)
    }
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
