//! The output folder of a positions run (`idexp positions`): [`write_outputs`]
//! writes
//!
//! * `plan.csv`: one row per candidate of the plan (m_i > 0) or of the relaxed
//!   support: `candidate` (1-based), `q1..qn` (when known), `m`, `weight`,
//!   `sensitivity` (D: tr(M⁻¹F_i)), and `x, y, z` of the plotted frame with a robot;
//! * `plan.json`: the same rows with parameter names, criterion and totals;
//! * `candidates.csv`: every candidate with its weight and sensitivity;
//! * `report.json` / `report.txt`: criterion value, certificate, efficiencies,
//!   solver status and times; `design.json`: the resolved design; `status.json`;
//! * `weights.svg` (weights and sensitivities over the candidates) and
//!   `poses.svg` (the chosen poses: two joint coordinates and the frame origin).

use super::design::PositionsRun;
use super::relax::Status;
use crate::error::Result;
use crate::io::plot::{write_svg, Panel, Series};
use crate::io::status::RunState;
use crate::robot::{frame_pose, Workspace};
use serde::Serialize;
use std::path::Path;
use std::time::SystemTime;

#[derive(Serialize)]
struct PlanRow {
    candidate: usize,
    q: Vec<f64>,
    m: usize,
    weight: f64,
    sensitivity: f64,
    position: Option<[f64; 3]>,
}

#[derive(Serialize)]
struct PlanJson<'a> {
    name: &'a str,
    criterion: &'a str,
    parameters: &'a [String],
    experiments: usize,
    cost: f64,
    budget: f64,
    rows: Vec<PlanRow>,
}

#[derive(Serialize)]
struct ReportJson<'a> {
    status: Status,
    criterion: &'a str,
    value_meaning: &'a str,
    parameters: usize,
    candidates: usize,
    candidates_generated: usize,
    rejected_by_limits: usize,
    rejected_by_workspace: usize,
    rejected_by_collision: usize,
    relaxed_value: f64,
    support: usize,
    certificate: &'a super::relax::Certificate,
    solver: &'a super::relax::SolveLog,
    rounded: &'a super::rounding::Rounded,
    information_time: f64,
    parameter_names: &'a [String],
}

fn positions_of(run: &PositionsRun, idx: &[usize]) -> Vec<Option<[f64; 3]>> {
    let Some(r) = &run.robot else { return vec![None; idx.len()] };
    let frame = run.design.plot_frame.as_ref().and_then(|f| r.find_frame(f)).unwrap_or_else(|| r.end_effector());
    let mut ws = Workspace::new(r);
    idx.iter()
        .map(|&i| {
            let q = &run.q[i];
            if q.len() != r.dof() {
                return None;
            }
            let t = frame_pose(r, &mut ws, q, &frame).translation.vector;
            Some([t.x, t.y, t.z])
        })
        .collect()
}

/// Indices of the plan rows: m_i > 0 or relaxed weight > 1e-6.
fn plan_indices(run: &PositionsRun) -> Vec<usize> {
    (0..run.relaxed.weights.len())
        .filter(|&i| run.rounded.m[i] > 0 || run.relaxed.weights[i] > 1e-6)
        .collect()
}

/// The human words for a relaxed-design status.
pub fn status_words(s: Status) -> &'static str {
    match s {
        Status::Optimal => "optimal (certified)",
        Status::NotCertified => "design found, certificate not reached",
        Status::Interrupted => "interrupted (best design so far)",
    }
}

/// Writes every output of a run into `out`; `started`: when the run began
/// (for `status.json`, `None` if unknown).
pub fn write_outputs(run: &PositionsRun, out: &Path, started: Option<SystemTime>) -> Result<()> {
    crate::io::folder::begin(out, "positions", &crate::io::status::fingerprint_of(&run.design)?)?;
    let rel = &run.relaxed;
    let idx = plan_indices(run);
    let pos = positions_of(run, &idx);
    let nq = run.q.first().map(|q| q.len()).unwrap_or(0);
    // plan.csv
    let mut header = vec!["candidate".to_string()];
    header.extend((1..=nq).map(|j| format!("q{j}")));
    header.extend(["m", "weight", "sensitivity"].iter().map(|s| s.to_string()));
    let with_pos = run.robot.is_some() && nq > 0;
    if with_pos {
        header.extend(["x", "y", "z"].iter().map(|s| s.to_string()));
    }
    let rows: Vec<Vec<f64>> = idx
        .iter()
        .zip(&pos)
        .map(|(&i, p)| {
            let mut r = vec![(i + 1) as f64];
            r.extend_from_slice(&run.q[i]);
            r.extend([run.rounded.m[i] as f64, rel.weights[i], rel.sensitivities[i]]);
            if with_pos {
                r.extend(p.unwrap_or([f64::NAN; 3]));
            }
            r
        })
        .collect();
    crate::io::write_csv(&out.join("plan.csv"), &header, &rows)?;
    // plan.json
    let plan = PlanJson {
        name: &run.design.name,
        criterion: rel.criterion.label(),
        parameters: &run.names,
        experiments: run.rounded.total,
        cost: run.rounded.cost,
        budget: run.budget,
        rows: idx
            .iter()
            .zip(&pos)
            .map(|(&i, p)| PlanRow {
                candidate: i + 1,
                q: run.q[i].clone(),
                m: run.rounded.m[i],
                weight: rel.weights[i],
                sensitivity: rel.sensitivities[i],
                position: *p,
            })
            .collect(),
    };
    crate::io::write_json(&out.join("plan.json"), &plan)?;
    // candidates.csv
    let mut h2 = vec!["candidate".to_string()];
    h2.extend((1..=nq).map(|j| format!("q{j}")));
    h2.extend(["rank", "cost", "weight", "sensitivity", "m"].iter().map(|s| s.to_string()));
    let rows2: Vec<Vec<f64>> = (0..rel.weights.len())
        .map(|i| {
            let mut r = vec![(i + 1) as f64];
            r.extend_from_slice(&run.q[i]);
            r.extend([
                run.ranks[i] as f64,
                run.costs.as_ref().map(|c| c[i]).unwrap_or(1.0),
                rel.weights[i],
                rel.sensitivities[i],
                run.rounded.m[i] as f64,
            ]);
            r
        })
        .collect();
    crate::io::write_csv(&out.join("candidates.csv"), &h2, &rows2)?;
    // reports
    let support = rel.weights.iter().filter(|&&w| w > 1e-6).count();
    let rep = ReportJson {
        status: rel.status,
        criterion: rel.criterion.label(),
        value_meaning: rel.criterion.value_label(),
        parameters: run.names.len(),
        candidates: rel.weights.len(),
        candidates_generated: run.generation.0,
        rejected_by_limits: run.generation.1,
        rejected_by_workspace: run.generation.2,
        rejected_by_collision: run.generation.3,
        relaxed_value: rel.value,
        support,
        certificate: &rel.certificate,
        solver: &rel.log,
        rounded: &run.rounded,
        information_time: run.information_time,
        parameter_names: &run.names,
    };
    crate::io::write_json(&out.join("report.json"), &rep)?;
    crate::io::write_atomic(&out.join("report.txt"), report_text(run).as_bytes())?;
    crate::io::write_json(&out.join("design.json"), &run.design)?;
    let state = match rel.status {
        Status::Optimal | Status::NotCertified => RunState::Complete,
        Status::Interrupted => RunState::Interrupted,
    };
    // plots
    let xs: Vec<f64> = (1..=rel.weights.len()).map(|i| i as f64).collect();
    let sx: Vec<f64> = idx.iter().map(|&i| (i + 1) as f64).collect();
    let p1 = Panel {
        title: "relaxed weights".into(),
        x_label: "candidate".into(),
        y_label: "weight".into(),
        series: vec![Series::bars("", sx.clone(), idx.iter().map(|&i| rel.weights[i]).collect())],
        ..Default::default()
    };
    let p2 = Panel {
        title: format!("sensitivity ({} criterion)", rel.criterion.label()),
        x_label: "candidate".into(),
        y_label: "s_i".into(),
        series: vec![
            Series::points("all", xs, rel.sensitivities.clone()),
            Series::points("plan", sx, idx.iter().map(|&i| rel.sensitivities[i]).collect()),
        ],
        hlines: vec![(rel.certificate.reference, "optimum level".into())],
        ..Default::default()
    };
    write_svg(
        &out.join("weights.svg"),
        &format!("{}: weights over the candidates", run.design.name),
        &[p1, p2],
        1,
    )?;
    if nq > 0 {
        // the two joints that vary most
        let mut var: Vec<(usize, f64)> = (0..nq)
            .map(|j| {
                let mean = run.q.iter().map(|q| q[j]).sum::<f64>() / run.q.len() as f64;
                (j, run.q.iter().map(|q| (q[j] - mean).powi(2)).sum::<f64>())
            })
            .collect();
        var.sort_by(|a, b| b.1.total_cmp(&a.1));
        let (ja, jb) = (var[0].0, var.get(1).map(|v| v.0).unwrap_or(var[0].0));
        let mut panels = vec![Panel {
            title: format!("joint space (q{} vs q{})", ja + 1, jb + 1),
            x_label: format!("q{} (rad)", ja + 1),
            y_label: format!("q{} (rad)", jb + 1),
            series: vec![
                Series::points("candidates", run.q.iter().map(|q| q[ja]).collect(), run.q.iter().map(|q| q[jb]).collect()),
                Series::points("plan", idx.iter().map(|&i| run.q[i][ja]).collect(), idx.iter().map(|&i| run.q[i][jb]).collect()),
            ],
            ..Default::default()
        }];
        if with_pos {
            let all: Vec<usize> = (0..run.q.len()).step_by(run.q.len().div_ceil(5000).max(1)).collect();
            let pa = positions_of(run, &all);
            let get = |v: &[Option<[f64; 3]>], k: usize| v.iter().flatten().map(|p| p[k]).collect::<Vec<f64>>();
            for (a, b, t) in [(0usize, 1usize, "top view"), (0, 2, "side view")] {
                let lab = ["x (m)", "y (m)", "z (m)"];
                panels.push(Panel {
                    title: format!("frame origin, {t}"),
                    x_label: lab[a].into(),
                    y_label: lab[b].into(),
                    series: vec![
                        Series::points("candidates", get(&pa, a), get(&pa, b)),
                        Series::points("plan", get(&pos, a), get(&pos, b)),
                    ],
                    ..Default::default()
                });
            }
        }
        let cols = panels.len();
        write_svg(&out.join("poses.svg"), &format!("{}: chosen poses", run.design.name), &panels, cols)?;
    }
    // the final status last: a folder without it is marked `running`
    crate::io::status::write_status(
        out,
        "positions",
        state,
        status_words(rel.status),
        started,
        crate::io::status::fingerprint_of(&run.design)?,
        serde_json::json!({ "relaxed_status": rel.status, "certified": rel.certificate.holds, "efficiency_bound": rel.certificate.efficiency_bound }),
    )?;
    Ok(())
}

/// Human-readable summary of a run.
pub fn report_text(run: &PositionsRun) -> String {
    use std::fmt::Write;
    let rel = &run.relaxed;
    let c = &rel.certificate;
    let r = &run.rounded;
    let mut s = String::new();
    let _ = writeln!(s, "positions: {}", run.design.name);
    let _ = writeln!(
        s,
        "candidates: {} ({} generated, {} outside the limits, {} outside the workspace{}); parameters p = {}",
        rel.weights.len(),
        run.generation.0,
        run.generation.1,
        run.generation.2,
        if run.generation.3 > 0 {
            format!(", {} in collision", run.generation.3)
        } else {
            String::new()
        },
        run.names.len()
    );
    let _ = writeln!(
        s,
        "criterion: {}-optimal, {} = {:.10e}",
        rel.criterion.label(),
        rel.criterion.value_label(),
        rel.value
    );
    let _ = writeln!(s, "status: {}", status_words(rel.status));
    let _ = writeln!(
        s,
        "certificate (all {} candidates): max sensitivity {:.9} at candidate {} vs optimum level {:.9} (prior term {:.3e})",
        c.candidates_checked,
        c.max_sensitivity,
        c.argmax + 1,
        c.reference,
        c.prior_term
    );
    let _ = writeln!(
        s,
        "  efficiency >= {:.9} ({}); criterion gap <= {:.3e}; holds at tol {:.0e}: {}",
        c.efficiency_bound, c.formula, c.gap_bound, c.tol, c.holds
    );
    let support = rel.weights.iter().filter(|&&w| w > 1e-6).count();
    let _ = writeln!(s, "relaxed support: {support} candidates (weight > 1e-6)");
    let l = &rel.log;
    let _ = writeln!(
        s,
        "solver: first order {} iterations (eps {:.2e}) in {:.3} s, pruned to {} candidates; Newton {} iterations on {} working set(s) ({} candidates) {:.3} s{}; Clarabel {} round(s) {:.3} s; total {:.3} s; information {:.3} s",
        l.first_order_iterations,
        l.first_order_eps,
        l.first_order_time,
        l.pruned_to,
        l.newton_iterations,
        l.newton_rounds,
        l.newton_working_set,
        l.newton_time,
        if l.newton_certified { ", certified" } else { "" },
        l.rounds.len(),
        l.clarabel_time,
        l.total_time,
        run.information_time
    );
    for (k, rd) in l.rounds.iter().enumerate() {
        let _ = writeln!(
            s,
            "  round {}: {} candidates, Clarabel {} in {} iterations ({:.3} s, {} variables, {} rows), efficiency bound {:.9}, {} added",
            k + 1,
            rd.working_set,
            rd.clarabel_status,
            rd.iterations,
            rd.solve_time,
            rd.size.0,
            rd.size.1,
            rd.efficiency_bound,
            rd.added
        );
    }
    let used = r.m.iter().filter(|&&m| m > 0).count();
    let _ = writeln!(
        s,
        "rounded plan: {} experiments at {} positions (cost {} of {}); efficiency vs relaxed {:.6} (apportionment {:.6}, {} exchanges); vs optimum >= {:.6}",
        r.total, used, r.cost, run.budget, r.efficiency, r.efficiency_apportionment, r.exchanges, r.efficiency_bound
    );
    s
}

/// The playable poses of a plan: joint names, poses, measurements per pose.
pub type PlanPoses = (Vec<String>, Vec<Vec<f64>>, Vec<usize>);

/// The poses of the rounded plan (m_i > 0) in candidate order, with their
/// number of measurements m_i, and the robot's joint names.
pub fn plan_poses(run: &PositionsRun) -> Result<PlanPoses> {
    let Some(r) = &run.robot else {
        return Err(crate::Error::invalid(
            &run.design.name,
            "export",
            "the plan's candidates are not robot poses (no robot in the design): nothing to play",
        ));
    };
    let names: Vec<String> = r.joints.iter().map(|j| j.name.clone()).collect();
    let mut poses = Vec::new();
    let mut m = Vec::new();
    for i in 0..run.rounded.m.len() {
        if run.rounded.m[i] == 0 {
            continue;
        }
        if run.q[i].len() != names.len() {
            return Err(crate::Error::invalid(
                &run.design.name,
                "export",
                format!("candidate {} has {} joint values, the robot {} joints", i + 1, run.q[i].len(), names.len()),
            ));
        }
        poses.push(run.q[i].clone());
        m.push(run.rounded.m[i]);
    }
    if poses.is_empty() {
        return Err(crate::Error::invalid(&run.design.name, "export", "the rounded plan has no pose"));
    }
    Ok((names, poses, m))
}

/// How the measurement poses are played.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanMotion {
    /// Joint speed of the moves (rad/s).
    pub speed: f64,
    /// Joint acceleration of the moves (rad/s²).
    pub acceleration: f64,
    /// Dwell per measurement at a pose (s); a pose with m_i measurements is
    /// held m_i · dwell.
    pub dwell: f64,
    /// Time to reach the first pose from wherever the robot is (s, ROS 2).
    pub approach: f64,
}

/// Duration of a rest-to-rest move of `dq` (max over joints) under a
/// trapezoidal speed profile with the given speed and acceleration.
fn move_time(dq: f64, v: f64, a: f64) -> f64 {
    let dq = dq.abs();
    if dq <= v * v / a {
        2.0 * (dq / a).sqrt()
    } else {
        dq / v + v / a
    }
}

/// Writes the plan's poses as a URScript `movej` sequence (`<stem>_poses.script`)
/// and/or ROS 2 JointTrajectory waypoints (`<stem>_poses_ros2.yaml`: each
/// pose reached at rest and held for its dwell); returns the paths written.
pub fn write_plan_exports(
    run: &PositionsRun,
    out: &Path,
    formats: &[crate::trajectory::export::Format],
    motion: &PlanMotion,
) -> Result<Vec<std::path::PathBuf>> {
    use crate::trajectory::export::{program_name, ros2_waypoints_yaml, urscript_poses, Format};
    let (names, poses, m) = plan_poses(run)?;
    for (what, v) in [("speed", motion.speed), ("acceleration", motion.acceleration), ("approach", motion.approach)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(crate::Error::invalid("positions export", what, format!("{v}: expected a positive value")));
        }
    }
    if !(motion.dwell.is_finite() && motion.dwell >= 0.0) {
        return Err(crate::Error::invalid("positions export", "dwell", format!("{} s: expected ≥ 0", motion.dwell)));
    }
    std::fs::create_dir_all(out).map_err(|e| crate::Error::io(out, e))?;
    let stem = program_name(&run.design.name);
    let mut written = Vec::new();
    for f in formats {
        match f {
            Format::Ur => {
                // one movej per pose, held for m_i dwells
                let prog = format!("{stem}_poses");
                let holds: Vec<f64> = m.iter().map(|&mi| mi as f64 * motion.dwell).collect();
                let text = urscript_poses(&names, &poses, &prog, (motion.acceleration, motion.speed), motion.dwell)?;
                let mut k = 0;
                let text: String = text
                    .lines()
                    .map(|l| {
                        if l.trim_start().starts_with("sleep(") && k < holds.len() {
                            k += 1;
                            format!("  sleep({})  # {} measurement(s)\n", holds[k - 1], m[k - 1])
                        } else {
                            format!("{l}\n")
                        }
                    })
                    .collect();
                let path = out.join(format!("{prog}.script"));
                crate::io::write_atomic(&path, text.as_bytes())?;
                written.push(path);
            }
            Format::Ros2 => {
                let mut pts = Vec::new();
                let mut times = Vec::new();
                let mut t = motion.approach;
                for (k, (q, &mi)) in poses.iter().zip(&m).enumerate() {
                    if k > 0 {
                        let dq = q.iter().zip(&poses[k - 1]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
                        t += move_time(dq, motion.speed, motion.acceleration);
                    }
                    pts.push(q.clone());
                    times.push(t);
                    let hold = mi as f64 * motion.dwell;
                    if hold > 0.0 {
                        t += hold;
                        pts.push(q.clone());
                        times.push(t);
                    }
                }
                let path = out.join(format!("{stem}_poses_ros2.yaml"));
                crate::io::write_atomic(&path, ros2_waypoints_yaml(&names, &pts, &times)?.as_bytes())?;
                written.push(path);
            }
            Format::Csv => {
                let mut rows = Vec::new();
                for (q, &mi) in poses.iter().zip(&m) {
                    let mut r = q.clone();
                    r.push(mi as f64);
                    rows.push(r);
                }
                let mut header = names.clone();
                header.push("measurements".into());
                let path = out.join(format!("{stem}_poses.csv"));
                crate::io::write_csv(&path, &header, &rows)?;
                written.push(path);
            }
        }
    }
    Ok(written)
}
