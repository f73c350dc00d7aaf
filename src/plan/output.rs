//! The plan's folder: `plan.json` (design, model summary, solution,
//! predictions, rehearsal), `report.txt`, `plan.csv` (per experiment),
//! `params.csv` (predicted σ of every parameter), `targets.csv`,
//! `sigma_vs_repetitions/<k>_<target>.svg` and `status.json` (`complete`,
//! `infeasible` for unreachable targets, `failed`, `interrupted`).

use super::model::{Space, TargetKind};
use super::solve::{curve, parameter_sigmas, PlanStatus, Prepared};
use super::PlanRun;
use crate::error::Result;
use crate::io::plot::{write_svg, Panel, Series};
use crate::io::status::RunState;
use serde::Serialize;
use std::fmt::Write;
use std::path::Path;
use std::time::SystemTime;

#[derive(Serialize)]
struct PlanJson<'a> {
    name: &'a str,
    design: &'a super::PlanDesign,
    space: Space,
    candidates: &'a [super::Candidate],
    tasks: &'a [super::Task],
    targets: &'a [super::Target],
    solution: &'a super::Solution,
    parameter_names: &'a [String],
    parameter_sigma: Vec<f64>,
    base_names: &'a [String],
    base_sigma: Vec<f64>,
    notes: &'a [String],
    rehearsal: Option<&'a super::Rehearsal>,
}

fn state_of(run: &PlanRun) -> (RunState, &'static str) {
    match run.solution.status {
        PlanStatus::Planned => (RunState::Complete, "every target met"),
        PlanStatus::Unreachable => (RunState::Infeasible, "some targets cannot be met by any combination (report.txt says why)"),
        PlanStatus::OverBudget => (
            RunState::Infeasible,
            "every target can be met, but not within the budget (report.txt gives the best plan within it and the targets it misses)",
        ),
        PlanStatus::Interrupted => (RunState::Interrupted, "stopped before the relaxation finished"),
        PlanStatus::Failed => (RunState::Failed, "the relaxation failed"),
    }
}

/// Writes the folder `out` (atomically per file; status.json last).
pub fn write_outputs(run: &PlanRun, out: &Path, started: Option<SystemTime>) -> Result<()> {
    let fp = crate::io::status::fingerprint_of(&run.design)?;
    crate::io::folder::begin(out, "plan", &fp)?;
    let model = &run.model;
    let sol = &run.solution;
    let pre = Prepared::new(model);
    let (own, base) = parameter_sigmas(model, &pre, &sol.repetitions);
    let j = PlanJson {
        name: &run.design.name,
        design: &run.design,
        space: model.space,
        candidates: &model.candidates,
        tasks: &model.tasks,
        targets: &model.targets,
        solution: sol,
        parameter_names: &model.names,
        parameter_sigma: own.clone(),
        base_names: &model.base.names,
        base_sigma: base.clone(),
        notes: &model.notes,
        rehearsal: run.rehearsal.as_ref(),
    };
    crate::io::write_json(&out.join("plan.json"), &j)?;
    crate::io::write_atomic(&out.join("report.txt"), report_text(run).as_bytes())?;
    // plan.csv
    let mut s = String::from("experiment,repetitions,relaxed,cost_per_repetition,setup,cost,max_repetitions,rows_per_repetition,within_budget_repetitions\n");
    for (e, c) in model.candidates.iter().enumerate() {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{}",
            c.name,
            sol.repetitions[e],
            crate::io::format_f64(sol.relaxed[e]),
            crate::io::format_f64(c.cost),
            crate::io::format_f64(c.setup),
            crate::io::format_f64(time_of(c, sol.repetitions[e])),
            c.max_repetitions,
            c.rows,
            sol.within_budget.as_ref().map_or(String::new(), |w| w.repetitions[e].to_string())
        );
    }
    crate::io::write_atomic(&out.join("plan.csv"), s.as_bytes())?;
    // params.csv
    let mut s = String::from("parameter,space,nominal,sigma,relative_sigma\n");
    let nominal_base = &model.base.k * model.robot.nominal_params();
    let rows = model
        .names
        .iter()
        .zip(own.iter())
        .zip(model.nominal.iter())
        .map(|((n, &sg), &v)| (n, if model.space == Space::Base { "base" } else { "standard" }, v, sg))
        .chain(if model.space == Space::Standard {
            model
                .base
                .names
                .iter()
                .zip(base.iter())
                .zip(nominal_base.iter())
                .map(|((n, &sg), &v)| (n, "base", v, sg))
                .collect::<Vec<_>>()
        } else {
            Vec::new()
        });
    for (n, sp, v, sg) in rows {
        let rel = if v != 0.0 { sg / v.abs() } else { f64::NAN };
        let _ = writeln!(
            s,
            "{n},{sp},{},{},{}",
            crate::io::format_f64(v),
            crate::io::format_f64(sg),
            crate::io::format_f64(rel)
        );
    }
    crate::io::write_atomic(&out.join("params.csv"), s.as_bytes())?;
    // targets.csv
    let mut s = String::from("target,bound,predicted,best_reachable,met\n");
    for (i, t) in model.targets.iter().enumerate() {
        let _ = writeln!(
            s,
            "{},{},{},{},{}",
            t.label,
            crate::io::format_f64(t.bound),
            crate::io::format_f64(sol.values[i]),
            crate::io::format_f64(sol.best[i]),
            sol.values[i] <= t.bound * (1.0 + 1e-9)
        );
    }
    crate::io::write_atomic(&out.join("targets.csv"), s.as_bytes())?;
    if matches!(sol.status, PlanStatus::Planned | PlanStatus::OverBudget) {
        write_curves(run, &pre, &out.join("sigma_vs_repetitions"))?;
    }
    let (state, words) = state_of(run);
    crate::io::status::write_status(
        out,
        "plan",
        state,
        words,
        started,
        fp,
        serde_json::json!({ "cost": sol.cost, "relaxed_cost": sol.relaxed_cost, "repetitions": sol.repetitions, "refused": sol.refused.len(), "budget": sol.budget }),
    )
}

/// One SVG per target: its predicted value against the repetitions of each
/// planned (or candidate) experiment, the others held at the plan.
fn write_curves(run: &PlanRun, pre: &Prepared, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
    let model = &run.model;
    let r = &run.solution.repetitions;
    let curves: Vec<Vec<(usize, Vec<f64>)>> = (0..r.len())
        .map(|e| {
            let upto = (2 * r[e] + 2).min(model.candidates[e].max_repetitions).max(r[e] + 1);
            curve(pre, r, e, upto)
        })
        .collect();
    for (i, t) in model.targets.iter().enumerate() {
        let mut series = Vec::new();
        for (e, c) in model.candidates.iter().enumerate() {
            let (x, y): (Vec<f64>, Vec<f64>) = curves[e].iter().filter(|(_, v)| v[i].is_finite()).map(|(k, v)| (*k as f64, v[i])).unzip();
            if !x.is_empty() {
                series.push(Series::line(format!("{} (others at plan)", c.name), x, y));
            }
        }
        let (px, py): (Vec<f64>, Vec<f64>) = r.iter().map(|&k| (k as f64, run.solution.values[i])).unzip();
        series.push(Series::points("the plan", px, py));
        let unit = match t.kind {
            TargetKind::Task { .. } => "RMS prediction error (N·m)".to_string(),
            TargetKind::Parameter { ref name, ref of, .. } => format!("predicted {} ({})", t.label, target_unit(model, name, of)),
        };
        let panel = Panel {
            title: t.label.clone(),
            x_label: "repetitions of the experiment".into(),
            y_label: unit,
            series,
            hlines: vec![(t.bound, "target".into())],
            log_y: true,
            ..Default::default()
        };
        let file = format!("{:02}_{}.svg", i + 1, sanitize(&t.label));
        write_svg(
            &dir.join(file),
            &format!("{}: predicted {} vs repetitions", run.design.name, t.label),
            &[panel],
            1,
        )?;
    }
    Ok(())
}

/// The unit of a parameter target (`of`: `base` or `standard`).
pub fn target_unit(model: &super::Model, name: &str, of: &str) -> &'static str {
    let found = match of {
        "base" => model.base.names.iter().position(|x| x == name).map(|k| model.base.unit(&model.robot, k)),
        _ => model
            .robot
            .params()
            .iter()
            .position(|p| p.name == name)
            .map(|j| crate::params::unit(&model.robot, j)),
    };
    found.unwrap_or("SI")
}

/// Robot time of `r` repetitions of candidate `c`: its repetitions and, if used, its setup (s).
fn time_of(c: &super::Candidate, r: usize) -> f64 {
    if r > 0 {
        c.cost * r as f64 + c.setup
    } else {
        0.0
    }
}

fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' { c } else { '_' })
        .collect::<String>()
        .trim_matches('_')
        .to_string()
}

fn g(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4e}")
    } else {
        "∞".into()
    }
}

/// The report.
pub fn report_text(run: &PlanRun) -> String {
    let model = &run.model;
    let sol = &run.solution;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "plan: {} (robot {}, {} base parameters)",
        run.design.name,
        model.robot.name,
        model.base.n_base()
    );
    let _ = writeln!(
        s,
        "space: {}",
        match model.space {
            Space::Base => "base parameters (no prior)".to_string(),
            Space::Standard => "standard parameters with the study's Euclidean prior (posterior σ)".to_string(),
        }
    );
    let _ = writeln!(
        s,
        "\ncandidates (information per repetition from the rows the study keeps; each row an independent torque sample):"
    );
    let _ = writeln!(
        s,
        "  {:<18} {:>9} {:>9} {:>8} {:>10} {:>6} {:>5}  σ per joint (N·m)",
        "experiment", "cost (s)", "setup (s)", "max", "rows/rep", "rank", "T (s)"
    );
    for c in &model.candidates {
        let sig: Vec<String> = c.sigma.iter().map(|v| format!("{v:.3}")).collect();
        let _ = writeln!(
            s,
            "  {:<18} {:>9.2} {:>9.1} {:>8} {:>10} {:>6} {:>5.1}  [{}]",
            c.name,
            c.cost,
            c.setup,
            c.max_repetitions,
            c.rows,
            c.rank,
            c.duration,
            sig.join(", ")
        );
    }
    for c in &model.candidates {
        let rep: Vec<String> = c.repeatable.iter().map(|v| format!("{v:.3}")).collect();
        let worst = c
            .repeatable
            .iter()
            .zip(&c.sigma)
            .map(|(s, n)| if *n > 0.0 { s / n } else { 0.0 })
            .fold(0.0, f64::max);
        let _ = writeln!(
            s,
            "  {}: repeatable residual (noise-free run) [{}] N·m{}",
            c.name,
            rep.join(", "),
            if worst > 0.1 {
                format!(
                    ": {:.0} % of σ — averaging more than ~{:.0} repetitions cannot lower it (a model or filter error, a bias the study reports as noise)",
                    100.0 * worst,
                    (1.0 / (worst * worst)).ceil()
                )
            } else {
                String::new()
            }
        );
    }
    for c in model.candidates.iter().filter(|c| c.noise_source != super::model::SIMULATED_NOISE) {
        let _ = writeln!(s, "  {}: σ from {}", c.name, c.noise_source);
    }
    for n in &model.notes {
        let _ = writeln!(s, "  note: {n}");
    }
    match sol.status {
        PlanStatus::Unreachable => {
            let _ = writeln!(
                s,
                "\nREFUSED: {} target(s) cannot be met by any combination of the candidates:",
                sol.refused.len()
            );
            for r in &sol.refused {
                let _ = writeln!(s, "  {}: asked {}, best reachable {}\n    {}", r.label, g(r.bound), g(r.best), r.reason);
            }
            return s;
        }
        PlanStatus::Interrupted | PlanStatus::Failed => {
            let _ = writeln!(s, "\nthe relaxation ended {} ({}): no plan", sol.solver_status, sol.status.name());
            return s;
        }
        PlanStatus::Planned | PlanStatus::OverBudget => {}
    }
    let _ = writeln!(
        s,
        "\n{3} (relaxation by supporting hyperplanes: {1} LPs, the last {0}; rounding: {2}):",
        sol.solver_status,
        sol.iterations,
        sol.rounding,
        if sol.status == PlanStatus::OverBudget {
            "the cheapest plan meeting every target, OVER THE BUDGET"
        } else {
            "plan"
        }
    );
    let _ = writeln!(s, "  {:<18} {:>11} {:>9} {:>10}", "experiment", "repetitions", "relaxed", "time (s)");
    for (e, c) in model.candidates.iter().enumerate() {
        let _ = writeln!(
            s,
            "  {:<18} {:>11} {:>9.3} {:>10.1}",
            c.name,
            sol.repetitions[e],
            sol.relaxed[e],
            time_of(c, sol.repetitions[e])
        );
    }
    let gap_pct = if sol.relaxed_cost > 0.0 { 100.0 * sol.gap / sol.relaxed_cost } else { 0.0 };
    let _ = writeln!(
        s,
        "  robot time {:.1} s ({:.2} h); relaxed bound {:.1} s (a lower bound on any plan; relaxation solved to {:.2e} s); gap {:.1} s ({gap_pct:.1} %)",
        sol.cost,
        sol.cost / 3600.0,
        sol.relaxed_cost,
        sol.relaxed_upper - sol.relaxed_cost,
        sol.gap
    );
    if let Some(b) = sol.budget {
        let _ = writeln!(
            s,
            "  budget {b:.1} s ({:.2} h): the plan uses {:.1} % of it{}",
            b / 3600.0,
            100.0 * sol.cost / b,
            if sol.status == PlanStatus::OverBudget { " — OVER BUDGET" } else { "" }
        );
    }
    if let Some(w) = &sol.within_budget {
        let _ = writeln!(
            s,
            "\nOVER BUDGET: the cheapest plan meeting every target needs {:.1} s, the budget is {:.1} s; {}.",
            sol.cost,
            sol.budget.unwrap_or(f64::NAN),
            if sol.relaxed_cost > sol.budget.unwrap_or(f64::INFINITY) {
                format!(
                    "no plan meeting every target fits (the relaxed bound, {:.1} s, is above the budget too)",
                    sol.relaxed_cost
                )
            } else {
                format!(
                    "the relaxed bound, {:.1} s, is within it, but no whole-repetition plan found fits",
                    sol.relaxed_cost
                )
            }
        );
        let _ = writeln!(
            s,
            "the best plan within the budget (smallest worst value/target ratio {:.3}; no plan within the budget does better than {:.3}):",
            w.worst_ratio, w.lower_bound
        );
        let _ = writeln!(s, "  {:<18} {:>11} {:>10}", "experiment", "repetitions", "time (s)");
        for (e, c) in model.candidates.iter().enumerate() {
            let _ = writeln!(s, "  {:<18} {:>11} {:>10.1}", c.name, w.repetitions[e], time_of(c, w.repetitions[e]));
        }
        let _ = writeln!(
            s,
            "  robot time {:.1} s ({:.1} % of the budget)",
            w.cost,
            100.0 * w.cost / sol.budget.unwrap_or(f64::NAN)
        );
        let _ = writeln!(s, "  it misses {} target(s):", w.missed.len());
        for m in &w.missed {
            let _ = writeln!(s, "    {}: asked {}, reaches {} ({:.2}× the target)", m.label, g(m.bound), g(m.value), m.ratio);
        }
    }
    let _ = writeln!(s, "\ntargets:");
    let _ = writeln!(s, "  {:<24} {:>11} {:>11} {:>11}", "target", "asked", "predicted", "best");
    for (i, t) in model.targets.iter().enumerate() {
        let _ = writeln!(s, "  {:<24} {:>11} {:>11} {:>11}", t.label, g(t.bound), g(sol.values[i]), g(sol.best[i]));
    }
    let pre = Prepared::new(model);
    let (own, base) = parameter_sigmas(model, &pre, &sol.repetitions);
    let _ = writeln!(s, "\npredicted σ of every base parameter:");
    let nominal_base = &model.base.k * model.robot.nominal_params();
    for (k, n) in model.base.names.iter().enumerate() {
        let rel = if nominal_base[k] != 0.0 {
            format!("{:.2} %", 100.0 * base[k] / nominal_base[k].abs())
        } else {
            "-".into()
        };
        let _ = writeln!(s, "  {:<24} {:>11} {:>10}", n, g(base[k]), rel);
    }
    if model.space == Space::Standard {
        let _ = writeln!(s, "(params.csv also lists every standard parameter's posterior σ; {} values)", own.len());
    }
    if let Some(r) = &run.rehearsal {
        let _ = writeln!(
            s,
            "\nrehearsal: {} noise seeds, repetitions {:?}; every target met (by the study's own σ) in {} of {} seeds",
            r.seeds, r.repetitions, r.all_met, r.seeds
        );
        let _ = writeln!(
            s,
            "  {:<24} {:>11} {:>11} {:>11} {:>6} {:>12} {:>7} {:>8}",
            "target", "asked", "predicted", "study σ", "met", "empirical", "ratio", "offset"
        );
        for t in &r.targets {
            let _ = writeln!(
                s,
                "  {:<24} {:>11} {:>11} {:>11} {:>6} {:>12} {:>7.3} {:>8.2}",
                t.label,
                g(t.bound),
                g(t.predicted),
                g(t.achieved_mean),
                format!("{}/{}", t.met, r.seeds),
                g(t.empirical),
                t.ratio,
                t.offset
            );
        }
        let _ = writeln!(s, "  (empirical: the estimates' standard deviation over the seeds, or a task's RMS validation error over the seeds; ratio: empirical / predicted spread; offset: mean error from the truth in predicted spreads)");
    }
    s
}
