//! Closed-loop rigid-body simulation: a robot with "true" parameters (the
//! nominal ones of a robot file, optionally perturbed) tracks a reference under
//! a joint PD/PID controller with model feedforward, at a controller rate,
//! with the friction model, measurement noise on torques and positions,
//! encoder quantisation, an unmeasured torque disturbance at the plant input,
//! and N repetitions. It writes runs in the format `idexp identify` reads
//! (see [`crate::data::run`]) and is the data source of the identification tests.
//!
//! # The loop (per controller period Δt = 1/rate)
//!
//! * measured position q_m = Q(q + n_q), n_q ~ N(0, σ_q²), Q the encoder
//!   quantiser (step 2π/counts);
//! * velocity estimate v = LP(Δq_m/Δt), a first-order low-pass (cut-off
//!   `velocity_filter`, Hz), so position noise is fed back through the controller;
//! * torque command τ = τ_ff(r, ṙ, r̈) + K_p (r − q_m) + K_d (ṙ − v) + K_i ∫(r − q_m),
//!   τ_ff the inverse dynamics of the **nominal** model (or its gravity part, or none);
//! * the plant (true parameters) integrates (q, q̇) over Δt with RK4 (`substeps`
//!   steps) under τ + d, d ~ N(0, σ_d²) held over the period (unmeasured disturbance);
//! * recorded: t, q_m, τ + n_τ (n_τ ~ N(0, σ_τ²), the torque measurement), r;
//!   with `record_velocity = true` also the drive's velocity as `qd1..qdn`:
//!   (q(t_k + Δt) − q(t_k))/Δt + n_v, the mean velocity over the controller
//!   period in which the row's torque acts (what a drive differentiating its
//!   motor encoder reports at the end of that period, put on the row of the
//!   command), n_v ~ N(0, σ_v²) (`noise.velocity`, default [`DRIVE_VELOCITY_NOISE`]).
//!
//! Default gains place each joint at `bandwidth` Hz with damping `damping`
//! using the diagonal of the nominal mass matrix at the start:
//! K_p = M_jj ω², K_d = 2 ζ M_jj ω, K_i = 0 (PD) or K_p ω / 10 (PID).
//!
//! Periodic references are simulated as one continuous run (a lead-in period,
//! then N periods cut into repetitions); other references (process motions,
//! dedicated experiments) start each repetition at rest at r(0). Every random
//! draw comes from `ChaCha8Rng::seed_from_u64(seed ⊕ index)` per period or repetition.

use crate::data::Repetition;
pub use crate::data::Truth;
use crate::error::{Error, Result};
use crate::optim::Control;
use crate::params::{BaseOptions, BaseParams};
use crate::robot::{gravity, inverse_dynamics, mass_matrix, Inertial, ParamKind, Robot, Workspace};
pub use crate::trajectory::{Reference, ReferenceSpec};
use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

mod design;
pub use design::*;

/// Everything the simulation loop needs, resolved for one robot.
#[derive(Debug, Clone)]
pub struct SimSetup {
    /// The nominal model (controller feedforward, default gains).
    pub nominal: Robot,
    /// The plant: the robot with the true parameters.
    pub truth: Robot,
    /// The reference.
    pub reference: Reference,
    /// Controller rate (Hz).
    pub rate: f64,
    /// RK4 substeps per period.
    pub substeps: usize,
    /// Record every k-th sample.
    pub decimate: usize,
    /// Gains K_p, K_d, K_i (n each).
    pub kp: Vec<f64>,
    /// Derivative gains.
    pub kd: Vec<f64>,
    /// Integral gains.
    pub ki: Vec<f64>,
    /// Feedforward.
    pub feedforward: Feedforward,
    /// Velocity filter cut-off (Hz, 0 = none).
    pub velocity_filter: f64,
    /// Torque noise σ_τ per joint.
    pub torque_noise: Vec<f64>,
    /// Position noise σ_q per joint.
    pub position_noise: Vec<f64>,
    /// Disturbance σ_d per joint.
    pub disturbance: Vec<f64>,
    /// σ_v of the logged drive velocities per joint, when they are logged.
    pub velocity_noise: Option<Vec<f64>>,
    /// Quantisation step (rad; 0 = none).
    pub quantum: f64,
    /// Repetitions.
    pub repetitions: usize,
    /// Seed.
    pub seed: u64,
    /// Controller periods by which the logged torques lag the positions (design key `drive_delay`).
    pub drive_delay: usize,
    /// Per joint, the logged currents' offset as a torque (N·m): design key
    /// `current_offset` (A) times the robot file's s·k_t·N; zeros without it.
    pub torque_offset: Vec<f64>,
}

/// Controller periods between two polls of the run control inside a
/// repetition (at 10 kHz with 4 RK4 substeps, well under 0.1 s of work).
pub const POLL_STEPS: usize = 64;

/// A stretch of controller periods: `steps` periods counted from `k0`,
/// recorded with times relative to `t_rec0`.
#[derive(Debug, Clone, Copy)]
struct Span {
    k0: usize,
    steps: usize,
    t_rec0: f64,
    /// Index of the period or repetition (0: lead-in): seeds the stream of
    /// the logged-velocity noise, separate from the loop's draws so that
    /// logging velocities leaves q and τ of the run unchanged.
    stream: u64,
}

/// Whether a simulation ran all its repetitions (serialised `complete` /
/// `interrupted`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunStatus {
    /// Every repetition was simulated.
    Complete,
    /// The run control stopped it; the repetitions written are the first ones, complete.
    Interrupted,
}

impl std::fmt::Display for RunStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RunStatus::Complete => "complete",
            RunStatus::Interrupted => "interrupted",
        })
    }
}

/// Outcome of a simulation.
#[derive(Debug, Clone, Serialize)]
pub struct SimStatus {
    /// `complete` or `interrupted`.
    pub status: RunStatus,
    /// Repetitions produced.
    pub repetitions: usize,
    /// Largest |r − q| per joint over the recorded data (rad).
    pub max_tracking_error: Vec<f64>,
    /// RMS of r − q per joint (rad).
    pub rms_tracking_error: Vec<f64>,
    /// Proportional gains used.
    pub kp: Vec<f64>,
    /// Derivative gains used.
    pub kd: Vec<f64>,
    /// Integral gains used.
    pub ki: Vec<f64>,
}

/// A finished simulation: the repetitions and what produced them.
#[derive(Debug, Clone)]
pub struct SimResult {
    /// Recorded repetitions.
    pub reps: Vec<Repetition>,
    /// The setup.
    pub setup: SimSetup,
    /// The status.
    pub status: SimStatus,
}

/// True standard parameters: the nominal ones perturbed as described in [`TruthSpec`].
pub fn perturb_params(robot: &Robot, rel: f64, seed: u64) -> Vec<f64> {
    let th = robot.nominal_params();
    if rel == 0.0 {
        return th.as_slice().to_vec();
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x7275_7468);
    let normal = Normal::new(0.0, 1.0).expect("unit normal");
    let mut z = || -> f64 { normal.sample(&mut rng) };
    let mut out = th.as_slice().to_vec();
    let info = robot.params().to_vec();
    for i in 0..robot.dof() {
        let o = robot.link_param_offset(i);
        let ine = Inertial::from_params(&th.as_slice()[o..o + 10]);
        let scale = |x: f64, z: f64| x * (1.0 + rel * z).max(0.2);
        if ine.mass > 0.0 {
            let c = ine.first_moment / ine.mass;
            let ic = ine.inertia - ine.mass * (c.norm_squared() * Matrix3::identity() - c * c.transpose());
            let m = scale(ine.mass, z());
            let step = rel * c.norm().max(0.02);
            let c2 = c + Vector3::new(z(), z(), z()) * step;
            let s = Matrix3::from_diagonal(&Vector3::new(
                (1.0 + rel * z()).max(0.45),
                (1.0 + rel * z()).max(0.45),
                (1.0 + rel * z()).max(0.45),
            ));
            let ic2 = s * ic * s;
            let p = Inertial::from_com(m, c2, ic2, Matrix3::identity()).to_params();
            out[o..o + 10].copy_from_slice(&p);
        } else {
            // massless link (only a rotational inertia): scale the inertia
            let f = (1.0 + rel * z()).max(0.2);
            for k in 0..6 {
                out[o + k] *= f;
            }
        }
    }
    for (k, p) in info.iter().enumerate() {
        if !p.kind.is_inertial() {
            let f = (1.0 + rel * z()).max(0.2);
            if matches!(p.kind, ParamKind::F0) {
                out[k] += rel * z() * out[k].abs().max(0.1);
            } else {
                out[k] *= f;
            }
        }
    }
    out
}

impl SimSetup {
    /// Resolves a design: loads the robot, draws the true parameters, builds the
    /// reference and the gains. `base` is the design file's folder.
    pub fn from_design(d: &SimDesign, base: &Path, ctx: &str) -> Result<SimSetup> {
        // the robot path: relative to `base` (the design file's folder on the command line), checked
        let nominal = crate::robot::load(&crate::io::path_in(ctx, base, "robot", &d.robot)?)?;
        let n = nominal.dof();
        if d.record != Record::Torque {
            if let Some(j) = nominal.drives.iter().position(|dr| dr.torque_constant.is_none()) {
                return Err(Error::invalid(
                    ctx,
                    "record",
                    format!(
                        "logging currents needs the torque constant of every drive, but joint `{}` of the robot file {} has none: add torque_constant = k_t (N·m/A) to its [[drive]] entry, or record = \"torque\"",
                        nominal.joints[j].name,
                        resolve(base, &d.robot).display()
                    ),
                ));
            }
        }
        let theta = perturb_params(&nominal, d.truth.perturbation, d.truth.seed.unwrap_or(d.seed));
        let truth = nominal.with_params(&theta)?;
        let truth = match &d.payload {
            Some(p) => {
                let (mount, payload) = crate::robot::payload::resolve(&nominal, p, ctx, "payload")?;
                mount.attach(&truth, &payload.params())?
            }
            None => truth,
        };
        let reference = d.reference.build(&nominal, base, d.rate, ctx)?;
        let mut ws = Workspace::new(&nominal);
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        reference.eval(0.0, &mut q, &mut qd, &mut qdd);
        let m = mass_matrix(&nominal, &mut ws, &q);
        let w = std::f64::consts::TAU * d.controller.bandwidth;
        let mjj: Vec<f64> = (0..n).map(|j| m[(j, j)].max(1e-6)).collect();
        let kp = match &d.controller.kp {
            Some(v) => v.resolve(n, ctx, "controller.kp")?,
            None => mjj.iter().map(|m| m * w * w).collect(),
        };
        let kd = match &d.controller.kd {
            Some(v) => v.resolve(n, ctx, "controller.kd")?,
            None => mjj.iter().map(|m| 2.0 * d.controller.damping * m * w).collect(),
        };
        let ki = match &d.controller.ki {
            Some(v) => v.resolve(n, ctx, "controller.ki")?,
            None if d.controller.integral => kp.iter().map(|k| k * w / 10.0).collect(),
            None => vec![0.0; n],
        };
        let quantum = if d.noise.encoder_counts > 0.0 {
            std::f64::consts::TAU / d.noise.encoder_counts
        } else {
            0.0
        };
        let steps = reference.duration() * d.rate * d.repetitions as f64;
        if !(steps.is_finite() && steps <= MAX_STEPS) {
            return Err(Error::invalid(
                ctx,
                "rate",
                format!(
                    "{} repetitions of {} s at {} Hz are {steps:.3e} controller steps; at most {MAX_STEPS:.0e} are simulated (lower the rate, the duration or the repetitions)",
                    d.repetitions,
                    reference.duration(),
                    d.rate
                ),
            ));
        }
        if reference.periodic() {
            let p = reference.duration() * d.rate;
            if (p - p.round()).abs() > 1e-6 * p.max(1.0) {
                return Err(Error::invalid(
                    ctx,
                    "rate",
                    format!(
                        "the reference period {} s is not a whole number of controller periods at {} Hz",
                        reference.duration(),
                        d.rate
                    ),
                ));
            }
            if (p.round() as usize) % d.decimate != 0 {
                return Err(Error::invalid(ctx, "decimate", "the period must be a whole number of recorded samples"));
            }
        }
        let torque_offset = match &d.current_offset {
            None => vec![0.0; n],
            Some(v) if v.len() != n => {
                return Err(Error::invalid(
                    ctx,
                    "current_offset",
                    format!("{} offsets for the {n} joints of {}", v.len(), nominal.name),
                ));
            }
            // record ≠ torque (validated): every drive has its torque constant (checked above)
            Some(v) => v.iter().zip(&nominal.drives).map(|(o, dr)| o * dr.torque_per_ampere().unwrap_or(0.0)).collect(),
        };
        Ok(SimSetup {
            torque_offset,
            torque_noise: d.noise.torque.resolve(n, ctx, "noise.torque")?,
            position_noise: d.noise.position.resolve(n, ctx, "noise.position")?,
            disturbance: d.noise.disturbance.resolve(n, ctx, "noise.disturbance")?,
            velocity_noise: match (d.record_velocity, &d.noise.velocity) {
                (false, _) => None,
                (true, None) => Some(vec![DRIVE_VELOCITY_NOISE; n]),
                (true, Some(v)) => Some(v.resolve(n, ctx, "noise.velocity")?),
            },
            nominal,
            truth,
            reference,
            rate: d.rate,
            substeps: d.substeps,
            decimate: d.decimate,
            kp,
            kd,
            ki,
            feedforward: d.controller.feedforward,
            velocity_filter: d.controller.velocity_filter,
            quantum,
            repetitions: d.repetitions,
            seed: d.seed,
            drive_delay: (d.drive_delay * d.rate).round() as usize,
        })
    }
}

fn resolve(base: &Path, p: &Path) -> PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}

/// State of the closed loop carried from one controller period to the next.
struct Loop {
    q: Vec<f64>,
    qd: Vec<f64>,
    q_prev_meas: Vec<f64>,
    v_filt: Vec<f64>,
    integral: Vec<f64>,
    first: bool,
    /// The last `drive_delay + 1` controller torques, newest last.
    past: std::collections::VecDeque<Vec<f64>>,
}

impl SimSetup {
    fn new_loop(&self) -> Loop {
        let n = self.truth.dof();
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        self.reference.eval(0.0, &mut q, &mut qd, &mut qdd);
        Loop {
            q_prev_meas: q.clone(),
            v_filt: qd.clone(),
            integral: vec![0.0; n],
            q,
            qd,
            first: true,
            past: std::collections::VecDeque::new(),
        }
    }

    /// Runs `span.steps` controller periods (counted from `span.k0`),
    /// recording every `decimate`-th sample with time `t - span.t_rec0`;
    /// `Ok(false)` when `ctl` asked to stop (polled every [`POLL_STEPS`] periods).
    fn run_steps(&self, lp: &mut Loop, span: Span, rng: &mut rand_chacha::ChaCha8Rng, record: Option<&mut Repetition>, ctl: &Control) -> Result<bool> {
        let Span { k0, steps, t_rec0, stream } = span;
        let mut vrng = rand_chacha::ChaCha8Rng::seed_from_u64(crate::rng::mix(self.seed, stream, 1));
        let n = self.truth.dof();
        let dt = 1.0 / self.rate;
        let mut ws_t = Workspace::new(&self.truth);
        let mut ws_n = Workspace::new(&self.nominal);
        let unit = Normal::new(0.0, 1.0).expect("unit normal");
        let (mut r, mut rd, mut rdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut ff = vec![0.0; n];
        let mut tau = vec![0.0; n];
        let mut qm = vec![0.0; n];
        let mut q_start = vec![0.0; n];
        let alpha = if self.velocity_filter > 0.0 {
            let wc = std::f64::consts::TAU * self.velocity_filter * dt;
            (-wc).exp()
        } else {
            0.0
        };
        let theta_nom = self.nominal.nominal_params();
        let mut rec = record;
        for s in 0..steps {
            if s % POLL_STEPS == 0 && ctl.should_stop() {
                return Ok(false);
            }
            let k = k0 + s;
            let t = k as f64 * dt;
            self.reference.eval(t, &mut r, &mut rd, &mut rdd);
            for j in 0..n {
                let mut x = lp.q[j] + self.position_noise[j] * unit.sample(rng);
                if self.quantum > 0.0 {
                    x = (x / self.quantum).round() * self.quantum;
                }
                qm[j] = x;
            }
            for j in 0..n {
                let v_raw = if lp.first { rd[j] } else { (qm[j] - lp.q_prev_meas[j]) / dt };
                lp.v_filt[j] = alpha * lp.v_filt[j] + (1.0 - alpha) * v_raw;
                lp.q_prev_meas[j] = qm[j];
            }
            lp.first = false;
            match self.feedforward {
                Feedforward::None => ff.iter_mut().for_each(|v| *v = 0.0),
                Feedforward::Gravity => {
                    let g = gravity(&self.nominal, &mut ws_n, &r);
                    ff.copy_from_slice(g.as_slice());
                    // gravity() is link side; with a coupling matrix the motor side is C⁻ᵀ g
                    if let Some(ct) = &self.nominal.coupling_inv_t {
                        let gm = ct * g;
                        ff.copy_from_slice(gm.as_slice());
                    }
                }
                Feedforward::Nominal => inverse_dynamics(&self.nominal, &mut ws_n, theta_nom.as_slice(), &r, &rd, &rdd, &mut ff),
            }
            for j in 0..n {
                let e = r[j] - qm[j];
                lp.integral[j] += e * dt;
                tau[j] = ff[j] + self.kp[j] * e + self.kd[j] * (rd[j] - lp.v_filt[j]) + self.ki[j] * lp.integral[j];
            }
            if lp.past.len() > self.drive_delay {
                lp.past.pop_front();
            }
            lp.past.push_back(tau.clone());
            if s % self.decimate == 0 {
                if let Some(rep) = rec.as_deref_mut() {
                    rep.t.push(t - t_rec0);
                    rep.q.push(qm.clone());
                    let logged = &lp.past[0]; // drive_delay periods ago (the oldest kept, at the start)
                    rep.tau.push(
                        (0..n)
                            .map(|j| logged[j] + self.torque_noise[j] * unit.sample(rng) + self.torque_offset[j])
                            .collect(),
                    );
                    if let Some(rr) = rep.r.as_mut() {
                        rr.push(r.clone());
                    }
                    if self.velocity_noise.is_some() {
                        q_start.copy_from_slice(&lp.q);
                    }
                }
            }
            // plant: RK4 under τ + d
            let drive: Vec<f64> = (0..n).map(|j| tau[j] + self.disturbance[j] * unit.sample(rng)).collect();
            let h = dt / self.substeps as f64;
            for _ in 0..self.substeps {
                rk4(&self.truth, &mut ws_t, &mut lp.q, &mut lp.qd, &drive, h)?;
            }
            // the drive's velocity: the motor-encoder difference over the period the row's torque acts in
            if s % self.decimate == 0 {
                if let (Some(rep), Some(sv)) = (rec.as_deref_mut(), &self.velocity_noise) {
                    if let Some(v) = rep.qd.as_mut() {
                        v.push((0..n).map(|j| (lp.q[j] - q_start[j]) / dt + sv[j] * unit.sample(&mut vrng)).collect());
                    }
                }
            }
        }
        Ok(true)
    }

    /// Runs the simulation. Stops early (status `interrupted`) when `ctl`
    /// says stop (stop request, deadline), with the repetitions finished so
    /// far; the control is polled every [`POLL_STEPS`] controller periods,
    /// also inside a repetition. Progress: phase `"simulate"`, one step per
    /// repetition. [`Error::Interrupted`] if not one repetition was finished.
    pub fn run(&self, ctl: &Control) -> Result<SimResult> {
        let n = self.truth.dof();
        let dt = 1.0 / self.rate;
        let new_rep = || Repetition {
            t: Vec::new(),
            q: Vec::new(),
            tau: Vec::new(),
            r: Some(Vec::new()),
            qd: self.velocity_noise.as_ref().map(|_| Vec::new()),
            qdd: None,
        };
        let obs = ctl.observer();
        obs.phase("simulate", Some(self.repetitions as u64));
        let done = std::sync::atomic::AtomicU64::new(0);
        let mut reps = Vec::with_capacity(self.repetitions);
        let mut interrupted = false;
        if self.reference.periodic() {
            let steps = (self.reference.duration() * self.rate).round() as usize;
            let mut lp = self.new_loop();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(crate::rng::mix(self.seed, 0, 0));
            interrupted = !self.run_steps(
                &mut lp,
                Span {
                    k0: 0,
                    steps,
                    t_rec0: 0.0,
                    stream: 0,
                },
                &mut rng,
                None,
                ctl,
            )?; // lead-in period
            for i in 0..self.repetitions {
                if interrupted {
                    break;
                }
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(crate::rng::mix(self.seed, (i + 1) as u64, 0));
                let mut rep = new_rep();
                let k0 = (i + 1) * steps;
                if !self.run_steps(
                    &mut lp,
                    Span {
                        k0,
                        steps,
                        t_rec0: k0 as f64 * dt,
                        stream: (i + 1) as u64,
                    },
                    &mut rng,
                    Some(&mut rep),
                    ctl,
                )? {
                    interrupted = true;
                    break;
                }
                reps.push(rep);
                obs.progress(reps.len() as u64, "");
            }
        } else {
            let steps = (self.reference.duration() * self.rate).round() as usize + 1;
            let out: Vec<Option<Result<Repetition>>> = (0..self.repetitions)
                .into_par_iter()
                .map(|i| {
                    if ctl.should_stop() {
                        return None;
                    }
                    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(crate::rng::mix(self.seed, (i + 1) as u64, 0));
                    let mut lp = self.new_loop();
                    let mut rep = new_rep();
                    let r = match self.run_steps(
                        &mut lp,
                        Span {
                            k0: 0,
                            steps,
                            t_rec0: 0.0,
                            stream: (i + 1) as u64,
                        },
                        &mut rng,
                        Some(&mut rep),
                        ctl,
                    ) {
                        Ok(true) => Ok(rep),
                        Ok(false) => return None,
                        Err(e) => Err(e),
                    };
                    let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                    obs.progress(k, "");
                    Some(r)
                })
                .collect();
            // the repetitions before the first stopped one (a valid prefix)
            for o in out {
                match o {
                    Some(r) if !interrupted => reps.push(r?),
                    Some(_) => {}
                    None => interrupted = true,
                }
            }
        }
        obs.phase_done();
        if reps.is_empty() {
            return Err(Error::Interrupted);
        }
        let mut max_e = vec![0.0f64; n];
        let mut rms = vec![0.0f64; n];
        let mut cnt = 0usize;
        for rep in &reps {
            if let Some(r) = &rep.r {
                for (q, r) in rep.q.iter().zip(r) {
                    for j in 0..n {
                        let e = r[j] - q[j];
                        max_e[j] = max_e[j].max(e.abs());
                        rms[j] += e * e;
                    }
                    cnt += 1;
                }
            }
        }
        rms.iter_mut().for_each(|v| *v = (*v / cnt.max(1) as f64).sqrt());
        Ok(SimResult {
            status: SimStatus {
                status: if interrupted { RunStatus::Interrupted } else { RunStatus::Complete },
                repetitions: reps.len(),
                max_tracking_error: max_e,
                rms_tracking_error: rms,
                kp: self.kp.clone(),
                kd: self.kd.clone(),
                ki: self.ki.clone(),
            },
            reps,
            setup: self.clone(),
        })
    }
}

fn rk4(robot: &Robot, ws: &mut Workspace, q: &mut [f64], qd: &mut [f64], tau: &[f64], h: f64) -> Result<()> {
    crate::robot::rk4_step(
        robot,
        ws,
        q,
        qd,
        tau,
        h,
        |a| {
            if a.iter().any(|v| !v.is_finite()) || a.iter().fold(0.0_f64, |m, v| m.max(v.abs())) > 1e6 {
                return Err(Error::Numerical(
                    "simulation diverged: accelerations above 1e6 (lower the gains or raise the rate)".into(),
                ));
            }
            Ok(())
        },
        |e| Error::Numerical(format!("simulation: {e} (the true parameters are not physical?)")),
    )
}

impl SimResult {
    /// The true parameters of the plant.
    pub fn truth(&self) -> Result<Truth> {
        let r = &self.setup.truth;
        let theta = r.nominal_params().as_slice().to_vec();
        let base = BaseParams::compute(r, &BaseOptions::default())?;
        Ok(Truth {
            robot: r.name.clone(),
            names: r.param_names(),
            base: base.base_values(&theta).as_slice().to_vec(),
            base_names: base.names.clone(),
            nominal: self.setup.nominal.nominal_params().as_slice().to_vec(),
            theta,
        })
    }

    /// Writes the run folder: `rep_001.csv`…, `reference.csv` (one repetition of
    /// the reference at the recording rate), `trajectory.json` (Fourier
    /// references), `truth.json`, `design.json` (the resolved design) and `status.json`.
    pub fn write(&self, dir: &Path, design: &SimDesign) -> Result<()> {
        crate::io::folder::begin(dir, "simulate", &crate::io::status::fingerprint_of(design)?)?;
        let scale: Option<Vec<f64>> = match design.record {
            Record::Torque => None,
            _ => self.setup.nominal.drives.iter().map(|d| d.torque_per_ampere()).collect(),
        };
        for (i, rep) in self.reps.iter().enumerate() {
            let path = dir.join(format!("rep_{:03}.csv", i + 1));
            match (&scale, design.record) {
                (Some(k), Record::Current) => rep.write_drive(&path, Some(k), false)?,
                (Some(k), Record::Both) => rep.write_drive(&path, Some(k), true)?,
                _ => rep.write(&path)?,
            }
        }
        let rate = self.setup.rate / self.setup.decimate as f64;
        self.setup.reference.sample(rate).write(&dir.join("reference.csv"))?;
        if let Some(f) = self.setup.reference.fourier() {
            crate::io::write_json(&dir.join("trajectory.json"), &serde_json::json!({ "trajectory": f }))?;
        }
        crate::io::write_json(&dir.join("truth.json"), &self.truth()?)?;
        crate::io::write_json(&dir.join("design.json"), design)?;
        let state = if self.status.status == RunStatus::Interrupted {
            crate::io::status::RunState::Interrupted
        } else {
            crate::io::status::RunState::Complete
        };
        let detail = format!("{} repetitions ({})", self.status.repetitions, self.status.status);
        let summary = crate::io::status::summary_of(&self.status)?;
        crate::io::status::write_status(dir, "simulate", state, detail, None, crate::io::status::fingerprint_of(design)?, summary)?;
        Ok(())
    }
}
