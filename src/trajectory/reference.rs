//! Reference motions for the simulators and the identification experiments
//! (and for real robots: the simulator writes every reference it plays as a
//! `t, q, qd, qdd` CSV).
//!
//! * a Fourier trajectory (paper 000 eq. 6, paper 002 eq. 17–19): from a
//!   `coefficients.json` written by `idexp excite`, inline in the design, or a
//!   random band-limited one scaled into the joint limits;
//! * a sampled trajectory (`t, q[, qd, qdd]` CSV; missing derivatives are
//!   computed by central differences);
//! * process motions of paper 000 §III-B: **pick-and-place** between two
//!   Cartesian areas (random points, joint-space minimum-jerk moves, dwell) and
//!   tracing a horizontal **square** with the end effector (position inverse
//!   kinematics by damped least squares);
//! * the dedicated experiments of paper 002 §3.2: **gravity slopes** (one joint
//!   at constant velocity ±v over a range, the others at rest) and
//!   **bang-bang** acceleration (one joint, triangular velocity profiles of
//!   several peak velocities in both directions).

use super::differentiate::differentiate;
pub use super::process::ik_position;
use super::process::{ee_frame, home, joint_index, min_jerk, piecewise_acceleration, via_points};
use super::FourierTrajectory;
use crate::error::{Error, Result};
use crate::io::States;
use crate::robot::{Robot, Workspace};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A box in Cartesian space (m, base frame): centre ± half_size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Area {
    /// Centre (x, y, z).
    pub center: [f64; 3],
    /// Half extents along x, y, z (≥ 0).
    pub half_size: [f64; 3],
}

/// The reference the controller tracks (design-file section `[reference]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ReferenceSpec {
    /// A Fourier trajectory from JSON (`coefficients.json` of `idexp excite`, or a bare trajectory).
    Fourier {
        /// Path (relative to the design file).
        file: PathBuf,
    },
    /// A Fourier trajectory given inline.
    FourierInline {
        /// The trajectory (omega, q0, a, b).
        #[serde(flatten)]
        trajectory: FourierTrajectory,
    },
    /// A random Fourier trajectory (uniform coefficients / k), scaled so that its
    /// analytic bounds use `amplitude` of the half range, velocity and acceleration limits.
    RandomFourier {
        /// Harmonics n_h.
        #[serde(default = "default_nh")]
        n_h: usize,
        /// Base frequency (Hz).
        #[serde(default = "default_f0")]
        frequency: f64,
        /// Fraction (0, 1] of the limits used.
        #[serde(default = "default_amp")]
        amplitude: f64,
        /// Offsets (default: middle of the joint ranges).
        #[serde(default)]
        q0: Option<Vec<f64>>,
        /// Seed of the coefficients.
        #[serde(default)]
        seed: u64,
    },
    /// A sampled trajectory CSV: `t, q1..qn` and optionally `qd*`, `qdd*`.
    States {
        /// Path (relative to the design file).
        file: PathBuf,
        /// The trajectory is one period of a periodic motion (as `idexp excite` writes).
        #[serde(default = "yes")]
        periodic: bool,
    },
    /// Pick-and-place between two areas (paper 000, process 1).
    PickAndPlace {
        /// Pick area.
        area_a: Area,
        /// Place area.
        area_b: Area,
        /// Number of pick → place → pick cycles.
        #[serde(default = "default_cycles")]
        cycles: usize,
        /// Duration of one move (s).
        #[serde(default = "default_move")]
        move_time: f64,
        /// Rest at each point (s).
        #[serde(default = "default_dwell")]
        dwell: f64,
        /// Home configuration, the IK start (default: middle of the ranges).
        #[serde(default)]
        q_home: Option<Vec<f64>>,
        /// End-effector frame (default: the robot's end effector).
        #[serde(default)]
        frame: Option<String>,
        /// Seed of the random points.
        #[serde(default)]
        seed: u64,
    },
    /// The end effector traces a horizontal square (paper 000, process 2).
    Square {
        /// Centre of the square (m).
        center: [f64; 3],
        /// Side length (m).
        side: f64,
        /// Time per side (s).
        #[serde(default = "default_move")]
        side_time: f64,
        /// Laps.
        #[serde(default = "default_laps")]
        laps: usize,
        /// Home configuration, the IK start.
        #[serde(default)]
        q_home: Option<Vec<f64>>,
        /// End-effector frame.
        #[serde(default)]
        frame: Option<String>,
    },
    /// Gravity experiment of paper 002 §3.2.1: joint `joint` (1-based) moves from
    /// `from` to `to` at +velocity, then back at −velocity; the others stay at `q_rest`.
    GravitySlopes {
        /// Joint (1-based).
        joint: usize,
        /// Start of the range (rad).
        from: f64,
        /// End of the range (rad).
        to: f64,
        /// Constant speed (rad/s, > 0).
        velocity: f64,
        /// Acceleration of the blends at the ends (rad/s²).
        #[serde(default = "default_blend_acc")]
        acceleration: f64,
        /// Configuration of all joints (the moving one starts at `from`).
        q_rest: Vec<f64>,
    },
    /// Friction experiment of paper 002 §3.2.2: bang-bang acceleration of one joint
    /// (triangular velocity profiles up to each of `velocities`, both signs).
    BangBang {
        /// Joint (1-based).
        joint: usize,
        /// Acceleration magnitude (rad/s²).
        acceleration: f64,
        /// Peak velocities (rad/s, > 0).
        velocities: Vec<f64>,
        /// Configuration of all joints (the moving joint oscillates about its value).
        q_rest: Vec<f64>,
    },
}

fn default_nh() -> usize {
    5
}
fn default_f0() -> f64 {
    0.1
}
fn default_amp() -> f64 {
    0.5
}
fn yes() -> bool {
    true
}
fn default_cycles() -> usize {
    3
}
fn default_move() -> f64 {
    1.0
}
/// The longest move or dwell of a pick-and-place reference (s).
pub const MAX_SEGMENT_S: f64 = 3600.0;
/// The most pick-and-place cycles.
pub const MAX_CYCLES: usize = 100_000;
/// The most samples of a generated reference (one repetition).
pub const MAX_REFERENCE_SAMPLES: f64 = 2.0e7;

fn default_dwell() -> f64 {
    0.3
}
fn default_laps() -> usize {
    1
}
fn default_blend_acc() -> f64 {
    2.0
}

/// A reference signal the simulator can evaluate at any time.
#[derive(Debug, Clone)]
pub enum Reference {
    /// Analytic Fourier series (periodic).
    Fourier(FourierTrajectory),
    /// Samples on a uniform grid t_i = i·dt, linear interpolation of q, q̇, q̈.
    Sampled {
        /// Sample step (s).
        dt: f64,
        /// Positions.
        q: Vec<Vec<f64>>,
        /// Velocities.
        qd: Vec<Vec<f64>>,
        /// Accelerations.
        qdd: Vec<Vec<f64>>,
        /// Wraps around after the last sample (one period of a periodic motion).
        periodic: bool,
    },
}

impl Reference {
    /// Duration of one repetition (s): the period, or the length of the motion.
    pub fn duration(&self) -> f64 {
        match self {
            Reference::Fourier(f) => f.period(),
            Reference::Sampled { dt, q, periodic, .. } => {
                if *periodic {
                    q.len() as f64 * dt
                } else {
                    (q.len().saturating_sub(1)) as f64 * dt
                }
            }
        }
    }

    /// True for periodic references (simulated as one continuous run cut into periods).
    pub fn periodic(&self) -> bool {
        match self {
            Reference::Fourier(_) => true,
            Reference::Sampled { periodic, .. } => *periodic,
        }
    }

    /// The Fourier trajectory, if the reference is one.
    pub fn fourier(&self) -> Option<&FourierTrajectory> {
        match self {
            Reference::Fourier(f) => Some(f),
            _ => None,
        }
    }

    /// Number of joints.
    pub fn n_joints(&self) -> usize {
        match self {
            Reference::Fourier(f) => f.n_joints(),
            Reference::Sampled { q, .. } => q.first().map_or(0, |v| v.len()),
        }
    }

    /// Evaluates r, ṙ, r̈ at time t (periodic references wrap, others hold the ends).
    pub fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        match self {
            Reference::Fourier(f) => f.eval(t, q, qd, qdd),
            Reference::Sampled {
                dt,
                q: sq,
                qd: sqd,
                qdd: sqdd,
                periodic,
            } => {
                let m = sq.len();
                let x = t / dt;
                let (i0, i1, w) = if *periodic {
                    let xm = x.rem_euclid(m as f64);
                    let i0 = (xm.floor() as usize).min(m - 1);
                    (i0, (i0 + 1) % m, xm - i0 as f64)
                } else if x <= 0.0 {
                    (0, 0, 0.0)
                } else if x >= (m - 1) as f64 {
                    (m - 1, m - 1, 0.0)
                } else {
                    let i0 = x.floor() as usize;
                    (i0, i0 + 1, x - i0 as f64)
                };
                for j in 0..q.len() {
                    q[j] = sq[i0][j] * (1.0 - w) + sq[i1][j] * w;
                    qd[j] = sqd[i0][j] * (1.0 - w) + sqd[i1][j] * w;
                    qdd[j] = sqdd[i0][j] * (1.0 - w) + sqdd[i1][j] * w;
                }
                if !*periodic && (x < 0.0 || x > (m - 1) as f64) {
                    qd.iter_mut().for_each(|v| *v = 0.0);
                    qdd.iter_mut().for_each(|v| *v = 0.0);
                }
            }
        }
    }

    /// Samples one repetition at `rate` Hz as states (t from 0).
    pub fn sample(&self, rate: f64) -> States {
        let n_s = (self.duration() * rate).round() as usize + usize::from(!self.periodic());
        let n = self.n_joints();
        let mut s = States {
            t: Some(Vec::with_capacity(n_s)),
            q: Vec::with_capacity(n_s),
            qd: Vec::with_capacity(n_s),
            qdd: Vec::with_capacity(n_s),
        };
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for i in 0..n_s {
            let t = i as f64 / rate;
            self.eval(t, &mut q, &mut qd, &mut qdd);
            if let Some(tt) = s.t.as_mut() {
                tt.push(t);
            }
            s.q.push(q.clone());
            s.qd.push(qd.clone());
            s.qdd.push(qdd.clone());
        }
        s
    }

    /// Builds a sampled reference from positions on a uniform grid: velocities and
    /// accelerations by central differences (periodic wrap or one-sided at the ends).
    pub fn from_positions(dt: f64, q: Vec<Vec<f64>>, periodic: bool) -> Reference {
        let (qd, qdd) = differentiate(&q, dt, periodic);
        Reference::Sampled { dt, q, qd, qdd, periodic }
    }
}

fn resolve(base: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

pub(super) fn mid_range(robot: &Robot) -> Vec<f64> {
    robot
        .joints
        .iter()
        .map(|j| {
            let (lo, hi) = (j.limits.lower, j.limits.upper);
            if lo.is_finite() && hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                0.0
            }
        })
        .collect()
}

pub(super) fn check_len(ctx: &str, field: &str, v: &[f64], n: usize) -> Result<()> {
    if v.len() != n {
        return Err(Error::invalid(ctx, field, format!("expected {n} values (one per joint), got {}", v.len())));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(Error::invalid(ctx, format!("{field}[{i}]"), "expected a finite number"));
    }
    Ok(())
}

impl ReferenceSpec {
    /// Checks the fields that do not need the robot; `ctx` names the design file.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let pos = |f: &str, v: f64| -> Result<()> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(ctx, format!("reference.{f}"), format!("expected a positive number, got {v}")))
            }
        };
        match self {
            ReferenceSpec::Fourier { .. } | ReferenceSpec::States { .. } => Ok(()),
            ReferenceSpec::FourierInline { trajectory } => trajectory.validate(&format!("{ctx}: reference")),
            ReferenceSpec::RandomFourier { n_h, frequency, amplitude, .. } => {
                if *n_h == 0 {
                    return Err(Error::invalid(ctx, "reference.n_h", "expected at least one harmonic"));
                }
                pos("frequency", *frequency)?;
                if !(*amplitude > 0.0 && *amplitude <= 1.0) {
                    return Err(Error::invalid(
                        ctx,
                        "reference.amplitude",
                        format!("expected 0 < amplitude ≤ 1, got {amplitude}"),
                    ));
                }
                Ok(())
            }
            ReferenceSpec::PickAndPlace {
                area_a,
                area_b,
                cycles,
                move_time,
                dwell,
                ..
            } => {
                for (name, a) in [("area_a", area_a), ("area_b", area_b)] {
                    if a.center.iter().chain(&a.half_size).any(|v| !v.is_finite()) || a.half_size.iter().any(|v| *v < 0.0) {
                        return Err(Error::invalid(
                            ctx,
                            format!("reference.{name}"),
                            "expected finite centre and non-negative half sizes",
                        ));
                    }
                }
                if *cycles == 0 {
                    return Err(Error::invalid(ctx, "reference.cycles", "expected at least 1"));
                }
                pos("move_time", *move_time)?;
                if !(dwell.is_finite() && *dwell >= 0.0) {
                    return Err(Error::invalid(ctx, "reference.dwell", "expected a non-negative time"));
                }
                for (name, v) in [("move_time", *move_time), ("dwell", *dwell)] {
                    if v > MAX_SEGMENT_S {
                        return Err(Error::invalid(
                            ctx,
                            format!("reference.{name}"),
                            format!("{v} s is longer than the longest move or dwell, {MAX_SEGMENT_S} s"),
                        ));
                    }
                }
                if *cycles > MAX_CYCLES {
                    return Err(Error::invalid(ctx, "reference.cycles", format!("{cycles} cycles; expected 1..={MAX_CYCLES}")));
                }
                Ok(())
            }
            ReferenceSpec::Square {
                center, side, side_time, laps, ..
            } => {
                if center.iter().any(|v| !v.is_finite()) {
                    return Err(Error::invalid(ctx, "reference.center", "expected finite numbers"));
                }
                pos("side", *side)?;
                pos("side_time", *side_time)?;
                if *laps == 0 {
                    return Err(Error::invalid(ctx, "reference.laps", "expected at least 1"));
                }
                Ok(())
            }
            ReferenceSpec::GravitySlopes {
                from,
                to,
                velocity,
                acceleration,
                ..
            } => {
                pos("velocity", *velocity)?;
                pos("acceleration", *acceleration)?;
                if !(from.is_finite() && to.is_finite() && to > from) {
                    return Err(Error::invalid(ctx, "reference.to", format!("expected from < to, got {from} and {to}")));
                }
                let blend = velocity * velocity / acceleration;
                if blend >= to - from {
                    return Err(Error::invalid(
                        ctx,
                        "reference.acceleration",
                        format!(
                            "the blends need {blend:.3} rad, more than the range {:.3} rad: raise the acceleration or widen the range",
                            to - from
                        ),
                    ));
                }
                Ok(())
            }
            ReferenceSpec::BangBang { acceleration, velocities, .. } => {
                pos("acceleration", *acceleration)?;
                if velocities.is_empty() {
                    return Err(Error::invalid(ctx, "reference.velocities", "expected at least one peak velocity"));
                }
                for (i, v) in velocities.iter().enumerate() {
                    pos(&format!("velocities[{i}]"), *v)?;
                }
                Ok(())
            }
        }
    }

    /// Builds the reference for `robot`; relative paths are resolved against `base`
    /// (the design file's folder); `rate` (Hz) is the sampling of generated motions.
    pub fn build(&self, robot: &Robot, base: &Path, rate: f64, ctx: &str) -> Result<Reference> {
        let n = robot.dof();
        let dt = 1.0 / rate;
        let r = match self {
            ReferenceSpec::Fourier { file } => {
                let t = FourierTrajectory::load(&resolve(base, file))?;
                Reference::Fourier(t)
            }
            ReferenceSpec::FourierInline { trajectory } => Reference::Fourier(trajectory.clone()),
            ReferenceSpec::RandomFourier {
                n_h,
                frequency,
                amplitude,
                q0,
                seed,
            } => Reference::Fourier(random_fourier(robot, *n_h, *frequency, *amplitude, q0.clone(), *seed, ctx)?),
            ReferenceSpec::States { file, periodic } => {
                let path = resolve(base, file);
                states_reference(&path, n, *periodic)?
            }
            ReferenceSpec::PickAndPlace {
                area_a,
                area_b,
                cycles,
                move_time,
                dwell,
                q_home,
                frame,
                seed,
            } => {
                let home = home(robot, q_home, ctx)?;
                let fr = ee_frame(robot, frame, ctx)?;
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(*seed);
                let mut ws = Workspace::new(robot);
                let mut pts = vec![home.clone()];
                let mut cur = home.clone();
                for _ in 0..*cycles {
                    for area in [area_a, area_b] {
                        let target = Vector3::from_fn(|i, _| area.center[i] + area.half_size[i] * rng.random_range(-1.0..=1.0));
                        cur = ik_position(robot, &mut ws, &fr, &target, &cur).map_err(|e| Error::invalid(ctx, "reference", e))?;
                        pts.push(cur.clone());
                    }
                }
                pts.push(home);
                let samples = pts.len() as f64 * (*move_time + *dwell) * rate;
                if samples > MAX_REFERENCE_SAMPLES {
                    return Err(Error::invalid(
                        ctx,
                        "reference",
                        format!(
                            "{} points × ({move_time} s + {dwell} s) at {rate} Hz are {samples:.3e} samples; at most {MAX_REFERENCE_SAMPLES:.0e}",
                            pts.len()
                        ),
                    ));
                }
                let q = via_points(&pts, *move_time, *dwell, dt);
                Reference::from_positions(dt, q, false)
            }
            ReferenceSpec::Square {
                center,
                side,
                side_time,
                laps,
                q_home,
                frame,
            } => {
                let home = home(robot, q_home, ctx)?;
                let fr = ee_frame(robot, frame, ctx)?;
                let mut ws = Workspace::new(robot);
                let c = Vector3::from_column_slice(center);
                let h = side / 2.0;
                let corners = [
                    c + Vector3::new(-h, -h, 0.0),
                    c + Vector3::new(h, -h, 0.0),
                    c + Vector3::new(h, h, 0.0),
                    c + Vector3::new(-h, h, 0.0),
                ];
                let start = ik_position(robot, &mut ws, &fr, &corners[0], &home).map_err(|e| Error::invalid(ctx, "reference.center", e))?;
                // approach: home → first corner in joint space, then the square in Cartesian space
                let mut q = via_points(&[home.clone(), start.clone()], *side_time, 0.2, dt);
                let steps = (side_time / dt).round().max(2.0) as usize;
                let mut cur = start;
                for _ in 0..*laps {
                    for s in 0..4 {
                        let (p0, p1) = (corners[s], corners[(s + 1) % 4]);
                        for i in 1..=steps {
                            let u = min_jerk(i as f64 / steps as f64);
                            let target = p0 + (p1 - p0) * u;
                            cur = ik_position(robot, &mut ws, &fr, &target, &cur).map_err(|e| Error::invalid(ctx, "reference.side", e))?;
                            q.push(cur.clone());
                        }
                    }
                }
                let back = via_points(&[cur, home], *side_time, 0.2, dt);
                q.extend(back.into_iter().skip(1));
                Reference::from_positions(dt, q, false)
            }
            ReferenceSpec::GravitySlopes {
                joint,
                from,
                to,
                velocity,
                acceleration,
                q_rest,
            } => {
                let j = joint_index(*joint, n, ctx)?;
                check_len(ctx, "reference.q_rest", q_rest, n)?;
                let l = &robot.joints[j].limits;
                if *from < l.lower || *to > l.upper {
                    return Err(Error::invalid(
                        ctx,
                        "reference.from",
                        format!("the range [{from}, {to}] leaves the joint limits [{}, {}]", l.lower, l.upper),
                    ));
                }
                let mut acc: Vec<(f64, f64)> = Vec::new(); // (duration, acceleration) pieces
                let tb = velocity / acceleration;
                let tc = (to - from - velocity * tb) / velocity;
                for sgn in [1.0, -1.0] {
                    acc.push((tb, sgn * acceleration));
                    acc.push((tc, 0.0));
                    acc.push((tb, -sgn * acceleration));
                    acc.push((0.5, 0.0));
                }
                let mut start = q_rest.clone();
                start[j] = *from;
                piecewise_acceleration(&start, j, &acc, dt)
            }
            ReferenceSpec::BangBang {
                joint,
                acceleration,
                velocities,
                q_rest,
            } => {
                let j = joint_index(*joint, n, ctx)?;
                check_len(ctx, "reference.q_rest", q_rest, n)?;
                let mut acc = Vec::new();
                let mut excursion: f64 = 0.0;
                for &v in velocities {
                    let t1 = v / acceleration;
                    // +v triangle (moves +v²/a), −v triangle (moves back), about the start
                    acc.push((t1, *acceleration));
                    acc.push((t1, -acceleration));
                    acc.push((0.2, 0.0));
                    acc.push((t1, -acceleration));
                    acc.push((t1, *acceleration));
                    acc.push((0.2, 0.0));
                    excursion = excursion.max(v * v / acceleration);
                }
                let l = &robot.joints[j].limits;
                let start = q_rest.clone();
                if start[j] + excursion > l.upper || start[j] < l.lower {
                    return Err(Error::invalid(
                        ctx,
                        "reference.velocities",
                        format!(
                            "joint {} would reach {:.3} rad, beyond its upper limit {}: lower the peak velocities or raise the acceleration",
                            j + 1,
                            start[j] + excursion,
                            l.upper
                        ),
                    ));
                }
                piecewise_acceleration(&start, j, &acc, dt)
            }
        };
        if r.n_joints() != n {
            return Err(Error::invalid(
                ctx,
                "reference",
                format!("the reference has {} joints, the robot {n}", r.n_joints()),
            ));
        }
        Ok(r)
    }
}

fn states_reference(path: &Path, n: usize, periodic: bool) -> Result<Reference> {
    let t = crate::io::Table::read(path)?;
    let it = t.require("t")?;
    let iq = t.numbered("q", n)?;
    let times = t.column(it);
    if times.len() < 3 {
        return Err(Error::Data {
            path: path.into(),
            row: times.len(),
            column: "t".into(),
            msg: "a reference needs at least 3 samples".into(),
        });
    }
    let dt = (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64;
    for (i, w) in times.windows(2).enumerate() {
        if dt.is_nan() || dt <= 0.0 || ((w[1] - w[0]) - dt).abs() > 1e-6 * dt.max(1e-9) + 1e-9 {
            return Err(Error::Data {
                path: path.into(),
                row: i + 2,
                column: "t".into(),
                msg: format!("expected uniform time steps of {dt} s, found {}", w[1] - w[0]),
            });
        }
    }
    let q: Vec<Vec<f64>> = t.rows.iter().map(|r| iq.iter().map(|&i| r[i]).collect()).collect();
    let has_d = t.index("qd1").is_some() && t.index("qdd1").is_some();
    if has_d {
        let s = States::from_table(&t, n)?;
        Ok(Reference::Sampled {
            dt,
            q: s.q,
            qd: s.qd,
            qdd: s.qdd,
            periodic,
        })
    } else {
        Ok(Reference::from_positions(dt, q, periodic))
    }
}

/// A random Fourier trajectory: a_k, b_k uniform in [−1, 1]/k, scaled so that
/// the analytic bounds use `amp` of the half range (about q0), of the velocity
/// limit (2 rad/s if unlimited) and of the acceleration limit (10 rad/s² if unlimited).
pub fn random_fourier(robot: &Robot, n_h: usize, f0: f64, amp: f64, q0: Option<Vec<f64>>, seed: u64, ctx: &str) -> Result<FourierTrajectory> {
    let n = robot.dof();
    let q0 = match q0 {
        Some(q) => {
            check_len(ctx, "reference.q0", &q, n)?;
            q
        }
        None => mid_range(robot),
    };
    let omega = std::f64::consts::TAU * f0;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut a = vec![vec![0.0; n_h]; n];
    let mut b = vec![vec![0.0; n_h]; n];
    for j in 0..n {
        for k in 0..n_h {
            a[j][k] = rng.random_range(-1.0..=1.0) / (k + 1) as f64;
            b[j][k] = rng.random_range(-1.0..=1.0) / (k + 1) as f64;
        }
    }
    let mut t = FourierTrajectory::new(omega, q0.clone(), a, b)?;
    let bounds = t.amplitude_bounds();
    for j in 0..n {
        let l = &robot.joints[j].limits;
        let half = if l.lower.is_finite() && l.upper.is_finite() {
            (q0[j] - l.lower).min(l.upper - q0[j])
        } else {
            std::f64::consts::PI
        };
        if half <= 0.0 {
            return Err(Error::invalid(ctx, "reference.q0", format!("joint {} is at or beyond its limits", j + 1)));
        }
        let vmax = if l.velocity.is_finite() { l.velocity } else { 2.0 };
        let amax = if l.acceleration.is_finite() { l.acceleration } else { 10.0 };
        let s = (amp * half / bounds[j][0]).min(amp * vmax / bounds[j][1]).min(amp * amax / bounds[j][2]);
        for k in 0..n_h {
            t.a[j][k] *= s;
            t.b[j][k] *= s;
        }
    }
    Ok(t)
}
