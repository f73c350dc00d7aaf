//! Odd random-phase multisine line sets (paper 001 §4): the design-file
//! section `[multisine]` and the harmonics it excites. With N_P = rate·period
//! samples per period and line spacing f₀ = 1/period (Hz), harmonic k has
//! frequency k·f₀; the excited lines are the odd k in the band, the even k in
//! the band are left unexcited to detect nonlinear distortion.

use serde::{Deserialize, Serialize};

/// Shape of the multisine amplitude spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Spectrum {
    /// Equal amplitudes on every excited line (paper 001 §6).
    #[default]
    Flat,
    /// A_k ∝ 1/f_k (more low-frequency speed, flatter acceleration).
    Inverse,
}

/// Odd random-phase orthogonal multisine (paper 001 §4).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MultisineSpec {
    /// Controller sample rate (Hz).
    pub rate: f64,
    /// Period (s); rate·period must be an even integer N_P. Line spacing 1/period.
    pub period: f64,
    /// Excited band [f_min, f_max] (Hz): odd lines k/period inside.
    pub band: [f64; 2],
    /// RMS of each motor speed reference (rad/s, joint side): one value or one per motor.
    pub amplitude: Vec<f64>,
    /// Amplitude spectrum shape.
    pub spectrum: Spectrum,
    /// Blocks with independent random phases.
    pub blocks: usize,
    /// Measured periods per experiment (steady state).
    pub periods: usize,
    /// Periods discarded before measuring (transient).
    pub transient: usize,
}

impl Default for MultisineSpec {
    fn default() -> Self {
        MultisineSpec {
            rate: 1000.0,
            period: 1.0,
            band: [2.0, 100.0],
            amplitude: vec![0.05],
            spectrum: Spectrum::Flat,
            blocks: 4,
            periods: 2,
            transient: 2,
        }
    }
}

/// Multisine lines of a spec: (N_P, excited odd harmonics, even detection harmonics).
pub fn lines(ms: &MultisineSpec) -> (usize, Vec<usize>, Vec<usize>) {
    let np = (ms.rate * ms.period).round() as usize;
    let f0 = 1.0 / ms.period;
    let kmax = np / 2 - 1;
    let inb = |k: usize| {
        let f = k as f64 * f0;
        f >= ms.band[0] - 1e-9 && f <= ms.band[1] + 1e-9
    };
    let odd = (1..=kmax).filter(|k| k % 2 == 1 && inb(*k)).collect();
    let even = (1..=kmax).filter(|k| k % 2 == 0 && inb(*k)).collect();
    (np, odd, even)
}
