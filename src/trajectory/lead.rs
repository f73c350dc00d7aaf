//! Rest-to-rest execution: a quintic lead-in from a home pose at rest to the
//! state where the periodic excitation starts, the periodic part repeated N
//! times, and a quintic lead-out back to the home pose at rest
//! ([`Delivered`]).
//!
//! Per joint, q(s) = Σ_{i=0}^{5} c_i s^i on s ∈ [0, T] with the position,
//! velocity and acceleration prescribed at both ends (six conditions, one
//! quintic). The duration T is the shortest on a geometric ladder
//! T_k = T_min · 1.05^k (each rounded up to a multiple of
//! [`DURATION_QUANTUM`]) whose motion passes the caller's check (joint
//! limits, torques, workspace, collision), sampled `dt` apart.

use super::{Motion, ShapeMotion};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Lead-in and lead-out durations are whole multiples of this (s): 40 ms is
/// a whole number of samples at 1 kHz, 500 Hz, 250 Hz, 125 Hz, 100 Hz, 50 Hz
/// and 25 Hz, so the lead parts start and end on the sample grid of every
/// usual controller rate.
pub const DURATION_QUANTUM: f64 = 0.04;

/// One quintic per joint over [0, T].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Quintic {
    /// Coefficients c_0..c_5 per joint (q(s) = Σ c_i sⁱ).
    pub coef: Vec<[f64; 6]>,
    /// Duration (s).
    pub duration: f64,
}

/// A boundary state: positions, velocities, accelerations.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// q (rad, m).
    pub q: Vec<f64>,
    /// q̇.
    pub qd: Vec<f64>,
    /// q̈.
    pub qdd: Vec<f64>,
}

impl State {
    /// At rest at `q`.
    pub fn rest(q: &[f64]) -> State {
        State {
            q: q.to_vec(),
            qd: vec![0.0; q.len()],
            qdd: vec![0.0; q.len()],
        }
    }

    /// The state of a motion (any [`Motion`]: a Fourier trajectory, a B-spline) at time t.
    pub fn of<M: Motion + ?Sized>(tr: &M, t: f64) -> State {
        let n = tr.n_joints();
        let mut s = State {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
        };
        tr.eval(t, &mut s.q, &mut s.qd, &mut s.qdd);
        s
    }
}

impl Quintic {
    /// The quintic from `a` at s = 0 to `b` at s = `t` (t > 0).
    pub fn new(a: &State, b: &State, t: f64) -> Quintic {
        let coef = (0..a.q.len())
            .map(|j| {
                let (q0, v0, a0) = (a.q[j], a.qd[j], a.qdd[j]);
                let (q1, v1, a1) = (b.q[j], b.qd[j], b.qdd[j]);
                let (t2, t3, t4, t5) = (t * t, t.powi(3), t.powi(4), t.powi(5));
                let h = q1 - q0;
                [
                    q0,
                    v0,
                    a0 / 2.0,
                    (20.0 * h - (8.0 * v1 + 12.0 * v0) * t - (3.0 * a0 - a1) * t2) / (2.0 * t3),
                    (-30.0 * h + (14.0 * v1 + 16.0 * v0) * t + (3.0 * a0 - 2.0 * a1) * t2) / (2.0 * t4),
                    (12.0 * h - 6.0 * (v1 + v0) * t - (a0 - a1) * t2) / (2.0 * t5),
                ]
            })
            .collect();
        Quintic { coef, duration: t }
    }

    /// q, q̇, q̈ at time s (clamped to [0, T]) into the slices.
    pub fn eval_into(&self, s: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let s = s.clamp(0.0, self.duration);
        for (j, c) in self.coef.iter().enumerate() {
            q[j] = c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))));
            qd[j] = c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])));
            qdd[j] = 2.0 * c[2] + s * (6.0 * c[3] + s * (12.0 * c[4] + s * 20.0 * c[5]));
        }
    }

    /// (q, q̇, q̈) at time s (clamped to [0, T]).
    pub fn eval(&self, s: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = self.coef.len();
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        self.eval_into(s, &mut q, &mut qd, &mut qdd);
        (q, qd, qdd)
    }
}

/// Why a sampled motion fails the caller's check: what, where, by how much.
pub type CheckResult = std::result::Result<(), String>;

/// The shortest quintic from `a` to `b` (T on the ladder from `t_min`, at most
/// `t_max`) for which `check(s, q, q̇, q̈)` holds at every sample `dt` apart
/// (both ends included). `check` returns `Err(reason)` at the first violated
/// sample; when no duration fits, the error names the reason found at the
/// shortest and at the longest duration tried.
pub fn shortest(a: &State, b: &State, t_min: f64, t_max: f64, dt: f64, mut check: impl FnMut(f64, &[f64], &[f64], &[f64]) -> CheckResult) -> Result<Quintic> {
    if !(t_min > 0.0 && t_max >= t_min && t_max.is_finite() && dt > 0.0) {
        return Err(Error::invalid(
            "execution",
            "lead duration",
            format!("need 0 < t_min ≤ t_max < ∞ and dt > 0, got {t_min}, {t_max}, {dt}"),
        ));
    }
    let quantise = |t: f64| (t / DURATION_QUANTUM - 1e-9).ceil().max(1.0) * DURATION_QUANTUM;
    let mut t = quantise(t_min);
    let mut first: Option<String> = None;
    let mut last = String::new();
    let mut tried = 0.0;
    let n = a.q.len();
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    while t <= t_max * (1.0 + 1e-12) {
        let p = Quintic::new(a, b, t);
        let m = (t / dt - 1e-9).ceil() as usize;
        let mut ok = Ok(());
        for k in 0..=m {
            let s = (k as f64 * dt).min(t);
            p.eval_into(s, &mut q, &mut qd, &mut qdd);
            if let Err(e) = check(s, &q, &qd, &qdd) {
                ok = Err(e);
                break;
            }
        }
        match ok {
            Ok(()) => return Ok(p),
            Err(e) => {
                let e = format!("{e} (with a duration of {t:.2} s)");
                if first.is_none() {
                    first = Some(e.clone());
                }
                last = e;
            }
        }
        tried = t;
        // next rung: 5 % longer, at least one quantum
        t = quantise((t * 1.05).max(t + DURATION_QUANTUM));
    }
    Err(Error::Numerical(format!(
        "no smooth transition of {t_min:.2}–{tried:.2} s stays within the limits: at the shortest, {}; at the longest, {last}",
        first.unwrap_or_default()
    )))
}

/// Segment number of a sample of a [`Delivered`] trajectory: 0 the lead-in,
/// k = 1..N period k, −1 the lead-out (and the rest sample after it).
pub const LEAD_IN: i64 = 0;
/// Segment number of the lead-out.
pub const LEAD_OUT: i64 = -1;

/// The trajectory as it is played on the robot: from `home` at rest, the
/// lead-in, `periods` repetitions of the periodic part, the lead-out back to
/// `home` at rest. A missing lead (None) has zero duration: the periodic
/// part then starts (ends) at rest at home by construction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Delivered {
    /// Home pose (rad, m): start and end, at rest.
    pub home: Vec<f64>,
    /// Lead-in from home at rest to the periodic part's state at t = 0.
    pub lead_in: Option<Quintic>,
    /// The excitation: a period of a periodic motion (a Fourier series),
    /// or a whole rest-to-rest motion (a B-spline, played without leads
    /// from and back to home = its start pose), repeated `periods` times.
    pub periodic: ShapeMotion,
    /// Number of periods played (≥ 1).
    pub periods: usize,
    /// Lead-out from the periodic part's state at the end of the last period
    /// to home at rest.
    pub lead_out: Option<Quintic>,
}

impl Delivered {
    /// Duration of the lead-in (s).
    pub fn lead_in_duration(&self) -> f64 {
        self.lead_in.as_ref().map_or(0.0, |p| p.duration)
    }

    /// Duration of the lead-out (s).
    pub fn lead_out_duration(&self) -> f64 {
        self.lead_out.as_ref().map_or(0.0, |p| p.duration)
    }

    /// Start time of the periodic part (s).
    pub fn periodic_start(&self) -> f64 {
        self.lead_in_duration()
    }

    /// End time of the periodic part (s).
    pub fn periodic_end(&self) -> f64 {
        self.lead_in_duration() + self.periods as f64 * self.periodic.duration()
    }

    /// Total duration (s).
    pub fn duration(&self) -> f64 {
        self.periodic_end() + self.lead_out_duration()
    }

    /// The segment time t belongs to ([`LEAD_IN`], period 1..N,
    /// [`LEAD_OUT`]), as [`Self::eval`] assigns it.
    ///
    /// A time within [`BOUNDARY_TOL`] of a boundary (lead-in end, period
    /// end, periodic end) belongs to the part that starts there: the
    /// durations are sums of decimal steps (1.4 s is 35 × 0.04 s =
    /// 1.4000000000000001), and the sample at t = 1400/1000 is the first of
    /// period 1, not the last of the lead-in.
    pub fn segment_at(&self, t: f64) -> i64 {
        let t_in = self.lead_in_duration();
        if t < t_in - BOUNDARY_TOL {
            return LEAD_IN;
        }
        if t < self.periodic_end() - BOUNDARY_TOL {
            let s = (t - t_in).max(0.0);
            let k = (((s + BOUNDARY_TOL) / self.periodic.duration()).floor() as usize).min(self.periods - 1);
            return k as i64 + 1;
        }
        LEAD_OUT
    }

    /// Evaluates at time t (after the end: home at rest) and returns the
    /// segment ([`Self::segment_at`]).
    pub fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) -> i64 {
        let seg = self.segment_at(t);
        match seg {
            LEAD_IN => {
                if let Some(p) = &self.lead_in {
                    if t <= 0.0 {
                        // exactly home at rest
                        q.copy_from_slice(&self.home);
                        qd.fill(0.0);
                        qdd.fill(0.0);
                    } else {
                        p.eval_into(t, q, qd, qdd);
                    }
                }
            }
            LEAD_OUT => match &self.lead_out {
                Some(_) if t >= self.duration() - 1e-9 => {
                    // exactly home at rest (the quintic's end value up to rounding)
                    q.copy_from_slice(&self.home);
                    qd.fill(0.0);
                    qdd.fill(0.0);
                }
                Some(p) => p.eval_into(t - self.periodic_end(), q, qd, qdd),
                None => {
                    // no lead-out: the periodic part ends at rest at home
                    // (a rest-to-rest motion at its end, which may differ
                    // from its start when its start is not home)
                    self.periodic.eval(0.0, q, qd, qdd);
                    if self.periodic.ends() == super::Ends::RestToRest {
                        let n = q.len();
                        let (mut qe, mut qde, mut qdde) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                        self.periodic.eval(self.periodic.duration(), &mut qe, &mut qde, &mut qdde);
                        if qe.iter().zip(q.iter()).any(|(a, b)| (a - b).abs() > 1e-12) {
                            q.copy_from_slice(&qe);
                            qd.copy_from_slice(&qde);
                            qdd.copy_from_slice(&qdde);
                        }
                    }
                }
            },
            k => {
                // evaluate at the time within the period: the series is
                // periodic, and the phase stays exact however many periods
                // are played
                let s = (t - self.lead_in_duration()).max(0.0);
                self.periodic.eval((s - (k - 1) as f64 * self.periodic.duration()).max(0.0), q, qd, qdd);
            }
        }
        seg
    }

    /// The rows of the `rate` Hz grid (t_k = k/rate) and which of them
    /// repeat another ([`RowPlan`]).
    pub fn rows(&self, rate: f64) -> RowPlan {
        // a period of a whole number of samples (to rounding, 10⁻¹²
        // relative: over 1000 periods of 10 s a phase error below 10⁻⁸ s):
        // the rows of period s ≥ 2 are at the phases of period 1's rows,
        // (s − 1)·N rows earlier
        let nf = self.periodic.duration() * rate;
        let per = nf.round();
        let period_rows = (self.periods > 1 && per >= 1.0 && (nf - per).abs() <= 1e-12 * per).then_some(per as usize);
        RowPlan { rate, period_rows }
    }

    /// Samples at `rate` Hz: t_k = k/rate from 0 up to the first grid point
    /// at or after the end (so the last row is home at rest).
    pub fn sample(&self, rate: f64) -> Result<DeliveredSamples> {
        if !(rate.is_finite() && rate > 0.0) {
            return Err(Error::invalid("sampling", "rate", format!("expected a positive rate in Hz, got {rate}")));
        }
        let steps = (self.duration() * rate - 1e-6).ceil().max(0.0);
        if steps + 1.0 > MAX_SAMPLES as f64 {
            return Err(Error::invalid(
                "sampling",
                "rate",
                format!(
                    "{rate} Hz over {:.1} s gives {} samples, more than the {MAX_SAMPLES} allowed",
                    self.duration(),
                    steps + 1.0
                ),
            ));
        }
        let m = steps as usize + 1;
        let n = self.home.len();
        let mut out = DeliveredSamples {
            rate,
            t: Vec::with_capacity(m),
            q: Vec::with_capacity(m),
            qd: Vec::with_capacity(m),
            qdd: Vec::with_capacity(m),
            segment: Vec::with_capacity(m),
            source: Vec::with_capacity(m),
        };
        let plan = self.rows(rate);
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for k in 0..m {
            let t = k as f64 / rate;
            let (seg, src) = plan.row(self, k);
            if src == k {
                let s = self.eval(t, &mut q, &mut qd, &mut qdd);
                debug_assert_eq!(s, seg);
                out.q.push(q.clone());
                out.qd.push(qd.clone());
                out.qdd.push(qdd.clone());
            } else {
                // bitwise the state of the row it repeats
                out.q.push(out.q[src].clone());
                out.qd.push(out.qd[src].clone());
                out.qdd.push(out.qdd[src].clone());
            }
            out.t.push(t);
            out.segment.push(seg);
            out.source.push(src);
        }
        Ok(out)
    }
}

/// Times this close to a part's boundary (s) belong to the part that
/// starts there ([`Delivered::eval`]): far below any controller's sample
/// interval, far above the rounding of sums of durations.
pub const BOUNDARY_TOL: f64 = 1e-9;

/// Largest number of samples a delivered trajectory is sampled into (about
/// 28 h at 1 kHz): bounds the memory before anything is allocated.
pub const MAX_SAMPLES: usize = 100_000_000;

/// The rows t_k = k/rate of a [`Delivered`] trajectory's grid
/// ([`Delivered::rows`]) and which of them repeat another.
///
/// When a period is a whole number N of samples (period × rate within 10⁻¹²
/// relative of an integer), the rows of period s ≥ 2 lie at the phases of
/// the rows of period 1, (s − 1)·N rows earlier: such a row takes that row's
/// state bitwise instead of evaluating the series at a phase that differs
/// from it only by rounding. So every period of trajectory.csv holds the
/// same numbers, and what is computed from a period's rows (limits,
/// collision distances, regressor rows) is computed once: a check of
/// period 1 is a check of every period, and the identifiability of the
/// delivered rows is that of the distinct rows counted with their
/// [`RowPlan::multiplicity`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowPlan {
    /// Sample rate (Hz).
    pub rate: f64,
    /// Rows per period when a period is a whole number of samples (and more
    /// than one period is played).
    pub period_rows: Option<usize>,
}

impl RowPlan {
    /// Segment of row k and the row whose state it takes: k itself, or the
    /// row (s − 1)·N earlier when row k is in period s ≥ 2 and that row is in
    /// period 1 (rows at a boundary, which rounding may put in a
    /// neighbouring segment, are evaluated).
    pub fn row(&self, d: &Delivered, k: usize) -> (i64, usize) {
        let seg = d.segment_at(k as f64 / self.rate);
        if let Some(n) = self.period_rows {
            if seg >= 2 {
                let shift = (seg as usize - 1) * n;
                if let Some(k1) = k.checked_sub(shift) {
                    if d.segment_at(k1 as f64 / self.rate) == 1 {
                        return (seg, k1);
                    }
                }
            }
        }
        (seg, k)
    }

    /// How many rows take row k's state (itself included; 0 when row k
    /// repeats another).
    pub fn multiplicity(&self, d: &Delivered, k: usize) -> usize {
        let (seg, src) = self.row(d, k);
        if src != k {
            return 0;
        }
        match (seg, self.period_rows) {
            (1, Some(n)) => {
                1 + (2..=d.periods)
                    .filter(|&s| {
                        let r = k + (s - 1) * n;
                        self.row(d, r) == (s as i64, k)
                    })
                    .count()
            }
            _ => 1,
        }
    }
}

/// A [`Delivered`] trajectory on a uniform grid, with the segment of every row.
#[derive(Debug, Clone, PartialEq)]
pub struct DeliveredSamples {
    /// Sample rate (Hz).
    pub rate: f64,
    /// Times (s), t_k = k / rate.
    pub t: Vec<f64>,
    /// Positions per sample.
    pub q: Vec<Vec<f64>>,
    /// Velocities per sample.
    pub qd: Vec<Vec<f64>>,
    /// Accelerations per sample.
    pub qdd: Vec<Vec<f64>>,
    /// Segment per sample: 0 lead-in, k period k, −1 lead-out.
    pub segment: Vec<i64>,
    /// Per sample, the sample whose state it repeats bitwise (its own index
    /// unless it lies in period 2 or later of a period of a whole number of
    /// samples: [`RowPlan`]).
    pub source: Vec<usize>,
}

impl DeliveredSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Writes `t, q1..qn, qd1..qdn, qdd1..qddn, segment` (the layout
    /// `idexp assess` and [`crate::io::States::read`] read; `segment` is an
    /// extra column they ignore).
    pub fn write_csv(&self, path: &std::path::Path) -> Result<()> {
        let n = self.q.first().map_or(0, |v| v.len());
        let mut header: Vec<String> = vec!["t".into()];
        for p in ["q", "qd", "qdd"] {
            header.extend((1..=n).map(|j| format!("{p}{j}")));
        }
        header.push("segment".into());
        use std::fmt::Write as _;
        let state = |k: usize, s: &mut String| {
            for b in [&self.q[k], &self.qd[k], &self.qdd[k]] {
                for v in b {
                    let _ = write!(s, ",{v}");
                }
            }
        };
        // the text of the rows others repeat ([`Self::source`]), formatted
        // once: the same bytes as formatting each repetition
        let (lo, hi) = self
            .source
            .iter()
            .enumerate()
            .filter(|&(k, &src)| src != k)
            .fold((usize::MAX, 0), |(lo, hi), (_, &src)| (lo.min(src), hi.max(src + 1)));
        let repeated: Vec<String> = {
            use rayon::prelude::*;
            (lo..hi.max(lo))
                .into_par_iter()
                .map(|k| {
                    let mut s = String::new();
                    state(k, &mut s);
                    s
                })
                .collect()
        };
        let s = crate::io::csv_text(&header.join(","), self.len(), |k, s| {
            let _ = write!(s, "{}", self.t[k]);
            let src = self.source.get(k).copied().unwrap_or(k);
            match repeated.get(src.wrapping_sub(lo)) {
                Some(text) => s.push_str(text),
                None => state(k, s),
            }
            let _ = writeln!(s, ",{}", self.segment[k]);
        });
        crate::io::write_atomic(path, s.as_bytes())
    }
}
