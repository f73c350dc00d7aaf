//! Odd random-phase orthogonal multisines (paper 001 §4).
//!
//! Block b, experiment e (e = 0..n−1) and motor i get the speed reference
//!
//! r_i^{(b,e)}(t) = Σ_k A_ik cos(ω_k t + φ_{b,i,k} + 2π i e / n),
//!
//! i.e. R(ω_k) = R_diag(ω_k) T with T_ie = e^{2πj i e/n} (0-based indices,
//! T Tᴴ = n I), ω_k = 2π k/(N_P T_s) on odd k inside the band, phases φ
//! uniform on [0, 2π) and independent between blocks and motors. The even
//! lines are left empty so nonlinear distortion shows there.

use super::design::Design;
use crate::trajectory::multisine::{lines, Spectrum};
use rand::{RngExt, SeedableRng};
use serde::Serialize;

/// A designed multisine excitation.
#[derive(Debug, Clone, Serialize)]
pub struct Multisine {
    /// Motors n.
    pub n: usize,
    /// Samples per period N_P.
    pub samples: usize,
    /// Sample rate (Hz).
    pub rate: f64,
    /// Excited harmonics k (odd).
    pub lines: Vec<usize>,
    /// Unexcited even harmonics inside the band (distortion detection).
    pub even_lines: Vec<usize>,
    /// Amplitudes A_ik (motor i, line index).
    pub amplitudes: Vec<Vec<f64>>,
    /// Phases φ_{b,i,k} (block, motor, line index), rad.
    pub phases: Vec<Vec<Vec<f64>>>,
}

pub use crate::rng::sub_seed;

/// Stream identifiers for [`sub_seed`].
pub mod streams {
    /// Multisine phases (index: block).
    pub const PHASES: u64 = 1;
    /// Simulated truth perturbation.
    pub const TRUTH: u64 = 2;
    /// Simulated noise (index: position).
    pub const NOISE: u64 = 3;
    /// Multistart perturbations (index: start).
    pub const STARTS: u64 = 4;
}

impl Multisine {
    /// The multisine of a design (phases from the design seed).
    pub fn new(d: &Design, n: usize) -> Multisine {
        let ms = &d.multisine;
        let (np, odd, even) = lines(ms);
        let f0 = 1.0 / ms.period;
        let amplitudes: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                let shape: Vec<f64> = odd
                    .iter()
                    .map(|&k| match ms.spectrum {
                        Spectrum::Flat => 1.0,
                        Spectrum::Inverse => 1.0 / (k as f64 * f0),
                    })
                    .collect();
                // RMS of Σ A cos = sqrt(Σ A²/2)
                let rms = (shape.iter().map(|a| a * a).sum::<f64>() / 2.0).sqrt();
                shape.iter().map(|a| a * d.amplitude(i) / rms).collect()
            })
            .collect();
        let phases = (0..ms.blocks)
            .map(|b| {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(sub_seed(d.seed, streams::PHASES, b as u64));
                (0..n)
                    .map(|_| odd.iter().map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect())
                    .collect()
            })
            .collect();
        Multisine {
            n,
            samples: np,
            rate: ms.rate,
            lines: odd,
            even_lines: even,
            amplitudes,
            phases,
        }
    }

    /// Line frequencies (Hz).
    pub fn freqs_hz(&self) -> Vec<f64> {
        self.lines.iter().map(|&k| k as f64 * self.rate / self.samples as f64).collect()
    }

    /// One period of Σ_l c_{il} f(2π k_l t/N_P + φ_{b,i,l} + 2π i e/n) for every
    /// drive i, t = 0..N_P, with the amplitude c_{il} = `amp(i, l, ω_l)` (ω_l in
    /// rad/s) and `f` = cos or sin: the sum of the experiment's phase-shifted
    /// lines that serves both the speed and the position reference.
    fn line_sum(&self, b: usize, e: usize, amp: impl Fn(usize, usize, f64) -> f64, f: fn(f64) -> f64) -> Vec<Vec<f64>> {
        let np = self.samples;
        (0..self.n)
            .map(|i| {
                let shift = std::f64::consts::TAU * (i * e) as f64 / self.n as f64;
                let mut r = vec![0.0; np];
                for (li, &k) in self.lines.iter().enumerate() {
                    let w = std::f64::consts::TAU * k as f64 * self.rate / np as f64;
                    let a = amp(i, li, w);
                    let ph = self.phases[b][i][li] + shift;
                    for (t, v) in r.iter_mut().enumerate() {
                        let arg = std::f64::consts::TAU * ((k * t) % np) as f64 / np as f64 + ph;
                        *v += a * f(arg);
                    }
                }
                r
            })
            .collect()
    }

    /// One period of the references of block `b`, experiment `e`: `out[i][t]`, t = 0..N_P.
    pub fn reference(&self, b: usize, e: usize) -> Vec<Vec<f64>> {
        self.line_sum(b, e, |i, li, _| self.amplitudes[i][li], f64::cos)
    }

    /// Motor-position reference (rad) of one period: the exact integral of the
    /// speed reference, Σ A/ω sin(ω t + φ) (zero mean, periodic).
    pub fn position_reference(&self, b: usize, e: usize) -> Vec<Vec<f64>> {
        self.line_sum(b, e, |i, li, w| self.amplitudes[i][li] / w, f64::sin)
    }

    /// Speed and position references of block `b`, experiment `e` (for the simulator).
    pub fn speed_and_position(&self, b: usize, e: usize) -> crate::elastic::sim::Reference {
        crate::elastic::sim::Reference {
            speed: self.reference(b, e),
            position: self.position_reference(b, e),
        }
    }

    /// Crest factor max|r| / rms(r) of a sampled signal.
    pub fn crest_factor(r: &[f64]) -> f64 {
        let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64).sqrt();
        let mx = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if rms > 0.0 {
            mx / rms
        } else {
            0.0
        }
    }
}
