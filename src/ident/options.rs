//! What an identification is asked: the estimator ([`Method`]), the filter
//! ([`FilterChoice`]), the standstill rule ([`Standstill`]) and how one run
//! is made ready for estimation ([`IdentOptions`], set from a study entry).

use super::{Filter, VelocityFrom};
use crate::error::{Error, Result};
use serde::Serialize;

/// Estimator (`method`: `ols`, `wls`, `projection`, `ml`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Ordinary least squares.
    Ols,
    /// Weighted least squares with sample-variance weights (paper 000).
    #[default]
    Wls,
    /// Projection method for closed-loop data (paper 002 eq. 10–12).
    Projection,
    /// Maximum likelihood with noisy positions and torques (paper 002 eq. 13–16).
    Ml,
}

impl Method {
    /// Every method, in the order of the command line's help.
    pub const ALL: [Method; 4] = [Method::Ols, Method::Wls, Method::Projection, Method::Ml];

    /// The name on the command line and in files (`ols`, `wls`, `projection`, `ml`).
    pub fn name(self) -> &'static str {
        match self {
            Method::Ols => "ols",
            Method::Wls => "wls",
            Method::Projection => "projection",
            Method::Ml => "ml",
        }
    }

    /// Human words for reports ("weighted least squares", ...).
    pub fn words(self) -> &'static str {
        match self {
            Method::Ols => "ordinary least squares",
            Method::Wls => "weighted least squares",
            Method::Projection => "projection method",
            Method::Ml => "maximum likelihood",
        }
    }
}

/// The name of [`Method::name`].
impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Parses [`Method::name`]; the error lists the allowed values.
impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| Error::invalid("identify", "method", format!("expected ols, wls, projection or ml, found `{s}`")))
    }
}

/// How positions are filtered.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum FilterChoice {
    /// Fourier filtering when the run's Fourier trajectory is known, else a low-pass at 10 Hz.
    #[default]
    Auto,
    /// This filter.
    Given(Filter),
}

/// Which slow rows (standstill, |q̇_j| below `slow_ratio`·max|q̇_j| or
/// `min_speed`) identification leaves out (`--standstill`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Standstill {
    /// Follow the model: drop the slow rows of joints whose friction is
    /// discontinuous at rest (Coulomb shape `sign`: the measured velocity at
    /// standstill is encoder noise and sign(q̇) flips between ±Fc), keep them
    /// for smooth shapes (`tanh`, `stribeck`) and joints without friction.
    #[default]
    Auto,
    /// Drop the slow rows of every joint (the former default rule).
    Drop,
    /// Keep every row of every joint.
    Keep,
}

impl Standstill {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Standstill::Auto => "auto",
            Standstill::Drop => "drop",
            Standstill::Keep => "keep",
        }
    }
}

impl std::str::FromStr for Standstill {
    type Err = Error;
    fn from_str(s: &str) -> Result<Standstill> {
        match s {
            "auto" => Ok(Standstill::Auto),
            "drop" => Ok(Standstill::Drop),
            "keep" => Ok(Standstill::Keep),
            _ => Err(Error::invalid("identify", "standstill", format!("expected auto, drop or keep, found `{s}`"))),
        }
    }
}

/// How one experiment or validation run is made ready for estimation
/// ([`prepare`](super::prepare)): what a study entry and the estimator say.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentOptions {
    /// Estimator.
    pub method: Method,
    /// Filter of the identification run.
    pub filter: FilterChoice,
    /// Harmonics kept by Fourier filtering (default: the trajectory's n_h, the
    /// excited ones as in paper 000 §III-C). More harmonics keep the part of the
    /// closed-loop response above the excitation band (tracking errors of a
    /// nonlinear plant) that filtering at n_h would remove from q̈.
    pub harmonics: Option<usize>,
    /// Keep every k-th processed sample.
    pub decimate: usize,
    /// Rows of joint j where |q̇_j| is below this fraction of the joint's largest
    /// speed in the run are left out (see [`Dataset::new`](super::Dataset::new)). Not applied by the
    /// projection method, which needs every sample.
    pub slow_ratio: f64,
    /// Rows of a joint slower than this speed are left out too (rad/s or m/s).
    pub min_speed: f64,
    /// Coulomb dead band (rad/s or m/s): for the joints with a `sign` Coulomb
    /// term, |q̇_j| below it is rest (no Coulomb term), in the
    /// identification and the validation run alike (default
    /// [`DEAD_BAND`](super::estimate::DEAD_BAND); 0: sign(q̇) everywhere).
    /// Not applied by the projection method, which needs every sample as it is.
    pub dead_band: f64,
    /// Which joints the slow-row rule applies to ([`Standstill`]; default:
    /// those with a `sign` Coulomb term).
    pub standstill: Standstill,
    /// Velocities from the logged `qd*` columns or from the positions
    /// ([`VelocityFrom`]; default: logged when present), for the
    /// identification and the validation run alike.
    pub velocity_from: VelocityFrom,
}

impl Default for IdentOptions {
    fn default() -> Self {
        IdentOptions {
            method: Method::Wls,
            filter: FilterChoice::Auto,
            harmonics: None,
            decimate: 1,
            slow_ratio: 0.1,
            min_speed: 0.01,
            dead_band: super::estimate::DEAD_BAND,
            standstill: Standstill::Auto,
            velocity_from: VelocityFrom::Auto,
        }
    }
}
