//! The design file of the FRF commands (`idexp multisine`, `frf`, `fit`):
//! model, positions, excitation, optional simulation, estimation and fit
//! settings. Every section has defaults; unknown keys are errors; `validate`
//! names the field and the allowed range.

use crate::elastic::{ElasticModel, ElasticSpec, Estimator, Output};
use crate::error::{Error, Result};
pub use crate::trajectory::multisine::{lines, MultisineSpec, Spectrum};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The most multistart starts of a fit (`fit.starts`, `--starts`): each
/// start is a record in the log and an entry of the report.
pub const MAX_STARTS: usize = 100_000;

/// A whole design file.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Design {
    /// Name (output folder `out/<name>/`).
    pub name: String,
    /// Seed of every random choice (phases, simulated noise, multistart).
    #[serde(default)]
    pub seed: u64,
    /// Measurement positions: actuated joint angles q0 (rad), one row per position.
    pub positions: Vec<Vec<f64>>,
    /// The elastic model and its unknowns.
    pub model: ElasticSpec,
    /// Excitation.
    #[serde(default)]
    pub multisine: MultisineSpec,
    /// Simulated measurements with known parameters (rehearsal), optional.
    #[serde(default)]
    pub simulate: Option<SimulateSpec>,
    /// FRF estimation.
    #[serde(default)]
    pub frf: FrfSpec,
    /// Parameter estimation.
    #[serde(default)]
    pub fit: FitSpec,
}

/// How measurements are simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SimMethod {
    /// Block FRFs G_b = G(θ_true) + noise from the linearised model (fast).
    #[default]
    Frequency,
    /// Closed-loop time-domain simulation of the nonlinear elastic model,
    /// recorded as runs, then the FRF estimated from them like measured data.
    Time,
}

/// Simulated experiments with known ("true") parameters.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimulateSpec {
    /// Frequency- or time-domain simulation.
    pub method: SimMethod,
    /// True values by parameter name (others: nominal, perturbed by `perturb`).
    pub truth: BTreeMap<String, f64>,
    /// Standard deviation of ln(θ_true/θ_nominal) for the unknowns not in `truth`.
    pub perturb: f64,
    /// Frequency method: relative standard deviation of each block FRF element.
    pub noise_rel: f64,
    /// Frequency method: absolute standard deviation added to each block FRF element.
    pub noise_abs: f64,
    /// Time method: standard deviation of the encoder (motor position) noise (rad).
    pub position_noise: f64,
    /// Time method: standard deviation of a white torque disturbance at the motors (N·m).
    pub torque_noise: f64,
    /// Time method: include Coulomb friction (a nonlinearity; the even lines show it).
    pub coulomb: bool,
    /// Time method: controller bandwidth (Hz) of the motor PID loops.
    pub bandwidth: f64,
}

impl Default for SimulateSpec {
    fn default() -> Self {
        SimulateSpec {
            method: SimMethod::Frequency,
            truth: BTreeMap::new(),
            perturb: 0.3,
            noise_rel: 0.02,
            noise_abs: 0.0,
            position_noise: 1e-7,
            torque_noise: 0.0,
            coulomb: false,
            bandwidth: 3.0,
        }
    }
}

/// FRF estimation settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrfSpec {
    /// Output of the FRF: motor `acceleration` (default), `velocity` or `position`.
    pub output: Output,
    /// Divide out the controller's zero-order hold e^{−jωT/2}·sinc(ωT/2).
    pub zoh: bool,
    /// Flag nonlinear distortion when the even (unexcited) lines exceed the noise floor by this many dB.
    pub distortion_db: f64,
}

impl Default for FrfSpec {
    fn default() -> Self {
        FrfSpec {
            output: Output::Acceleration,
            zoh: true,
            distortion_db: 10.0,
        }
    }
}

/// Kind of weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum WeightKind {
    /// User-defined weights ([`UserWeights`]).
    #[default]
    User,
    /// Optimal weights from the estimated covariance: eq. 6 (NLS), eq. 8 (LLS) with G(θ0) ≈ Ĝ.
    Optimal,
}

/// User-defined weights 1/Λ: constant per element, zero outside a band, per-position factors.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct UserWeights {
    /// Weight of the diagonal elements G_ii.
    pub diagonal: f64,
    /// Weight of the off-diagonal elements G_ij, i ≠ j.
    pub off_diagonal: f64,
    /// Optional explicit n×n element weights (overrides `diagonal`/`off_diagonal`).
    pub elements: Option<Vec<Vec<f64>>>,
    /// Band [f_lo, f_hi] (Hz) with non-zero weight (default: everything).
    pub band: Option<[f64; 2]>,
    /// Factor per position (default 1).
    pub positions: Vec<f64>,
    /// Zero weight where |Ĝ_ij| / σ̂_ij is below this (unreliable estimate); 0 disables.
    pub min_snr: f64,
}

impl Default for UserWeights {
    fn default() -> Self {
        UserWeights {
            diagonal: 1.0,
            off_diagonal: 0.3,
            elements: None,
            band: None,
            positions: Vec::new(),
            min_snr: 3.0,
        }
    }
}

/// Parameter estimation and multistart settings (paper 001 §5, §6).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FitSpec {
    /// Estimator: `lls` (eq. 7), `lls_magnitude`, `nls` (eq. 4).
    pub estimator: Estimator,
    /// `user` or `optimal` weights.
    pub weights: WeightKind,
    /// User weights (also used by the common evaluation cost).
    pub user: UserWeights,
    /// Number of starts θ_init·10^φ.
    pub starts: usize,
    /// φ ~ U[−spread, spread] per element.
    pub spread: f64,
    /// A model is reasonable when its normalised common cost is below this (paper: 1.5).
    pub reasonable: f64,
    /// Levenberg–Marquardt iteration limit.
    pub max_iter: usize,
    /// Stop when the relative cost decrease of an accepted step is below this.
    pub ftol: f64,
    /// Stop when the step (in log/scaled parameters) is below this.
    pub xtol: f64,
}

impl Default for FitSpec {
    fn default() -> Self {
        FitSpec {
            estimator: Estimator::Lls,
            weights: WeightKind::User,
            user: UserWeights::default(),
            starts: 100,
            spread: 1.0,
            reasonable: 1.5,
            max_iter: 200,
            ftol: 1e-10,
            xtol: 1e-9,
        }
    }
}

impl Design {
    /// Reads and validates a design file; returns it with the loaded model.
    pub fn load(path: &Path) -> Result<(Design, ElasticModel)> {
        let d: Design = crate::io::read_toml(path)?;
        crate::io::design_path(path, "model.robot", Path::new(&d.model.robot))?;
        let base = path.parent().unwrap_or(Path::new("."));
        let ctx = path.display().to_string();
        let model = ElasticModel::from_spec(&d.model, base, &ctx)?;
        d.validate(&ctx, &model)?;
        Ok((d, model))
    }

    /// Checks every field against the model; errors name the field.
    pub fn validate(&self, ctx: &str, model: &ElasticModel) -> Result<()> {
        let n = model.n_motors();
        let inv = |f: &str, m: String| Err(Error::invalid(ctx, f, m));
        if self.name.is_empty() || self.name.contains('/') || self.name.contains('\\') {
            return inv("name", "expected a non-empty name without path separators".into());
        }
        if self.positions.is_empty() {
            return inv("positions", "expected at least one position (a list of joint-angle rows)".into());
        }
        let (lo, hi) = model.rigid.position_limits();
        for (i, q) in self.positions.iter().enumerate() {
            if q.len() != n {
                return inv(&format!("positions[{i}]"), format!("expected {n} joint angles, found {}", q.len()));
            }
            for j in 0..n {
                if !q[j].is_finite() || q[j] < lo[j] || q[j] > hi[j] {
                    return inv(
                        &format!("positions[{i}][{j}]"),
                        format!("expected a finite angle within the joint limits [{}, {}], found {}", lo[j], hi[j], q[j]),
                    );
                }
            }
        }
        if model.n_unknowns() == 0 {
            return inv(
                "model.unknowns",
                "no unknown parameters: list names or groups such as \"springs\", \"dampers\"".into(),
            );
        }
        let ms = &self.multisine;
        if !(ms.rate.is_finite() && ms.rate > 0.0) {
            return inv("multisine.rate", format!("expected a positive sample rate (Hz), found {}", ms.rate));
        }
        let npf = ms.rate * ms.period;
        if !(ms.period.is_finite() && ms.period > 0.0) || (npf - npf.round()).abs() > 1e-6 || (npf.round() as usize) % 2 != 0 || npf < 8.0 {
            return inv(
                "multisine.period",
                format!("rate·period must be an even integer ≥ 8 (samples per period), found {npf}"),
            );
        }
        if !(ms.band[0] > 0.0 && ms.band[1] > ms.band[0] && ms.band[1] < ms.rate / 2.0) {
            return inv(
                "multisine.band",
                format!("expected 0 < f_min < f_max < rate/2 = {}, found {:?}", ms.rate / 2.0, ms.band),
            );
        }
        let (_, odd, _) = lines(ms);
        if odd.is_empty() {
            return inv("multisine.band", "no odd line k/period falls inside the band".into());
        }
        if !(ms.amplitude.len() == 1 || ms.amplitude.len() == n) || ms.amplitude.iter().any(|a| !a.is_finite() || *a <= 0.0) {
            return inv("multisine.amplitude", format!("expected 1 or {n} positive RMS values (rad/s)"));
        }
        if ms.blocks < 1 || ms.periods < 1 {
            return inv("multisine.blocks", "blocks and periods must be ≥ 1".into());
        }
        if let Some(s) = &self.simulate {
            for (name, v) in &s.truth {
                let i = model
                    .param_index(name)
                    .ok_or_else(|| Error::invalid(ctx, format!("simulate.truth.{name}"), "no parameter of that name"))?;
                if !v.is_finite() || (model.params[i].positive && *v <= 0.0) {
                    return inv(&format!("simulate.truth.{name}"), format!("expected a finite positive value, found {v}"));
                }
            }
            for (f, v) in [
                ("perturb", s.perturb),
                ("noise_rel", s.noise_rel),
                ("noise_abs", s.noise_abs),
                ("position_noise", s.position_noise),
                ("torque_noise", s.torque_noise),
            ] {
                if !v.is_finite() || v < 0.0 {
                    return inv(&format!("simulate.{f}"), format!("expected a non-negative number, found {v}"));
                }
            }
            if !(s.bandwidth.is_finite() && s.bandwidth > 0.0) {
                return inv("simulate.bandwidth", format!("expected a positive frequency (Hz), found {}", s.bandwidth));
            }
            // the motor loops' velocity is a backward difference at the multisine rate:
            // a bandwidth at or above Nyquist makes the sampled loop diverge
            if s.method == SimMethod::Time && s.bandwidth >= 0.5 * ms.rate {
                return inv(
                    "simulate.bandwidth",
                    format!(
                        "expected a controller bandwidth below the Nyquist frequency rate/2 = {} Hz (multisine.rate = {}), found {} Hz",
                        0.5 * ms.rate,
                        ms.rate,
                        s.bandwidth
                    ),
                );
            }
            if s.method == SimMethod::Frequency && s.noise_rel == 0.0 && s.noise_abs == 0.0 && ms.blocks > 1 {
                return inv(
                    "simulate.noise_rel",
                    "noise-free block FRFs give a zero covariance: set noise_rel or noise_abs > 0".into(),
                );
            }
        }
        if !self.frf.distortion_db.is_finite() {
            return inv("frf.distortion_db", format!("expected a finite level in dB, found {}", self.frf.distortion_db));
        }
        let f = &self.fit;
        let u = &f.user;
        for (name, v) in [
            ("fit.user.diagonal", u.diagonal),
            ("fit.user.off_diagonal", u.off_diagonal),
            ("fit.user.min_snr", u.min_snr),
        ] {
            if !v.is_finite() || v < 0.0 {
                return inv(name, format!("expected a non-negative number, found {v}"));
            }
        }
        if let Some(e) = &u.elements {
            if e.len() != n || e.iter().any(|r| r.len() != n || r.iter().any(|v| !v.is_finite() || *v < 0.0)) {
                return inv("fit.user.elements", format!("expected a {n}×{n} matrix of non-negative weights"));
            }
        }
        if let Some(b) = u.band {
            if !(b[0] >= 0.0 && b[1] > b[0]) {
                return inv("fit.user.band", format!("expected 0 ≤ f_lo < f_hi, found {b:?}"));
            }
        }
        if !u.positions.is_empty() && (u.positions.len() != self.positions.len() || u.positions.iter().any(|v| !v.is_finite() || *v < 0.0)) {
            return inv(
                "fit.user.positions",
                format!("expected {} non-negative factors (one per position)", self.positions.len()),
            );
        }
        if f.starts == 0 || f.starts > MAX_STARTS {
            return inv("fit.starts", format!("{}: expected 1..={MAX_STARTS} starts", f.starts));
        }
        if !(f.spread.is_finite() && f.spread >= 0.0) {
            return inv("fit.spread", format!("expected a non-negative number of decades, found {}", f.spread));
        }
        if !(f.reasonable.is_finite() && f.reasonable >= 1.0) {
            return inv("fit.reasonable", format!("expected a factor ≥ 1, found {}", f.reasonable));
        }
        if f.max_iter == 0 || f.ftol.is_nan() || f.ftol < 0.0 || f.xtol.is_nan() || f.xtol < 0.0 {
            return inv("fit.max_iter", "expected max_iter ≥ 1 and non-negative tolerances".into());
        }
        Ok(())
    }

    /// Amplitude (RMS) of motor `j`'s speed reference.
    pub fn amplitude(&self, j: usize) -> f64 {
        let a = &self.multisine.amplitude;
        if a.len() == 1 {
            a[0]
        } else {
            a[j]
        }
    }

    /// The output folder: `out/<name>` unless given.
    pub fn out_dir(&self, out: Option<&Path>) -> PathBuf {
        out.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("out").join(&self.name))
    }
}

/// `[simulate]` as read by the other problems: only the relative noise.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct SimulateNoise {
    /// Relative standard deviation of each block FRF element.
    pub noise_rel: Option<f64>,
}

/// `[fit]` as read by the other problems: only the estimator.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct FitEstimator {
    /// NLS or log-LS criterion.
    pub estimator: Option<Estimator>,
}

/// `[frf]` as read by the other problems: only the output quantity.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct FrfOutput {
    /// Output of the estimate.
    pub output: Option<Output>,
}

/// The tables of an elastic design file that the other problems reuse
/// (position selection reads them from a design or a bare model file):
/// `[multisine]` (the whole, checked spec), `[simulate].noise_rel`,
/// `[fit].estimator` and `[frf].output`. Every table and key is optional;
/// other tables and keys are left to [`Design`].
#[derive(Debug, Clone, Default, Deserialize)]
pub struct SharedSections {
    /// Excitation, if the file has a `[multisine]` table.
    #[serde(default)]
    pub multisine: Option<MultisineSpec>,
    /// Simulation noise.
    #[serde(default)]
    pub simulate: SimulateNoise,
    /// Estimator.
    #[serde(default)]
    pub fit: FitEstimator,
    /// FRF output.
    #[serde(default)]
    pub frf: FrfOutput,
}

impl SharedSections {
    /// Reads the shared tables of a design or model file.
    pub fn read(path: &Path) -> Result<SharedSections> {
        crate::io::read_toml(path)
    }
}
