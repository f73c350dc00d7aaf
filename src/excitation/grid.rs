//! Fixed time grids with precomputed sin(kωt_i), cos(kωt_i), so that
//! evaluating a Fourier trajectory on the grid costs multiply-adds only.

use crate::trajectory::{Basis, FourierTrajectory};

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
