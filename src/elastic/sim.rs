//! Time-domain closed-loop simulation of the nonlinear elastic model around a
//! position (paper 001 Fig. 2), to rehearse FRF experiments on data with known
//! parameters.
//!
//! # Plant
//!
//! The full nonlinear equations of [`super::model`]: rigid-body dynamics of
//! the extended robot (forward dynamics of the foundation, true inertial
//! parameters), gearbox springs/dampers with coupling, arm springs/dampers,
//! motor inertias, viscous friction and optionally Coulomb friction
//! (smoothed as Fc·tanh(q̇_m/ε), ε = 10⁻³ rad/s, so the integrator sees a
//! Lipschitz right-hand side). Integration: classical Runge–Kutta 4 with
//! `substeps` steps per controller sample; by default enough that
//! ω_max·h ≤ 0.5 for the fastest mode of the linearised model.
//!
//! # Controller
//!
//! Per motor, at the controller rate with a zero-order hold:
//! u = τ_0 + k_p (p_ref − y) + k_d (r − ẏ) + k_i Σ (p_ref − y) T_s, with τ_0 the
//! static gravity torque, r the speed reference, p_ref = q_m0 + ∫ r the
//! position reference, y the measured motor position (encoder noise) and ẏ
//! its backward difference. The gains put a triple pole at the bandwidth ω_c
//! on the rigid motor-side inertia J_j = Ia_j + M_jj: k_d = 3Jω_c,
//! k_p = 3Jω_c², k_i = Jω_c³. Motor-side (collocated) feedback keeps the
//! elastic modes stable. An unmeasured white torque disturbance can be added.
//! Recorded: the controller output u and the measured motor positions y.

use super::model::{ElasticModel, ParamRole};
use crate::data::MotorRecord;
use crate::error::{Error, Result};
use crate::robot::{self, Robot, Workspace};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Simulation settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SimSettings {
    /// Controller sample rate (Hz).
    pub rate: f64,
    /// RK4 steps per sample (0: automatic from the fastest mode).
    pub substeps: usize,
    /// Include (smoothed) Coulomb friction.
    pub coulomb: bool,
    /// Encoder noise standard deviation (rad).
    pub position_noise: f64,
    /// White motor torque disturbance standard deviation (N·m).
    pub torque_noise: f64,
    /// Controller bandwidth (Hz).
    pub bandwidth_hz: f64,
}

/// One period of references: speed `r[i][t]` (rad/s) and position ∫r (rad, zero mean).
#[derive(Debug, Clone)]
pub struct Reference {
    /// Speed references per motor.
    pub speed: Vec<Vec<f64>>,
    /// Position references per motor (relative to the static motor position).
    pub position: Vec<Vec<f64>>,
}

/// A closed loop around one position, with true parameter values.
#[derive(Debug, Clone)]
pub struct ClosedLoop {
    ext: Robot,
    na: usize,
    act: Vec<usize>,
    elastic: Vec<usize>,
    c: nalgebra::DMatrix<f64>,
    kg: Vec<f64>,
    dg: Vec<f64>,
    ke: Vec<f64>,
    de: Vec<f64>,
    ia: Vec<f64>,
    fv: Vec<f64>,
    fc: Vec<f64>,
    q_ext0: Vec<f64>,
    qm0: Vec<f64>,
    tau0: Vec<f64>,
    kp: Vec<f64>,
    kd: Vec<f64>,
    ki: Vec<f64>,
    /// Integration steps per sample.
    pub substeps: usize,
    settings: SimSettings,
}

impl ClosedLoop {
    /// Builds the loop at actuated position `q0` for full parameter values `vals`
    /// (static equilibrium of these values; gains from the settings).
    pub fn new(model: &ElasticModel, vals: &[f64], q0: &[f64], s: &SimSettings) -> Result<ClosedLoop> {
        if !(s.rate > 0.0 && s.bandwidth_hz > 0.0) {
            return Err(Error::invalid("simulation", "rate", "rate and bandwidth must be positive"));
        }
        let na = model.n_motors();
        let op = model.operating_point(q0, vals)?;
        let lin = model.linear_model(&op, vals);
        let ext = model.ext.with_params(&model.ext_params(vals))?;
        let get = |r: ParamRole| model.value_of(vals, r);
        let kg: Vec<f64> = (0..na).map(|j| get(ParamRole::GearSpring(j))).collect();
        let dg: Vec<f64> = (0..na).map(|j| get(ParamRole::GearDamper(j))).collect();
        let ke: Vec<f64> = (0..model.n_elastic()).map(|e| get(ParamRole::ArmSpring(e))).collect();
        let de: Vec<f64> = (0..model.n_elastic()).map(|e| get(ParamRole::ArmDamper(e))).collect();
        let ia: Vec<f64> = (0..na).map(|j| get(ParamRole::RotorInertia(j))).collect();
        let fv: Vec<f64> = (0..na).map(|j| get(ParamRole::MotorViscous(j))).collect();
        let fc: Vec<f64> = (0..na)
            .map(|j| match model.rigid.drives[j].friction {
                crate::robot::Friction::Symmetric { fc, .. } => fc,
                crate::robot::Friction::Asymmetric { fc_pos, fc_neg, .. } => 0.5 * (fc_pos - fc_neg),
                crate::robot::Friction::None => 0.0,
            })
            .collect();
        let c = model.coupling.clone();
        let qm0: Vec<f64> = (0..na).map(|j| (0..na).map(|a| c[(j, a)] * q0[a]).sum::<f64>() + op.delta0[j]).collect();
        let wc = std::f64::consts::TAU * s.bandwidth_hz;
        let jj: Vec<f64> = (0..na).map(|j| ia[j] + op.m0[(model.act_index[j], model.act_index[j])]).collect();
        let kd = jj.iter().map(|j| 3.0 * j * wc).collect();
        let kp = jj.iter().map(|j| 3.0 * j * wc * wc).collect();
        let ki = jj.iter().map(|j| j * wc * wc * wc).collect();
        let substeps = if s.substeps > 0 {
            s.substeps
        } else {
            let wmax = super::modes(&lin)?.iter().map(|m| std::f64::consts::TAU * m.freq_hz).fold(0.0, f64::max);
            // the motor-side closed loop adds k_d/Ia as a real pole rate
            let pole = (0..na).map(|j| 3.0 * jj[j] * wc / ia[j]).fold(0.0, f64::max);
            (((wmax.max(pole)) / s.rate / 0.5).ceil() as usize).max(1)
        };
        Ok(ClosedLoop {
            ext,
            na,
            act: model.act_index.clone(),
            elastic: model.elastic_index.clone(),
            c,
            kg,
            dg,
            ke,
            de,
            ia,
            fv,
            fc: if s.coulomb { fc } else { vec![0.0; na] },
            q_ext0: op.q_ext.clone(),
            qm0,
            tau0: op.tau0.clone(),
            kp,
            kd,
            ki,
            substeps,
            settings: s.clone(),
        })
    }

    /// Static motor positions q_m0 (rad).
    pub fn motor_rest(&self) -> &[f64] {
        &self.qm0
    }

    fn deriv(&self, ws: &mut Workspace, x: &[f64], u: &[f64], dx: &mut [f64]) -> Result<()> {
        let na = self.na;
        let nx = self.ext.dof();
        let (qm, rest) = x.split_at(na);
        let (qmd, rest) = rest.split_at(na);
        let (q, qd) = rest.split_at(nx);
        let mut tl = vec![0.0; nx];
        for j in 0..na {
            let mut cq = 0.0;
            let mut cqd = 0.0;
            for a in 0..na {
                cq += self.c[(j, a)] * q[self.act[a]];
                cqd += self.c[(j, a)] * qd[self.act[a]];
            }
            let tg = self.kg[j] * (qm[j] - cq) + self.dg[j] * (qmd[j] - cqd);
            let fr = self.fv[j] * qmd[j] + if self.fc[j] != 0.0 { self.fc[j] * (qmd[j] / 1e-3).tanh() } else { 0.0 };
            dx[j] = qmd[j];
            dx[na + j] = (u[j] - tg - fr) / self.ia[j];
            for a in 0..na {
                tl[self.act[a]] += self.c[(j, a)] * tg;
            }
        }
        for (e, &x) in self.elastic.iter().enumerate() {
            tl[x] -= self.ke[e] * q[x] + self.de[e] * qd[x];
        }
        let qdd = robot::forward_dynamics(&self.ext, ws, q, qd, &tl)?;
        for i in 0..nx {
            dx[2 * na + i] = qd[i];
            dx[2 * na + nx + i] = qdd[i];
        }
        Ok(())
    }

    /// Simulates `periods` periods of the reference from rest at the static
    /// equilibrium, returning the sampled controller output and measured motor positions.
    pub fn run(&self, r: &Reference, periods: usize, seed: u64) -> Result<MotorRecord> {
        let na = self.na;
        let nx = self.ext.dof();
        let np = r.speed.first().map(|v| v.len()).unwrap_or(0);
        if r.speed.len() != na || r.position.len() != na || np == 0 {
            return Err(Error::dim("reference signals", na, r.speed.len()));
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut ws = Workspace::new(&self.ext);
        let dim = 2 * na + 2 * nx;
        let mut x = vec![0.0; dim];
        x[..na].copy_from_slice(&self.qm0);
        x[2 * na..2 * na + nx].copy_from_slice(&self.q_ext0);
        let ts = 1.0 / self.settings.rate;
        let h = ts / self.substeps as f64;
        let mut integ = vec![0.0; na];
        let mut y_prev: Option<Vec<f64>> = None;
        let total = periods * np;
        let mut out = MotorRecord {
            u: Vec::with_capacity(total),
            y: Vec::with_capacity(total),
        };
        let (mut k1, mut k2, mut k3, mut k4) = (vec![0.0; dim], vec![0.0; dim], vec![0.0; dim], vec![0.0; dim]);
        let mut xt = vec![0.0; dim];
        let mut u = vec![0.0; na];
        let mut ut = vec![0.0; na];
        for t in 0..total {
            let ti = t % np;
            let y: Vec<f64> = (0..na)
                .map(|j| {
                    let n: f64 = StandardNormal.sample(&mut rng);
                    x[j] + self.settings.position_noise * n
                })
                .collect();
            let yd: Vec<f64> = match &y_prev {
                Some(p) => (0..na).map(|j| (y[j] - p[j]) / ts).collect(),
                None => vec![0.0; na],
            };
            for j in 0..na {
                let e = self.qm0[j] + r.position[j][ti] - y[j];
                integ[j] += e * ts;
                u[j] = self.tau0[j] + self.kp[j] * e + self.kd[j] * (r.speed[j][ti] - yd[j]) + self.ki[j] * integ[j];
                let v: f64 = StandardNormal.sample(&mut rng);
                ut[j] = u[j] + self.settings.torque_noise * v;
            }
            out.u.push(u.clone());
            out.y.push(y.clone());
            y_prev = Some(y);
            for _ in 0..self.substeps {
                self.deriv(&mut ws, &x, &ut, &mut k1)?;
                for i in 0..dim {
                    xt[i] = x[i] + 0.5 * h * k1[i];
                }
                self.deriv(&mut ws, &xt, &ut, &mut k2)?;
                for i in 0..dim {
                    xt[i] = x[i] + 0.5 * h * k2[i];
                }
                self.deriv(&mut ws, &xt, &ut, &mut k3)?;
                for i in 0..dim {
                    xt[i] = x[i] + h * k3[i];
                }
                self.deriv(&mut ws, &xt, &ut, &mut k4)?;
                for i in 0..dim {
                    x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
            }
            if x.iter().any(|v| !v.is_finite()) {
                return Err(Error::Numerical(format!(
                    "simulation diverged at sample {t} (unstable closed loop or too few substeps)"
                )));
            }
        }
        Ok(out)
    }
}
