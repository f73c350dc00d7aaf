//! Signal processing of a run (paper 000 §III-C): averaging over the N_r
//! repetitions with the sample variance per joint and time step (eq. 7),
//! Fourier filtering of the averaged positions at the excited harmonics with
//! analytic derivatives, or — for references that are not Fourier series —
//! a zero-phase low-pass (2nd-order Butterworth run forwards and backwards)
//! and central differences.
//!
//! With N_r ≥ 2 every repetition is also filtered on its own, which gives the
//! sample covariance of the filtered states and torques per time step (used by
//! the maximum-likelihood estimator and reported as the position noise floor).

use super::{Repetition, Run};
use crate::error::{Error, Result};
use crate::trajectory::differentiate;
use crate::trajectory::FourierTrajectory;
use serde::Serialize;

/// Where identification takes the joint velocities from (`identify --velocity-from`).
///
/// With logged velocities (`qd*` columns, the drive's own velocity from the
/// motor encoder through the gear ratio) the averaged logged q̇ is used as it
/// is, unfiltered: at rest a smooth friction model's torque Fc·tanh(q̇/v_s)
/// depends on q̇ at the scale v_s, where any filter's bias matters. q still
/// comes from the position filter, and q̈ (unless `qdd*` are logged too) from
/// the logged velocity through the same filter: zero-phase low-pass at the
/// cut-off then central differences, the Fourier fit at the run's harmonics
/// differentiated analytically, or central differences for `Filter::None`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocityFrom {
    /// The logged velocities when the run has `qd*` columns, else the positions.
    #[default]
    Auto,
    /// The logged velocities `qd*` (an error when the run has none).
    Log,
    /// Differentiated filtered positions, even when velocities are logged.
    Positions,
}

impl std::str::FromStr for VelocityFrom {
    type Err = Error;
    fn from_str(s: &str) -> Result<VelocityFrom> {
        match s {
            "auto" => Ok(VelocityFrom::Auto),
            "log" => Ok(VelocityFrom::Log),
            "positions" => Ok(VelocityFrom::Positions),
            _ => Err(Error::invalid(
                "identify",
                "velocity_from",
                format!("expected auto, log or positions, found `{s}`"),
            )),
        }
    }
}

impl std::fmt::Display for VelocityFrom {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            VelocityFrom::Auto => "auto",
            VelocityFrom::Log => "log",
            VelocityFrom::Positions => "positions",
        })
    }
}

/// Where the velocities and accelerations of a processed run came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocitySource {
    /// q̇ and q̈ from the filtered positions.
    Positions,
    /// q̇ logged (`qd*`), q̈ from the logged q̇ through the filter.
    Logged,
    /// q̇ and q̈ logged (`qd*`, `qdd*`).
    LoggedWithAcceleration,
}

impl VelocitySource {
    /// In words, for reports.
    pub fn words(self, filter: &Filter) -> String {
        let how = match filter {
            Filter::Fourier { n_h, .. } => format!("its Fourier fit at {n_h} harmonics, differentiated"),
            Filter::LowPass { cutoff } => format!("zero-phase low-pass {cutoff} Hz + central differences"),
            Filter::None => "central differences".into(),
        };
        match self {
            VelocitySource::Positions => "q̇, q̈ from the positions (the filter above)".into(),
            VelocitySource::Logged => format!("q̇ logged (qd* columns, unfiltered), q̈ from the logged q̇: {how}"),
            VelocitySource::LoggedWithAcceleration => "q̇, q̈ logged (qd*, qdd* columns, unfiltered)".into(),
        }
    }
}

/// How positions are filtered and differentiated.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Filter {
    /// Least-squares Fourier fit with `n_h` harmonics of ω (rad/s); analytic q̇, q̈.
    Fourier {
        /// Base angular frequency (rad/s).
        omega: f64,
        /// Harmonics kept.
        n_h: usize,
    },
    /// Zero-phase Butterworth low-pass with cut-off `cutoff` (Hz), then central differences.
    LowPass {
        /// Cut-off (Hz).
        cutoff: f64,
    },
    /// Central differences of the averaged positions, no filtering.
    None,
}

/// The processed run: averaged, filtered signals on the time grid.
#[derive(Debug, Clone)]
pub struct Processed {
    /// Times (s, from 0).
    pub t: Vec<f64>,
    /// Filtered positions (per sample, n).
    pub q: Vec<Vec<f64>>,
    /// Velocities.
    pub qd: Vec<Vec<f64>>,
    /// Accelerations.
    pub qdd: Vec<Vec<f64>>,
    /// Averaged torques τ̄ (per sample, n).
    pub tau: Vec<Vec<f64>>,
    /// Sample variance of the individual torque measurements σ²_{j,p} (eq. 7), if N_r ≥ 2.
    pub tau_var: Option<Vec<Vec<f64>>>,
    /// Averaged reference, if the files had one.
    pub r: Option<Vec<Vec<f64>>>,
    /// Per sample, the sample covariance (4n × 4n, row-major) of one repetition's
    /// (τ, q, q̇, q̈) after filtering, if N_r ≥ 2.
    pub joint_cov: Option<Vec<Vec<f64>>>,
    /// Number of repetitions averaged.
    pub n_reps: usize,
    /// Filter used.
    pub filter: Filter,
    /// Where q̇ and q̈ came from.
    pub velocity: VelocitySource,
    /// The Fourier fit of the averaged positions (Fourier filter only).
    pub fourier: Option<FourierTrajectory>,
    /// Per joint, the RMS of (averaged − filtered) positions and the RMS noise
    /// of the averaged positions (σ_q/√N_r from the repetitions, if N_r ≥ 2):
    /// a residual well above the noise means the filter removes motion (for a
    /// Fourier filter: harmonics of the closed-loop response above n_h).
    pub filter_residual: Vec<(f64, Option<f64>)>,
}

impl Processed {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        self.q.first().map_or(0, |v| v.len())
    }

    /// Keeps every k-th sample (k ≥ 1).
    pub fn decimated(&self, k: usize) -> Processed {
        if k <= 1 {
            return self.clone();
        }
        let pick = |v: &Vec<Vec<f64>>| v.iter().step_by(k).cloned().collect::<Vec<_>>();
        Processed {
            t: self.t.iter().step_by(k).copied().collect(),
            q: pick(&self.q),
            qd: pick(&self.qd),
            qdd: pick(&self.qdd),
            tau: pick(&self.tau),
            tau_var: self.tau_var.as_ref().map(pick),
            r: self.r.as_ref().map(pick),
            joint_cov: self.joint_cov.as_ref().map(pick),
            n_reps: self.n_reps,
            filter: self.filter.clone(),
            velocity: self.velocity,
            fourier: self.fourier.clone(),
            filter_residual: self.filter_residual.clone(),
        }
    }
}

fn mean_of(reps: &[&Vec<Vec<f64>>]) -> Vec<Vec<f64>> {
    let m = reps[0].len();
    let n = reps[0][0].len();
    let k = reps.len() as f64;
    let mut out = vec![vec![0.0; n]; m];
    for r in reps {
        for p in 0..m {
            for j in 0..n {
                out[p][j] += r[p][j] / k;
            }
        }
    }
    out
}

/// (q, q̇, q̈), per sample.
type Signals = (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<Vec<f64>>);

/// Filters positions (and gives q̇, q̈) on the uniform grid `t`.
fn filter_positions(t: &[f64], q: &[Vec<f64>], filter: &Filter) -> Result<(Signals, Option<FourierTrajectory>)> {
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    match filter {
        Filter::Fourier { omega, n_h } => {
            let f = FourierTrajectory::fit(t, q, *omega, *n_h)?;
            let s = f.sample_at(t);
            Ok(((s.q, s.qd, s.qdd), Some(f)))
        }
        Filter::LowPass { cutoff } => {
            let n = q[0].len();
            let mut fq = vec![vec![0.0; n]; q.len()];
            for j in 0..n {
                let x: Vec<f64> = q.iter().map(|v| v[j]).collect();
                let y = filtfilt(&x, *cutoff, 1.0 / dt)?;
                for (p, v) in y.into_iter().enumerate() {
                    fq[p][j] = v;
                }
            }
            let (qd, qdd) = differentiate(&fq, dt, false);
            Ok(((fq, qd, qdd), None))
        }
        Filter::None => {
            let (qd, qdd) = differentiate(q, dt, false);
            Ok(((q.to_vec(), qd, qdd), None))
        }
    }
}

/// The signals of one record (or of the averages): q through `filter`; q̇
/// logged when `qd` is given (q̈ logged when `qdd` is given too, else the
/// logged q̇ through `filter`, differentiated), else from the filtered q.
fn signals(t: &[f64], q: &[Vec<f64>], qd: Option<&[Vec<f64>]>, qdd: Option<&[Vec<f64>]>, filter: &Filter) -> Result<(Signals, Option<FourierTrajectory>)> {
    let ((fq, fqd, fqdd), fourier) = filter_positions(t, q, filter)?;
    let Some(qd) = qd else {
        return Ok(((fq, fqd, fqdd), fourier));
    };
    let qdd = match qdd {
        Some(a) => a.to_vec(),
        None => {
            // the filter applied to the logged velocity: its first derivative is q̈
            let ((_, a, _), _) = filter_positions(t, qd, filter)?;
            a
        }
    };
    Ok(((fq, qd.to_vec(), qdd), fourier))
}

/// Checks that a Fourier filter fits the record: the duration must be a whole
/// number of periods (within 1 % of a sample).
pub fn check_fourier_span(t: &[f64], omega: f64) -> Result<()> {
    let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    let span = t.len() as f64 * dt;
    let periods = span * omega / std::f64::consts::TAU;
    let err = (periods - periods.round()).abs() * std::f64::consts::TAU / omega;
    if periods.round() < 1.0 || err > 0.01 * dt + 1e-9 {
        return Err(Error::invalid(
            "Fourier filtering",
            "omega",
            format!(
                "the record spans {span} s = {periods:.4} periods of {} s; Fourier filtering needs whole periods (use the low-pass filter for other runs)",
                std::f64::consts::TAU / omega
            ),
        ));
    }
    Ok(())
}

/// Averages the repetitions (paper 000 §III-C, eq. 7) and filters the
/// positions; logged velocities are used when present ([`VelocityFrom::Auto`]).
pub fn process(run: &Run, filter: &Filter) -> Result<Processed> {
    process_with(run, filter, VelocityFrom::Auto)
}

/// [`process`] with the velocity source `from` ([`VelocityFrom`]).
pub fn process_with(run: &Run, filter: &Filter, from: VelocityFrom) -> Result<Processed> {
    let reps = &run.reps;
    let nr = reps.len();
    let n = run.n_joints();
    let t0 = reps[0].t[0];
    let t: Vec<f64> = reps[0].t.iter().map(|x| x - t0).collect();
    if let Filter::Fourier { omega, n_h } = filter {
        check_fourier_span(&t, *omega)?;
        if *n_h == 0 {
            return Err(Error::invalid("Fourier filtering", "n_h", "expected at least one harmonic"));
        }
    }
    if let Filter::LowPass { cutoff } = filter {
        let fs = 1.0 / run.dt();
        if !(*cutoff > 0.0 && *cutoff < 0.5 * fs) {
            return Err(Error::invalid(
                "low-pass filter",
                "cutoff",
                format!("expected 0 < cutoff < {} Hz (half the sample rate), got {cutoff}", 0.5 * fs),
            ));
        }
    }
    let q_mean = mean_of(&reps.iter().map(|r| &r.q).collect::<Vec<_>>());
    let tau = mean_of(&reps.iter().map(|r| &r.tau).collect::<Vec<_>>());
    let r = if reps[0].r.is_some() {
        Some(mean_of(&reps.iter().filter_map(|r| r.r.as_ref()).collect::<Vec<_>>()))
    } else {
        None
    };
    let m = t.len();
    let tau_var = if let Some(av) = &run.averaged {
        Some(av.var_tau.clone())
    } else if nr >= 2 {
        let mut v = vec![vec![0.0; n]; m];
        for rep in reps {
            for p in 0..m {
                for j in 0..n {
                    let d = rep.tau[p][j] - tau[p][j];
                    v[p][j] += d * d / (nr - 1) as f64;
                }
            }
        }
        Some(v)
    } else {
        None
    };
    let logged = match from {
        VelocityFrom::Positions => false,
        VelocityFrom::Auto => reps[0].qd.is_some(),
        VelocityFrom::Log => {
            if reps[0].qd.is_none() {
                let file = run.files.first().map_or_else(|| "run".to_string(), |f| f.display().to_string());
                return Err(Error::invalid(
                    file,
                    "velocity_from",
                    format!("`log`, but the run logs no velocities qd1..qd{n}: use velocity_from = \"positions\" (or \"auto\")"),
                ));
            }
            true
        }
    };
    let with_acc = logged && reps[0].qdd.is_some();
    let mean_opt = |f: fn(&Repetition) -> Option<&Vec<Vec<f64>>>, on: bool| on.then(|| mean_of(&reps.iter().filter_map(f).collect::<Vec<_>>()));
    let qd_log = mean_opt(|r| r.qd.as_ref(), logged);
    let qdd_log = mean_opt(|r| r.qdd.as_ref(), with_acc);
    let ((q, qd, qdd), fourier) = signals(&t, &q_mean, qd_log.as_deref(), qdd_log.as_deref(), filter)?;
    let q_noise_avg: Option<Vec<f64>> = run.averaged.as_ref().and_then(|av| {
        av.var_q.as_ref().map(|vq| {
            (0..n)
                .map(|j| (vq.iter().map(|v| v[j]).sum::<f64>() / m as f64 / av.repetitions as f64).sqrt())
                .collect()
        })
    });
    let q_noise: Option<Vec<f64>> = q_noise_avg.or_else(|| {
        (nr >= 2).then(|| {
            (0..n)
                .map(|j| {
                    let v: f64 = reps
                        .iter()
                        .map(|rep| (0..m).map(|p| (rep.q[p][j] - q_mean[p][j]).powi(2)).sum::<f64>())
                        .sum::<f64>()
                        / ((nr - 1) * m) as f64;
                    (v / nr as f64).sqrt()
                })
                .collect()
        })
    });
    let filter_residual = (0..n)
        .map(|j| {
            let r = ((0..m).map(|p| (q_mean[p][j] - q[p][j]).powi(2)).sum::<f64>() / m as f64).sqrt();
            (r, q_noise.as_ref().map(|v| v[j]))
        })
        .collect();
    let joint_cov = if nr >= 2 {
        let d = 4 * n;
        let per: Vec<Signals> = reps
            .iter()
            .map(|rep| {
                let qd = rep.qd.as_deref().filter(|_| logged);
                let qdd = rep.qdd.as_deref().filter(|_| with_acc);
                signals(&t, &rep.q, qd, qdd, filter).map(|(sig, _)| sig)
            })
            .collect::<Result<_>>()?;
        let mut cov = vec![vec![0.0; d * d]; m];
        let mut x = vec![0.0; d];
        for (ri, rep) in reps.iter().enumerate() {
            for p in 0..m {
                for j in 0..n {
                    x[j] = rep.tau[p][j] - tau[p][j];
                    x[n + j] = per[ri].0[p][j] - q[p][j];
                    x[2 * n + j] = per[ri].1[p][j] - qd[p][j];
                    x[3 * n + j] = per[ri].2[p][j] - qdd[p][j];
                }
                let c = &mut cov[p];
                for a in 0..d {
                    for b in 0..d {
                        c[a * d + b] += x[a] * x[b] / (nr - 1) as f64;
                    }
                }
            }
        }
        Some(cov)
    } else {
        None
    };
    Ok(Processed {
        t,
        q,
        qd,
        qdd,
        tau,
        tau_var,
        r,
        joint_cov,
        n_reps: run.n_reps(),
        filter: filter.clone(),
        velocity: match (logged, with_acc) {
            (false, _) => VelocitySource::Positions,
            (true, false) => VelocitySource::Logged,
            (true, true) => VelocitySource::LoggedWithAcceleration,
        },
        fourier,
        filter_residual,
    })
}

/// Zero-phase low-pass: a 2nd-order Butterworth biquad (bilinear transform with
/// pre-warping) run forwards then backwards (4th-order magnitude, no phase),
/// with odd-reflection padding at both ends to suppress edge transients.
pub fn filtfilt(x: &[f64], cutoff: f64, fs: f64) -> Result<Vec<f64>> {
    if !(cutoff > 0.0 && cutoff < 0.5 * fs) {
        return Err(Error::invalid(
            "low-pass filter",
            "cutoff",
            format!("expected 0 < cutoff < fs/2 = {}", 0.5 * fs),
        ));
    }
    let m = x.len();
    if m < 4 {
        return Ok(x.to_vec());
    }
    let k = (std::f64::consts::PI * cutoff / fs).tan();
    let s2 = std::f64::consts::SQRT_2;
    let norm = 1.0 / (1.0 + s2 * k + k * k);
    let b0 = k * k * norm;
    let (b1, b2) = (2.0 * b0, b0);
    let a1 = 2.0 * (k * k - 1.0) * norm;
    let a2 = (1.0 - s2 * k + k * k) * norm;
    let pad = (3.0 * fs / cutoff).ceil().min((m - 1) as f64) as usize;
    let mut ext = Vec::with_capacity(m + 2 * pad);
    for i in (1..=pad).rev() {
        ext.push(2.0 * x[0] - x[i]);
    }
    ext.extend_from_slice(x);
    for i in 1..=pad {
        ext.push(2.0 * x[m - 1] - x[m - 1 - i]);
    }
    let run = |v: &mut Vec<f64>| {
        let c = v[0];
        let mut z2 = (b2 - a2) * c;
        let mut z1 = (b1 - a1) * c + z2;
        for s in v.iter_mut() {
            let xin = *s;
            let y = b0 * xin + z1;
            z1 = b1 * xin - a1 * y + z2;
            z2 = b2 * xin - a2 * y;
            *s = y;
        }
    };
    run(&mut ext);
    ext.reverse();
    run(&mut ext);
    ext.reverse();
    Ok(ext[pad..pad + m].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtfilt_keeps_slow_sines_without_phase_and_removes_fast_ones() {
        let fs = 200.0;
        let t: Vec<f64> = (0..2000).map(|i| i as f64 / fs).collect();
        let slow: Vec<f64> = t.iter().map(|t| (std::f64::consts::TAU * 1.0 * t).sin()).collect();
        let fast: Vec<f64> = t.iter().map(|t| (std::f64::consts::TAU * 60.0 * t).sin()).collect();
        let ys = filtfilt(&slow, 10.0, fs).unwrap();
        let yf = filtfilt(&fast, 10.0, fs).unwrap();
        // interior: slow sine unchanged (gain |H(1 Hz)|² ≈ 1, no phase), fast one attenuated by > 1e3
        for i in 200..1800 {
            assert!((ys[i] - slow[i]).abs() < 1e-3, "slow sine changed at {i}: {} vs {}", ys[i], slow[i]);
            assert!(yf[i].abs() < 1e-3);
        }
        assert!(filtfilt(&slow, 150.0, fs).is_err());
    }

    #[test]
    fn averaging_variance_and_fourier_filtering() {
        // two repetitions of q = 0.3 sin(ωt), τ = ±1 about 2: mean 2, sample variance 2 (eq. 7)
        let w = std::f64::consts::TAU * 0.5;
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.01).collect();
        let mk = |s: f64| Repetition {
            t: t.clone(),
            q: t.iter().map(|t| vec![0.3 * (w * t).sin() + 1e-3 * s * (37.0 * t).sin()]).collect(),
            tau: t.iter().map(|_| vec![2.0 + s]).collect(),
            r: None,
            qd: None,
            qdd: None,
        };
        let run = Run::new(vec![], vec![mk(1.0), mk(-1.0)]).unwrap();
        let pr = process(&run, &Filter::Fourier { omega: w, n_h: 3 }).unwrap();
        for p in 0..200 {
            assert!((pr.tau[p][0] - 2.0).abs() < 1e-12);
            assert!((pr.tau_var.as_ref().unwrap()[p][0] - 2.0).abs() < 1e-12);
            let tt = t[p];
            assert!((pr.q[p][0] - 0.3 * (w * tt).sin()).abs() < 1e-9);
            assert!((pr.qd[p][0] - 0.3 * w * (w * tt).cos()).abs() < 1e-8);
            assert!((pr.qdd[p][0] + 0.3 * w * w * (w * tt).sin()).abs() < 1e-7);
        }
        // a record that is not a whole number of periods is refused for Fourier filtering
        assert!(process(&run, &Filter::Fourier { omega: w * 1.1, n_h: 3 }).is_err());
    }

    #[test]
    fn logged_velocities_are_used_unfiltered_and_differentiated_through_the_filter() {
        // q = 0.3 sin(ωt) with its exact velocity logged, plus a 40 Hz ripple on
        // the logged velocity that the low-pass must remove from q̈ but not from q̇
        let w = std::f64::consts::TAU * 0.5;
        let t: Vec<f64> = (0..400).map(|i| i as f64 * 0.005).collect();
        let ripple = |t: f64| 1e-4 * (std::f64::consts::TAU * 40.0 * t).sin();
        let rep = |acc: bool| Repetition {
            t: t.clone(),
            q: t.iter().map(|t| vec![0.3 * (w * t).sin()]).collect(),
            tau: t.iter().map(|_| vec![1.0]).collect(),
            r: None,
            qd: Some(t.iter().map(|t| vec![0.3 * w * (w * t).cos() + ripple(*t)]).collect()),
            qdd: acc.then(|| t.iter().map(|t| vec![-0.3 * w * w * (w * t).sin()]).collect()),
        };
        let run = Run::new(vec![], vec![rep(false), rep(false)]).unwrap();
        let lp = Filter::LowPass { cutoff: 10.0 };
        let pr = process(&run, &lp).unwrap();
        assert_eq!(pr.velocity, VelocitySource::Logged);
        assert!(pr.joint_cov.is_some());
        for p in 40..360 {
            let tt = t[p];
            assert_eq!(pr.qd[p][0], 0.3 * w * (w * tt).cos() + ripple(tt));
            // the ripple's derivative (2.5e-2 rad/s²) is filtered out of q̈
            assert!((pr.qdd[p][0] + 0.3 * w * w * (w * tt).sin()).abs() < 2e-3, "{p}: {}", pr.qdd[p][0]);
        }
        // the Fourier path differentiates the Fourier fit of the logged velocity
        let pf = process(&run, &Filter::Fourier { omega: w, n_h: 3 }).unwrap();
        for p in 0..400 {
            assert!((pf.qdd[p][0] + 0.3 * w * w * (w * t[p]).sin()).abs() < 1e-6, "{p}");
        }
        // logged accelerations are taken as they are
        let pa = process(&Run::new(vec![], vec![rep(true), rep(true)]).unwrap(), &lp).unwrap();
        assert_eq!(pa.velocity, VelocitySource::LoggedWithAcceleration);
        assert_eq!(pa.qdd[17][0], -0.3 * w * w * (w * t[17]).sin());
        // positions only: the logged columns are ignored
        let pp = process_with(&run, &lp, VelocityFrom::Positions).unwrap();
        assert_eq!(pp.velocity, VelocitySource::Positions);
        assert!((pp.qd[200][0] - 0.3 * w * (w * t[200]).cos()).abs() < 1e-3);
        assert_ne!(pp.qd[200][0], pr.qd[200][0]);
        // log without logged velocities
        let mut bare = rep(false);
        bare.qd = None;
        let e = process_with(&Run::new(vec![], vec![bare]).unwrap(), &lp, VelocityFrom::Log).unwrap_err();
        assert!(e.to_string().contains("velocity_from") && e.to_string().contains("qd1..qd1"), "{e}");
    }
}
