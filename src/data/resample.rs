//! Irregularly sampled logs onto a uniform grid.
//!
//! Robot controllers often log at an irregular rate (a ~94 Hz recorder on a
//! 2 ms controller clock takes 10 or 12 ms per step). idexp's filters
//! (Fourier fit, zero-phase Butterworth, central differences) assume a
//! uniform grid, so an irregular repetition is **resampled**: every column
//! (positions, torques, logged velocities and accelerations, references) is
//! interpolated by a natural cubic spline through the logged samples (error
//! O(h⁴) inside the record for smooth signals, where linear interpolation
//! would bias q by h²q̈/8) and evaluated at t₀ + k/`rate`, k = 0, 1, … up to
//! the last logged time. The default rate is the inverse of the median logged
//! step. What was done is reported ([`Sampling`]).

use super::run::Repetition;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Relative spread of the time steps below which a log counts as uniform
/// (the run format's own tolerance: 0.1 % of the mean step).
pub const UNIFORM_TOLERANCE: f64 = 1e-3;

/// How a run's sample times were handled.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sampling {
    /// True when the logged steps vary by more than [`UNIFORM_TOLERANCE`] of their mean.
    pub irregular: bool,
    /// Smallest logged step (s), over the repetitions.
    pub min_step: f64,
    /// Median logged step (s) of the first repetition.
    pub median_step: f64,
    /// Largest logged step (s), over the repetitions.
    pub max_step: f64,
    /// The uniform rate the run was resampled to (Hz); None when it was uniform already.
    pub resampled_to: Option<f64>,
    /// Samples per repetition before and after resampling.
    pub samples: (usize, usize),
}

impl Sampling {
    /// One line for reports.
    pub fn text(&self) -> String {
        match self.resampled_to {
            Some(rate) => format!(
                "irregular time stamps (steps {:.4}–{:.4} s, median {:.4} s): resampled to a uniform {rate:.4} Hz grid by natural cubic splines ({} → {} samples)",
                self.min_step, self.max_step, self.median_step, self.samples.0, self.samples.1
            ),
            None => format!("uniform time steps of {:.6} s", self.median_step),
        }
    }
}

/// Step statistics (min, median, max) of strictly increasing times.
pub fn step_stats(t: &[f64]) -> (f64, f64, f64) {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return (0.0, 0.0, 0.0);
    }
    d.sort_by(f64::total_cmp);
    (d[0], d[d.len() / 2], d[d.len() - 1])
}

/// True when the steps of `t` vary by more than [`UNIFORM_TOLERANCE`] of the mean step.
pub fn is_irregular(t: &[f64]) -> bool {
    if t.len() < 3 {
        return false;
    }
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    t.windows(2).any(|w| ((w[1] - w[0]) - dt).abs() > UNIFORM_TOLERANCE * dt)
}

/// Checks that the times of `file` strictly increase and are finite; the
/// error names the row (1-based data row) and the two times.
pub fn check_increasing(file: &Path, t: &[f64]) -> Result<()> {
    for (k, w) in t.windows(2).enumerate() {
        if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) {
            return Err(Error::Data {
                path: file.to_path_buf(),
                row: k + 2,
                column: "t".into(),
                msg: format!("time must strictly increase: t = {} after t = {}", w[1], w[0]),
            });
        }
    }
    Ok(())
}

/// Second derivatives of the natural cubic spline through (t_i, y_i)
/// (tridiagonal system, Thomas algorithm; M_0 = M_{n−1} = 0).
fn spline_moments(t: &[f64], y: &[f64], work: &mut Vec<f64>, m: &mut Vec<f64>) {
    let n = t.len();
    m.clear();
    m.resize(n, 0.0);
    if n < 3 {
        return;
    }
    // c' of the forward sweep in `work`, d' in `m`
    work.clear();
    work.resize(n, 0.0);
    for i in 1..n - 1 {
        let h0 = t[i] - t[i - 1];
        let h1 = t[i + 1] - t[i];
        let a = h0 / 6.0;
        let b = (h0 + h1) / 3.0;
        let c = h1 / 6.0;
        let d = (y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0;
        let denom = b - a * work[i - 1];
        work[i] = c / denom;
        m[i] = (d - a * m[i - 1]) / denom;
    }
    for i in (1..n - 1).rev() {
        m[i] -= work[i] * m[i + 1];
    }
}

/// Values of the natural cubic spline through (t, y) at the increasing `grid`
/// (inside [t_0, t_{n−1}]).
fn spline_eval(t: &[f64], y: &[f64], m: &[f64], grid: &[f64], out: &mut [f64]) {
    let mut i = 0;
    for (g, o) in grid.iter().zip(out.iter_mut()) {
        while i + 2 < t.len() && t[i + 1] < *g {
            i += 1;
        }
        let h = t[i + 1] - t[i];
        let a = (t[i + 1] - g) / h;
        let b = (g - t[i]) / h;
        *o = a * y[i] + b * y[i + 1] + ((a * a * a - a) * m[i] + (b * b * b - b) * m[i + 1]) * h * h / 6.0;
    }
}

/// Resamples rows (per sample, `cols` values) logged at `t` onto `grid`.
fn resample_rows(t: &[f64], rows: &[Vec<f64>], grid: &[f64]) -> Vec<Vec<f64>> {
    let cols = rows.first().map_or(0, Vec::len);
    let mut out = vec![vec![0.0; cols]; grid.len()];
    let (mut y, mut work, mut m) = (Vec::with_capacity(t.len()), Vec::new(), Vec::new());
    let mut col = vec![0.0; grid.len()];
    for c in 0..cols {
        y.clear();
        y.extend(rows.iter().map(|r| r[c]));
        spline_moments(t, &y, &mut work, &mut m);
        spline_eval(t, &y, &m, grid, &mut col);
        for (o, v) in out.iter_mut().zip(&col) {
            o[c] = *v;
        }
    }
    out
}

/// Number of points of [`uniform_grid`] (as f64: checked against limits before allocating).
pub fn grid_len(t0: f64, t_end: f64, rate: f64) -> f64 {
    ((t_end - t0) * rate * (1.0 + 1e-12)).floor() + 1.0
}

/// The uniform grid t₀ + k/rate, k = 0..=⌊(t_end − t₀)·rate⌋.
pub fn uniform_grid(t0: f64, t_end: f64, rate: f64) -> Vec<f64> {
    let n = grid_len(t0, t_end, rate) as usize;
    (0..n).map(|k| t0 + k as f64 / rate).collect()
}

impl Repetition {
    /// This repetition on the uniform grid t₀ + k/`rate` (natural cubic
    /// splines through every column; see the module documentation), with at
    /// most `max_len` samples (repetitions of one run are cut to a common length).
    pub fn resampled(&self, rate: f64, max_len: Option<usize>) -> Repetition {
        let mut grid = uniform_grid(self.t[0], self.t[self.t.len() - 1], rate);
        if let Some(m) = max_len {
            grid.truncate(m);
        }
        let f = |rows: &Vec<Vec<f64>>| resample_rows(&self.t, rows, &grid);
        Repetition {
            q: f(&self.q),
            tau: f(&self.tau),
            r: self.r.as_ref().map(f),
            qd: self.qd.as_ref().map(f),
            qdd: self.qdd.as_ref().map(f),
            t: grid,
        }
    }
}

/// Resamples irregular repetitions (in place) to a common uniform grid at
/// `rate` Hz (default: the inverse median step of the first repetition);
/// uniform repetitions are left as they are unless a rate is given that
/// differs from theirs. Each repetition starts at its own first time stamp;
/// all are cut to the shortest. `limit` bounds the samples per repetition
/// after resampling (an error names the file, the rate and the limit).
pub fn resample_run(reps: &mut [Repetition], files: &[std::path::PathBuf], rate: Option<f64>, limit: usize) -> Result<Sampling> {
    let first = &reps[0].t;
    let (_, median, _) = step_stats(first);
    let mut min_step = f64::INFINITY;
    let mut max_step = 0.0_f64;
    let mut irregular = false;
    for r in reps.iter() {
        let (a, _, b) = step_stats(&r.t);
        min_step = min_step.min(a);
        max_step = max_step.max(b);
        irregular |= is_irregular(&r.t);
    }
    let before = first.len();
    let target = match rate {
        Some(hz) => {
            if !(hz.is_finite() && hz > 0.0) {
                return Err(Error::invalid(
                    files.first().map_or_else(|| "run".into(), |f| f.display().to_string()),
                    "resample",
                    format!("expected a positive rate in Hz, found {hz}"),
                ));
            }
            let own = 1.0 / median;
            (irregular || (hz - own).abs() > UNIFORM_TOLERANCE * own).then_some(hz)
        }
        None => irregular.then_some(1.0 / median),
    };
    let Some(hz) = target else {
        return Ok(Sampling {
            irregular,
            min_step,
            median_step: median,
            max_step,
            resampled_to: None,
            samples: (before, before),
        });
    };
    let common = reps.iter().map(|r| grid_len(r.t[0], r.t[r.len() - 1], hz)).fold(f64::INFINITY, f64::min);
    if common > limit as f64 {
        return Err(Error::invalid(
            files.first().map_or_else(|| "run".into(), |f| f.display().to_string()),
            "resample",
            format!("{hz} Hz over the record gives {common} samples per repetition, more than the limit of {limit}: choose a lower rate"),
        ));
    }
    let common = common as usize;
    if common < 3 {
        return Err(Error::invalid(
            files.first().map_or_else(|| "run".into(), |f| f.display().to_string()),
            "resample",
            format!("{hz} Hz over the record gives {common} samples, at least 3 are needed"),
        ));
    }
    for r in reps.iter_mut() {
        *r = r.resampled(hz, Some(common));
    }
    Ok(Sampling {
        irregular,
        min_step,
        median_step: median,
        max_step,
        resampled_to: Some(hz),
        samples: (before, common),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_spline_is_exact_on_cubics_inside_and_accurate_on_smooth_signals() {
        // irregular steps of 10 and 12 ms, as a 2 ms-clock recorder at ~94 Hz
        let mut t = vec![0.0];
        for k in 0..400 {
            let last = t[t.len() - 1];
            t.push(last + if k % 3 == 0 { 0.012 } else { 0.010 });
        }
        let f = |x: f64| (2.0 * x).sin() + 0.3 * (5.0 * x).cos();
        let rows: Vec<Vec<f64>> = t.iter().map(|&x| vec![f(x), x]).collect();
        let grid = uniform_grid(t[0], t[t.len() - 1], 100.0);
        let out = resample_rows(&t, &rows, &grid);
        // linear functions are reproduced exactly (natural end conditions hold for them)
        for (g, o) in grid.iter().zip(&out) {
            assert!((o[1] - g).abs() < 1e-12, "{} vs {g}", o[1]);
        }
        // away from the ends the error is O(h⁴) (h = 12 ms: far below 1e-7)
        let inner: f64 = grid
            .iter()
            .zip(&out)
            .filter(|(g, _)| **g > 0.3 && **g < t[t.len() - 1] - 0.3)
            .map(|(g, o)| (o[0] - f(*g)).abs())
            .fold(0.0, f64::max);
        // (linear interpolation would be off by up to h²/8·|f''| ≈ 1e-4 here)
        assert!(inner < 1e-7, "interior error {inner:e}");
    }

    #[test]
    fn uniform_runs_are_left_alone_and_irregular_ones_resampled_to_a_common_length() {
        let mk = |t: Vec<f64>| Repetition {
            q: t.iter().map(|x| vec![*x]).collect(),
            tau: t.iter().map(|x| vec![2.0 * x]).collect(),
            r: None,
            qd: None,
            qdd: None,
            t,
        };
        let mut reps = vec![mk((0..50).map(|k| k as f64 * 0.01).collect())];
        let s = resample_run(&mut reps, &[], None, 1000).unwrap();
        assert!(!s.irregular && s.resampled_to.is_none() && reps[0].len() == 50);
        let a: Vec<f64> = (0..60).map(|k| k as f64 * 0.01 + if k % 2 == 1 { 0.002 } else { 0.0 }).collect();
        let b: Vec<f64> = (0..55).map(|k| 5.0 + k as f64 * 0.0105).collect();
        let mut reps = vec![mk(a), mk(b)];
        let s = resample_run(&mut reps, &[], None, 1000).unwrap();
        assert!(s.irregular);
        assert_eq!(reps[0].len(), reps[1].len());
        assert!((reps[1].t[0] - 5.0).abs() < 1e-12);
        assert!(resample_run(&mut reps, &[], Some(1e6), 1000).is_err());
        // the limit is checked before the grid is allocated
        assert!(resample_run(&mut reps, &[], Some(1e18), 1000).is_err());
    }
}
