//! What an identification is asked: the estimator ([`Method`]) and the
//! standstill rule ([`Standstill`]).

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
