//! Identifiability report of a trajectory and the output files of
//! `idexp excite` / `idexp assess`.
//!
//! For samples (q, q̇, q̈)_i, i = 1..N, of any trajectory, C is the stacked
//! base regressor (N·n × m, unweighted) and C_w = W½ C with W½ = diag(1/σ_j)
//! the torque-noise weights. The report gives
//!
//! * the singular values and the condition number of C_w with unit columns,
//!   and the numerical rank (σ_k > 10⁻⁸ σ_1);
//! * the sensitivity of each parameter, c̄_i = ‖c_i‖₁ / (n N) (paper 000 eq. 10);
//! * the covariance of the WLS estimate from the given data with noise
//!   σ_j on joint j, var(θ̂) = (C_wᵀ C_w)⁻¹ (paper 000 eq. 13 with N_f = 1),
//!   the standard deviations σ_i and the relative ones σ*_i = σ_i / |θ_i|
//!   (eq. 14) at the nominal base-parameter values; when C is rank
//!   deficient, those of the model without the non-excited parameters (which
//!   get ∞);
//! * the parameters that are not excited: zero columns, and those with a
//!   component above 0.1 in a right singular vector of the numerical null space.

use super::constraints::{ConstraintKind, Margin};
use super::{ExciteResult, Problem, Status};
use crate::error::{Error, Result};
use crate::io::plot::{write_svg, Panel, Series};
use crate::io::status::RunState;
use crate::io::States;
use crate::optim::Termination;
use crate::params::BaseParams;
use crate::robot::{regressor_rows, Robot, Workspace};
use nalgebra::DMatrix;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Relative rank tolerance on the singular values of the unit-column matrix.
pub const RANK_TOL: f64 = 1e-8;

/// Identifiability measures of a sampled trajectory.
#[derive(Debug, Clone, Serialize)]
pub struct Identifiability {
    /// Number of samples N.
    pub samples: usize,
    /// Rows N·n of C.
    pub rows: usize,
    /// Base-parameter names (columns of C).
    pub names: Vec<String>,
    /// Each base parameter as a combination of standard ones.
    pub groupings: Vec<String>,
    /// Numerical rank of C.
    pub rank: usize,
    /// Condition number of C_w with unit columns (∞ when rank deficient).
    pub cond: f64,
    /// Singular values of C_w with unit columns, decreasing.
    pub singular_values: Vec<f64>,
    /// Condition number of the model without the non-excited parameters (= `cond` at full rank).
    pub cond_excited: f64,
    /// Sensitivities c̄_i (paper 000 eq. 10), in the units of torque per unit parameter.
    pub sensitivity: Vec<f64>,
    /// Nominal base-parameter values.
    pub nominal: Vec<f64>,
    /// Predicted standard deviations σ_i from one period (eq. 13).
    pub std_dev: Vec<f64>,
    /// Predicted relative standard deviations σ*_i = σ_i/|θ_i| (eq. 14; ∞ if θ_i = 0 or rank deficient).
    pub rel_std_dev: Vec<f64>,
    /// Torque noise standard deviation per joint used for W and σ_i.
    pub noise: Vec<f64>,
    /// Parameters not excited (zero column or in the numerical null space).
    pub unexcited: Vec<String>,
    /// Excited parameters whose predicted relative standard deviation exceeds 100 % (nominal ≠ 0) or is unbounded.
    pub poorly_identifiable: Vec<String>,
}

/// Stacks the base regressor of `states` and computes the report.
/// `noise`: σ_j per joint (N·m).
pub fn assess(robot: &Robot, base: &BaseParams, states: &States, noise: &[f64]) -> Result<Identifiability> {
    let n = robot.dof();
    let mut acc = AssessAccumulator::new(robot, base, noise)?;
    for i in 0..states.len() {
        for (what, v) in [("q", &states.q[i]), ("qd", &states.qd[i]), ("qdd", &states.qdd[i])] {
            if v.len() != n {
                return Err(Error::dim(format!("{what} of sample {i}"), n, v.len()));
            }
        }
        acc.add(&states.q[i], &states.qd[i], &states.qdd[i]);
    }
    acc.finish()
}

/// [`assess`] of a states CSV read block by block ([`read_states`]'s format
/// and checks, every `every`-th row): memory independent of the file length.
pub fn assess_file(robot: &Robot, base: &BaseParams, path: &Path, every: usize, noise: &[f64]) -> Result<Identifiability> {
    let n = robot.dof();
    let mut rdr = crate::io::states::StatesReader::open(path, n)?;
    let mut acc = AssessAccumulator::new(robot, base, noise)?;
    let mut block = crate::io::states::StateBlock::default();
    while rdr.next_block(4096, every, &mut block)? > 0 {
        for i in 0..block.len(n) {
            let r = i * n..(i + 1) * n;
            acc.add(&block.q[r.clone()], &block.qd[r.clone()], &block.qdd[r]);
        }
    }
    if acc.samples == 0 {
        return Err(Error::Data {
            path: path.to_path_buf(),
            row: 0,
            column: "q1".into(),
            msg: "the file has no data rows".into(),
        });
    }
    acc.finish()
}

/// Rows of the weighted base regressor per QR update of the accumulator.
const ASSESS_BLOCK: usize = 1024;

/// Incremental [`assess`]: the weighted base regressor C_w (rows C/σ_j) is
/// never stored; its triangular QR factor R (C_w = Q R, m×m) is updated block
/// by block, and R has C_w's singular values, right singular vectors and
/// column norms.
struct AssessAccumulator<'a> {
    robot: &'a Robot,
    base: &'a BaseParams,
    noise: Vec<f64>,
    ws: Workspace,
    y: Vec<f64>,
    qd: Vec<f64>,
    /// Pending rows (row-major, m each) of C_w.
    rows: Vec<f64>,
    r: Option<DMatrix<f64>>,
    abs_sum: Vec<f64>,
    samples: usize,
}

impl<'a> AssessAccumulator<'a> {
    fn new(robot: &'a Robot, base: &'a BaseParams, noise: &[f64]) -> Result<Self> {
        let n = robot.dof();
        if noise.len() != n {
            return Err(Error::dim("noise levels (one per joint)", n, noise.len()));
        }
        let m = base.n_base();
        Ok(AssessAccumulator {
            robot,
            base,
            noise: noise.to_vec(),
            ws: Workspace::new(robot),
            y: vec![0.0; n * robot.n_params()],
            qd: vec![0.0; n],
            rows: Vec::with_capacity((ASSESS_BLOCK + n) * m),
            r: None,
            abs_sum: vec![0.0; m],
            samples: 0,
        })
    }

    fn add(&mut self, q: &[f64], qd: &[f64], qdd: &[f64]) {
        let n = self.robot.dof();
        let p = self.robot.n_params();
        self.qd.copy_from_slice(qd);
        for v in self.qd.iter_mut() {
            if v.abs() < super::objective::ZERO_VELOCITY {
                *v = 0.0;
            }
        }
        regressor_rows(self.robot, &mut self.ws, q, &self.qd, qdd, &mut self.y);
        for r in 0..n {
            for (j, &col) in self.base.independent.iter().enumerate() {
                let c = self.y[r * p + col];
                self.abs_sum[j] += c.abs();
                self.rows.push(c / self.noise[r]);
            }
        }
        self.samples += 1;
        if self.rows.len() >= ASSESS_BLOCK * self.base.n_base() {
            self.flush();
        }
    }

    /// R ← triangular factor of [R; pending rows].
    fn flush(&mut self) {
        let m = self.base.n_base();
        let nr = self.rows.len() / m;
        if nr == 0 {
            return;
        }
        let prev = self.r.as_ref().map(|r| r.nrows()).unwrap_or(0);
        let mut a = DMatrix::zeros(prev + nr, m);
        if let Some(r) = &self.r {
            a.view_mut((0, 0), (prev, m)).copy_from(r);
        }
        for i in 0..nr {
            for j in 0..m {
                a[(prev + i, j)] = self.rows[i * m + j];
            }
        }
        self.rows.clear();
        let r = if a.nrows() >= m { a.qr().r() } else { a };
        self.r = Some(r);
    }

    fn finish(mut self) -> Result<Identifiability> {
        let n = self.robot.dof();
        let m = self.base.n_base();
        let ns = self.samples;
        if ns * n < m {
            return Err(Error::invalid(
                "assess",
                "states",
                format!("{ns} samples × {n} joints cannot determine {m} base parameters"),
            ));
        }
        self.flush();
        let cw = self.r.take().unwrap_or_else(|| DMatrix::zeros(m, m));
        let sensitivity: Vec<f64> = self.abs_sum.iter().map(|s| s / (ns * n) as f64).collect();
        identifiability_from_factor(self.robot, self.base, &self.noise, cw, sensitivity, ns)
    }
}

/// The report from a matrix with the weighted base regressor's singular
/// values, right singular vectors and column norms (its QR factor R).
fn identifiability_from_factor(robot: &Robot, base: &BaseParams, noise: &[f64], cw: DMatrix<f64>, sensitivity: Vec<f64>, ns: usize) -> Result<Identifiability> {
    let n = robot.dof();
    let m = base.n_base();
    let norms: Vec<f64> = (0..m).map(|j| cw.column(j).norm()).collect();
    let maxn = norms.iter().cloned().fold(0.0, f64::max);
    let mut cn = cw.clone();
    for j in 0..m {
        let f = if norms[j] > 1e-14 * maxn.max(1e-300) { 1.0 / norms[j] } else { 0.0 };
        cn.column_mut(j).scale_mut(f);
    }
    let (_, s, v) = crate::linalg::thin_svd(&cn)?;
    let s1 = s[0];
    let rank = s.iter().filter(|&&x| x > RANK_TOL * s1).count();
    let cond = if rank < m { f64::INFINITY } else { s1 / s[m - 1] };
    let theta = robot.nominal_params();
    let nominal: Vec<f64> = base.base_values(theta.as_slice()).iter().copied().collect();
    let mut unexcited_idx = Vec::new();
    for i in 0..m {
        let zero = norms[i] <= 1e-14 * maxn.max(1e-300);
        let null = (rank..m).any(|k| v[(i, k)].abs() > 0.1);
        if zero || null {
            unexcited_idx.push(i);
        }
    }
    let unexcited: Vec<String> = unexcited_idx.iter().map(|&i| base.names[i].clone()).collect();
    // standard deviations: of the full model when C has full rank, else of the
    // model with the non-excited parameters removed (they stay at ∞)
    let mut std_dev = vec![f64::INFINITY; m];
    let keep: Vec<usize> = (0..m).filter(|i| !unexcited_idx.contains(i)).collect();
    let mut cond_excited = cond;
    if rank == m {
        for i in 0..m {
            let d = 1.0 / norms[i];
            let var: f64 = (0..m).map(|k| (v[(i, k)] / s[k]).powi(2)).sum();
            std_dev[i] = d * var.sqrt();
        }
    } else if !keep.is_empty() {
        let sub = DMatrix::from_fn(cn.nrows(), keep.len(), |r, c| cn[(r, keep[c])]);
        let (_, s2, v2) = crate::linalg::thin_svd(&sub)?;
        let k = keep.len();
        cond_excited = if s2[k - 1] > RANK_TOL * s2[0] { s2[0] / s2[k - 1] } else { f64::INFINITY };
        if s2[k - 1] > RANK_TOL * s2[0] {
            for (a, &i) in keep.iter().enumerate() {
                let var: f64 = (0..k).map(|c| (v2[(a, c)] / s2[c]).powi(2)).sum();
                std_dev[i] = var.sqrt() / norms[i];
            }
        }
    }
    let rel_std_dev: Vec<f64> = (0..m)
        .map(|i| {
            if nominal[i].abs() > 0.0 {
                std_dev[i] / nominal[i].abs()
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let poorly_identifiable = (0..m)
        .filter(|&i| !unexcited_idx.contains(&i) && (!std_dev[i].is_finite() || (nominal[i] != 0.0 && rel_std_dev[i] > 1.0)))
        .map(|i| base.names[i].clone())
        .collect();
    Ok(Identifiability {
        samples: ns,
        rows: ns * n,
        names: base.names.clone(),
        groupings: base.groupings.clone(),
        rank,
        cond,
        singular_values: s.iter().copied().collect(),
        cond_excited,
        sensitivity,
        nominal,
        std_dev,
        rel_std_dev,
        noise: noise.to_vec(),
        unexcited,
        poorly_identifiable,
    })
}

impl Identifiability {
    /// A short text summary.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let m = self.names.len();
        let _ = writeln!(s, "samples: {} ({} rows), base parameters: {m}, rank: {}", self.samples, self.rows, self.rank);
        let _ = writeln!(s, "condition number (unit columns): {}", fmt_num(self.cond));
        let _ = writeln!(
            s,
            "singular values: {} … {}",
            fmt_num(self.singular_values[0]),
            fmt_num(*self.singular_values.last().unwrap_or(&0.0))
        );
        let _ = writeln!(s, "torque noise per joint (N·m): {:?}", self.noise);
        if self.unexcited.is_empty() {
            let _ = writeln!(s, "every base parameter is excited");
        } else {
            let _ = writeln!(s, "NOT excited ({}): {}", self.unexcited.len(), self.unexcited.join(" "));
            let _ = writeln!(s, "condition number without them: {}", fmt_num(self.cond_excited));
        }
        if !self.poorly_identifiable.is_empty() {
            let _ = writeln!(
                s,
                "relative std dev > 100 % ({}): {}",
                self.poorly_identifiable.len(),
                self.poorly_identifiable.join(" ")
            );
        }
        let _ = writeln!(s, "\n  #  parameter        nominal      sensitivity c̄   std dev σ     rel. σ*");
        for i in 0..m {
            let _ = writeln!(
                s,
                "{:>3}  {:<14} {:>12} {:>14} {:>13} {:>10}",
                i + 1,
                self.names[i],
                fmt_num(self.nominal[i]),
                fmt_num(self.sensitivity[i]),
                fmt_num(self.std_dev[i]),
                if self.rel_std_dev[i].is_finite() {
                    format!("{:.2} %", 100.0 * self.rel_std_dev[i])
                } else {
                    "∞".into()
                }
            );
        }
        s
    }

    /// Writes report.json, report.txt and singular_values.svg into `dir`.
    pub fn write(&self, dir: &Path, title: &str) -> Result<()> {
        crate::io::write_json(&dir.join("report.json"), self)?;
        crate::io::write_atomic(&dir.join("report.txt"), format!("{title}\n\n{}", self.text()).as_bytes())?;
        spectrum_svg(&dir.join("singular_values.svg"), &self.singular_values, title)
    }
}

fn fmt_list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}

fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return if v > 0.0 { "∞".into() } else { format!("{v}") };
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

fn spectrum_svg(path: &Path, s: &[f64], title: &str) -> Result<()> {
    let x: Vec<f64> = (1..=s.len()).map(|i| i as f64).collect();
    let panel = Panel {
        title: "singular values of the unit-column regressor".into(),
        x_label: "index".into(),
        y_label: "σ".into(),
        series: vec![Series::bars("σ_i", x, s.to_vec())],
        log_y: true,
        ..Default::default()
    };
    write_svg(path, title, &[panel], 1)
}

/// Everything `idexp excite` writes, in one JSON document (report.json).
#[derive(Debug, Serialize)]
struct ExciteReport<'a> {
    design: &'a super::design::ExciteDesign,
    robot: &'a str,
    result: &'a ExciteResult,
    identifiability: &'a Identifiability,
    verification_rate: f64,
    applied_limits: &'a [super::limits::AppliedLimit],
}

/// Writes the outputs of a design run into `dir`: coefficients.json,
/// trajectory.csv (the delivered trajectory, rest to rest, with a `segment`
/// column: 0 lead-in, k period k, −1 lead-out), periodic.csv (one period,
/// `t, q, qd, qdd`), report.json, report.txt, design.json, status.json and
/// the SVG plots (joints.svg, singular_values.svg, ee_path.svg).
pub fn write_outputs(p: &Problem, r: &ExciteResult, dir: &Path) -> Result<Identifiability> {
    let d = &p.design;
    crate::io::folder::begin(dir, "excite", &crate::io::status::fingerprint_of(d)?)?;
    let noise = d.objective.noise.clone().unwrap_or_else(|| vec![1.0; p.robot.dof()]);
    let samples = r.trajectory.sample(d.objective.sample_rate)?;
    let ident = assess(&p.robot, &p.base, &samples, &noise)?;
    let coeff = serde_json::json!({
        "design": d.name,
        "robot": d.robot.display().to_string(),
        "status": r.status,
        "criterion": d.objective.criterion,
        "criterion_value": r.criterion,
        "cond": r.spectrum.cond,
        "frequency_hz": d.trajectory.frequency,
        "harmonics": d.trajectory.harmonics,
        "at_rest": d.trajectory.at_rest,
        "layout": p.layout,
        "x": r.x,
        "trajectory": r.trajectory,
        "joint_names": p.robot.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
        "revolute": p.robot.joints.iter().map(|j| j.kind == crate::robot::JointKind::Revolute).collect::<Vec<_>>(),
        "controller_rate": d.trajectory.controller_rate,
        "delivered": r.execution.delivered,
    });
    crate::io::write_json(&dir.join("coefficients.json"), &coeff)?;
    // trajectory.csv: the delivered trajectory (lead-in, periods, lead-out)
    // with its segment column; periodic.csv: one period, the former layout
    let delivered = match &r.execution.delivered {
        Some(dl) => dl.clone(),
        None => crate::trajectory::lead::Delivered {
            home: r.trajectory.q0.clone(),
            lead_in: None,
            periodic: r.trajectory.clone(),
            periods: 1,
            lead_out: None,
        },
    };
    delivered.sample(d.trajectory.controller_rate)?.write_csv(&dir.join("trajectory.csv"))?;
    r.trajectory.sample(d.trajectory.controller_rate)?.write(&dir.join("periodic.csv"))?;
    crate::io::write_json(&dir.join("design.json"), d)?;
    let summary = serde_json::json!({
        "design_status": r.status,
        "stopped_by": r.stopped_by,
        "violated": r.violated.iter().map(|m| format!("{}: {} {} beyond the limit", m.name, fmt_num(-m.margin), m.unit)).collect::<Vec<_>>(),
        "cond": r.spectrum.cond,
        "seconds": r.seconds,
        "execution_problem": r.execution.problem,
        "delivered_seconds": r.execution.delivered.as_ref().map(|dl| dl.duration()),
    });
    let interrupted = r
        .stopped_by
        .as_ref()
        .is_some_and(|b| b.ga == Some(Termination::Interrupted) || b.refine == Some(Termination::Interrupted));
    let (state, detail) = match (r.status, interrupted) {
        (super::Status::Infeasible, _) => (
            RunState::Infeasible,
            match (&r.execution.problem, r.violated.len()) {
                _ if r.unexcited().is_some() => format!("infeasible: {}", r.unexcited().unwrap_or_default()),
                (Some(e), 0) => format!("infeasible: not playable rest to rest: {e}"),
                (_, k) => format!("infeasible: {k} constraint(s) violated"),
            },
        ),
        (super::Status::Feasible, true) => (RunState::Interrupted, "interrupted; the best feasible design so far".to_string()),
        (super::Status::Feasible, false) => (RunState::Complete, format!("feasible, condition number {:.4}", r.spectrum.cond)),
    };
    let started = std::time::SystemTime::now().checked_sub(std::time::Duration::from_secs_f64(r.seconds.max(0.0)));
    let robot_path = d.robot.display().to_string();
    crate::io::write_json(
        &dir.join("report.json"),
        &ExciteReport {
            design: d,
            robot: &robot_path,
            result: r,
            identifiability: &ident,
            verification_rate: d.limits.check_rate,
            applied_limits: &p.applied_limits,
        },
    )?;
    crate::io::write_atomic(&dir.join("report.txt"), excite_text(p, r, &ident).as_bytes())?;
    spectrum_svg(
        &dir.join("singular_values.svg"),
        &r.spectrum.singular_values,
        &format!("{}: singular values", d.name),
    )?;
    joints_svg(p, r, &dir.join("joints.svg"))?;
    ee_svg(p, r, &dir.join("ee_path.svg"))?;
    // the final status last: a folder without it is marked `running`
    crate::io::status::write_status(dir, "excite", state, detail, started, crate::io::status::fingerprint_of(d)?, summary)?;
    Ok(ident)
}

/// The text summary of a design run (report.txt).
pub fn excite_text(p: &Problem, r: &ExciteResult, ident: &Identifiability) -> String {
    let d = &p.design;
    let mut s = String::new();
    let _ = writeln!(s, "excitation design `{}` for robot `{}` ({})", d.name, p.robot.name, d.robot.display());
    let _ = writeln!(
        s,
        "trajectory: {} harmonics of {} Hz (period {} s), {} design variables{}{}",
        d.trajectory.harmonics,
        d.trajectory.frequency,
        1.0 / d.trajectory.frequency,
        p.layout.n_vars(),
        if d.trajectory.vary_q0 { ", q0 free" } else { "" },
        if d.trajectory.at_rest { ", starts and ends at rest" } else { "" }
    );
    let _ = writeln!(
        s,
        "criterion: {} of the base regressor with {} ({} columns, {} samples at {} Hz)",
        match d.objective.criterion {
            super::Criterion::Cond => "condition number",
            super::Criterion::LogDet => "−log det (D-optimality)",
            super::Criterion::InvSigmaMin => "1/σ_min (E-optimality)",
        },
        match d.objective.scaling {
            super::Scaling::UnitColumn => "unit-norm columns",
            super::Scaling::Nominal => "columns scaled by the nominal parameters",
            super::Scaling::None => "unscaled columns",
        },
        p.objective.n_cols(),
        p.objective.times.len(),
        d.objective.sample_rate
    );
    let _ = writeln!(s);
    let status = match r.status {
        Status::Feasible => "FEASIBLE".to_string(),
        Status::Infeasible => "INFEASIBLE".to_string(),
    };
    let _ = writeln!(
        s,
        "status: {status}{}",
        r.stopped_by.as_ref().map(|b| format!(" (stopped early: {b})")).unwrap_or_default()
    );
    let _ = writeln!(s, "criterion value: {}", fmt_num(r.criterion));
    let _ = writeln!(s, "condition number: {}", fmt_num(r.spectrum.cond));
    if !r.violated.is_empty() {
        let _ = writeln!(s, "\nviolated constraints (on the {} Hz verification grid), worst first:", d.limits.check_rate);
        for m in &r.violated {
            if is_distance(m) {
                let _ = writeln!(s, "  {}", distance_violation(m));
                continue;
            }
            let _ = writeln!(
                s,
                "  {}: reaches {} {} at t = {:.3} s, {} {} beyond the limit",
                m.name,
                fmt_num(m.worst),
                m.unit,
                m.at,
                fmt_num(-m.margin),
                m.unit
            );
        }
        let _ = writeln!(s, "  (no trajectory found by the search meets these; relax them or move q0 / the workspace)");
    }
    s.push_str(&collision_text(p, &r.margins, d.limits.check_rate));
    let _ = writeln!(s, "\ndelivered trajectory (what trajectory.csv and the exports hold):");
    match (&r.execution.delivered, &r.execution.problem) {
        (Some(dl), problem) => {
            let _ = writeln!(
                s,
                "  from home {} at rest: lead-in {:.2} s, {} period(s) of {} s, lead-out {:.2} s back to home at rest; total {:.2} s",
                fmt_list(&dl.home),
                dl.lead_in_duration(),
                dl.periods,
                dl.periodic.period(),
                dl.lead_out_duration(),
                dl.duration()
            );
            match problem {
                None => {
                    let _ = writeln!(
                        s,
                        "  every sample within every joint limit{} on the {} Hz grid",
                        if d.workspace.is_empty() { "" } else { " and workspace constraint" },
                        r.execution.check_rate
                    );
                }
                Some(e) => {
                    let _ = writeln!(s, "  NOT playable: {e}");
                }
            }
        }
        (None, Some(e)) => {
            let _ = writeln!(s, "  NOT playable: {e}");
        }
        (None, None) => {}
    }
    let _ = writeln!(s, "\nlimits applied (value imposed; source):");
    for a in &p.applied_limits {
        let v = if a.class == "position" {
            format!("[{}, {}]", fmt_num(a.imposed[0]), fmt_num(a.imposed[1]))
        } else {
            format!("±{}", fmt_num(a.imposed[1]))
        };
        let _ = writeln!(s, "  {:<22} {:<13} {:>24} {:<7} {}", a.joint, a.class, v, a.unit, a.source);
    }
    let _ = writeln!(s, "\nworst margin per constraint ({} Hz grid; ≥ 0 holds):", d.limits.check_rate);
    for m in &r.margins {
        let _ = writeln!(s, "  {:<60} margin {:>12} {}", m.name, fmt_num(m.margin), m.unit);
    }
    let _ = writeln!(
        s,
        "\nsolver: GA {} generations, {} evaluations, {:.2} s ({:?}); best GA criterion {}",
        r.ga.generations,
        r.ga.evaluations,
        r.ga.seconds,
        r.ga.stop,
        fmt_num(r.ga.best)
    );
    for (k, rf) in r.refinements.iter().enumerate() {
        let _ = writeln!(
            s,
            "  refine #{}: {} → {} in {} evaluations, {:.2} s, {}{}",
            k + 1,
            fmt_num(rf.start),
            fmt_num(rf.end),
            rf.evaluations,
            rf.seconds,
            rf.status,
            if rf.violation > 0.0 {
                format!(", violation {:.2e}", rf.violation)
            } else {
                String::new()
            }
        );
    }
    let _ = writeln!(s, "chosen: {}; total {:.2} s on {} threads", r.chosen, r.seconds, r.threads);
    let _ = writeln!(s, "\nidentifiability (one period, predicted for the stated torque noise):");
    s.push_str(&ident.text());
    s
}

/// The trajectory the plots show: the delivered one (lead-in, periods,
/// lead-out) when there is one, else one period. Samples at `rate` Hz with
/// their phase names; each phase as its own run of samples, the first sample
/// of the next phase repeated at its end so that the curve is continuous.
struct PlotPhases {
    names: Vec<String>,
    t: Vec<Vec<f64>>,
    q: Vec<Vec<Vec<f64>>>,
    qd: Vec<Vec<Vec<f64>>>,
}

fn plot_phases(r: &ExciteResult, rate: f64) -> Result<PlotPhases> {
    let mut out = PlotPhases {
        names: Vec::new(),
        t: Vec::new(),
        q: Vec::new(),
        qd: Vec::new(),
    };
    match &r.execution.delivered {
        Some(d) => {
            let s = d.sample(rate)?;
            let mut k = 0;
            while k < s.len() {
                let seg = s.segment[k];
                let mut e = k;
                while e < s.len() && s.segment[e] == seg {
                    e += 1;
                }
                let last = e.min(s.len() - 1);
                out.names.push(match seg {
                    0 => "lead-in".to_string(),
                    -1 => "lead-out".to_string(),
                    p => format!("period {p}"),
                });
                out.t.push(s.t[k..=last].to_vec());
                out.q.push(s.q[k..=last].to_vec());
                out.qd.push(s.qd[k..=last].to_vec());
                k = e;
            }
        }
        None => {
            let s = r.trajectory.sample(rate)?;
            out.names.push("one period (no delivered trajectory)".into());
            out.t.push(s.t.clone().unwrap_or_default());
            out.q.push(s.q.clone());
            out.qd.push(s.qd.clone());
        }
    }
    Ok(out)
}

fn joints_svg(p: &Problem, r: &ExciteResult, path: &Path) -> Result<()> {
    let n = p.robot.dof();
    let rate = (400.0 * p.design.trajectory.frequency).max(50.0 * p.design.trajectory.frequency * p.design.trajectory.harmonics as f64);
    let ph = plot_phases(r, rate)?;
    let unit = |j: usize, d: &str| -> String {
        let lin = p.robot.joints[j].kind == crate::robot::JointKind::Prismatic;
        format!("{}{d}", if lin { "m" } else { "rad" })
    };
    // one legend (first panel) names the phases; the colours repeat in every panel
    let series = |j: usize, first: bool, get: &dyn Fn(usize, usize) -> Vec<f64>| -> Vec<Series> {
        (0..ph.names.len())
            .map(|k| Series::line(if first { ph.names[k].clone() } else { String::new() }, ph.t[k].clone(), get(k, j)))
            .collect()
    };
    let mut panels = Vec::new();
    for j in 0..n {
        let name = &p.robot.joints[j].name;
        let mut hl = Vec::new();
        let [lo, hi] = p.limits.position[j];
        // one legend in all (first panel): the phases and the limit lines
        let lim = if j == 0 { "limit".to_string() } else { String::new() };
        if lo.is_finite() {
            hl.push((lo, lim.clone()));
        }
        if hi.is_finite() {
            hl.push((hi, if lo.is_finite() { String::new() } else { lim.clone() }));
        }
        panels.push(Panel {
            title: format!("q{} ({name})", j + 1),
            x_label: "t (s)".into(),
            y_label: unit(j, ""),
            series: series(j, j == 0, &|k, j| ph.q[k].iter().map(|v| v[j]).collect()),
            hlines: hl,
            ..Default::default()
        });
        let mut hv = Vec::new();
        let v = p.limits.velocity[j];
        if v.is_finite() {
            hv.push((v, String::new()));
            hv.push((-v, String::new()));
        }
        panels.push(Panel {
            title: format!("qd{} ({name})", j + 1),
            x_label: "t (s)".into(),
            y_label: unit(j, "/s"),
            series: series(j, false, &|k, j| ph.qd[k].iter().map(|v| v[j]).collect()),
            hlines: hv,
            ..Default::default()
        });
    }
    let what = if r.execution.delivered.is_some() {
        "delivered joint trajectory (lead-in, periods, lead-out), limits dashed red"
    } else {
        "joint trajectory (one period), limits dashed red"
    };
    write_svg(path, &format!("{}: {what}", p.design.name), &panels, 2)
}

fn ee_svg(p: &Problem, r: &ExciteResult, path: &Path) -> Result<()> {
    let frame = match p.design.workspace.first() {
        Some(c) => c.resolve(&p.robot, "design", "workspace[0]")?,
        None => p.robot.end_effector(),
    };
    let mut ph = plot_phases(r, (200.0 * p.design.trajectory.frequency).max(20.0))?;
    // the periods trace the same closed path: one series for all of them
    let periods: Vec<usize> = (0..ph.names.len()).filter(|&k| ph.names[k].starts_with("period ")).collect();
    if periods.len() > 1 {
        let (k0, n) = (periods[0], periods.len());
        ph.names[k0] = format!("periods 1–{n} (one closed path)");
        for &k in periods[1..].iter().rev() {
            ph.names.remove(k);
            ph.t.remove(k);
            ph.q.remove(k);
            ph.qd.remove(k);
        }
    }
    let mut ws = Workspace::new(&p.robot);
    let paths: Vec<Vec<[f64; 3]>> =
        ph.q.iter()
            .map(|qs| {
                qs.iter()
                    .map(|q| {
                        let v = super::constraints::frame_point(&p.robot, &mut ws, q, &frame);
                        [v.x, v.y, v.z]
                    })
                    .collect()
            })
            .collect();
    let all: Vec<[f64; 3]> = paths.iter().flatten().copied().collect();
    let ax = ["x", "y", "z"];
    let mut panels = Vec::new();
    for (pi, (a, b)) in [(0usize, 1usize), (0, 2), (1, 2)].into_iter().enumerate() {
        let mut series: Vec<Series> = paths
            .iter()
            .enumerate()
            .map(|(k, pts)| {
                Series::line(
                    if pi == 0 { ph.names[k].clone() } else { String::new() },
                    pts.iter().map(|v| v[a]).collect(),
                    pts.iter().map(|v| v[b]).collect(),
                )
            })
            .collect();
        let (lo, hi) = bounds(&all);
        for (ci, c) in p.design.workspace.iter().enumerate() {
            for (k, (xs, ys)) in outline(&c.shape, a, b, lo, hi).into_iter().enumerate() {
                series.push(Series::line(if k == 0 { format!("constraint {}", ci + 1) } else { String::new() }, xs, ys));
            }
        }
        panels.push(Panel {
            title: format!("{}–{} projection", ax[a], ax[b]),
            x_label: format!("{} (m)", ax[a]),
            y_label: format!("{} (m)", ax[b]),
            series,
            ..Default::default()
        });
    }
    write_svg(
        path,
        &format!(
            "{}: {} path (delivered trajectory by phase) and workspace constraints",
            p.design.name, frame.name
        ),
        &panels,
        3,
    )
}

fn bounds(pts: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pts {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    for i in 0..3 {
        let pad = 0.2 * (hi[i] - lo[i]).max(0.1);
        lo[i] -= pad;
        hi[i] += pad;
    }
    (lo, hi)
}

/// Outline(s) of a shape projected on axes (a, b), as polylines.
fn outline(shape: &crate::robot::cartesian::Shape, a: usize, b: usize, lo: [f64; 3], hi: [f64; 3]) -> Vec<(Vec<f64>, Vec<f64>)> {
    use crate::robot::cartesian::Shape;
    let rect = |mn: [f64; 3], mx: [f64; 3]| (vec![mn[a], mx[a], mx[a], mn[a], mn[a]], vec![mn[b], mn[b], mx[b], mx[b], mn[b]]);
    match shape {
        Shape::Box { min, max } => vec![rect(*min, *max)],
        Shape::OutsideBox { min, max, clearance } => {
            let mn = [min[0] - clearance, min[1] - clearance, min[2] - clearance];
            let mx = [max[0] + clearance, max[1] + clearance, max[2] + clearance];
            vec![rect(mn, mx)]
        }
        Shape::Sphere { center, radius } => {
            let k = 72;
            let th: Vec<f64> = (0..=k).map(|i| std::f64::consts::TAU * i as f64 / k as f64).collect();
            vec![(
                th.iter().map(|t| center[a] + radius * t.cos()).collect(),
                th.iter().map(|t| center[b] + radius * t.sin()).collect(),
            )]
        }
        Shape::HalfSpace { normal, offset } => {
            let nn = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
            let nv = [normal[0] / nn, normal[1] / nn, normal[2] / nn];
            let third = 3 - a - b;
            if nv[third].abs() > 1e-9 {
                return vec![];
            }
            // n_a x + n_b y = offset
            if nv[b].abs() > 1e-9 {
                let xs = vec![lo[a], hi[a]];
                let ys = xs.iter().map(|x| (offset - nv[a] * x) / nv[b]).collect();
                vec![(xs, ys)]
            } else {
                let x = offset / nv[a];
                vec![(vec![x, x], vec![lo[b], hi[b]])]
            }
        }
        Shape::Sector { center, azimuth, radius, z } => {
            if (a, b) == (0, 1) {
                let k = 48;
                let arc = |r: f64| -> (Vec<f64>, Vec<f64>) {
                    let ph: Vec<f64> = (0..=k).map(|i| azimuth[0] + (azimuth[1] - azimuth[0]) * i as f64 / k as f64).collect();
                    (
                        ph.iter().map(|p| center[0] + r * p.cos()).collect(),
                        ph.iter().map(|p| center[1] + r * p.sin()).collect(),
                    )
                };
                let ray = |p: f64| {
                    (
                        vec![center[0] + radius[0] * p.cos(), center[0] + radius[1] * p.cos()],
                        vec![center[1] + radius[0] * p.sin(), center[1] + radius[1] * p.sin()],
                    )
                };
                vec![arc(radius[0]), arc(radius[1]), ray(azimuth[0]), ray(azimuth[1])]
            } else {
                let zz = [center[2] + z[0], center[2] + z[1]];
                zz.iter().map(|&h| (vec![lo[a], hi[a]], vec![h, h])).collect()
            }
        }
    }
}

/// Reads a trajectory CSV (`t, q, qd, qdd`) for `idexp assess`, optionally
/// keeping every `every`-th row.
pub fn read_states(path: &Path, n: usize, every: usize) -> Result<States> {
    let s = States::read(path, n)?;
    if s.is_empty() {
        return Err(Error::Data {
            path: path.to_path_buf(),
            row: 0,
            column: "q1".into(),
            msg: "the file has no data rows".into(),
        });
    }
    if every <= 1 {
        return Ok(s);
    }
    let keep = |v: &Vec<Vec<f64>>| v.iter().step_by(every).cloned().collect::<Vec<_>>();
    Ok(States {
        t: s.t.as_ref().map(|t| t.iter().step_by(every).copied().collect()),
        q: keep(&s.q),
        qd: keep(&s.qd),
        qdd: keep(&s.qdd),
    })
}

/// The margins that are violated, as readable lines.
pub fn violation_lines(m: &[Margin]) -> Vec<String> {
    m.iter()
        .filter(|m| m.margin < 0.0)
        .map(|m| {
            if is_distance(m) {
                distance_violation(m)
            } else {
                format!("{}: {} {} beyond the limit", m.name, fmt_num(-m.margin), m.unit)
            }
        })
        .collect()
}

fn is_distance(m: &Margin) -> bool {
    matches!(m.kind, ConstraintKind::SelfCollision | ConstraintKind::WorldCollision)
}

/// `collision self: forearm_link – wrist_2_link at t = 3.141 s: distance −0.0130 m
/// (penetration 0.0130 m), 0.0330 m inside the 0.02 m margin`.
fn distance_violation(m: &Margin) -> String {
    let pair = m.name.trim_start_matches("distance ").split(" ≥ ").next().unwrap_or(&m.name);
    let pen = if m.worst < 0.0 {
        format!("penetration depth {:.4} m", -m.worst)
    } else {
        "no contact".to_string()
    };
    format!(
        "collision {pair} at t = {:.3} s: distance {:.4} m ({pen}), {:.4} m inside the {} m margin",
        m.at, m.worst, -m.margin, m.limit
    )
}

/// The collision lines of the report: geometry, checked and excluded pairs,
/// the worst distance per class on the verification grid.
pub fn collision_text(p: &Problem, margins: &[Margin], rate: f64) -> String {
    let mut s = String::new();
    let Some(sc) = p.constraints.scene() else {
        let why = if !p.design.collision.enabled {
            "off ([collision] enabled = false)"
        } else {
            "nothing to check (the robot file gives no collision geometry)"
        };
        let _ = writeln!(s, "\ncollision: {why}");
        return s;
    };
    let n_self = sc.pairs.iter().filter(|q| q.class == crate::robot::collision::PairClass::SelfCollision).count();
    let _ = writeln!(
        s,
        "\ncollision: margin {} m for {} pairs ({} self, {} world: {}); {} pairs not checked",
        sc.margin,
        sc.len(),
        n_self,
        sc.len() - n_self,
        {
            let mut w: Vec<&str> = sc
                .pairs
                .iter()
                .filter(|q| q.class == crate::robot::collision::PairClass::World)
                .map(|q| q.b.as_str())
                .collect();
            w.dedup();
            if w.is_empty() {
                "none".to_string()
            } else {
                w.join(", ")
            }
        },
        sc.excluded.len()
    );
    for e in &sc.excluded {
        let _ = writeln!(s, "  not checked: {} – {}: {}", e.a, e.b, e.reason);
    }
    let _ = writeln!(
        s,
        "  distances between convex parts (primitives, convex hulls of the meshes): a hull holds its mesh, so the \
         mesh distance is at least the one reported (replay on the full meshes: scripts/safety-replay.py)"
    );
    for (kind, label) in [(ConstraintKind::SelfCollision, "self"), (ConstraintKind::WorldCollision, "world")] {
        if let Some(w) = margins.iter().filter(|m| m.kind == kind).min_by(|a, b| a.worst.total_cmp(&b.worst)) {
            let pair = w.name.trim_start_matches("distance ").split(" ≥ ").next().unwrap_or(&w.name);
            let _ = writeln!(
                s,
                "  worst {label} distance on the {rate} Hz grid: {:.4} m ({pair}, t = {:.3} s){}",
                w.worst,
                w.at,
                if w.margin < 0.0 { " — VIOLATES the margin" } else { "" }
            );
        }
    }
    s
}
