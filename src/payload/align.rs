//! A loaded run and its unloaded twin recorded separately: the time shift
//! between them, their common grid and what remains of the difference.
//!
//! Twins recorded by hand start a fraction of a second apart and end a few
//! samples apart. With the processed (filtered) positions q_L(t) of the
//! loaded run and q_U(t) of the unloaded one, both on grids of step Δt
//! starting at 0, the shift δ (unloaded time = loaded time + δ) minimises
//!
//! e(δ) = Σ_s Σ_j ((q_U,j(t_s + δ) − q_L,j(t_s)) / r_j)²
//!
//! over the loaded samples s whose shifted time falls in the unloaded run
//! (r_j: the RMS of joint j's motion about its mean in the loaded run, at
//! least [`MIN_MOTION`]): first over whole samples (|δ| up to
//! (1 − [`MIN_OVERLAP`]) of the shorter run; of the local minima within a
//! factor [`TIE`] of the best, the smallest shift — a trajectory played
//! twice fits as well one period later), then to a fraction of a sample
//! by Gauss–Newton on the interpolated positions (cubic Hermite from q_U and
//! q̇_U, whose derivative is q̇_U). The unloaded run is then read at t_s + δ
//! on the loaded samples of the overlap: q and q̇ by cubic Hermite (from q̇,
//! q̈), q̈, the torques and their variances linearly. A shift under
//! [`NO_SHIFT`] samples between runs of the same length is no shift (the
//! samples are paired as recorded).
//!
//! Refused, with the numbers: different sample steps (another rate or
//! decimation), an overlap under [`MIN_OVERLAP`] of the shorter run, and
//! twins whose aligned positions still differ by more than [`MAX_DIFFERENCE`]
//! of a joint's motion (RMS): not the same trajectory.

use crate::data::process::Processed;
use crate::error::{Error, Result};
use serde::Serialize;

/// Smallest overlap, as a fraction of the shorter run.
pub const MIN_OVERLAP: f64 = 0.5;
/// Largest RMS position difference after alignment, as a fraction of the joint's motion (RMS about its mean).
pub const MAX_DIFFERENCE: f64 = 0.1;
/// Smallest motion scale r_j (rad or m) in the criterion and the refusal rule.
pub const MIN_MOTION: f64 = 1e-3;
/// Whole-sample shifts whose criterion is within this factor of the best one
/// count as equally good (the smallest of them is taken).
pub const TIE: f64 = 2.0;
/// Shifts below this many samples between runs of equal length are none.
pub const NO_SHIFT: f64 = 1e-3;

/// The coarse shift search's grid: about this many samples (a longer run is
/// searched on every k-th sample and lag, then refined at full resolution).
pub const COARSE_SAMPLES: usize = 2000;

/// How a loaded run was paired with its unloaded twin.
#[derive(Debug, Clone, Serialize)]
pub struct Alignment {
    /// δ (s): the unloaded run's time = the loaded run's time + δ.
    pub shift_s: f64,
    /// δ in samples of the processed grid.
    pub shift_samples: f64,
    /// Processed samples of the loaded and the unloaded run.
    pub samples: [usize; 2],
    /// The loaded run's samples used: [first, end) (the overlap).
    pub overlap: [usize; 2],
    /// Per joint: RMS of q_L − q_U on the overlap after alignment (rad or m).
    pub rms_difference: Vec<f64>,
    /// Per joint: largest |q_L − q_U| on the overlap after alignment.
    pub max_difference: Vec<f64>,
    /// Per joint: RMS of the loaded run's motion about its mean (the scale r_j).
    pub motion: Vec<f64>,
}

/// The unloaded twin read on the loaded run's samples `overlap[0]..overlap[1]`.
#[derive(Debug, Clone)]
pub struct Twin {
    /// Positions, velocities, accelerations, torques per overlap sample.
    pub q: Vec<Vec<f64>>,
    /// Velocities.
    pub qd: Vec<Vec<f64>>,
    /// Accelerations.
    pub qdd: Vec<Vec<f64>>,
    /// Torques.
    pub tau: Vec<Vec<f64>>,
    /// Variances of the torques (joint-major over the overlap: j·len + i), if the twin has them.
    pub var: Option<Vec<f64>>,
}

/// The step of a processed grid (s).
fn step(p: &Processed) -> f64 {
    let m = p.t.len();
    if m < 2 {
        return f64::NAN;
    }
    (p.t[m - 1] - p.t[0]) / (m - 1) as f64
}

/// Cubic Hermite on [0, 1] between (p0, m0) and (p1, m1), slopes per sample.
fn hermite(f: f64, p0: f64, m0: f64, p1: f64, m1: f64) -> f64 {
    let (f2, f3) = (f * f, f * f * f);
    (2.0 * f3 - 3.0 * f2 + 1.0) * p0 + (f3 - 2.0 * f2 + f) * m0 + (-2.0 * f3 + 3.0 * f2) * p1 + (f3 - f2) * m1
}

/// Index and fraction of position `x` (in samples) on a grid of `m` samples.
fn locate(x: f64, m: usize) -> (usize, f64) {
    let i = (x.floor().max(0.0) as usize).min(m - 2);
    (i, x - i as f64)
}

/// q_U,j and q̇_U,j at position `x` (samples).
fn q_at(u: &Processed, dt: f64, x: f64, j: usize) -> (f64, f64) {
    let (i, f) = locate(x, u.t.len());
    let q = hermite(f, u.q[i][j], u.qd[i][j] * dt, u.q[i + 1][j], u.qd[i + 1][j] * dt);
    let qd = hermite(f, u.qd[i][j], u.qdd[i][j] * dt, u.qd[i + 1][j], u.qdd[i + 1][j] * dt);
    (q, qd)
}

/// The loaded samples [first, end) whose time shifted by `d` samples lies in the unloaded run.
fn overlap(ml: usize, mu: usize, d: f64) -> (usize, usize) {
    let first = (-d).ceil().max(0.0) as usize;
    let end = ((mu - 1) as f64 - d).floor() + 1.0;
    let end = (end.max(0.0) as usize).min(ml);
    (first.min(end), end)
}

/// Estimates the shift of `u` against `l` and checks that they play the same
/// trajectory; `ctx` names the loaded run in errors.
pub fn align(l: &Processed, u: &Processed, ctx: &str, twin: &str) -> Result<Alignment> {
    let (ml, mu) = (l.t.len(), u.t.len());
    let n = l.q.first().map_or(0, |r| r.len());
    if ml < 4 || mu < 4 {
        return Err(Error::invalid(
            ctx,
            "unloaded",
            format!("{ml} processed samples, its unloaded twin `{twin}` {mu}: at least 4 each are needed to align them"),
        ));
    }
    let (dl, du) = (step(l), step(u));
    if (dl - du).abs() > 1e-6 * dl || !(dl.is_finite() && du.is_finite()) {
        return Err(Error::invalid(
            ctx,
            "unloaded",
            format!(
                "processed sample step {dl:.6e} s, its unloaded twin `{twin}` {du:.6e} s: record both at the same rate and process them the same way (filter, decimate)"
            ),
        ));
    }
    let motion: Vec<f64> = (0..n)
        .map(|j| {
            let mean = l.q.iter().map(|r| r[j]).sum::<f64>() / ml as f64;
            (l.q.iter().map(|r| (r[j] - mean).powi(2)).sum::<f64>() / ml as f64).sqrt()
        })
        .collect();
    let w: Vec<f64> = motion.iter().map(|r| 1.0 / r.max(MIN_MOTION).powi(2)).collect();
    // whole samples: the unloaded sample s + k against the loaded sample s
    let shorter = ml.min(mu);
    let need = (MIN_OVERLAP * shorter as f64).ceil() as usize;
    let kmax = (shorter - need) as i64;
    // the mean weighted squared difference at lag k, over every `every`-th sample of the overlap
    let cost_at = |k: i64, every: usize| -> f64 {
        let (a, b) = overlap(ml, mu, k as f64);
        if b - a < need {
            return f64::INFINITY;
        }
        let (mut e, mut count) = (0.0, 0usize);
        for s in (a..b).step_by(every) {
            let su = (s as i64 + k) as usize;
            for j in 0..n {
                e += w[j] * (u.q[su][j] - l.q[s][j]).powi(2);
            }
            count += 1;
        }
        e / count as f64
    };
    // long runs: the lags and the samples on a grid of about COARSE_SAMPLES
    // (the search costs O(grid² · n), not O(samples² · n)), then every lag
    // around the coarse minimum at full resolution
    let stride = (shorter / COARSE_SAMPLES).max(1);
    let lags: Vec<i64> = (-kmax..=kmax).step_by(stride).collect();
    let cost: Vec<f64> = lags.iter().map(|&k| cost_at(k, stride)).collect();
    // a trajectory played twice fits as well one period later: of the local
    // minima within TIE of the best, the smallest shift (the largest overlap)
    let best = cost.iter().copied().fold(f64::INFINITY, f64::min);
    let k0 = (0..lags.len())
        .filter(|&i| cost[i] <= TIE * best + 1e-300)
        .filter(|&i| (i == 0 || cost[i] <= cost[i - 1]) && (i + 1 == lags.len() || cost[i] <= cost[i + 1]))
        .min_by_key(|&i| lags[i].abs())
        .map_or(0, |i| lags[i]);
    let k0 = if stride > 1 {
        let r = stride as i64;
        ((k0 - r).max(-kmax)..=(k0 + r).min(kmax))
            .map(|k| (k, cost_at(k, 1)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(k0, |(k, _)| k)
    } else {
        k0
    };
    // a fraction of a sample: Gauss–Newton on the interpolated positions
    let mut d = k0 as f64;
    for _ in 0..50 {
        let (a, b) = overlap(ml, mu, d);
        let (mut g, mut h) = (0.0, 0.0);
        for s in a..b {
            for j in 0..n {
                let (q, qd) = q_at(u, du, s as f64 + d, j);
                let jac = qd * du;
                g += w[j] * (q - l.q[s][j]) * jac;
                h += w[j] * jac * jac;
            }
        }
        if h <= 0.0 {
            break;
        }
        let delta = (-g / h).clamp(-1.0, 1.0);
        d += delta;
        if delta.abs() < 1e-9 {
            break;
        }
    }
    if ml == mu && d.abs() < NO_SHIFT {
        d = 0.0;
    }
    let (a, b) = overlap(ml, mu, d);
    if b - a < need {
        return Err(Error::invalid(
            ctx,
            "unloaded",
            format!(
                "its unloaded twin `{twin}` is shifted by {:.3} s ({d:.2} samples): they overlap on {} samples, fewer than {:.0} % of the shorter run ({shorter}); record the same trajectory in both",
                d * dl,
                b - a,
                100.0 * MIN_OVERLAP
            ),
        ));
    }
    let mut rms = vec![0.0; n];
    let mut max = vec![0.0f64; n];
    for s in a..b {
        for j in 0..n {
            let e = (l.q[s][j] - q_at(u, du, s as f64 + d, j).0).abs();
            rms[j] += e * e;
            max[j] = max[j].max(e);
        }
    }
    for v in rms.iter_mut() {
        *v = (*v / (b - a) as f64).sqrt();
    }
    let al = Alignment {
        shift_s: d * dl,
        shift_samples: d,
        samples: [ml, mu],
        overlap: [a, b],
        rms_difference: rms,
        max_difference: max,
        motion,
    };
    let (jw, ratio) = (0..n)
        .map(|j| (j, al.rms_difference[j] / al.motion[j].max(MIN_MOTION)))
        .fold((0, 0.0), |acc, x| if x.1 > acc.1 { x } else { acc });
    if ratio > MAX_DIFFERENCE {
        return Err(Error::invalid(
            ctx,
            "unloaded",
            format!(
                "not the same trajectory as its unloaded twin `{twin}`: after the best time shift ({:.4} s, {:.2} samples) joint {} still differs by {:.4} RMS, {:.0} % of its motion ({:.4} RMS about its mean; allowed ≤ {:.0} %); RMS differences per joint: [{}]",
                al.shift_s,
                d,
                jw + 1,
                al.rms_difference[jw],
                100.0 * ratio,
                al.motion[jw],
                100.0 * MAX_DIFFERENCE,
                al.rms_difference.iter().map(|v| format!("{v:.2e}")).collect::<Vec<_>>().join(", ")
            ),
        ));
    }
    Ok(al)
}

/// The unloaded run `u` read on the loaded samples of `al`'s overlap
/// (`var_u`: its torque variances, joint-major j·m_u + s).
pub fn resample(u: &Processed, var_u: Option<&[f64]>, al: &Alignment) -> Twin {
    let mu = u.t.len();
    let n = u.q.first().map_or(0, |r| r.len());
    let du = step(u);
    let [a, b] = al.overlap;
    let len = b - a;
    let mut tw = Twin {
        q: Vec::with_capacity(len),
        qd: Vec::with_capacity(len),
        qdd: Vec::with_capacity(len),
        tau: Vec::with_capacity(len),
        var: var_u.map(|_| vec![0.0; n * len]),
    };
    for (k, s) in (a..b).enumerate() {
        let x = s as f64 + al.shift_samples;
        let (i, f) = locate(x, mu);
        let lin = |v: &[Vec<f64>], j: usize| v[i][j] + f * (v[i + 1][j] - v[i][j]);
        if al.shift_samples == 0.0 {
            tw.q.push(u.q[s].clone());
            tw.qd.push(u.qd[s].clone());
            tw.qdd.push(u.qdd[s].clone());
            tw.tau.push(u.tau[s].clone());
        } else {
            tw.q.push((0..n).map(|j| q_at(u, du, x, j).0).collect());
            tw.qd.push((0..n).map(|j| q_at(u, du, x, j).1).collect());
            tw.qdd.push((0..n).map(|j| lin(&u.qdd, j)).collect());
            tw.tau.push((0..n).map(|j| lin(&u.tau, j)).collect());
        }
        if let (Some(v), Some(out)) = (var_u, tw.var.as_mut()) {
            for j in 0..n {
                out[j * len + k] = if al.shift_samples == 0.0 {
                    v[j * mu + s]
                } else {
                    v[j * mu + i] + f * (v[j * mu + i + 1] - v[j * mu + i])
                };
            }
        }
    }
    tw
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(t0: f64, m: usize, dt: f64, w: f64) -> Processed {
        let mut p = Processed {
            t: vec![],
            q: vec![],
            qd: vec![],
            qdd: vec![],
            tau: vec![],
            tau_var: None,
            r: None,
            joint_cov: None,
            n_reps: 1,
            filter: crate::data::process::Filter::None,
            velocity: crate::data::process::VelocitySource::Positions,
            fourier: None,
            filter_residual: vec![],
        };
        for s in 0..m {
            let t = t0 + s as f64 * dt;
            p.t.push(s as f64 * dt);
            p.q.push(vec![(w * t).sin(), 0.5 * (2.0 * w * t).cos()]);
            p.qd.push(vec![w * (w * t).cos(), -w * (2.0 * w * t).sin()]);
            p.qdd.push(vec![-w * w * (w * t).sin(), -2.0 * w * w * (2.0 * w * t).cos()]);
            p.tau.push(vec![t, -t]);
        }
        p
    }

    #[test]
    fn a_sub_sample_shift_is_found_and_the_twin_read_on_the_loaded_grid() {
        let dt = 0.005;
        let l = run(0.0, 1000, dt, 1.3);
        let u = run(0.0137, 960, dt, 1.3); // starts 2.74 samples later, 40 samples shorter
        let al = align(&l, &u, "loaded", "unloaded").unwrap();
        assert!((al.shift_samples + 2.74).abs() < 1e-6, "{}", al.shift_samples);
        assert!((al.shift_s + 0.0137).abs() < 1e-8);
        assert_eq!(al.overlap, [3, 962]);
        let tw = resample(&u, None, &al);
        for (k, s) in (al.overlap[0]..al.overlap[1]).enumerate() {
            for j in 0..2 {
                assert!((tw.q[k][j] - l.q[s][j]).abs() < 1e-8);
                assert!((tw.qd[k][j] - l.qd[s][j]).abs() < 1e-6);
            }
            assert!((tw.tau[k][0] - s as f64 * dt).abs() < 1e-12);
        }
        assert!(al.rms_difference.iter().all(|v| *v < 1e-8));
    }

    #[test]
    fn a_trajectory_played_several_times_is_shifted_by_the_least() {
        // period 2π/(2π·0.5) = 2 s = 400 samples; 2000 samples: five periods
        let w = std::f64::consts::PI;
        let l = run(0.0, 2000, 0.005, w);
        let u = run(0.0075, 1990, 0.005, w);
        let al = align(&l, &u, "loaded", "unloaded").unwrap();
        assert!((al.shift_samples + 1.5).abs() < 1e-6, "{}", al.shift_samples);
    }

    #[test]
    fn a_long_run_is_searched_on_a_coarse_grid_then_at_full_resolution() {
        // 60 s at 1 kHz, several periods: the lag search on about COARSE_SAMPLES
        // samples, refined to the same sub-sample shift
        let w = 0.9;
        let l = run(0.0, 60_000, 0.001, w);
        let u = run(0.0174, 59_950, 0.001, w); // 17.4 samples later, 50 shorter
        let al = align(&l, &u, "loaded", "unloaded").unwrap();
        assert!((al.shift_samples + 17.4).abs() < 1e-6, "{}", al.shift_samples);
    }

    #[test]
    fn another_trajectory_is_refused_with_the_numbers() {
        let l = run(0.0, 800, 0.005, 1.3);
        let u = run(0.0, 800, 0.005, 2.1);
        let e = align(&l, &u, "loaded run `a`", "b").unwrap_err().to_string();
        assert!(e.contains("not the same trajectory") && e.contains("allowed ≤ 10 %"), "{e}");
        let u = run(0.0, 800, 0.01, 1.3);
        let e = align(&l, &u, "loaded run `a`", "b").unwrap_err().to_string();
        assert!(e.contains("sample step"), "{e}");
    }
}
