//! The Fourier series behind the trajectory-shape seam
//! ([`TrajectoryShape`] for [`FourierLayout`]), with its fast grid: fixed
//! times with precomputed sin(kωt_i), cos(kωt_i), so that evaluating a
//! Fourier trajectory on the grid costs multiply-adds only ([`TrigGrid`]).

use super::shape::{Ends, JointBox, StateGradient, TimeGrid, TrajectoryShape};
use super::{Basis, FourierLayout, FourierTrajectory};
use std::ops::Range;

/// Grid points per period of the highest harmonic used to bracket joint
/// extrema ([`TrajectoryShape::scan_times`]).
pub const SCAN_PER_HARMONIC: usize = 24;

/// A time grid with its trigonometric table.
#[derive(Debug, Clone)]
pub struct TrigGrid {
    /// Times (s).
    pub times: Vec<f64>,
    /// Base angular frequency ω.
    pub omega: f64,
    /// Number of harmonics.
    pub n_h: usize,
    sin: Vec<f64>,
    cos: Vec<f64>,
}

impl TrigGrid {
    /// Table for `times`, ω and n_h harmonics.
    pub fn new(times: Vec<f64>, omega: f64, n_h: usize) -> Self {
        let mut sin = Vec::with_capacity(times.len() * n_h);
        let mut cos = Vec::with_capacity(times.len() * n_h);
        for &t in &times {
            for k in 1..=n_h {
                let (s, c) = (k as f64 * omega * t).sin_cos();
                sin.push(s);
                cos.push(c);
            }
        }
        TrigGrid { times, omega, n_h, sin, cos }
    }

    /// Number of grid points.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True for an empty grid.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// q, q̇, q̈ at grid point i (as [`FourierTrajectory::eval`]).
    #[inline]
    pub fn state(&self, tr: &FourierTrajectory, i: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let nh = self.n_h;
        let (s, c) = (&self.sin[i * nh..(i + 1) * nh], &self.cos[i * nh..(i + 1) * nh]);
        for j in 0..tr.q0.len() {
            let (mut p, mut v, mut a) = (tr.q0[j], 0.0, 0.0);
            let (aj, bj) = (&tr.a[j], &tr.b[j]);
            for k in 0..nh {
                let kw = (k + 1) as f64 * self.omega;
                let (sk, ck) = (s[k], c[k]);
                p += (aj[k] * sk - bj[k] * ck) / kw;
                v += aj[k] * ck + bj[k] * sk;
                a += kw * (bj[k] * ck - aj[k] * sk);
            }
            q[j] = p;
            qd[j] = v;
            qdd[j] = a;
        }
    }

    /// The m-th time derivative of q_j at grid point i (m = 0 includes q0).
    #[inline]
    pub fn derivative(&self, tr: &FourierTrajectory, j: usize, m: usize, i: usize) -> f64 {
        let nh = self.n_h;
        let (s, c) = (&self.sin[i * nh..(i + 1) * nh], &self.cos[i * nh..(i + 1) * nh]);
        let mut v = if m == 0 { tr.q0[j] } else { 0.0 };
        let (aj, bj) = (&tr.a[j], &tr.b[j]);
        for k in 0..nh {
            let kw = (k + 1) as f64 * self.omega;
            // sin(θ + mπ/2), cos(θ + mπ/2)
            let (sm, cm) = match m % 4 {
                0 => (s[k], c[k]),
                1 => (c[k], -s[k]),
                2 => (-s[k], -c[k]),
                _ => (-c[k], s[k]),
            };
            v += kw.powi(m as i32 - 1) * (aj[k] * sm - bj[k] * cm);
        }
        v
    }

    /// [`TrigGrid::derivative`] at every grid point into `out` (the same
    /// bits: the same products summed in the same order, with the factors
    /// (kω)^(m−1) and the quarter-turn signs taken out of the loop).
    pub fn series(&self, tr: &FourierTrajectory, j: usize, m: usize, out: &mut Vec<f64>) {
        let nh = self.n_h;
        let start = if m == 0 { tr.q0[j] } else { 0.0 };
        let (aj, bj) = (&tr.a[j], &tr.b[j]);
        // per harmonic: v += f_k (a_k sm − b_k cm), (sm, cm) = (sin, cos)(θ + mπ/2)
        // = (ps·s or ps·c, pc·c or pc·s) by the quarter turn
        let swap = m % 2 == 1;
        let (ps, pc) = match m % 4 {
            0 => (1.0, 1.0),
            1 => (1.0, -1.0),
            2 => (-1.0, -1.0),
            _ => (-1.0, 1.0),
        };
        let f: Vec<f64> = (0..nh).map(|k| ((k + 1) as f64 * self.omega).powi(m as i32 - 1)).collect();
        out.clear();
        out.extend(self.sin.chunks_exact(nh).zip(self.cos.chunks_exact(nh)).map(|(s, c)| {
            let mut v = start;
            for k in 0..nh {
                let (sm, cm) = if swap { (ps * c[k], pc * s[k]) } else { (ps * s[k], pc * c[k]) };
                v += f[k] * (aj[k] * sm - bj[k] * cm);
            }
            v
        }));
    }

    /// The coefficient basis at grid point i (as [`FourierTrajectory::basis`]).
    pub fn basis(&self, i: usize, out: &mut Basis) {
        let nh = self.n_h;
        out.k.resize(nh, [0.0; 6]);
        for k in 0..nh {
            let kw = (k + 1) as f64 * self.omega;
            let (s, c) = (self.sin[i * nh + k], self.cos[i * nh + k]);
            out.k[k] = [s / kw, -c / kw, c, s, -kw * s, kw * c];
        }
    }
}

impl TimeGrid for TrigGrid {
    fn times(&self) -> &[f64] {
        &self.times
    }
}

/// Buffers of [`FourierLayout`]'s [`TrajectoryShape::pull_back`]: the basis at t and
/// the gradient with respect to the full coefficients (q0, a, b).
#[derive(Debug, Clone, Default)]
pub struct FourierScratch {
    basis: Basis,
    g_q0: Vec<f64>,
    g_a: Vec<Vec<f64>>,
    g_b: Vec<Vec<f64>>,
}

impl TrajectoryShape for FourierLayout {
    type Motion = FourierTrajectory;
    type Scratch = FourierScratch;
    type Grid = TrigGrid;

    fn n_vars(&self) -> usize {
        FourierLayout::n_vars(self)
    }

    fn n_joints(&self) -> usize {
        self.n
    }

    fn duration(&self) -> f64 {
        std::f64::consts::TAU / self.omega
    }

    fn ends(&self) -> Ends {
        Ends::Periodic
    }

    fn motion(&self, x: &[f64]) -> FourierTrajectory {
        self.trajectory(x)
    }

    /// Every harmonic zero, q0 at the layout's q0.
    fn rest_vars(&self) -> Vec<f64> {
        self.vars(&FourierTrajectory::at_rest(self.q0.clone(), self.n_h, self.omega))
    }

    /// The harmonics of joint j (q0 excluded).
    fn joint_vars(&self, j: usize) -> Range<usize> {
        let vpj = self.vars_per_joint();
        j * vpj + usize::from(self.vary_q0)..(j + 1) * vpj
    }

    /// q0_j (a design variable with `vary_q0`).
    fn centre(&self, x: &[f64], j: usize) -> f64 {
        if self.vary_q0 {
            x[j * self.vars_per_joint()]
        } else {
            self.q0[j]
        }
    }

    /// A free q0_j into its range, 10⁻³ of the range away from the ends.
    fn clamp_centre(&self, x: &mut [f64], position: &[[f64; 2]]) {
        if !self.vary_q0 {
            return;
        }
        let vpj = self.vars_per_joint();
        for (j, &[lo, hi]) in position.iter().enumerate().take(self.n) {
            let v = &mut x[j * vpj];
            if lo.is_finite() && hi.is_finite() {
                let pad = 1e-3 * (hi - lo);
                *v = v.clamp(lo + pad, hi - pad);
            }
        }
    }

    /// [`SCAN_PER_HARMONIC`] points per period of the highest harmonic (at least 32).
    fn scan_times(&self) -> Vec<f64> {
        let period = TrajectoryShape::duration(self);
        let ns = (SCAN_PER_HARMONIC * self.n_h).max(32);
        (0..ns).map(|i| period * i as f64 / ns as f64).collect()
    }

    fn grid(&self, times: Vec<f64>) -> TrigGrid {
        TrigGrid::new(times, self.omega, self.n_h)
    }

    fn grid_state(&self, grid: &TrigGrid, m: &FourierTrajectory, i: usize, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        grid.state(m, i, q, qd, qdd)
    }

    fn grid_derivative(&self, grid: &TrigGrid, m: &FourierTrajectory, j: usize, order: usize, i: usize) -> f64 {
        grid.derivative(m, j, order, i)
    }

    fn grid_series(&self, grid: &TrigGrid, m: &FourierTrajectory, j: usize, order: usize, out: &mut Vec<f64>) {
        grid.series(m, j, order, out)
    }

    /// Per joint the gradient with respect to (q0_j, a_1j..a_nj, b_1j..b_nj).
    fn acc_len(&self) -> usize {
        self.n * (1 + 2 * self.n_h)
    }

    /// Through the basis at t_i ([`TrigGrid::basis`]) into the gradient with
    /// respect to the full coefficients (q0, a, b).
    fn grid_accumulate(&self, grid: &TrigGrid, _: &FourierTrajectory, i: usize, g: &[f64], s: &mut FourierScratch, acc: &mut [f64]) {
        let (n, nh) = (self.n, self.n_h);
        let len = 1 + 2 * nh;
        grid.basis(i, &mut s.basis);
        for (g, acc) in g.chunks_exact(3 * n).zip(acc.chunks_exact_mut(n * len)) {
            for j in 0..n {
                let (gq, gqd, gqdd) = (g[j], g[n + j], g[2 * n + j]);
                acc[j * len] += gq;
                for k in 0..nh {
                    let b = &s.basis.k[k];
                    acc[j * len + 1 + k] += gq * b[0] + gqd * b[2] + gqdd * b[4];
                    acc[j * len + 1 + nh + k] += gq * b[1] + gqd * b[3] + gqdd * b[5];
                }
            }
        }
    }

    /// [`FourierLayout::pullback`] of the summed full-coefficient gradient.
    fn grid_finish(&self, acc: &[f64], gx: &mut [f64]) {
        let (n, nh) = (self.n, self.n_h);
        let len = 1 + 2 * nh;
        let g_q0: Vec<f64> = (0..n).map(|j| acc[j * len]).collect();
        let g_a: Vec<Vec<f64>> = (0..n).map(|j| acc[j * len + 1..j * len + 1 + nh].to_vec()).collect();
        let g_b: Vec<Vec<f64>> = (0..n).map(|j| acc[j * len + 1 + nh..(j + 1) * len].to_vec()).collect();
        self.pullback(&g_q0, &g_a, &g_b, gx);
    }

    /// Each harmonic alone within the joint's limits: |a_kj|, |b_kj| ≤
    /// min(kω·room, q̇_max, q̈_max/(kω)), room the distance from q0 to the
    /// nearer position limit (half the range when q0 is free, π without
    /// limits); a free q0 within the position limits (q0 ± π without).
    fn bounds(&self, limits: &JointBox) -> (Vec<f64>, Vec<f64>) {
        let (position, q0, omega) = (limits.position, &self.q0, self.omega);
        let mut lower = vec![0.0; FourierLayout::n_vars(self)];
        let mut upper = vec![0.0; FourierLayout::n_vars(self)];
        let vpj = self.vars_per_joint();
        for j in 0..self.n {
            let [lo, hi] = position[j];
            let room = if self.vary_q0 {
                if lo.is_finite() && hi.is_finite() {
                    0.5 * (hi - lo)
                } else {
                    std::f64::consts::PI
                }
            } else {
                let r = (hi - q0[j]).min(q0[j] - lo);
                if r.is_finite() {
                    r.max(1e-9)
                } else {
                    std::f64::consts::PI
                }
            };
            if self.vary_q0 {
                let (a, b) = if lo.is_finite() && hi.is_finite() {
                    (lo, hi)
                } else {
                    (q0[j] - std::f64::consts::PI, q0[j] + std::f64::consts::PI)
                };
                lower[j * vpj] = a;
                upper[j * vpj] = b;
            }
            for k0 in usize::from(self.at_rest)..self.n_h {
                let kw = (k0 + 1) as f64 * omega;
                let mut r = kw * room;
                if limits.velocity[j].is_finite() {
                    r = r.min(limits.velocity[j]);
                }
                if limits.acceleration[j].is_finite() {
                    r = r.min(limits.acceleration[j] / kw);
                }
                let (ia, ib) = self.index(j, k0);
                for i in [ia, ib] {
                    lower[i] = -r;
                    upper[i] = r;
                }
            }
        }
        (lower, upper)
    }

    /// Through the Fourier basis at t ([`FourierTrajectory::basis`]) to the
    /// full coefficients, then [`FourierLayout::pullback`].
    fn pull_back(&self, m: &FourierTrajectory, t: f64, g: &StateGradient, s: &mut FourierScratch, gx: &mut [f64]) {
        let (n, nh) = (self.n, self.n_h);
        m.basis(t, &mut s.basis);
        s.g_q0.resize(n, 0.0);
        s.g_a.resize_with(n, || vec![0.0; nh]);
        s.g_b.resize_with(n, || vec![0.0; nh]);
        let f = g.factor;
        for a in 0..n {
            s.g_q0[a] = f * g.q[a];
            for k in 0..nh {
                let b = &s.basis.k[k];
                s.g_a[a][k] = f * (g.q[a] * b[0] + g.qd[a] * b[2] + g.qdd[a] * b[4]);
                s.g_b[a][k] = f * (g.q[a] * b[1] + g.qd[a] * b[3] + g.qdd[a] * b[5]);
            }
        }
        self.pullback(&s.g_q0, &s.g_a, &s.g_b, gx);
    }
}
