//! Rest-to-rest joint trajectories as clamped uniform B-splines: the second
//! [`TrajectoryShape`].
//!
//! For joint j, degree p (3 … 5), s segments of equal length on [0, T] and
//! the clamped knot vector u = (0, …, 0, T/s, 2T/s, …, T, …, T) (p + 1 zeros
//! and p + 1 copies of T),
//!
//! q_j(t) = Σ_{i=0}^{s+p−1} N_{i,p}(t) P_{j,i}
//!
//! with the B-spline basis N_{i,p} (Cox–de Boor; derivatives by Piegl and
//! Tiller, *The NURBS Book*, algorithm A2.3). A clamped spline starts at P_0
//! with q̇(0) ∝ P_1 − P_0 and q̈(0) a combination of P_0, P_1, P_2 (likewise at
//! the end), so P_0 = P_1 = P_2 = P_{m−3} = P_{m−2} = P_{m−1} = q0_j makes the
//! motion start and end at rest at q0 ([`Ends::RestToRest`]: no lead-in or
//! lead-out). The design variables are the other control points, as offsets
//! from q0: x_{j,i} = P_{j,i} − q0_j, i = 3 … s + p − 4 (s + p ≥ 7). The
//! motion is linear in x; its Jacobian at t is the basis values
//! N_{i,p}^{(d)}(t), d = 0, 1, 2. By the convex-hull property, control points
//! within the position limits keep the motion within them: that is the box
//! of x ([`TrajectoryShape::bounds`]).
//!
//! **Free ends** (FIGAROH's form: a motion between poses of the search's
//! choosing, at rest at both): with `free_start` the three start control
//! points are one more design variable per joint, x_{j,s} = P_{j,0} − q0_j
//! (= P_{j,1} − q0_j = P_{j,2} − q0_j), the first of the joint's block; with
//! `free_end` the three end control points likewise, the last of the block.
//! Without `free_end` the end is the start (q0, or the free start pose).
//! Each x still moves control points only, so the motion stays linear in x,
//! the box still keeps it within the limits, and scaling a joint's block
//! scales q_j − q0_j. A motion whose ends are not at home is played between
//! a lead-in from and a lead-out to home (`excitation::execution`).
//!
//! **Given ends**: `start_pose` (`end_pose`) fixes the three start (end)
//! control points at a pose of the design's instead of q0 (no variable);
//! the offsets of the other control points stay measured from q0, the home.
//! Scaling a joint's block then scales the free control points about q0
//! while the given ends stay put (the GA's repair and the final shrink are
//! heuristics there; the verification decides).
//!
//! **Waypoints** (`pieces` = w − 1 > 1 for w waypoints, FIGAROH's form): the
//! motion is w − 1 rest-to-rest pieces of equal duration T/(w − 1), each a
//! clamped B-spline of s/(w − 1) segments. The knot vector is the uniform one
//! of s segments with each of the w − 2 interior waypoint times repeated p
//! times (so the pieces share their boundary control point), and the five
//! control points about each interior waypoint are one design variable per
//! joint: q̇ = q̈ = 0 at every waypoint. A joint's block is then: the free
//! start, then for each piece its s/(w − 1) + p − 6 inner control points
//! followed by the waypoint that ends it (none after the last piece), then
//! the free end.

use super::shape::{Ends, JointBox, Motion, StateGradient, TimeGrid, TrajectoryShape};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Highest degree supported.
pub const MAX_DEGREE: usize = 5;

/// Control points fixed at each end (the rest conditions q, q̇, q̈).
const FIXED: usize = 3;

/// Scan points per segment bracketing the joint extrema (the knots among
/// them: the acceleration of a cubic is extremal at a knot).
pub const SCAN_PER_SEGMENT: usize = 16;

/// A clamped uniform B-spline motion: degree, knots and control points per joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BSplineMotion {
    /// Degree p.
    pub degree: usize,
    /// Knot vector (s + 2p + 1 values, clamped on [0, T]).
    pub knots: Vec<f64>,
    /// Control points `control[j][i]` (rad or m), s + p per joint.
    pub control: Vec<Vec<f64>>,
}

/// How a flat design vector x maps to a [`BSplineMotion`] starting and
/// ending at rest at `q0` (module documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BSplineLayout {
    /// Number of joints.
    pub n: usize,
    /// Degree p (3 … 5).
    pub degree: usize,
    /// Number of equal segments s (the interior knots are s − 1).
    pub segments: usize,
    /// Duration T (s).
    pub duration: f64,
    /// Start and end configuration (rad or m); with free ends, the home
    /// pose and the centre of the box.
    pub q0: Vec<f64>,
    /// The start pose is a design variable (module documentation).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub free_start: bool,
    /// The end pose is a design variable of its own (else the end is the start).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub free_end: bool,
    /// A given start pose (else q0, or free).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_pose: Option<Vec<f64>>,
    /// A given end pose (else the start, or free).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub end_pose: Option<Vec<f64>>,
    /// Rest-to-rest pieces between waypoints (1: one piece, no interior waypoint).
    #[serde(default = "one_piece", skip_serializing_if = "is_one_piece")]
    pub pieces: usize,
}

fn one_piece() -> usize {
    1
}

fn is_one_piece(v: &usize) -> bool {
    *v == 1
}

/// Where a control point of a joint goes: a design variable of its block,
/// or one of the fixed ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Slot {
    Var(usize),
    Start,
    End,
}

impl BSplineLayout {
    /// Builds a layout; errors name the design field (`trajectory.degree`,
    /// `trajectory.segments`, `trajectory.duration`).
    pub fn new(q0: Vec<f64>, degree: usize, segments: usize, duration: f64) -> Result<Self> {
        if !(3..=MAX_DEGREE).contains(&degree) {
            return Err(Error::invalid(
                "trajectory",
                "degree",
                format!("expected a B-spline degree of 3, 4 or 5, got {degree}"),
            ));
        }
        if segments + degree < 2 * FIXED + 1 {
            return Err(Error::invalid(
                "trajectory",
                "segments",
                format!(
                    "expected at least {} segments for degree {degree} (three control points are fixed at each end), got {segments}",
                    2 * FIXED + 1 - degree
                ),
            ));
        }
        if !(duration.is_finite() && duration > 0.0) {
            return Err(Error::invalid(
                "trajectory",
                "duration",
                format!("expected a positive duration (s), got {duration}"),
            ));
        }
        if let Some(v) = q0.iter().find(|v| !v.is_finite()) {
            return Err(Error::invalid("trajectory", "q0", format!("expected finite values, got {v}")));
        }
        Ok(BSplineLayout {
            n: q0.len(),
            degree,
            segments,
            duration,
            q0,
            free_start: false,
            free_end: false,
            start_pose: None,
            end_pose: None,
            pieces: 1,
        })
    }

    /// The same layout with `waypoints` waypoints at rest (w − 1 pieces of
    /// segments/(w − 1) segments each; module documentation). Errors name
    /// `trajectory.waypoints` and `trajectory.segments`.
    pub fn with_waypoints(mut self, waypoints: usize) -> Result<Self> {
        if waypoints < 2 {
            return Err(Error::invalid(
                "trajectory",
                "waypoints",
                format!("expected at least 2 waypoints (the start and the end), got {waypoints}"),
            ));
        }
        let pieces = waypoints - 1;
        let (s, p) = (self.segments, self.degree);
        if s % pieces != 0 || (pieces > 1 && s / pieces + p < 2 * FIXED) {
            return Err(Error::invalid(
                "trajectory",
                "segments",
                format!(
                    "expected a multiple of the {pieces} pieces between {waypoints} waypoints, with at least {} segments per piece for degree {p} (three control points are fixed at each waypoint), got {s}",
                    (2 * FIXED).saturating_sub(p).max(1)
                ),
            ));
        }
        self.pieces = pieces;
        Ok(self)
    }

    /// The same layout starting (ending) at rest at a given pose instead of
    /// q0 (the start); `None` leaves that end as it is. Errors name
    /// `trajectory.start` / `trajectory.end`.
    pub fn with_given_ends(mut self, start: Option<Vec<f64>>, end: Option<Vec<f64>>) -> Result<Self> {
        for (field, pose) in [("start", &start), ("end", &end)] {
            if let Some(q) = pose {
                if q.len() != self.n {
                    return Err(Error::invalid(
                        "trajectory",
                        field,
                        format!("expected a pose of {} joint values, got {}", self.n, q.len()),
                    ));
                }
                if let Some(j) = q.iter().position(|v| !v.is_finite()) {
                    return Err(Error::invalid("trajectory", format!("{field}[{j}]"), "expected a finite number"));
                }
            }
        }
        if start.is_some() {
            self.free_start = false;
        }
        if end.is_some() {
            self.free_end = false;
        }
        self.start_pose = start;
        self.end_pose = end;
        Ok(self)
    }

    /// Whether the motion starts or ends elsewhere than q0 (the home pose):
    /// it is then played between a lead-in from and a lead-out to q0.
    pub fn leaves_home(&self) -> bool {
        self.free_start || self.free_end || self.start_pose.is_some() || self.end_pose.is_some()
    }

    /// Whether the motion ends where it starts (so it can be repeated back to back).
    pub fn ends_at_start(&self) -> bool {
        !self.free_end && self.end_pose.as_ref().is_none_or(|e| Some(e) == self.start_pose.as_ref())
    }

    /// The same layout with the start and/or end pose free (module documentation).
    pub fn with_free_ends(mut self, start: bool, end: bool) -> Self {
        self.free_start = start;
        self.free_end = end;
        self
    }

    /// Control points per piece (s/pieces + p; neighbouring pieces share one).
    fn piece_len(&self) -> usize {
        self.segments / self.pieces + self.degree
    }

    /// Free control points inside a piece (none fixed at its waypoints).
    fn inner(&self) -> usize {
        self.piece_len() - 2 * FIXED
    }

    /// Where control point i goes (module documentation).
    fn slot(&self, i: usize) -> Slot {
        let m = self.n_control();
        let lead = usize::from(self.free_start);
        let start = if self.free_start { Slot::Var(0) } else { Slot::Start };
        if i < FIXED {
            return start;
        }
        if i >= m - FIXED {
            return if self.free_end {
                Slot::Var(self.vars_per_joint() - 1)
            } else if self.end_pose.is_some() {
                Slot::End
            } else {
                start
            };
        }
        // piece k holds control points k(l − 1) … k(l − 1) + l − 1
        let (l, inner) = (self.piece_len(), self.inner());
        let (k, r) = (i / (l - 1), i % (l - 1));
        if r < FIXED {
            // about interior waypoint k (k ≥ 1: i ≥ FIXED)
            Slot::Var(lead + k * (inner + 1) - 1)
        } else if r >= l - FIXED {
            // about interior waypoint k + 1 (not the end: i < m − FIXED)
            Slot::Var(lead + (k + 1) * (inner + 1) - 1)
        } else {
            Slot::Var(lead + k * (inner + 1) + r - FIXED)
        }
    }

    /// The entry of a joint's block of x that moves control point i (None: a fixed end).
    fn var_of(&self, i: usize) -> Option<usize> {
        match self.slot(i) {
            Slot::Var(k) => Some(k),
            _ => None,
        }
    }

    /// Control point i of joint j for the joint's block `xj`.
    fn control_point(&self, j: usize, i: usize, xj: &[f64]) -> f64 {
        match self.slot(i) {
            Slot::Var(k) => self.q0[j] + xj[k],
            Slot::Start => self.start_pose.as_ref().map_or(self.q0[j], |q| q[j]),
            Slot::End => self.end_pose.as_ref().map_or(self.q0[j], |q| q[j]),
        }
    }

    /// Control points per joint (s + p, less one per interior waypoint:
    /// the pieces share them).
    pub fn n_control(&self) -> usize {
        self.pieces * (self.piece_len() - 1) + 1
    }

    /// Design variables per joint (s + p − 6 for one piece; per piece
    /// s/pieces + p − 6 and one per interior waypoint; plus one per free end).
    pub fn vars_per_joint(&self) -> usize {
        self.pieces * self.inner() + (self.pieces - 1) + usize::from(self.free_start) + usize::from(self.free_end)
    }

    /// The clamped knot vector: uniform over the s segments, each interior
    /// waypoint's time repeated p times.
    pub fn knots(&self) -> Vec<f64> {
        let (p, s, t, np) = (self.degree, self.segments, self.duration, self.pieces);
        let sp = s / np;
        let at = |i: usize| t * i as f64 / s as f64;
        let mut u = vec![0.0; p + 1];
        for k in 0..np {
            u.extend((1..sp).map(|i| at(k * sp + i)));
            if k + 1 < np {
                u.extend(std::iter::repeat_n(at((k + 1) * sp), p));
            }
        }
        u.extend(std::iter::repeat_n(t, p + 1));
        u
    }

    /// The design vector of a motion of this layout (the free control points minus q0).
    pub fn vars(&self, m: &BSplineMotion) -> Vec<f64> {
        let vpj = self.vars_per_joint();
        let mut x = vec![0.0; self.n * vpj];
        for j in 0..self.n {
            for i in 0..self.n_control() {
                if let Some(k) = self.var_of(i) {
                    x[j * vpj + k] = m.control[j][i] - self.q0[j];
                }
            }
        }
        x
    }
}

/// Buffers of [`BSplineLayout`]'s pull-back (none needed: the basis values
/// are on the stack).
#[derive(Debug, Clone, Default)]
pub struct BSplineScratch;

/// Basis values N_{span−p+r,p}^{(k)}(t), `ders[k][r]` for k ≤ 4, r ≤ p.
type Ders = [[f64; MAX_DEGREE + 1]; 5];

/// A fixed time grid with the knot span and the basis values (orders 0 … 2)
/// at each time: the knots are the layout's, so they serve every motion of
/// it, and a grid evaluation costs p + 1 multiply-adds per joint and order.
#[derive(Debug, Clone)]
pub struct BSplineGrid {
    times: Vec<f64>,
    span: Vec<usize>,
    ders: Vec<[[f64; MAX_DEGREE + 1]; 3]>,
}

impl TimeGrid for BSplineGrid {
    fn times(&self) -> &[f64] {
        &self.times
    }
}

impl BSplineGrid {
    /// q_j^(order) (order ≤ 2) of `m` at grid time i, as [`Motion::eval`] computes it.
    #[inline]
    fn value(&self, m: &BSplineMotion, j: usize, order: usize, i: usize) -> f64 {
        let (first, d) = (self.span[i] - m.degree, &self.ders[i][order]);
        let c = &m.control[j];
        let s: f64 = (0..=m.degree).map(|r| d[r] * (c[first + r] - c[0])).sum();
        if order == 0 {
            c[0] + s
        } else {
            s
        }
    }
}

impl BSplineMotion {
    /// Checks a motion read from a file: degree 3 … 5, a clamped
    /// nondecreasing knot vector from 0, s + p control points per joint,
    /// all finite, at rest at both ends (the first and last three control
    /// points of each joint equal); `ctx` names the source.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let p = self.degree;
        if !(3..=MAX_DEGREE).contains(&p) {
            return Err(Error::invalid(ctx, "degree", format!("expected a B-spline degree of 3, 4 or 5, got {p}")));
        }
        let u = &self.knots;
        let ok_knots = u.len() >= 2 * p + 2
            && u.iter().all(|v| v.is_finite())
            && u.windows(2).all(|w| w[0] <= w[1])
            && u[0] == 0.0
            && u[..=p].iter().all(|&v| v == u[0])
            && u[u.len() - p - 1..].iter().all(|&v| v == u[u.len() - 1])
            && u[u.len() - 1] > 0.0;
        if !ok_knots {
            return Err(Error::invalid(
                ctx,
                "knots",
                format!("expected a clamped nondecreasing knot vector from 0 with {} equal values at each end", p + 1),
            ));
        }
        let m = u.len() - p - 1;
        if self.control.is_empty() {
            return Err(Error::invalid(ctx, "control", "expected one row of control points per joint, got none"));
        }
        for (j, c) in self.control.iter().enumerate() {
            if c.len() != m {
                return Err(Error::invalid(
                    ctx,
                    format!("control[{j}]"),
                    format!("expected {m} control points (knots − degree − 1), got {}", c.len()),
                ));
            }
            if let Some(i) = c.iter().position(|v| !v.is_finite()) {
                return Err(Error::invalid(ctx, format!("control[{j}][{i}]"), "expected a finite number"));
            }
            let (a, b) = (c[0], c[m - 1]);
            if m < 2 * FIXED || c[..FIXED].iter().any(|&v| v != a) || c[m - FIXED..].iter().any(|&v| v != b) {
                return Err(Error::invalid(
                    ctx,
                    format!("control[{j}]"),
                    "expected the first three and the last three control points equal (at rest at both ends)",
                ));
            }
        }
        Ok(())
    }

    fn n_control(&self) -> usize {
        self.knots.len() - self.degree - 1
    }

    /// The knot span of t ∈ [0, T]: the i with u_i ≤ t < u_{i+1} (the last
    /// non-empty span at t = T).
    fn span(&self, t: f64) -> usize {
        let (p, m) = (self.degree, self.n_control());
        if t >= self.knots[m] {
            return m - 1;
        }
        if t <= self.knots[p] {
            return p;
        }
        // u_p ≤ t < u_m: the last knot ≤ t
        let k = self.knots.partition_point(|&u| u <= t) - 1;
        k.clamp(p, m - 1)
    }

    /// The span of t and the basis derivatives there up to order `nd` (≤ 4),
    /// zero above the degree; t is clamped to [0, T] and the derivatives
    /// vanish outside (the motion rests there).
    fn basis(&self, t: f64, nd: usize) -> (usize, Ders) {
        let (lo, hi) = (self.knots[0], self.knots[self.knots.len() - 1]);
        let tc = t.clamp(lo, hi);
        let span = self.span(tc);
        let mut ders = ders_basis(span, tc, self.degree, &self.knots, nd.min(self.degree));
        if t < lo || t > hi {
            for row in ders.iter_mut().skip(1) {
                *row = [0.0; MAX_DEGREE + 1];
            }
        }
        (span, ders)
    }
}

/// Piegl and Tiller's algorithm A2.3: the nonzero basis functions at t and
/// their derivatives up to order nd ≤ p.
fn ders_basis(span: usize, t: f64, p: usize, u: &[f64], nd: usize) -> Ders {
    const P1: usize = MAX_DEGREE + 1;
    let mut ndu = [[0.0; P1]; P1];
    let (mut left, mut right) = ([0.0; P1], [0.0; P1]);
    ndu[0][0] = 1.0;
    for j in 1..=p {
        left[j] = t - u[span + 1 - j];
        right[j] = u[span + j] - t;
        let mut saved = 0.0;
        for r in 0..j {
            ndu[j][r] = right[r + 1] + left[j - r];
            let temp = ndu[r][j - 1] / ndu[j][r];
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    let mut ders: Ders = [[0.0; P1]; 5];
    for j in 0..=p {
        ders[0][j] = ndu[j][p];
    }
    let p_i = p as isize;
    for r in 0..=p {
        let ri = r as isize;
        let mut a = [[0.0; P1]; 2];
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0][0] = 1.0;
        for k in 1..=nd {
            let ki = k as isize;
            let mut d = 0.0;
            let rk = ri - ki;
            let pk = (p_i - ki) as usize;
            if ri >= ki {
                a[s2][0] = a[s1][0] / ndu[pk + 1][rk as usize];
                d = a[s2][0] * ndu[rk as usize][pk];
            }
            let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
            let j2 = if ri - 1 <= pk as isize { k - 1 } else { p - r };
            for j in j1..=j2 {
                let c = (rk + j as isize) as usize;
                a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][c];
                d += a[s2][j] * ndu[c][pk];
            }
            if r <= pk {
                a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
                d += a[s2][k] * ndu[r][pk];
            }
            ders[k][r] = d;
            std::mem::swap(&mut s1, &mut s2);
        }
    }
    let mut f = p as f64;
    for (k, row) in ders.iter_mut().enumerate().take(nd + 1).skip(1) {
        for v in row.iter_mut().take(p + 1) {
            *v *= f;
        }
        f *= (p - k) as f64;
    }
    ders
}

impl Motion for BSplineMotion {
    fn n_joints(&self) -> usize {
        self.control.len()
    }

    fn duration(&self) -> f64 {
        self.knots[self.knots.len() - 1] - self.knots[0]
    }

    fn ends(&self) -> Ends {
        Ends::RestToRest
    }

    fn rest_pose(&self) -> Vec<f64> {
        self.control.iter().map(|c| c[0]).collect()
    }

    fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let (span, d) = self.basis(t, 2);
        let first = span - self.degree;
        for (j, c) in self.control.iter().enumerate() {
            // offsets from the start point: the derivatives of a motion at
            // rest are exactly 0 (Σ_r N_r^(k) = 0 for k ≥ 1 holds only to rounding)
            let c0 = c[0];
            let (mut p, mut v, mut a) = (c0, 0.0, 0.0);
            for r in 0..=self.degree {
                let pc = c[first + r] - c0;
                p += d[0][r] * pc;
                v += d[1][r] * pc;
                a += d[2][r] * pc;
            }
            q[j] = p;
            qd[j] = v;
            qdd[j] = a;
        }
    }

    fn derivatives(&self, j: usize, m: usize, t: f64) -> [f64; 3] {
        let mut out = [0.0; 3];
        if m > self.degree {
            return out;
        }
        let (span, d) = self.basis(t, (m + 2).min(4));
        let first = span - self.degree;
        let c = &self.control[j];
        for (o, order) in out.iter_mut().zip(m..m + 3) {
            if order > self.degree || order > 4 {
                continue;
            }
            let s: f64 = (0..=self.degree).map(|r| d[order][r] * (c[first + r] - c[0])).sum();
            *o = if order == 0 { c[0] + s } else { s };
        }
        out
    }
}

impl TrajectoryShape for BSplineLayout {
    type Motion = BSplineMotion;
    type Scratch = BSplineScratch;
    type Grid = BSplineGrid;

    fn n_vars(&self) -> usize {
        self.n * self.vars_per_joint()
    }

    fn n_joints(&self) -> usize {
        self.n
    }

    fn duration(&self) -> f64 {
        self.duration
    }

    fn ends(&self) -> Ends {
        Ends::RestToRest
    }

    /// Every free control point at q0.
    fn rest_vars(&self) -> Vec<f64> {
        vec![0.0; TrajectoryShape::n_vars(self)]
    }

    fn joint_vars(&self, j: usize) -> std::ops::Range<usize> {
        let vpj = self.vars_per_joint();
        j * vpj..(j + 1) * vpj
    }

    fn centre(&self, _: &[f64], j: usize) -> f64 {
        self.q0[j]
    }

    /// [`SCAN_PER_SEGMENT`] points per segment, the knots among them.
    fn scan_times(&self) -> Vec<f64> {
        let ns = SCAN_PER_SEGMENT * self.segments;
        (0..ns).map(|i| self.duration * i as f64 / ns as f64).collect()
    }

    fn grid(&self, times: Vec<f64>) -> BSplineGrid {
        let m = self.motion(&vec![0.0; TrajectoryShape::n_vars(self)]);
        let (mut span, mut ders) = (Vec::with_capacity(times.len()), Vec::with_capacity(times.len()));
        for &t in &times {
            let (s, d) = m.basis(t, 2);
            span.push(s);
            ders.push([d[0], d[1], d[2]]);
        }
        BSplineGrid { times, span, ders }
    }

    fn grid_state(&self, grid: &BSplineGrid, m: &BSplineMotion, i: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        for j in 0..self.n {
            q[j] = grid.value(m, j, 0, i);
            qd[j] = grid.value(m, j, 1, i);
            qdd[j] = grid.value(m, j, 2, i);
        }
    }

    fn grid_derivative(&self, grid: &BSplineGrid, m: &BSplineMotion, j: usize, order: usize, i: usize) -> f64 {
        if order <= 2 {
            grid.value(m, j, order, i)
        } else {
            m.derivatives(j, order, grid.times[i])[0]
        }
    }

    /// The basis values at t_i times each block of `g`, added to the free
    /// control points they touch (as [`TrajectoryShape::pull_back`], without buffers).
    fn grid_accumulate(&self, grid: &BSplineGrid, _: &BSplineMotion, i: usize, g: &[f64], _: &mut BSplineScratch, acc: &mut [f64]) {
        let (first, d) = (grid.span[i] - self.degree, &grid.ders[i]);
        let (n, vpj) = (self.n, self.vars_per_joint());
        for (g, acc) in g.chunks_exact(3 * n).zip(acc.chunks_exact_mut(n * vpj)) {
            for a in 0..n {
                for r in 0..=self.degree {
                    if let Some(k) = self.var_of(first + r) {
                        acc[a * vpj + k] += g[a] * d[0][r] + g[n + a] * d[1][r] + g[2 * n + a] * d[2][r];
                    }
                }
            }
        }
    }

    fn motion(&self, x: &[f64]) -> BSplineMotion {
        let (m, vpj) = (self.n_control(), self.vars_per_joint());
        let control = (0..self.n)
            .map(|j| (0..m).map(|i| self.control_point(j, i, &x[j * vpj..(j + 1) * vpj])).collect())
            .collect();
        BSplineMotion {
            degree: self.degree,
            knots: self.knots(),
            control,
        }
    }

    /// Control points within the position limits (offsets from q0; ±π
    /// without a limit): the motion then keeps them (convex hull).
    /// Velocity and acceleration are left to the constraints.
    fn bounds(&self, limits: &JointBox) -> (Vec<f64>, Vec<f64>) {
        let vpj = self.vars_per_joint();
        let (mut lower, mut upper) = (Vec::with_capacity(self.n * vpj), Vec::with_capacity(self.n * vpj));
        for j in 0..self.n {
            let [lo, hi] = limits.position[j];
            let (a, b) = if lo.is_finite() && hi.is_finite() {
                (lo - self.q0[j], hi - self.q0[j])
            } else {
                (-std::f64::consts::PI, std::f64::consts::PI)
            };
            lower.extend(std::iter::repeat_n(a.min(0.0), vpj));
            upper.extend(std::iter::repeat_n(b.max(0.0), vpj));
        }
        (lower, upper)
    }

    /// ∂q_j(t)/∂x_{j,i} = N_{3+i,p}(t) (likewise q̇, q̈ with the basis
    /// derivatives); zero for the other joints and outside the span of t.
    /// A free end's entry sums the basis functions of its three control points.
    fn pull_back(&self, m: &BSplineMotion, t: f64, g: &StateGradient, _: &mut BSplineScratch, gx: &mut [f64]) {
        gx.iter_mut().for_each(|v| *v = 0.0);
        let (span, d) = m.basis(t, 2);
        let first = span - self.degree;
        let vpj = self.vars_per_joint();
        for a in 0..self.n {
            for r in 0..=self.degree {
                if let Some(k) = self.var_of(first + r) {
                    gx[a * vpj + k] += g.factor * (g.q[a] * d[0][r] + g.qd[a] * d[1][r] + g.qdd[a] * d[2][r]);
                }
            }
        }
    }
}
