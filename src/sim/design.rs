//! The simulation design file (`idexp simulate design.toml`): robot, truth,
//! controller, noise, reference, payload, what is recorded; serde with
//! defaults, `deny_unknown_fields`, and `validate()` naming the field.

use crate::error::{Error, Result};
use crate::trajectory::ReferenceSpec;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A scalar for every joint or one value per joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerJoint {
    /// The same value for all joints.
    All(f64),
    /// One value per joint.
    Each(Vec<f64>),
}

impl Default for PerJoint {
    fn default() -> Self {
        PerJoint::All(0.0)
    }
}

impl PerJoint {
    /// Checks that every value is finite and ≥ 0 (the joint count is checked by [`PerJoint::resolve`]).
    pub fn check(&self, ctx: &str, field: &str) -> Result<()> {
        let v: &[f64] = match self {
            PerJoint::All(x) => std::slice::from_ref(x),
            PerJoint::Each(v) => v,
        };
        if let Some(i) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
            return Err(Error::invalid(ctx, field, format!("value {} must be finite and ≥ 0, got {}", i + 1, v[i])));
        }
        Ok(())
    }

    /// The values for `n` joints, or an error naming `field`.
    pub fn resolve(&self, n: usize, ctx: &str, field: &str) -> Result<Vec<f64>> {
        let v = match self {
            PerJoint::All(x) => vec![*x; n],
            PerJoint::Each(v) => {
                if v.len() != n {
                    return Err(Error::invalid(
                        ctx,
                        field,
                        format!("expected one value or {n} values (one per joint), got {}", v.len()),
                    ));
                }
                v.clone()
            }
        };
        if let Some(i) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
            return Err(Error::invalid(ctx, field, format!("value {} must be finite and ≥ 0, got {}", i + 1, v[i])));
        }
        Ok(v)
    }
}

/// How the true parameters differ from the robot file's nominal ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TruthSpec {
    /// Relative standard deviation of the perturbation (0 = nominal parameters).
    /// Masses, principal inertias about the centre of mass, rotor inertias and
    /// friction coefficients are scaled by (1 + ε z), z ~ N(0, 1) (clamped to
    /// stay ≥ 20 % of nominal); centres of mass move by ε·max(|c|, 2 cm)·z⃗, so
    /// the true parameters stay physically consistent.
    pub perturbation: f64,
    /// Seed of the perturbation (default: the design seed).
    pub seed: Option<u64>,
}

impl Default for TruthSpec {
    fn default() -> Self {
        TruthSpec { perturbation: 0.0, seed: None }
    }
}

/// Model feedforward of the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Feedforward {
    /// None: pure feedback.
    None,
    /// Gravity torques of the nominal model at the reference.
    Gravity,
    /// Full inverse dynamics (with friction) of the nominal model at the reference.
    Nominal,
}

/// Joint controller (design section `[controller]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerSpec {
    /// Include an integral term (PID) instead of PD.
    pub integral: bool,
    /// Closed-loop bandwidth for the default gains (Hz).
    pub bandwidth: f64,
    /// Damping ratio for the default gains.
    pub damping: f64,
    /// Explicit proportional gains (N·m/rad), overriding the default.
    pub kp: Option<PerJoint>,
    /// Explicit derivative gains (N·m·s/rad).
    pub kd: Option<PerJoint>,
    /// Explicit integral gains (N·m/(rad·s)).
    pub ki: Option<PerJoint>,
    /// Feedforward.
    pub feedforward: Feedforward,
    /// Cut-off of the first-order low-pass on the differentiated encoder signal (Hz, 0 = none).
    pub velocity_filter: f64,
}

impl Default for ControllerSpec {
    fn default() -> Self {
        ControllerSpec {
            integral: false,
            bandwidth: 5.0,
            damping: 1.0,
            kp: None,
            kd: None,
            ki: None,
            feedforward: Feedforward::Nominal,
            velocity_filter: 100.0,
        }
    }
}

/// Noise and quantisation (design section `[noise]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseSpec {
    /// Standard deviation of the torque measurement noise (N·m).
    pub torque: PerJoint,
    /// Standard deviation of the position measurement noise (rad), fed back through the controller.
    pub position: PerJoint,
    /// Encoder counts per revolution (0 = no quantisation); step 2π/counts.
    pub encoder_counts: f64,
    /// Standard deviation of the unmeasured torque disturbance at the plant input (N·m).
    pub disturbance: PerJoint,
    /// Standard deviation of the drive's logged velocity (rad/s or m/s; with
    /// `record_velocity = true`; default [`DRIVE_VELOCITY_NOISE`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub velocity: Option<PerJoint>,
}

/// Default noise of a logged drive velocity (rad/s): the quantisation of a
/// velocity taken from a 2²⁰-count motor encoder through a 100:1 gear over a
/// 1 ms logging period, 2π/(2²⁰·100·1 ms) = 6.0e-5 rad/s per count, whose
/// uniform rounding error has σ = 6.0e-5/√12 = 1.7e-5 rad/s (simulated as
/// white Gaussian noise of that σ).
pub const DRIVE_VELOCITY_NOISE: f64 = 1.7e-5;

/// A simulation design file (`idexp simulate <design.toml>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimDesign {
    /// Name (output folder `out/<name>`; default: the file stem).
    #[serde(default)]
    pub name: Option<String>,
    /// Robot file (relative to the design file).
    pub robot: PathBuf,
    /// True parameters.
    #[serde(default)]
    pub truth: TruthSpec,
    /// Controller.
    #[serde(default)]
    pub controller: ControllerSpec,
    /// Controller rate (Hz).
    #[serde(default = "default_rate")]
    pub rate: f64,
    /// RK4 steps per controller period.
    #[serde(default = "one")]
    pub substeps: usize,
    /// Record every k-th controller sample.
    #[serde(default = "one")]
    pub decimate: usize,
    /// Noise.
    #[serde(default)]
    pub noise: NoiseSpec,
    /// Repetitions N_r.
    #[serde(default = "default_reps")]
    pub repetitions: usize,
    /// Seed of every random draw.
    #[serde(default)]
    pub seed: u64,
    /// The reference motion.
    pub reference: ReferenceSpec,
    /// What the run files log of the drive input: `torque` (default,
    /// `tau*`), `current` (`cur*` only, i = τ/(s·k_t·N) with the robot
    /// file's torque_constant, gear_ratio and current_sign) or `both`.
    #[serde(default, skip_serializing_if = "Record::is_torque")]
    pub record: Record,
    /// Also log the drive's joint velocities `qd1..qdn` (the mean velocity
    /// over the controller period of each row's torque plus `noise.velocity`),
    /// as UR, KUKA, ABB and Franka controllers log the velocity of the motor
    /// encoder through the gear.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub record_velocity: bool,
    /// A payload the true robot carries (`[payload]`: frame, mass, com,
    /// inertia; [`crate::robot::payload::PayloadSpec`]); the controller's
    /// model (feedforward, gains) does not know it. Absent: no payload.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<crate::robot::payload::PayloadSpec>,
    /// The logged drive input (torques, currents) lags the logged positions
    /// by this time (s, a whole number of controller periods): each row logs
    /// the controller's torque of `drive_delay` earlier (a sensor chain's delay).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub drive_delay: f64,
    /// A constant offset per joint of the logged currents (A, logged minus
    /// true; `record = "current"` or `"both"`, whose torque columns carry it
    /// too): a drive's current-sensor offset. Absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_offset: Option<Vec<f64>>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// What a simulated run logs of the drive input (design key `record`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Record {
    /// Joint torques `tau1..taun` (with the torque noise).
    #[default]
    Torque,
    /// Motor currents `cur1..curn` (A): the noisy torque divided by s·k_t·N.
    Current,
    /// Both, consistent with each other.
    Both,
}

impl Record {
    fn is_torque(&self) -> bool {
        *self == Record::Torque
    }
}

fn default_rate() -> f64 {
    1000.0
}
fn one() -> usize {
    1
}
fn default_reps() -> usize {
    10
}

impl SimDesign {
    /// Reads and validates a design file.
    pub fn read(path: &Path) -> Result<SimDesign> {
        let d: SimDesign = crate::io::read_toml(path)?;
        d.validate(&path.display().to_string())?;
        Ok(d)
    }

    /// Checks ranges; `ctx` names the file in messages.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let pos = |f: &str, v: f64| -> Result<()> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(ctx, f, format!("expected a positive number, got {v}")))
            }
        };
        pos("rate", self.rate)?;
        if self.rate > MAX_RATE {
            return Err(Error::invalid(
                ctx,
                "rate",
                format!("{} Hz is above the largest controller rate {MAX_RATE} Hz", self.rate),
            ));
        }
        pos("controller.bandwidth", self.controller.bandwidth)?;
        pos("controller.damping", self.controller.damping)?;
        if !(self.controller.velocity_filter.is_finite() && self.controller.velocity_filter >= 0.0) {
            return Err(Error::invalid(ctx, "controller.velocity_filter", "expected a cut-off ≥ 0 Hz (0 = no filter)"));
        }
        if self.controller.velocity_filter > 0.5 * self.rate {
            return Err(Error::invalid(
                ctx,
                "controller.velocity_filter",
                format!(
                    "{} Hz is above the Nyquist frequency {} Hz of the controller rate; expected 0 (no filter) or a cut-off in (0, {}] Hz",
                    self.controller.velocity_filter,
                    0.5 * self.rate,
                    0.5 * self.rate
                ),
            ));
        }
        if self.controller.bandwidth * 10.0 > self.rate {
            return Err(Error::invalid(
                ctx,
                "controller.bandwidth",
                format!(
                    "{} Hz is too close to the controller rate {} Hz (keep it below rate/10)",
                    self.controller.bandwidth, self.rate
                ),
            ));
        }
        if self.substeps == 0 || self.substeps > 100 {
            return Err(Error::invalid(ctx, "substeps", "expected 1..=100"));
        }
        if self.decimate == 0 {
            return Err(Error::invalid(ctx, "decimate", "expected ≥ 1"));
        }
        let k = self.drive_delay * self.rate;
        if !(k.is_finite() && k >= 0.0 && (k - k.round()).abs() < 1e-6 && k <= 1000.0) {
            return Err(Error::invalid(
                ctx,
                "drive_delay",
                format!("{} s: expected 0 … 1000 whole controller periods of {} s", self.drive_delay, 1.0 / self.rate),
            ));
        }
        if let Some(v) = &self.current_offset {
            if self.record == Record::Torque {
                return Err(Error::invalid(
                    ctx,
                    "current_offset",
                    "offsets of the logged currents need record = \"current\" or \"both\"",
                ));
            }
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(Error::invalid(ctx, "current_offset", format!("expected finite offsets in A, found {x}")));
            }
        }
        if self.repetitions == 0 || self.repetitions > 10_000 {
            return Err(Error::invalid(ctx, "repetitions", "expected 1..=10000"));
        }
        if !(self.truth.perturbation.is_finite() && (0.0..=1.0).contains(&self.truth.perturbation)) {
            return Err(Error::invalid(ctx, "truth.perturbation", "expected a relative standard deviation in [0, 1]"));
        }
        self.noise.torque.check(ctx, "noise.torque")?;
        self.noise.position.check(ctx, "noise.position")?;
        self.noise.disturbance.check(ctx, "noise.disturbance")?;
        if let Some(v) = &self.noise.velocity {
            v.check(ctx, "noise.velocity")?;
            if !self.record_velocity {
                return Err(Error::invalid(
                    ctx,
                    "noise.velocity",
                    "the noise of the logged drive velocities, but no velocities are logged: add record_velocity = true (or drop noise.velocity)",
                ));
            }
        }
        for (f, v) in [
            ("controller.kp", &self.controller.kp),
            ("controller.kd", &self.controller.kd),
            ("controller.ki", &self.controller.ki),
        ] {
            if let Some(v) = v {
                v.check(ctx, f)?;
            }
        }
        if !(self.noise.encoder_counts.is_finite() && self.noise.encoder_counts >= 0.0) {
            return Err(Error::invalid(ctx, "noise.encoder_counts", "expected counts per revolution ≥ 0 (0 = none)"));
        }
        self.reference.validate(ctx)
    }
}

/// The largest controller rate of a simulation (Hz).
pub const MAX_RATE: f64 = 100_000.0;
/// The most controller steps of a simulation (all repetitions): 2·10⁷
/// (at 1 kHz, 5.5 hours of motion; the recorded run is at most this many rows).
pub const MAX_STEPS: f64 = 2.0e7;
