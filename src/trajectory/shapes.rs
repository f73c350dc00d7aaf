//! The trajectory shapes a design can name, one variant each: [`Shape`]
//! (the design vector's map), [`ShapeMotion`] (its motion) and their grids
//! and buffers, dispatching the [`TrajectoryShape`] seam to the variant.
//!
//! A new shape is one file implementing [`TrajectoryShape`] and [`Motion`]
//! (like [`super::bspline`]) plus one variant in each enum here and in the
//! design's `[trajectory] shape` ([`crate::excitation::design::ShapeKind`]).
//!
//! Motions serialise as their variant's own fields (untagged): a Fourier
//! series as `{omega, q0, a, b}`, a B-spline as `{degree, knots, control}`,
//! so files written before the B-splines read back unchanged.
//!
//! # Panics
//!
//! The [`TrajectoryShape`] methods that take a motion, a grid or a scratch
//! panic when these belong to another variant than the shape: they are
//! always made by the same shape ([`TrajectoryShape::motion`],
//! [`TrajectoryShape::grid`]); a mismatched scratch is replaced.

use super::bspline::{BSplineGrid, BSplineLayout, BSplineMotion, BSplineScratch};
use super::shape::{Ends, JointBox, Motion, StateGradient, TimeGrid, TrajectoryShape};
use super::{period_grid, seconds_text, FourierLayout, FourierScratch, FourierTrajectory, TrigGrid};
use crate::error::Result;
use crate::io::States;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// A design's trajectory shape.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Shape {
    /// Periodic finite Fourier series.
    Fourier(FourierLayout),
    /// Clamped B-spline, at rest at both ends.
    BSpline(BSplineLayout),
}

/// The motion of a [`Shape`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ShapeMotion {
    /// A Fourier series.
    Fourier(FourierTrajectory),
    /// A B-spline.
    BSpline(BSplineMotion),
}

/// The grid of a [`Shape`].
#[derive(Debug, Clone)]
pub enum ShapeGrid {
    /// With the sin/cos table.
    Fourier(TrigGrid),
    /// With the basis values.
    BSpline(BSplineGrid),
}

/// The pull-back buffers of a [`Shape`].
#[derive(Debug, Clone, Default)]
pub enum ShapeScratch {
    /// None yet.
    #[default]
    Empty,
    /// Fourier basis buffers.
    Fourier(FourierScratch),
    /// B-spline (none).
    BSpline(BSplineScratch),
}

impl From<FourierLayout> for Shape {
    fn from(l: FourierLayout) -> Self {
        Shape::Fourier(l)
    }
}

impl From<BSplineLayout> for Shape {
    fn from(l: BSplineLayout) -> Self {
        Shape::BSpline(l)
    }
}

impl From<FourierTrajectory> for ShapeMotion {
    fn from(t: FourierTrajectory) -> Self {
        ShapeMotion::Fourier(t)
    }
}

impl From<BSplineMotion> for ShapeMotion {
    fn from(m: BSplineMotion) -> Self {
        ShapeMotion::BSpline(m)
    }
}

/// `$body` with `$v` bound to the variant's value of `$e` (same arms in every enum).
macro_rules! each {
    ($e:expr, $v:ident => $body:expr) => {
        match $e {
            Shape::Fourier($v) => $body,
            Shape::BSpline($v) => $body,
        }
    };
}

macro_rules! each_motion {
    ($e:expr, $v:ident => $body:expr) => {
        match $e {
            ShapeMotion::Fourier($v) => $body,
            ShapeMotion::BSpline($v) => $body,
        }
    };
}

fn mismatch() -> ! {
    panic!("a motion or grid of another trajectory shape")
}

impl Shape {
    /// The shape's name in designs and reports (`fourier`, `bspline`).
    pub fn name(&self) -> &'static str {
        match self {
            Shape::Fourier(_) => "fourier",
            Shape::BSpline(_) => "bspline",
        }
    }

    /// The Fourier layout, if this is one.
    pub fn fourier(&self) -> Option<&FourierLayout> {
        match self {
            Shape::Fourier(l) => Some(l),
            _ => None,
        }
    }

    fn scratch_fourier(s: &mut ShapeScratch) -> &mut FourierScratch {
        if !matches!(s, ShapeScratch::Fourier(_)) {
            *s = ShapeScratch::Fourier(FourierScratch::default());
        }
        match s {
            ShapeScratch::Fourier(f) => f,
            _ => mismatch(),
        }
    }
}

impl ShapeMotion {
    /// The Fourier series, if this is one.
    pub fn fourier(&self) -> Option<&FourierTrajectory> {
        match self {
            ShapeMotion::Fourier(t) => Some(t),
            _ => None,
        }
    }

    /// Checks dimensions and finiteness of a motion read from a file; `ctx` names the source.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        match self {
            ShapeMotion::Fourier(t) => t.validate(ctx),
            ShapeMotion::BSpline(m) => m.validate(ctx),
        }
    }

    /// T for a report ([`seconds_text`]).
    pub fn duration_text(&self) -> String {
        seconds_text(self.duration())
    }

    /// Samples [0, T) at `rate` Hz: t = i/rate, i = 0..round(T·rate) (for a
    /// rest-to-rest motion the state at T is the state at 0).
    pub fn sample(&self, rate: f64) -> Result<States> {
        Ok(self.sample_at(&period_grid(self.duration(), rate)?))
    }
}

impl Motion for ShapeMotion {
    fn n_joints(&self) -> usize {
        each_motion!(self, m => m.n_joints())
    }
    fn duration(&self) -> f64 {
        each_motion!(self, m => Motion::duration(m))
    }
    fn ends(&self) -> Ends {
        each_motion!(self, m => m.ends())
    }
    fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        each_motion!(self, m => Motion::eval(m, t, q, qd, qdd))
    }
    fn derivatives(&self, j: usize, o: usize, t: f64) -> [f64; 3] {
        each_motion!(self, m => Motion::derivatives(m, j, o, t))
    }
    fn rest_pose(&self) -> Vec<f64> {
        each_motion!(self, m => m.rest_pose())
    }
    fn sample_at(&self, times: &[f64]) -> States {
        each_motion!(self, m => Motion::sample_at(m, times))
    }
}

impl TimeGrid for ShapeGrid {
    fn times(&self) -> &[f64] {
        match self {
            ShapeGrid::Fourier(g) => g.times(),
            ShapeGrid::BSpline(g) => g.times(),
        }
    }
}

impl TrajectoryShape for Shape {
    type Motion = ShapeMotion;
    type Scratch = ShapeScratch;
    type Grid = ShapeGrid;

    fn n_vars(&self) -> usize {
        each!(self, s => TrajectoryShape::n_vars(s))
    }
    fn n_joints(&self) -> usize {
        each!(self, s => TrajectoryShape::n_joints(s))
    }
    fn duration(&self) -> f64 {
        each!(self, s => TrajectoryShape::duration(s))
    }
    fn ends(&self) -> Ends {
        each!(self, s => TrajectoryShape::ends(s))
    }
    fn motion(&self, x: &[f64]) -> ShapeMotion {
        each!(self, s => s.motion(x).into())
    }
    fn bounds(&self, limits: &JointBox) -> (Vec<f64>, Vec<f64>) {
        each!(self, s => s.bounds(limits))
    }
    fn pull_back(&self, m: &ShapeMotion, t: f64, g: &StateGradient, scratch: &mut ShapeScratch, gx: &mut [f64]) {
        match (self, m) {
            (Shape::Fourier(s), ShapeMotion::Fourier(m)) => s.pull_back(m, t, g, Self::scratch_fourier(scratch), gx),
            (Shape::BSpline(s), ShapeMotion::BSpline(m)) => s.pull_back(m, t, g, &mut BSplineScratch, gx),
            _ => mismatch(),
        }
    }
    fn rest_vars(&self) -> Vec<f64> {
        each!(self, s => s.rest_vars())
    }
    fn joint_vars(&self, j: usize) -> Range<usize> {
        each!(self, s => s.joint_vars(j))
    }
    fn centre(&self, x: &[f64], j: usize) -> f64 {
        each!(self, s => s.centre(x, j))
    }
    fn clamp_centre(&self, x: &mut [f64], position: &[[f64; 2]]) {
        each!(self, s => s.clamp_centre(x, position))
    }
    fn scan_times(&self) -> Vec<f64> {
        each!(self, s => s.scan_times())
    }
    fn grid(&self, times: Vec<f64>) -> ShapeGrid {
        match self {
            Shape::Fourier(s) => ShapeGrid::Fourier(s.grid(times)),
            Shape::BSpline(s) => ShapeGrid::BSpline(s.grid(times)),
        }
    }
    fn grid_state(&self, grid: &ShapeGrid, m: &ShapeMotion, i: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        match (self, grid, m) {
            (Shape::Fourier(s), ShapeGrid::Fourier(g), ShapeMotion::Fourier(m)) => s.grid_state(g, m, i, q, qd, qdd),
            (Shape::BSpline(s), ShapeGrid::BSpline(g), ShapeMotion::BSpline(m)) => s.grid_state(g, m, i, q, qd, qdd),
            _ => mismatch(),
        }
    }
    fn grid_derivative(&self, grid: &ShapeGrid, m: &ShapeMotion, j: usize, order: usize, i: usize) -> f64 {
        match (self, grid, m) {
            (Shape::Fourier(s), ShapeGrid::Fourier(g), ShapeMotion::Fourier(m)) => s.grid_derivative(g, m, j, order, i),
            (Shape::BSpline(s), ShapeGrid::BSpline(g), ShapeMotion::BSpline(m)) => s.grid_derivative(g, m, j, order, i),
            _ => mismatch(),
        }
    }
    fn grid_series(&self, grid: &ShapeGrid, m: &ShapeMotion, j: usize, order: usize, out: &mut Vec<f64>) {
        match (self, grid, m) {
            (Shape::Fourier(s), ShapeGrid::Fourier(g), ShapeMotion::Fourier(m)) => s.grid_series(g, m, j, order, out),
            (Shape::BSpline(s), ShapeGrid::BSpline(g), ShapeMotion::BSpline(m)) => s.grid_series(g, m, j, order, out),
            _ => mismatch(),
        }
    }
    fn acc_len(&self) -> usize {
        each!(self, s => s.acc_len())
    }
    fn grid_accumulate(&self, grid: &ShapeGrid, m: &ShapeMotion, i: usize, g: &[f64], scratch: &mut ShapeScratch, acc: &mut [f64]) {
        match (self, grid, m) {
            (Shape::Fourier(s), ShapeGrid::Fourier(gr), ShapeMotion::Fourier(m)) => s.grid_accumulate(gr, m, i, g, Self::scratch_fourier(scratch), acc),
            (Shape::BSpline(s), ShapeGrid::BSpline(gr), ShapeMotion::BSpline(m)) => s.grid_accumulate(gr, m, i, g, &mut BSplineScratch, acc),
            _ => mismatch(),
        }
    }
    fn grid_finish(&self, acc: &[f64], gx: &mut [f64]) {
        each!(self, s => s.grid_finish(acc, gx))
    }
}
