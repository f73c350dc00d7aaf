//! Nonparametric FRF estimates (paper 001 §4, eq. 2): per position and block
//! G_b(ω_k) = Y_b(ω_k) U_b(ω_k)⁻¹ from the period-averaged DFTs of n
//! experiments, averaged over blocks, with the sample covariance of the mean;
//! the unexcited even lines measure nonlinear distortion against the noise
//! floor.
//!
//! DFT convention: X(k) = (1/N_P) Σ_t x_t e^{−2πj k t/N_P}.

use crate::data::MotorRecord;
use crate::elastic::{Output, C64};
use crate::error::{Error, Result};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A complex n×n matrix in files (row-major real and imaginary parts).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CMat {
    /// Real parts, row-major.
    pub re: Vec<f64>,
    /// Imaginary parts, row-major.
    pub im: Vec<f64>,
}

impl CMat {
    /// From a complex matrix.
    pub fn from_mat(m: &DMatrix<C64>) -> Self {
        let n = m.nrows();
        let mut re = Vec::with_capacity(n * n);
        let mut im = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..m.ncols() {
                re.push(m[(i, j)].re);
                im.push(m[(i, j)].im);
            }
        }
        CMat { re, im }
    }
    /// To an n×n complex matrix.
    pub fn to_mat(&self, n: usize) -> DMatrix<C64> {
        DMatrix::from_fn(n, n, |i, j| C64::new(self.re[i * n + j], self.im[i * n + j]))
    }
}

/// Nonlinear distortion seen on the even (unexcited) lines of one position.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Distortion {
    /// Output power at the even lines relative to the excited odd lines, per motor (dB).
    pub even_vs_odd_db: Vec<f64>,
    /// Output power at the even lines relative to the noise floor there, per motor (dB; needs ≥ 2 periods).
    pub even_vs_noise_db: Option<Vec<f64>>,
    /// True when any motor's even lines exceed the noise floor by the design's `frf.distortion_db`.
    pub flagged: bool,
}

/// FRF estimate at one position.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FrfPosition {
    /// Actuated joint angles q0 (rad).
    pub q0: Vec<f64>,
    /// Blocks averaged.
    pub blocks: usize,
    /// Ĝ(ω_k), one per line.
    pub g: Vec<CMat>,
    /// Variance of each element of Ĝ(ω_k) (covariance of the block mean; diagonal of Λ̂), row-major.
    pub var: Vec<Vec<f64>>,
    /// Even-line distortion (time-domain data only).
    pub distortion: Option<Distortion>,
}

/// FRF estimates at all positions.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FrfData {
    /// Output quantity.
    pub output: Output,
    /// Motors n.
    pub n: usize,
    /// Line frequencies (Hz).
    pub freqs_hz: Vec<f64>,
    /// Per position.
    pub positions: Vec<FrfPosition>,
    /// Where the data came from.
    pub source: String,
}

impl FrfData {
    /// Reads and checks an `frf.json` file.
    pub fn read(path: &Path) -> Result<FrfData> {
        let text = crate::io::read_to_string(path)?;
        let d: FrfData = serde_json::from_str(&text).map_err(|e| Error::parse(path, format!("line {}: {e}", e.line())))?;
        let nn = d.n * d.n;
        let ctx = path.display().to_string();
        if d.n == 0 || d.freqs_hz.is_empty() || d.freqs_hz.iter().any(|f| !f.is_finite() || *f <= 0.0) {
            return Err(Error::invalid(&ctx, "freqs_hz", "expected positive finite frequencies and n ≥ 1"));
        }
        for (i, p) in d.positions.iter().enumerate() {
            if p.g.len() != d.freqs_hz.len() || p.var.len() != d.freqs_hz.len() {
                return Err(Error::invalid(
                    &ctx,
                    format!("positions[{i}].g"),
                    format!("expected {} lines", d.freqs_hz.len()),
                ));
            }
            for (k, (g, v)) in p.g.iter().zip(&p.var).enumerate() {
                if g.re.len() != nn || g.im.len() != nn || v.len() != nn {
                    return Err(Error::invalid(&ctx, format!("positions[{i}].g[{k}]"), format!("expected {nn} entries")));
                }
                if g.re.iter().chain(&g.im).chain(v).any(|x| !x.is_finite()) || v.iter().any(|x| *x < 0.0) {
                    return Err(Error::invalid(
                        &ctx,
                        format!("positions[{i}].g[{k}]"),
                        "expected finite values and non-negative variances",
                    ));
                }
            }
        }
        Ok(d)
    }
}

/// Mean FRF per line and element variances of the mean per line.
pub type BlockAverage = (Vec<DMatrix<C64>>, Vec<DMatrix<f64>>);

/// Block average: Ĝ = mean_b G_b and, per element, the variance of that mean
/// Σ_b |G_b − Ĝ|² / (B(B−1)) (0 for B = 1).
pub fn average_blocks(gb: &[Vec<DMatrix<C64>>]) -> Result<BlockAverage> {
    let nb = gb.len();
    if nb == 0 {
        return Err(Error::Numerical("no blocks to average".into()));
    }
    let nl = gb[0].len();
    let mut mean = Vec::with_capacity(nl);
    let mut var = Vec::with_capacity(nl);
    for k in 0..nl {
        let n = gb[0][k].nrows();
        let mut m = DMatrix::from_element(n, n, C64::new(0.0, 0.0));
        for b in gb {
            m += &b[k];
        }
        m /= C64::new(nb as f64, 0.0);
        let mut v = DMatrix::zeros(n, n);
        if nb > 1 {
            for b in gb {
                for i in 0..n {
                    for j in 0..n {
                        v[(i, j)] += (b[k][(i, j)] - m[(i, j)]).norm_sqr();
                    }
                }
            }
            v /= (nb * (nb - 1)) as f64;
        }
        mean.push(m);
        var.push(v);
    }
    Ok((mean, var))
}

/// Full sample covariance Λ̂(ω_k) of vec Ĝ (n²×n², column-stacked vec) from block FRFs.
pub fn block_covariance(gb: &[Vec<DMatrix<C64>>], k: usize) -> DMatrix<C64> {
    let nb = gb.len();
    let n = gb[0][k].nrows();
    let nn = n * n;
    let vecm = |m: &DMatrix<C64>| nalgebra::DVector::from_fn(nn, |r, _| m[(r % n, r / n)]);
    let mut mean = nalgebra::DVector::from_element(nn, C64::new(0.0, 0.0));
    for b in gb {
        mean += vecm(&b[k]);
    }
    mean /= C64::new(nb as f64, 0.0);
    let mut c = DMatrix::from_element(nn, nn, C64::new(0.0, 0.0));
    if nb > 1 {
        for b in gb {
            let d = vecm(&b[k]) - &mean;
            c += &d * d.adjoint();
        }
        c /= C64::new((nb * (nb - 1)) as f64, 0.0);
    }
    c
}

/// The zero-order-hold response e^{−jωT/2} sinc(ωT/2) at ω (rad/s), sample time `ts`.
pub fn zoh(omega: f64, ts: f64) -> C64 {
    let x = 0.5 * omega * ts;
    let s = if x.abs() < 1e-12 { 1.0 } else { x.sin() / x };
    C64::from_polar(s, -x)
}

/// Description of a set of runs (one position), as written by the simulator.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RunsManifest {
    /// Sample rate (Hz).
    pub rate: f64,
    /// Samples per period N_P.
    pub samples: usize,
    /// Periods discarded at the start of each run.
    pub transient: usize,
    /// Measured periods after the transient.
    pub periods: usize,
    /// Motors n.
    pub n: usize,
    /// Excited harmonics k.
    pub lines: Vec<usize>,
    /// Even detection harmonics.
    pub even_lines: Vec<usize>,
    /// Positions q0.
    pub positions: Vec<Vec<f64>>,
    /// Blocks per position.
    pub blocks: usize,
    /// Output of the estimate.
    pub output: Output,
    /// Divide out the zero-order hold.
    pub zoh: bool,
    /// Distortion threshold (dB).
    pub distortion_db: f64,
    /// Run files, relative to the manifest: `files[position][block][experiment]`.
    pub files: Vec<Vec<Vec<String>>>,
}

fn dft_lines(x: &[f64], np: usize, lines: &[usize], planner: &mut rustfft::FftPlanner<f64>) -> Vec<C64> {
    let fft = planner.plan_fft_forward(np);
    let mut buf: Vec<C64> = x.iter().map(|&v| C64::new(v, 0.0)).collect();
    fft.process(&mut buf);
    lines.iter().map(|&k| buf[k] / np as f64).collect()
}

/// FRF of one position from its runs `runs[block][experiment]` (n experiments each).
pub fn estimate_position(m: &RunsManifest, q0: &[f64], runs: &[Vec<MotorRecord>], distortion_db: f64) -> Result<(FrfPosition, Vec<Vec<DMatrix<C64>>>)> {
    let n = m.n;
    let np = m.samples;
    let need = (m.transient + m.periods) * np;
    let ts = 1.0 / m.rate;
    let mut planner = rustfft::FftPlanner::new();
    let mut gb: Vec<Vec<DMatrix<C64>>> = Vec::new();
    let nl = m.lines.len();
    let ne = m.even_lines.len();
    let mut p_odd = vec![0.0; n];
    let mut p_even = vec![0.0; n];
    let mut p_noise = vec![0.0; n];
    let mut count = 0usize;
    for (b, exps) in runs.iter().enumerate() {
        if exps.len() != n {
            return Err(Error::dim(format!("experiments in block {b}"), n, exps.len()));
        }
        let mut uk = vec![DMatrix::from_element(n, n, C64::new(0.0, 0.0)); nl];
        let mut yk = vec![DMatrix::from_element(n, n, C64::new(0.0, 0.0)); nl];
        for (e, run) in exps.iter().enumerate() {
            if run.u.len() < need || run.y.len() < need {
                return Err(Error::dim(
                    format!("samples of run (block {b}, experiment {e})"),
                    need,
                    run.u.len().min(run.y.len()),
                ));
            }
            for ch in 0..n {
                let mut even_per: Vec<Vec<C64>> = Vec::new();
                let mut uacc = vec![C64::new(0.0, 0.0); nl];
                let mut yacc = vec![C64::new(0.0, 0.0); nl];
                for p in 0..m.periods {
                    let s0 = (m.transient + p) * np;
                    let us: Vec<f64> = (s0..s0 + np).map(|t| run.u[t][ch]).collect();
                    let ys: Vec<f64> = (s0..s0 + np).map(|t| run.y[t][ch]).collect();
                    let uf = dft_lines(&us, np, &m.lines, &mut planner);
                    let mut all: Vec<usize> = m.lines.clone();
                    all.extend_from_slice(&m.even_lines);
                    let yf = dft_lines(&ys, np, &all, &mut planner);
                    for l in 0..nl {
                        uacc[l] += uf[l];
                        yacc[l] += yf[l];
                    }
                    even_per.push(yf[nl..].to_vec());
                }
                let pp = m.periods as f64;
                for l in 0..nl {
                    uk[l][(ch, e)] = uacc[l] / pp;
                    yk[l][(ch, e)] = yacc[l] / pp;
                    p_odd[ch] += (yacc[l] / pp).norm_sqr() / nl as f64;
                }
                for l in 0..ne {
                    let mean: C64 = even_per.iter().map(|v| v[l]).sum::<C64>() / pp;
                    p_even[ch] += mean.norm_sqr() / ne.max(1) as f64;
                    if m.periods > 1 {
                        let var: f64 = even_per.iter().map(|v| (v[l] - mean).norm_sqr()).sum::<f64>() / (pp - 1.0) / pp;
                        p_noise[ch] += var / ne.max(1) as f64;
                    }
                }
            }
            count += 1;
        }
        let mut g = Vec::with_capacity(nl);
        for l in 0..nl {
            let w = std::f64::consts::TAU * m.lines[l] as f64 * m.rate / np as f64;
            let uinv = uk[l].clone().try_inverse().ok_or_else(|| {
                Error::Numerical(format!(
                    "block {b}: the input spectrum matrix U(ω) is singular at line {} (experiments not independent)",
                    m.lines[l]
                ))
            })?;
            let s = C64::new(0.0, w);
            let mut gl = &yk[l] * uinv * s.powi(m.output.power());
            if m.zoh {
                gl /= zoh(w, ts);
            }
            g.push(gl);
        }
        gb.push(g);
    }
    let (mean, var) = average_blocks(&gb)?;
    let distortion = if ne > 0 && count > 0 {
        let db = |a: f64, b: f64| if a > 0.0 && b > 0.0 { 10.0 * (a / b).log10() } else { f64::NEG_INFINITY };
        let evo: Vec<f64> = (0..n).map(|c| db(p_even[c], p_odd[c])).collect();
        let evn: Option<Vec<f64>> = if m.periods > 1 {
            Some((0..n).map(|c| db(p_even[c], p_noise[c])).collect())
        } else {
            None
        };
        let flagged = evn.as_ref().is_some_and(|v| v.iter().any(|x| *x > distortion_db));
        Some(Distortion {
            even_vs_odd_db: evo.iter().map(|v| if v.is_finite() { *v } else { -400.0 }).collect(),
            even_vs_noise_db: evn.map(|v| v.iter().map(|x| if x.is_finite() { *x } else { -400.0 }).collect()),
            flagged,
        })
    } else {
        None
    };
    Ok((
        FrfPosition {
            q0: q0.to_vec(),
            blocks: gb.len(),
            g: mean.iter().map(CMat::from_mat).collect(),
            var: var.iter().map(|v| (0..n * n).map(|r| v[(r / n, r % n)]).collect()).collect(),
            distortion,
        },
        gb,
    ))
}

/// Estimates the FRF at every position of a runs manifest (`runs.json`).
pub fn estimate_from_manifest(path: &Path) -> Result<FrfData> {
    let text = crate::io::read_to_string(path)?;
    let m: RunsManifest = serde_json::from_str(&text).map_err(|e| Error::parse(path, format!("line {}: {e}", e.line())))?;
    let ctx = path.display().to_string();
    if m.n == 0 || m.samples < 8 || m.lines.is_empty() || m.rate.is_nan() || m.rate <= 0.0 || m.periods == 0 {
        return Err(Error::invalid(
            &ctx,
            "samples",
            "expected n ≥ 1, samples ≥ 8, rate > 0, periods ≥ 1 and excited lines",
        ));
    }
    if m.lines.iter().chain(&m.even_lines).any(|&k| k == 0 || k >= m.samples / 2) {
        return Err(Error::invalid(&ctx, "lines", format!("harmonics must lie in 1..{}", m.samples / 2)));
    }
    if m.files.len() != m.positions.len() {
        return Err(Error::invalid(
            &ctx,
            "files",
            format!("expected one entry per position ({})", m.positions.len()),
        ));
    }
    let dir: PathBuf = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut positions = Vec::new();
    for (pi, (q0, blocks)) in m.positions.iter().zip(&m.files).enumerate() {
        if blocks.len() != m.blocks {
            return Err(Error::invalid(&ctx, format!("files[{pi}]"), format!("expected {} blocks", m.blocks)));
        }
        let runs: Vec<Vec<MotorRecord>> = blocks
            .iter()
            .map(|exps| exps.iter().map(|f| MotorRecord::read(&dir.join(f), m.n)).collect::<Result<Vec<_>>>())
            .collect::<Result<_>>()?;
        let (pos, _) = estimate_position(&m, q0, &runs, m.distortion_db)?;
        positions.push(pos);
    }
    Ok(FrfData {
        output: m.output,
        n: m.n,
        freqs_hz: m.lines.iter().map(|&k| k as f64 * m.rate / m.samples as f64).collect(),
        positions,
        source: format!("runs {}", path.display()),
    })
}
