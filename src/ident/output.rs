//! The output folders of the dedicated experiments of paper 002 §3.2
//! (`idexp identify --experiment gravity|friction`): the fit as JSON, a
//! figure of the data with the fitted model, and `report.txt`. Each writer
//! returns the report text it wrote.

use super::experiments::{FrictionFit, GravityFit};
use super::Processed;
use crate::error::{Error, Result};
use crate::io::plot::{write_svg, Panel, Series};
use std::path::Path;

/// Writes `gravity.json`, `gravity.svg` (measured torque of joint `joint`,
/// 1-based, against q with the fitted k sin(q + q_off)) and `report.txt`
/// into `out`.
pub fn write_gravity(out: &Path, joint: usize, pr: &Processed, g: &GravityFit) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let j = joint.saturating_sub(1);
    crate::io::write_json(&out.join("gravity.json"), g)?;
    let q: Vec<f64> = pr.q.iter().map(|v| v[j]).collect();
    let tau: Vec<f64> = pr.tau.iter().map(|v| v[j]).collect();
    let fit: Vec<f64> = q.iter().map(|&x| g.torque(x)).collect();
    write_svg(
        &out.join("gravity.svg"),
        &format!("gravity experiment, joint {joint}"),
        &[Panel {
            title: "measured torque and fitted gravity k sin(q + q_off)".into(),
            x_label: "q (rad)".into(),
            y_label: "torque (N·m)".into(),
            series: vec![Series::points("measured", q.clone(), tau), Series::line("gravity fit", q, fit)],
            ..Default::default()
        }],
        1,
    )?;
    let text = format!(
        "gravity experiment, joint {joint}: k = {:.6} N·m, q_off = {:.6} rad ({:.3}°), c+ = {:.6}, c- = {:.6} N·m at {:.4} rad/s, {} samples, rms {:.4e} N·m\n",
        g.k,
        g.q_off,
        g.q_off.to_degrees(),
        g.offset_pos,
        g.offset_neg,
        g.speed,
        g.samples,
        g.rms
    );
    crate::io::write_atomic(&out.join("report.txt"), text.as_bytes())?;
    Ok(text)
}

/// Writes `friction.json`, `friction.svg` (τ − J q̈ − τ_g of joint `joint`,
/// 1-based, against q̇ for |q̇| > `min_speed`, with the fitted asymmetric
/// Coulomb + viscous friction) and `report.txt` into `out`. `gravity_source`
/// says where the gravity term came from (for the report).
pub fn write_friction(out: &Path, joint: usize, pr: &Processed, f: &FrictionFit, min_speed: f64, gravity_source: &str) -> Result<String> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let j = joint.saturating_sub(1);
    crate::io::write_json(&out.join("friction.json"), f)?;
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
    write_svg(
        &out.join("friction.svg"),
        &format!("friction experiment, joint {joint}"),
        &[Panel {
            title: "τ − J q̈ − τ_g against q̇, and the fitted friction (eq. 2)".into(),
            x_label: "q̇ (rad/s)".into(),
            y_label: "torque (N·m)".into(),
            series: vec![Series::points("measured", v, tf), Series::line("fit", vs, model)],
            ..Default::default()
        }],
        1,
    )?;
    let text = format!(
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
    );
    crate::io::write_atomic(&out.join("report.txt"), text.as_bytes())?;
    Ok(text)
}

/// `params.csv`: every base parameter (estimate, std, σ*, grouping; and the
/// consistent value when present) and every standard parameter (the
/// consistent value; std and σ* when it is a base parameter on its own, empty
/// when the data only determine it in combination with others).
pub fn params_csv(est: &super::Estimate) -> String {
    let q = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    let mut s = String::from("kind,name,value,std,rel_std,consistent,grouping\n");
    let cons = est.consistent.as_ref();
    for i in 0..est.names.len() {
        s.push_str(&format!(
            "base,{},{},{},{},{},{}\n",
            est.names[i],
            est.theta[i],
            est.std[i],
            est.rel_std[i],
            cons.map(|c| c.base[i].to_string()).unwrap_or_default(),
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
        let v = cons.map(|c| c.standard[j].to_string()).unwrap_or_default();
        s.push_str(&format!(
            "standard,{nm},{v},{sd},{rs},{v},{}\n",
            q(if alone.is_some() { "identifiable alone" } else { "in combination only" })
        ));
    }
    s
}
