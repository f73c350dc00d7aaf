//! The figures and tables of identification that the study's writer
//! ([`super::study::StudyResult::write`]) draws (torques, parameters, the
//! reduction, `params.csv`), and the files of a dedicated one-joint fit of
//! paper 002 §3.2 ([`write_joint_fit`]: the fit as JSON, a figure of the data
//! with the fitted model, and `report.txt`).

use super::experiments::{FrictionFit, GravityFit};
use super::study::dedicated::JointFit;
use super::Processed;
use crate::error::{Error, Result};
use crate::io::plot::{write_svg, Panel, Series};
use std::path::Path;

/// Writes a dedicated fit's files into `out` (1-based `joint`, `pr` its
/// processed run) and returns its report line:
/// - gravity: `gravity.json`, `gravity.svg` (measured torque against q with
///   the fitted model of both slopes, [`gravity_panel`]), `report.txt`;
/// - friction: `friction.json`, `friction.svg` (τ − J q̈ − τ_g against q̇ for
///   |q̇| > `min_speed`, with the fitted asymmetric Coulomb + viscous
///   friction), `report.txt`.
pub fn write_joint_fit(out: &Path, joint: usize, pr: &Processed, fit: &JointFit) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let j = joint.saturating_sub(1);
    match fit {
        JointFit::Gravity(g) => {
            crate::io::write_json(&out.join("gravity.json"), g)?;
            let q: Vec<f64> = pr.q.iter().map(|v| v[j]).collect();
            let tau: Vec<f64> = pr.tau.iter().map(|v| v[j]).collect();
            let qd: Vec<f64> = pr.qd.iter().map(|v| v[j]).collect();
            write_svg(
                &out.join("gravity.svg"),
                &format!("gravity experiment, joint {joint}"),
                &[gravity_panel(&q, &qd, &tau, g)],
                1,
            )?;
        }
        JointFit::Friction { fit: f, min_speed, .. } => {
            crate::io::write_json(&out.join("friction.json"), f)?;
            write_svg(
                &out.join("friction.svg"),
                &format!("friction experiment, joint {joint}"),
                &[friction_panel(pr, j, f, *min_speed)],
                1,
            )?;
        }
    }
    let text = fit_text(joint, fit);
    crate::io::write_atomic(&out.join("report.txt"), text.as_bytes())?;
    Ok(text)
}

/// A dedicated fit's report line.
pub fn fit_text(joint: usize, fit: &JointFit) -> String {
    match fit {
        JointFit::Gravity(g) => format!(
            "gravity experiment, joint {joint}: k = {:.6} N·m, q_off = {:.6} rad ({:.3}°), c+ = {:.6}, c- = {:.6} N·m at {:.4} rad/s, {} samples, rms {:.4e} N·m\n",
            g.k,
            g.q_off,
            g.q_off.to_degrees(),
            g.offset_pos,
            g.offset_neg,
            g.speed,
            g.samples,
            g.rms
        ),
        JointFit::Friction { fit: f, gravity_source, .. } => format!(
            "friction experiment, joint {joint}: J = {:.6} kg·m², Fc+ = {:.6}, Fv+ = {:.6}, Fc- = {:.6}, Fv- = {:.6} (std {:?}), gravity k = {:.6}, q_off = {:.6} ({}), {} samples, rms {:.4e} N·m\n",
            f.inertia,
            f.fc_pos,
            f.fv_pos,
            f.fc_neg,
            f.fv_neg,
            f.std.iter().map(|s| format!("{s:.2e}")).collect::<Vec<_>>(),
            f.gravity_k,
            f.gravity_q_off,
            gravity_source,
            f.samples,
            f.rms
        ),
    }
}

/// The gravity figure: measured torque against q, split by the direction of
/// motion (q̇ > 0, q̇ < 0, standstill), with the fitted model of eq. 23 on
/// each slope, k sin(q + q_off) + c₊ and k sin(q + q_off) + c₋, drawn over
/// the q range that slope covers (the two branches the data follow).
pub fn gravity_panel(q: &[f64], qd: &[f64], tau: &[f64], g: &GravityFit) -> Panel {
    let pick = |f: &dyn Fn(f64) -> bool| -> (Vec<f64>, Vec<f64>) { q.iter().zip(qd).zip(tau).filter(|((_, v), _)| f(**v)).map(|((a, _), t)| (*a, *t)).unzip() };
    let moving = 0.02 * g.speed;
    let (qp, tp) = pick(&|v| v > moving);
    let (qn, tn) = pick(&|v| v < -moving);
    let (qs, ts) = pick(&|v| v.abs() <= moving);
    let branch = |qs: &[f64], c: f64| -> (Vec<f64>, Vec<f64>) {
        let lo = qs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = qs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !(lo.is_finite() && hi.is_finite()) {
            return (vec![], vec![]);
        }
        let x: Vec<f64> = (0..=200).map(|i| lo + (hi - lo) * i as f64 / 200.0).collect();
        let y = x.iter().map(|&v| g.torque(v) + c).collect();
        (x, y)
    };
    let (xp, yp) = branch(&qp, g.offset_pos);
    let (xn, yn) = branch(&qn, g.offset_neg);
    let mut series = vec![Series::points("measured, q̇ > 0", qp, tp), Series::points("measured, q̇ < 0", qn, tn)];
    if !qs.is_empty() {
        series.push(Series::points("measured, q̇ ≈ 0", qs, ts));
    }
    series.push(Series::line(format!("k sin(q + q_off) + c₊, c₊ = {:.3} N·m", g.offset_pos), xp, yp));
    series.push(Series::line(format!("k sin(q + q_off) + c₋, c₋ = {:.3} N·m", g.offset_neg), xn, yn));
    Panel {
        title: format!("measured torque and fitted model (k = {:.3} N·m, q_off = {:.4} rad)", g.k, g.q_off),
        x_label: "q (rad)".into(),
        y_label: "torque (N·m)".into(),
        series,
        ..Default::default()
    }
}

/// The panels of `params.svg`: the estimates with ±3σ error bars, the
/// relative standard deviations σ* and (with a truth) the z scores, each
/// with the parameter names on the x axis.
pub fn params_panels(est: &super::Estimate) -> Vec<Panel> {
    let k = est.names.len();
    let x: Vec<f64> = (1..=k).map(|i| i as f64).collect();
    let mut bars = Series::bars("θ̂ ± 3σ", x.clone(), est.theta.clone());
    bars.err = Some(est.std.iter().map(|s| 3.0 * s).collect());
    let mut panels = vec![
        Panel {
            title: format!("{k} base parameter estimates θ̂ with ±3σ error bars"),
            x_label: "parameter".into(),
            y_label: "value (SI)".into(),
            series: vec![bars],
            x_names: est.names.clone(),
            ..Default::default()
        },
        Panel {
            title: "relative standard deviation σ* (eq. 14)".into(),
            x_label: "parameter".into(),
            y_label: "σ* (%)".into(),
            series: vec![Series::bars("σ*", x, est.rel_std.iter().map(|v| 100.0 * v.min(1e6)).collect())],
            log_y: true,
            x_names: est.names.clone(),
            ..Default::default()
        },
    ];
    if let Some(tr) = &est.truth {
        let xs: Vec<f64> = (1..=tr.len()).map(|i| i as f64).collect();
        panels.push(Panel {
            title: "(estimate − truth)/σ".into(),
            x_label: "parameter".into(),
            y_label: "z".into(),
            series: vec![Series::bars("z", xs, tr.iter().map(|r| r.z).collect())],
            hlines: vec![(3.0, "±3".into()), (-3.0, String::new())],
            x_names: tr.iter().map(|r| r.name.clone()).collect(),
            ..Default::default()
        });
    }
    panels
}

/// The panels of `reduction.svg`: per step (x axis: the parameter tried),
/// the condition number of the tried model and the largest relative error
/// growth, removed and kept parameters apart, against the e_tol line.
pub fn reduction_panels(r: &super::reduce::Reduction) -> Vec<Panel> {
    let names: Vec<String> = r.steps.iter().map(|s| s.parameter.clone()).collect();
    let x: Vec<f64> = (1..=r.steps.len()).map(|i| i as f64).collect();
    let split = |f: &dyn Fn(&super::reduce::Step) -> f64, removed: bool| -> (Vec<f64>, Vec<f64>) {
        x.iter()
            .zip(&r.steps)
            .filter(|(_, s)| (s.decision == "removed") == removed)
            .map(|(a, s)| (*a, f(s)))
            .unzip()
    };
    let (xr, cr) = split(&|s| s.cond, true);
    let (xk, ck) = split(&|s| s.cond, false);
    // growth on a log axis (it spans decades around e_tol); values below
    // e_tol/100 (including a shrinking error) are drawn at that floor
    let tol = 100.0 * r.options.tol;
    let floor = if tol > 0.0 { tol / 100.0 } else { 1e-6 };
    let (_, gr) = split(&|s| (100.0 * s.growth).max(floor), true);
    let (_, gk) = split(&|s| (100.0 * s.growth).max(floor), false);
    vec![
        Panel {
            title: "condition number of the tried model".into(),
            x_label: "parameter tried (in step order)".into(),
            y_label: "cond".into(),
            series: vec![Series::points("removed", xr.clone(), cr), Series::points("kept", xk.clone(), ck)],
            log_y: true,
            x_names: names.clone(),
            ..Default::default()
        },
        Panel {
            title: format!("largest relative growth of e*_j (floor {} %)", crate::io::plot::tick_label(floor)),
            x_label: "parameter tried (in step order)".into(),
            y_label: "growth (%)".into(),
            series: vec![Series::points("removed", xr, gr), Series::points("kept", xk, gk)],
            hlines: vec![(tol, format!("e_tol = {} %", crate::io::plot::tick_label(tol)))],
            log_y: true,
            x_names: names,
            ..Default::default()
        },
    ]
}

/// The friction figure: τ − J q̈ − τ_g of joint `j` (0-based) against q̇,
/// and the fitted friction (eq. 2) where |q̇| > `min_speed`.
fn friction_panel(pr: &Processed, j: usize, f: &FrictionFit, min_speed: f64) -> Panel {
    let v: Vec<f64> = pr.qd.iter().map(|s| s[j]).collect();
    let tf: Vec<f64> = (0..pr.len())
        .map(|p| pr.tau[p][j] - f.inertia * pr.qdd[p][j] - f.gravity_k * (pr.q[p][j] + f.gravity_q_off).sin())
        .collect();
    let mut vs: Vec<f64> = v.iter().copied().filter(|x| x.abs() > min_speed).collect();
    vs.sort_by(f64::total_cmp);
    let model: Vec<f64> = vs
        .iter()
        .map(|&x| if x > 0.0 { f.fc_pos + f.fv_pos * x } else { f.fc_neg + f.fv_neg * x })
        .collect();
    Panel {
        title: "τ − J q̈ − τ_g against q̇, and the fitted friction (eq. 2)".into(),
        x_label: "q̇ (rad/s)".into(),
        y_label: "torque (N·m)".into(),
        series: vec![Series::points("measured", v, tf), Series::line("fit", vs, model)],
        ..Default::default()
    }
}

/// `params.csv`: every base parameter (estimate, std, σ*, grouping; and the
/// consistent value when present) and every standard parameter (the
/// consistent value; std and σ* when it is a base parameter on its own, empty
/// when the data only determine it in combination with others).
pub fn params_csv(est: &super::Estimate) -> String {
    let cons = est.consistent.as_ref().map(|c| (c.base.as_slice(), c.standard.as_slice()));
    let q = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    let mut s = String::from("kind,name,value,std,rel_std,consistent,grouping\n");
    for i in 0..est.names.len() {
        s.push_str(&format!(
            "base,{},{},{},{},{},{}\n",
            est.names[i],
            est.theta[i],
            est.std[i],
            est.rel_std[i],
            cons.map(|c| c.0[i].to_string()).unwrap_or_default(),
            q(&est.groupings[i])
        ));
    }
    for (j, nm) in est.standard_names.iter().enumerate() {
        // a standard parameter that is a base parameter on its own (its row of K is a unit vector on it)
        let alone = est
            .base_k
            .iter()
            .position(|row| row[j] == 1.0 && row.iter().enumerate().all(|(c, &v)| c == j || v == 0.0));
        let (sd, rs) = match alone {
            Some(i) => (est.std[i].to_string(), est.rel_std[i].to_string()),
            None => (String::new(), String::new()),
        };
        let v = cons.map(|c| c.1[j].to_string()).unwrap_or_default();
        s.push_str(&format!(
            "standard,{nm},{v},{sd},{rs},{v},{}\n",
            q(if alone.is_some() { "identifiable alone" } else { "in combination only" })
        ));
    }
    s
}

/// Per joint, measured against predicted torques of `ds` (at most ~1500
/// points per curve) for each labelled estimate of `fits`; with `resid`, the
/// residual of the first fit ("measured − predicted").
pub fn torque_panels(ds: &super::Dataset, t: &[f64], fits: &[(&str, &[f64])], resid: bool) -> Vec<Panel> {
    let preds: Vec<nalgebra::DVector<f64>> = fits.iter().map(|(_, th)| &ds.c * nalgebra::DVector::from_column_slice(th)).collect();
    let step = ds.n_samples.div_ceil(1500).max(1);
    (0..ds.n)
        .map(|j| {
            let idx: Vec<usize> = (0..ds.y.len()).filter(|&i| ds.joint[i] == j && ds.sample[i] % step == 0).collect();
            let x: Vec<f64> = idx.iter().map(|&i| t.get(ds.sample[i]).copied().unwrap_or(ds.sample[i] as f64)).collect();
            let meas: Vec<f64> = idx.iter().map(|&i| ds.y[i]).collect();
            let series = if resid {
                let pr = &preds[0];
                vec![Series::line(
                    "measured − predicted",
                    x,
                    idx.iter().zip(&meas).map(|(&i, m)| m - pr[i]).collect(),
                )]
            } else {
                let mut v = vec![Series::line("measured", x.clone(), meas)];
                for ((label, _), pr) in fits.iter().zip(&preds) {
                    v.push(Series::line(*label, x.clone(), idx.iter().map(|&i| pr[i]).collect()));
                }
                v
            };
            Panel {
                title: format!("joint {}", j + 1),
                x_label: "t (s)".into(),
                y_label: "torque (N·m)".into(),
                series,
                ..Default::default()
            }
        })
        .collect()
}
