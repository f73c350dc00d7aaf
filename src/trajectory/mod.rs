//! Periodic joint trajectories as finite Fourier series (paper 000 eq. 6,
//! paper 002 eq. 17–19) and their sampled form.
//!
//! For joint j, with base angular frequency ω (rad/s) and n_h harmonics,
//!
//! q_j(t)   = q0_j + Σ_k [ a_kj/(kω) sin(kωt) − b_kj/(kω) cos(kωt) ]
//! q̇_j(t)  = Σ_k [ a_kj cos(kωt) + b_kj sin(kωt) ]
//! q̈_j(t)  = Σ_k kω [ −a_kj sin(kωt) + b_kj cos(kωt) ]
//!
//! The trajectory is linear in (q0, a, b); [`FourierTrajectory::basis`] gives
//! the coefficients of that linear map at a time t, which is what gradients
//! with respect to the coefficients need. [`FourierLayout`] maps a flat design
//! vector to a trajectory (optionally with q0 free, optionally starting and
//! ending at rest, built into the parameterisation) and pulls gradients back.
//! A sampled trajectory is an [`crate::io::States`] (`t, q, qd, qdd` CSV).

pub mod bspline;
pub mod differentiate;
pub mod export;
mod fourier_shape;
pub mod lead;
pub mod multisine;
mod process;
pub mod reference;
pub mod shape;
pub mod shapes;

pub use differentiate::differentiate;
pub use fourier_shape::{FourierScratch, TrigGrid, SCAN_PER_HARMONIC};
pub use reference::{Reference, ReferenceSpec};
pub use shape::{Ends, JointBox, Motion, PlainGrid, StateGradient, TimeGrid, TrajectoryShape};
pub use shapes::{Shape, ShapeMotion};

use crate::error::{Error, Result};
use crate::io::States;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A periodic joint trajectory: q0 (n), a and b (n × n_h, `a[j][k-1]`), ω.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FourierTrajectory {
    /// Base angular frequency ω (rad/s); the period is 2π/ω.
    pub omega: f64,
    /// Offsets q0_j (rad or m).
    pub q0: Vec<f64>,
    /// Sine coefficients a_kj, `a[j][k-1]` (rad/s).
    pub a: Vec<Vec<f64>>,
    /// Cosine coefficients b_kj, `b[j][k-1]` (rad/s).
    pub b: Vec<Vec<f64>>,
}

/// Values of the basis functions at one time, per harmonic k = 1..n_h:
/// ∂q/∂a_k, ∂q/∂b_k, ∂q̇/∂a_k, ∂q̇/∂b_k, ∂q̈/∂a_k, ∂q̈/∂b_k (the same for
/// every joint; ∂q/∂q0 = 1).
#[derive(Debug, Clone, Default)]
pub struct Basis {
    /// `[dq_da, dq_db, dqd_da, dqd_db, dqdd_da, dqdd_db]` for each harmonic.
    pub k: Vec<[f64; 6]>,
}

impl FourierTrajectory {
    /// Builds and validates a trajectory: ω > 0 and finite, every joint with
    /// the same number (≥ 1) of harmonics, all values finite.
    pub fn new(omega: f64, q0: Vec<f64>, a: Vec<Vec<f64>>, b: Vec<Vec<f64>>) -> Result<Self> {
        let t = FourierTrajectory { omega, q0, a, b };
        t.validate("trajectory")?;
        Ok(t)
    }

    /// A trajectory at rest at `q0` with `n_h` zero harmonics.
    pub fn at_rest(q0: Vec<f64>, n_h: usize, omega: f64) -> Self {
        let n = q0.len();
        FourierTrajectory {
            omega,
            q0,
            a: vec![vec![0.0; n_h]; n],
            b: vec![vec![0.0; n_h]; n],
        }
    }

    /// Checks dimensions and finiteness; `ctx` names the source in messages.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        if !(self.omega.is_finite() && self.omega > 0.0) {
            return Err(Error::invalid(
                ctx,
                "omega",
                format!("expected a positive angular frequency in rad/s, got {}", self.omega),
            ));
        }
        let n = self.q0.len();
        if n == 0 {
            return Err(Error::invalid(ctx, "q0", "expected one offset per joint, got none"));
        }
        for (name, m) in [("a", &self.a), ("b", &self.b)] {
            if m.len() != n {
                return Err(Error::invalid(ctx, name, format!("expected {n} rows (one per joint, as q0), got {}", m.len())));
            }
        }
        let nh = self.a[0].len();
        if nh == 0 {
            return Err(Error::invalid(ctx, "a", "expected at least one harmonic per joint"));
        }
        for (name, m) in [("a", &self.a), ("b", &self.b)] {
            for (j, row) in m.iter().enumerate() {
                if row.len() != nh {
                    return Err(Error::invalid(
                        ctx,
                        format!("{name}[{j}]"),
                        format!("expected {nh} harmonics (as a[0]), got {}", row.len()),
                    ));
                }
                if let Some(k) = row.iter().position(|v| !v.is_finite()) {
                    return Err(Error::invalid(ctx, format!("{name}[{j}][{k}]"), "expected a finite number"));
                }
            }
        }
        if let Some(j) = self.q0.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(ctx, format!("q0[{j}]"), "expected a finite number"));
        }
        Ok(())
    }

    /// Number of joints n.
    pub fn n_joints(&self) -> usize {
        self.q0.len()
    }

    /// Number of harmonics n_h.
    pub fn n_harmonics(&self) -> usize {
        self.a.first().map_or(0, |r| r.len())
    }

    /// Period 2π/ω (s).
    pub fn period(&self) -> f64 {
        std::f64::consts::TAU / self.omega
    }

    /// The period for a report: [`seconds_text`] of [`FourierTrajectory::period`]
    /// (2π/ω of a 0.01 Hz trajectory is 99.99999999999999 s; this says 100).
    pub fn period_text(&self) -> String {
        seconds_text(self.period())
    }

    /// Fills `out` with the basis values at time t (allocates only if `out`
    /// has the wrong length).
    pub fn basis(&self, t: f64, out: &mut Basis) {
        basis_values(self.omega, self.n_harmonics(), t, out);
    }

    /// Evaluates q, q̇, q̈ at time t (each slice of length n).
    pub fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let w = self.omega;
        for j in 0..self.n_joints() {
            let (mut p, mut v, mut acc) = (self.q0[j], 0.0, 0.0);
            for (k0, (&a, &b)) in self.a[j].iter().zip(&self.b[j]).enumerate() {
                let kw = (k0 + 1) as f64 * w;
                let (s, c) = (kw * t).sin_cos();
                p += (a * s - b * c) / kw;
                v += a * c + b * s;
                acc += kw * (b * c - a * s);
            }
            q[j] = p;
            qd[j] = v;
            qdd[j] = acc;
        }
    }

    /// Samples one period at `rate` Hz: t = i/rate for i = 0..N with
    /// N = round(period·rate) (the last sample is one step before the period).
    pub fn sample(&self, rate: f64) -> Result<States> {
        let times = period_grid(self.period(), rate)?;
        Ok(self.sample_at(&times))
    }

    /// Evaluates the trajectory at the given times ([`Motion::sample_at`]).
    pub fn sample_at(&self, times: &[f64]) -> States {
        <Self as Motion>::sample_at(self, times)
    }

    /// Analytic bounds valid for all t, per joint: (max |q − q0|, max |q̇|, max |q̈|)
    /// ≤ (Σ r_k/(kω), Σ r_k, Σ kω r_k) with r_k = √(a_k² + b_k²).
    pub fn amplitude_bounds(&self) -> Vec<[f64; 3]> {
        (0..self.n_joints())
            .map(|j| {
                let mut b3 = [0.0; 3];
                for (k0, (&a, &b)) in self.a[j].iter().zip(&self.b[j]).enumerate() {
                    let kw = (k0 + 1) as f64 * self.omega;
                    let r = a.hypot(b);
                    b3[0] += r / kw;
                    b3[1] += r;
                    b3[2] += kw * r;
                }
                b3
            })
            .collect()
    }

    /// Least-squares fit of a Fourier series with `n_h` harmonics of ω to
    /// samples `q[i][j]` at times `t[i]` (the Fourier filtering of paper 000
    /// §III-C). Needs at least 2·n_h + 1 samples spanning the period.
    pub fn fit(t: &[f64], q: &[Vec<f64>], omega: f64, n_h: usize) -> Result<FourierTrajectory> {
        let m = t.len();
        if q.len() != m {
            return Err(Error::dim("Fourier fit: positions vs times", m, q.len()));
        }
        let cols = 2 * n_h + 1;
        if n_h == 0 || m < cols {
            return Err(Error::Numerical(format!(
                "Fourier fit with {n_h} harmonics needs at least {cols} samples, got {m}"
            )));
        }
        if !(omega.is_finite() && omega > 0.0) {
            return Err(Error::invalid(
                "Fourier fit",
                "omega",
                format!("expected a positive angular frequency, got {omega}"),
            ));
        }
        let n = q[0].len();
        let mut basis = Basis::default();
        let mut x = nalgebra::DMatrix::zeros(m, cols);
        let mut y = nalgebra::DMatrix::zeros(m, n);
        for i in 0..m {
            if q[i].len() != n {
                return Err(Error::dim(format!("Fourier fit: joints in sample {i}"), n, q[i].len()));
            }
            basis_values(omega, n_h, t[i], &mut basis);
            x[(i, 0)] = 1.0;
            for k in 0..n_h {
                x[(i, 1 + k)] = basis.k[k][0];
                x[(i, 1 + n_h + k)] = basis.k[k][1];
            }
            for j in 0..n {
                y[(i, j)] = q[i][j];
            }
        }
        let svd = x.svd(true, true);
        let smax = svd.singular_values.max();
        let smin = svd.singular_values.min();
        if smin.is_nan() || smin <= 1e-10 * smax {
            return Err(Error::Numerical(
                "Fourier fit: the sample times do not determine the harmonics (too short or aliased)".into(),
            ));
        }
        let c = svd.solve(&y, 0.0).map_err(|e| Error::Numerical(format!("Fourier fit: {e}")))?;
        let q0 = (0..n).map(|j| c[(0, j)]).collect();
        let a = (0..n).map(|j| (0..n_h).map(|k| c[(1 + k, j)]).collect()).collect();
        let b = (0..n).map(|j| (0..n_h).map(|k| c[(1 + n_h + k, j)]).collect()).collect();
        FourierTrajectory::new(omega, q0, a, b)
    }

    /// Reads a trajectory from JSON: either the bare trajectory or an object
    /// with a `trajectory` field (as `idexp excite` writes in coefficients.json).
    pub fn load(path: &Path) -> Result<FourierTrajectory> {
        let text = crate::io::read_to_string(path)?;
        let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| Error::parse(path, format!("line {}, column {}: {e}", e.line(), e.column())))?;
        let inner = v.get("trajectory").cloned().unwrap_or(v);
        let t: FourierTrajectory = serde_json::from_value(inner).map_err(|e| Error::parse(path, format!("trajectory: {e}")))?;
        t.validate(&path.display().to_string())?;
        Ok(t)
    }
}

/// Times t = i/rate, i = 0..round(period·rate), for one period.
pub fn period_grid(period: f64, rate: f64) -> Result<Vec<f64>> {
    if !(rate.is_finite() && rate > 0.0) {
        return Err(Error::invalid("sampling", "rate", format!("expected a positive rate in Hz, got {rate}")));
    }
    let n = (period * rate).round();
    if !(1.0..=1e8).contains(&n) {
        return Err(Error::invalid(
            "sampling",
            "rate",
            format!("a period of {period} s at {rate} Hz gives {n} samples"),
        ));
    }
    Ok((0..n as usize).map(|i| i as f64 / rate).collect())
}

fn basis_values(omega: f64, n_h: usize, t: f64, out: &mut Basis) {
    out.k.resize(n_h, [0.0; 6]);
    for k0 in 0..n_h {
        let kw = (k0 + 1) as f64 * omega;
        let (s, c) = (kw * t).sin_cos();
        out.k[k0] = [s / kw, -c / kw, c, s, -kw * s, kw * c];
    }
}

/// How a flat design vector x maps to a [`FourierTrajectory`].
///
/// Per joint j, in order: q0_j (if `vary_q0`), then a_kj and b_kj for the free
/// harmonics. With `at_rest`, q̇(0) = q̈(0) = 0 (hence also at the end of each
/// period) is built in by eliminating the first harmonic:
/// a_1j = −Σ_{k≥2} a_kj and b_1j = −Σ_{k≥2} k·b_kj, so the free harmonics are
/// k = 2..n_h (n_h ≥ 2 is then required).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FourierLayout {
    /// Number of joints.
    pub n: usize,
    /// Number of harmonics n_h.
    pub n_h: usize,
    /// Base angular frequency ω (rad/s).
    pub omega: f64,
    /// q0 is a design variable (else fixed at `q0`).
    pub vary_q0: bool,
    /// Start and end at rest.
    pub at_rest: bool,
    /// Fixed (or initial) offsets.
    pub q0: Vec<f64>,
}

impl FourierLayout {
    /// Builds a layout; `at_rest` needs at least two harmonics.
    pub fn new(q0: Vec<f64>, n_h: usize, omega: f64, vary_q0: bool, at_rest: bool) -> Result<Self> {
        if n_h == 0 || (at_rest && n_h < 2) {
            let need = if at_rest { 2 } else { 1 };
            return Err(Error::invalid(
                "trajectory",
                "harmonics",
                format!("expected at least {need} harmonics, got {n_h}"),
            ));
        }
        if !(omega.is_finite() && omega > 0.0) {
            return Err(Error::invalid(
                "trajectory",
                "omega",
                format!("expected a positive angular frequency, got {omega}"),
            ));
        }
        Ok(FourierLayout {
            n: q0.len(),
            n_h,
            omega,
            vary_q0,
            at_rest,
            q0,
        })
    }

    fn first_free(&self) -> usize {
        usize::from(self.at_rest)
    }

    /// Design variables per joint.
    pub fn vars_per_joint(&self) -> usize {
        usize::from(self.vary_q0) + 2 * (self.n_h - self.first_free())
    }

    /// Length of the design vector.
    pub fn n_vars(&self) -> usize {
        self.n * self.vars_per_joint()
    }

    /// Index in x of a_kj (k0 = k−1 is zero-based, k0 ≥ first free) and the
    /// offset of b: returns (index of a, index of b).
    pub fn index(&self, j: usize, k0: usize) -> (usize, usize) {
        let nf = self.n_h - self.first_free();
        let base = j * self.vars_per_joint() + usize::from(self.vary_q0);
        let i = k0 - self.first_free();
        (base + i, base + nf + i)
    }

    /// The trajectory for design vector x.
    pub fn trajectory(&self, x: &[f64]) -> FourierTrajectory {
        let mut t = FourierTrajectory::at_rest(self.q0.clone(), self.n_h, self.omega);
        let f = self.first_free();
        for j in 0..self.n {
            if self.vary_q0 {
                t.q0[j] = x[j * self.vars_per_joint()];
            }
            for k0 in f..self.n_h {
                let (ia, ib) = self.index(j, k0);
                t.a[j][k0] = x[ia];
                t.b[j][k0] = x[ib];
            }
            if self.at_rest {
                t.a[j][0] = -(1..self.n_h).map(|k0| t.a[j][k0]).sum::<f64>();
                t.b[j][0] = -(1..self.n_h).map(|k0| (k0 + 1) as f64 * t.b[j][k0]).sum::<f64>();
            }
        }
        t
    }

    /// The design vector of a trajectory (the inverse of [`Self::trajectory`]
    /// on trajectories that satisfy the layout; the eliminated harmonic is dropped).
    pub fn vars(&self, t: &FourierTrajectory) -> Vec<f64> {
        let mut x = vec![0.0; self.n_vars()];
        for j in 0..self.n {
            if self.vary_q0 {
                x[j * self.vars_per_joint()] = t.q0[j];
            }
            for k0 in self.first_free()..self.n_h {
                let (ia, ib) = self.index(j, k0);
                x[ia] = t.a[j][k0];
                x[ib] = t.b[j][k0];
            }
        }
        x
    }

    /// Pulls a gradient with respect to the full coefficients (`g_q0[j]`,
    /// `g_a[j][k0]`, `g_b[j][k0]`) back to the design vector (chain rule through
    /// the linear map, including the at-rest elimination).
    pub fn pullback(&self, g_q0: &[f64], g_a: &[Vec<f64>], g_b: &[Vec<f64>], gx: &mut [f64]) {
        for j in 0..self.n {
            if self.vary_q0 {
                gx[j * self.vars_per_joint()] = g_q0[j];
            }
            for k0 in self.first_free()..self.n_h {
                let (ia, ib) = self.index(j, k0);
                let (mut ga, mut gb) = (g_a[j][k0], g_b[j][k0]);
                if self.at_rest {
                    ga -= g_a[j][0];
                    gb -= (k0 + 1) as f64 * g_b[j][0];
                }
                gx[ia] = ga;
                gx[ib] = gb;
            }
        }
    }
}

impl FourierTrajectory {
    /// Time derivatives of orders m, m+1, m+2 of q_j at t (order 0 includes q0),
    /// with one sin_cos and the angle-addition recurrence for the harmonics.
    pub fn derivatives(&self, j: usize, m: usize, t: f64) -> [f64; 3] {
        let w = self.omega;
        let (s1, c1) = (w * t).sin_cos();
        let (mut s, mut c) = (s1, c1);
        let mut out = [0.0; 3];
        if m == 0 {
            out[0] = self.q0[j];
        }
        for (k0, (&a, &b)) in self.a[j].iter().zip(&self.b[j]).enumerate() {
            let kw = (k0 + 1) as f64 * w;
            for (d, o) in out.iter_mut().enumerate() {
                let order = m + d;
                let (sm, cm) = match order % 4 {
                    0 => (s, c),
                    1 => (c, -s),
                    2 => (-s, -c),
                    _ => (-c, s),
                };
                *o += kw.powi(order as i32 - 1) * (a * sm - b * cm);
            }
            let sn = s * c1 + c * s1;
            c = c * c1 - s * s1;
            s = sn;
        }
        out
    }
}

impl Motion for FourierTrajectory {
    fn n_joints(&self) -> usize {
        self.q0.len()
    }

    fn duration(&self) -> f64 {
        self.period()
    }

    fn ends(&self) -> Ends {
        Ends::Periodic
    }

    fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        FourierTrajectory::eval(self, t, q, qd, qdd)
    }

    fn derivatives(&self, j: usize, m: usize, t: f64) -> [f64; 3] {
        FourierTrajectory::derivatives(self, j, m, t)
    }

    fn rest_pose(&self) -> Vec<f64> {
        self.q0.clone()
    }
}

/// A duration for a report: at most six decimals, trailing zeros dropped
/// (`100`, `33.333333`, `0.5`), so that the last bits of a computed period
/// do not show.
///
/// ```
/// use idexp::trajectory::seconds_text;
/// assert_eq!(seconds_text(99.99999999999999), "100"); // 2π/ω at 0.01 Hz
/// assert_eq!(seconds_text(1.0 / 0.03), "33.333333");
/// assert_eq!(seconds_text(1.1600000000000001), "1.16");
/// assert_eq!(seconds_text(0.5), "0.5");
/// assert_eq!(seconds_text(-1e-9), "0");
/// ```
pub fn seconds_text(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let t = format!("{v:.6}");
    let t = t.trim_end_matches('0').trim_end_matches('.');
    if t == "-0" {
        "0".to_string()
    } else {
        t.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> FourierTrajectory {
        FourierTrajectory::new(
            0.7,
            vec![0.1, -0.2],
            vec![vec![0.3, -0.1, 0.05], vec![0.0, 0.2, -0.3]],
            vec![vec![-0.2, 0.4, 0.1], vec![0.1, 0.0, 0.25]],
        )
        .unwrap()
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let tr = example();
        let (mut q, mut qd, mut qdd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        let (mut qp, mut qdp, mut qddp) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        let (mut qm, mut qdm, mut qddm) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        let h = 1e-5;
        for &t in &[0.0, 0.37, 2.1, 7.9] {
            tr.eval(t, &mut q, &mut qd, &mut qdd);
            tr.eval(t + h, &mut qp, &mut qdp, &mut qddp);
            tr.eval(t - h, &mut qm, &mut qdm, &mut qddm);
            for j in 0..2 {
                assert!(((qp[j] - qm[j]) / (2.0 * h) - qd[j]).abs() < 1e-8);
                assert!(((qdp[j] - qdm[j]) / (2.0 * h) - qdd[j]).abs() < 1e-8);
            }
        }
        // periodic
        tr.eval(tr.period(), &mut qp, &mut qdp, &mut qddp);
        tr.eval(0.0, &mut q, &mut qd, &mut qdd);
        for j in 0..2 {
            assert!((qp[j] - q[j]).abs() < 1e-12 && (qddp[j] - qdd[j]).abs() < 1e-12);
        }
    }

    #[test]
    fn basis_reproduces_eval() {
        let tr = example();
        let mut b = Basis::default();
        let (mut q, mut qd, mut qdd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        let t = 1.234;
        tr.eval(t, &mut q, &mut qd, &mut qdd);
        tr.basis(t, &mut b);
        for j in 0..2 {
            let mut v = [tr.q0[j], 0.0, 0.0];
            for k in 0..3 {
                for d in 0..3 {
                    v[d] += b.k[k][2 * d] * tr.a[j][k] + b.k[k][2 * d + 1] * tr.b[j][k];
                }
            }
            assert!((v[0] - q[j]).abs() < 1e-13 && (v[1] - qd[j]).abs() < 1e-13 && (v[2] - qdd[j]).abs() < 1e-13);
        }
    }

    #[test]
    fn amplitude_bounds_hold_on_a_fine_grid() {
        let tr = example();
        let bounds = tr.amplitude_bounds();
        let s = tr.sample(1000.0).unwrap();
        for i in 0..s.len() {
            for j in 0..2 {
                assert!((s.q[i][j] - tr.q0[j]).abs() <= bounds[j][0] + 1e-12);
                assert!(s.qd[i][j].abs() <= bounds[j][1] + 1e-12);
                assert!(s.qdd[i][j].abs() <= bounds[j][2] + 1e-12);
            }
        }
    }

    #[test]
    fn at_rest_layout_starts_at_rest_and_pullback_is_the_chain_rule() {
        let lay = FourierLayout::new(vec![0.3, -0.1], 4, 0.9, true, true).unwrap();
        assert_eq!(lay.n_vars(), 2 * (1 + 2 * 3));
        let x: Vec<f64> = (0..lay.n_vars()).map(|i| ((i * 7 + 3) % 11) as f64 / 10.0 - 0.5).collect();
        let tr = lay.trajectory(&x);
        let (mut q, mut qd, mut qdd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        tr.eval(0.0, &mut q, &mut qd, &mut qdd);
        assert!(qd.iter().chain(&qdd).all(|v| v.abs() < 1e-12));
        assert_eq!(lay.vars(&tr), x);
        // f(x) = Σ_j q_j(t) q̈_j(t) at a fixed t: gradient by the chain rule vs FD
        let t = 0.77;
        let f = |x: &[f64]| {
            let tr = lay.trajectory(x);
            let (mut q, mut qd, mut qdd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
            tr.eval(t, &mut q, &mut qd, &mut qdd);
            q[0] * qdd[0] + q[1] * qdd[1] + qd[1]
        };
        let mut b = Basis::default();
        tr.basis(t, &mut b);
        tr.eval(t, &mut q, &mut qd, &mut qdd);
        let mut ga = vec![vec![0.0; 4]; 2];
        let mut gb = vec![vec![0.0; 4]; 2];
        let mut g0 = vec![0.0; 2];
        for j in 0..2 {
            g0[j] = qdd[j];
            for k in 0..4 {
                let dqd = if j == 1 { 1.0 } else { 0.0 };
                ga[j][k] = b.k[k][0] * qdd[j] + q[j] * b.k[k][4] + dqd * b.k[k][2];
                gb[j][k] = b.k[k][1] * qdd[j] + q[j] * b.k[k][5] + dqd * b.k[k][3];
            }
        }
        let mut gx = vec![0.0; lay.n_vars()];
        lay.pullback(&g0, &ga, &gb, &mut gx);
        for i in 0..x.len() {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[i] += 1e-6;
            xm[i] -= 1e-6;
            let fd = (f(&xp) - f(&xm)) / 2e-6;
            assert!((fd - gx[i]).abs() < 1e-7, "var {i}: fd {fd} vs {}", gx[i]);
        }
    }

    #[test]
    fn fit_recovers_the_series_and_rejects_short_data() {
        let tr = example();
        let s = tr.sample(20.0).unwrap();
        let t = s.t.clone().unwrap();
        let fit = FourierTrajectory::fit(&t, &s.q, tr.omega, 3).unwrap();
        for j in 0..2 {
            assert!((fit.q0[j] - tr.q0[j]).abs() < 1e-10);
            for k in 0..3 {
                assert!((fit.a[j][k] - tr.a[j][k]).abs() < 1e-9 && (fit.b[j][k] - tr.b[j][k]).abs() < 1e-9);
            }
        }
        assert!(FourierTrajectory::fit(&t[..5], &s.q[..5], tr.omega, 3).is_err());
    }

    #[test]
    fn validation_names_the_field() {
        let e = FourierTrajectory::new(1.0, vec![0.0, 0.0], vec![vec![0.0], vec![f64::NAN]], vec![vec![0.0], vec![0.0]]).unwrap_err();
        assert!(e.to_string().contains("a[1][0]"), "{e}");
        let e = FourierTrajectory::new(-1.0, vec![0.0], vec![vec![0.0]], vec![vec![0.0]]).unwrap_err();
        assert!(e.to_string().contains("omega"), "{e}");
    }
}
