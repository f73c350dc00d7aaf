//! Multistart report (paper 001 §6): costs of all starts sorted and normalised
//! by the best (Fig. 3), the share of reasonable models (normalised cost below
//! a stated factor), parameter statistics over the reasonable models (Table 1:
//! min, median, max, mean, std, also normalised by the best model), the
//! theoretical standard deviations of the best model (eq. 5), and Bode
//! magnitude/phase plots of measured vs fitted FRFs per position (Fig. 9).

use super::estimate::FrfData;
use super::fit::FitProblem;
use super::multistart::StartRecord;
use crate::error::Result;
use crate::io::plot::{write_svg, Panel, Series};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Statistics of one parameter over the reasonable models.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ParamStats {
    /// Parameter name.
    pub name: String,
    /// Value in the best model.
    pub best: f64,
    /// Minimum.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation.
    pub std: f64,
    /// Theoretical standard deviation of the best model (eq. 5), if the information matrix is regular.
    pub std_th: Option<f64>,
    /// True value (simulated data only).
    pub truth: Option<f64>,
}

/// The multistart report (`fit.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Estimator name.
    pub estimator: String,
    /// Weights kind.
    pub weights: String,
    /// Starts requested.
    pub starts: usize,
    /// Starts finished.
    pub finished: usize,
    /// Starts with a finite common cost.
    pub evaluated: usize,
    /// Index of the best start (lowest common cost).
    pub best_index: Option<usize>,
    /// Its common cost (LLS, user weights).
    pub best_common_cost: Option<f64>,
    /// Its own estimator cost.
    pub best_cost: Option<f64>,
    /// Reasonable-model factor on the normalised common cost.
    pub reasonable_factor: f64,
    /// Number of reasonable models.
    pub reasonable: usize,
    /// Share of reasonable models among the finished starts.
    pub reasonable_share: f64,
    /// Normalised common costs, sorted (Fig. 3).
    pub normalised_costs: Vec<f64>,
    /// Starts by solver status.
    pub status_counts: BTreeMap<String, usize>,
    /// Parameter statistics (Table 1), physical units.
    pub params: Vec<ParamStats>,
    /// Worst |θ̂ − θ_true| / std_th over the springs of the best model (simulated data only).
    pub max_spring_error_sigma: Option<f64>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Builds the report from the records. `truth` is θ_true when known.
pub fn build(problem: &FitProblem, records: &[StartRecord], starts: usize, factor: f64, weights: &str, truth: Option<&[f64]>) -> Report {
    let names = problem.model.unknown_names();
    let mut ok: Vec<&StartRecord> = records.iter().filter(|r| r.common_cost.is_some()).collect();
    ok.sort_by(|a, b| {
        a.common_cost
            .unwrap_or(f64::INFINITY)
            .total_cmp(&b.common_cost.unwrap_or(f64::INFINITY))
            .then(a.index.cmp(&b.index))
    });
    let best = ok.first().copied();
    let cbest = best.and_then(|b| b.common_cost).unwrap_or(f64::NAN);
    let normalised: Vec<f64> = ok.iter().map(|r| r.common_cost.unwrap_or(f64::NAN) / cbest).collect();
    let reasonable: Vec<&StartRecord> = ok.iter().zip(&normalised).filter(|(_, c)| **c <= factor).map(|(r, _)| *r).collect();
    let mut status_counts = BTreeMap::new();
    for r in records {
        let s = serde_json::to_value(r.status)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default();
        *status_counts.entry(s).or_insert(0) += 1;
    }
    let std_th: Option<Vec<f64>> = best
        .and_then(|b| problem.covariance(&b.theta).ok())
        .map(|p| (0..p.nrows()).map(|i| p[(i, i)].max(0.0).sqrt()).collect());
    let params: Vec<ParamStats> = match best {
        None => Vec::new(),
        Some(b) => (0..names.len())
            .map(|i| {
                let mut v: Vec<f64> = reasonable.iter().map(|r| r.theta[i]).collect();
                let n = v.len() as f64;
                let mean = v.iter().sum::<f64>() / n;
                let std = if v.len() > 1 {
                    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
                } else {
                    0.0
                };
                let min = v.iter().copied().fold(f64::INFINITY, f64::min);
                let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                ParamStats {
                    name: names[i].clone(),
                    best: b.theta[i],
                    min,
                    median: median(&mut v),
                    max,
                    mean,
                    std,
                    std_th: std_th.as_ref().map(|s| s[i]),
                    truth: truth.map(|t| t[i]),
                }
            })
            .collect(),
    };
    let max_spring_error_sigma = match (truth, &std_th, best) {
        (Some(t), Some(s), Some(b)) => Some(
            names
                .iter()
                .enumerate()
                .filter(|(_, n)| n.starts_with("k_"))
                .map(|(i, _)| (b.theta[i] - t[i]).abs() / s[i])
                .fold(0.0, f64::max),
        ),
        _ => None,
    };
    Report {
        estimator: problem.estimator.name().to_string(),
        weights: weights.to_string(),
        starts,
        finished: records.len(),
        evaluated: ok.len(),
        best_index: best.map(|b| b.index),
        best_common_cost: best.and_then(|b| b.common_cost),
        best_cost: best.and_then(|b| b.cost),
        reasonable_factor: factor,
        reasonable: reasonable.len(),
        reasonable_share: if records.is_empty() {
            0.0
        } else {
            reasonable.len() as f64 / records.len() as f64
        },
        normalised_costs: normalised,
        status_counts,
        params,
        max_spring_error_sigma,
    }
}

impl Report {
    /// Human-readable summary (stdout).
    pub fn text(&self) -> String {
        let mut s = format!(
            "estimator {} ({} weights): {}/{} starts finished, best start {} with common cost {:.6e}\nreasonable models (normalised cost ≤ {}): {} of {} = {:.0} %\n",
            self.estimator,
            self.weights,
            self.finished,
            self.starts,
            self.best_index.map(|i| i.to_string()).unwrap_or("-".into()),
            self.best_common_cost.unwrap_or(f64::NAN),
            self.reasonable_factor,
            self.reasonable,
            self.finished,
            100.0 * self.reasonable_share
        );
        s.push_str("status:");
        for (k, v) in &self.status_counts {
            s.push_str(&format!(" {k} {v}"));
        }
        s.push('\n');
        let truth = self.params.iter().any(|p| p.truth.is_some());
        s.push_str(&format!(
            "{:<12} {:>12} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9}{}\n",
            "param",
            "best",
            "min",
            "median",
            "max",
            "mean",
            "std",
            "std_th",
            if truth { "  true/best" } else { "" }
        ));
        for p in &self.params {
            let r = |v: f64| v / p.best;
            s.push_str(&format!(
                "{:<12} {:>12.5e} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>9.2e} {:>9}{}\n",
                p.name,
                p.best,
                r(p.min),
                r(p.median),
                r(p.max),
                r(p.mean),
                p.std / p.best.abs(),
                p.std_th.map(|v| format!("{:.2e}", v / p.best.abs())).unwrap_or("-".into()),
                p.truth.map(|t| format!("  {:.5}", t / p.best)).unwrap_or_default()
            ));
        }
        s.push_str("(min..std normalised by the best model, as paper 001 Table 1)\n");
        if let Some(e) = self.max_spring_error_sigma {
            s.push_str(&format!("springs of the best model vs truth: max |θ̂ − θ| / std_th = {e:.2}\n"));
        }
        s
    }
}

/// Sorted normalised costs (Fig. 3) as SVG.
pub fn costs_svg(path: &Path, r: &Report) -> Result<()> {
    let x: Vec<f64> = (1..=r.normalised_costs.len()).map(|i| i as f64).collect();
    let panel = Panel {
        title: format!("{} ({} weights): sorted normalised LLS cost", r.estimator, r.weights),
        x_label: "optimisation (sorted)".into(),
        y_label: "V / V_best".into(),
        series: vec![Series::points("starts", x, r.normalised_costs.clone())],
        hlines: vec![(r.reasonable_factor, format!("reasonable ≤ {}", r.reasonable_factor))],
        log_y: true,
        log_x: false,
        x_names: vec![],
    };
    write_svg(path, "Multistart costs (paper 001 Fig. 3)", &[panel], 1)
}

/// The unit of G = s^r Bᵀ A⁻¹ B (motor torque in, motor position, speed or
/// acceleration out) for the FRF output: "rad/(N·m)", "(rad/s)/(N·m)" or
/// "(rad/s²)/(N·m)".
pub fn g_unit(output: crate::elastic::linear::Output) -> &'static str {
    use crate::elastic::linear::Output;
    match output {
        Output::Position => "rad/(N·m)",
        Output::Velocity => "(rad/s)/(N·m)",
        Output::Acceleration => "(rad/s²)/(N·m)",
    }
}

/// Bode plots (magnitude of every element, phase of the diagonal) of measured
/// vs fitted FRFs at every position: `bode_pos<i>.svg`, `phase_pos<i>.svg` in `dir`.
pub fn bode_svgs(dir: &Path, problem: &FitProblem, data: &FrfData, theta: &[f64]) -> Result<()> {
    let n = data.n;
    let fitted = problem.model_frfs(theta)?;
    for (pi, p) in data.positions.iter().enumerate() {
        let mut mag = Vec::new();
        let mut ph = Vec::new();
        for a in 0..n {
            for b in 0..n {
                let meas: Vec<f64> = p.g.iter().map(|g| g.to_mat(n)[(a, b)].norm()).collect();
                let fit: Vec<f64> = fitted[pi].iter().map(|g| g[(a, b)].norm()).collect();
                let sd: Vec<f64> = p.var.iter().map(|v| v[a * n + b].sqrt()).collect();
                mag.push(Panel {
                    title: format!("|G{}{}|", a + 1, b + 1),
                    x_label: "f (Hz)".into(),
                    y_label: format!("|G{}{}| ({})", a + 1, b + 1, g_unit(data.output)),
                    series: vec![
                        Series::points("measured", data.freqs_hz.clone(), meas),
                        Series::line("σ̂", data.freqs_hz.clone(), sd),
                        Series::line("model", data.freqs_hz.clone(), fit),
                    ],
                    hlines: vec![],
                    log_y: true,
                    log_x: true,
                    x_names: vec![],
                });
            }
            let deg = |c: crate::elastic::C64| c.arg().to_degrees();
            ph.push(Panel {
                title: format!("arg G{}{}", a + 1, a + 1),
                x_label: "f (Hz)".into(),
                y_label: format!("arg G{}{} (deg)", a + 1, a + 1),
                series: vec![
                    Series::points("measured", data.freqs_hz.clone(), p.g.iter().map(|g| deg(g.to_mat(n)[(a, a)])).collect()),
                    Series::line("model", data.freqs_hz.clone(), fitted[pi].iter().map(|g| deg(g[(a, a)])).collect()),
                ],
                hlines: vec![],
                log_y: false,
                log_x: true,
                x_names: vec![],
            });
        }
        let q: Vec<String> = p.q0.iter().map(|v| format!("{v:.2}")).collect();
        write_svg(
            &dir.join(format!("bode_pos{}.svg", pi + 1)),
            &format!("position {} (q0 = [{}]): measured vs fitted |G|", pi + 1, q.join(", ")),
            &mag,
            n,
        )?;
        write_svg(
            &dir.join(format!("phase_pos{}.svg", pi + 1)),
            &format!("position {}: phase of the diagonal", pi + 1),
            &ph,
            n.min(3),
        )?;
    }
    Ok(())
}

/// Parameter statistics as CSV rows (name column written separately): best, min, median, max, mean, std, std_th, truth.
pub fn params_csv(path: &Path, r: &Report) -> Result<()> {
    let mut s = String::from("param,best,min,median,max,mean,std,std_th,truth\n");
    let f = |v: Option<f64>| v.map(crate::io::format_f64).unwrap_or_default();
    for p in &r.params {
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{}\n",
            p.name,
            crate::io::format_f64(p.best),
            crate::io::format_f64(p.min),
            crate::io::format_f64(p.median),
            crate::io::format_f64(p.max),
            crate::io::format_f64(p.mean),
            crate::io::format_f64(p.std),
            f(p.std_th),
            f(p.truth)
        ));
    }
    crate::io::write_atomic(path, s.as_bytes())
}
