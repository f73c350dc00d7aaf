//! The true parameters of a simulated plant (`truth.json`), written by the
//! rigid-body simulator and read by `identify --truth`.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The true parameters written next to a simulated run (`truth.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Truth {
    /// Robot name.
    pub robot: String,
    /// Standard parameter names.
    pub names: Vec<String>,
    /// True standard parameters.
    pub theta: Vec<f64>,
    /// Nominal standard parameters (robot file).
    pub nominal: Vec<f64>,
    /// Base parameter names (default base-parameter options).
    pub base_names: Vec<String>,
    /// True base parameters θ_b = K θ.
    pub base: Vec<f64>,
}

impl Truth {
    /// Reads a `truth.json`.
    pub fn read(path: &Path) -> Result<Truth> {
        let text = crate::io::read_to_string(path)?;
        serde_json::from_str(&text).map_err(|e| Error::parse(path, format!("line {}, column {}: {e}", e.line(), e.column())))
    }
}
