//! The output records (sample sets, criterion.json, report.json) and the
//! writer of the output folder of `idexp excite`.

use super::assess::{assess, assess_delivered, Identifiability, TimeStats};
use super::plots::{ee_svg, joints_svg, progress_svg, spectrum_svg};
use super::text::{excite_report_text, fmt_num, ordinal};
use crate::error::Result;
use crate::excitation::{Criterion, ExciteResult, Problem, Scaling};
use crate::io::status::RunState;
use crate::optim::Termination;
use crate::params::BaseParams;
use crate::robot::Robot;
use crate::trajectory::{seconds_text, Ends, TrajectoryShape};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// The samples one reported figure is computed from.
#[derive(Debug, Clone, Serialize)]
pub struct SampleSet {
    /// The CSV file holding them (`t`, q1..qn, qd1..qdn, qdd1..qddn), relative
    /// to the output folder when it is one of its files.
    pub file: String,
    /// Only the rows whose `segment` column holds this value (trajectory.csv:
    /// 0 lead-in, k period k, −1 lead-out); absent: every row.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segment: Option<i64>,
    /// Keep every `every`-th data row of the file (of the segment's rows when
    /// `segment` is given), starting with the first.
    pub every: usize,
    /// Number of samples N (rows of C: N·n).
    pub count: usize,
    /// Sample rate (Hz) of the rows used, when they are uniformly spaced.
    pub rate_hz: Option<f64>,
    /// Time of the first and of the last sample used (s), when the file has a `t` column.
    pub t_range: Option<[f64; 2]>,
    /// The same in words.
    pub description: String,
}

/// One base column of the stacked regressor C.
#[derive(Debug, Clone, Serialize)]
pub struct ColumnRecord {
    /// Base-parameter name (suffix `R`: other standard parameters are regrouped into it).
    pub name: String,
    /// The robot's standard parameter whose regressor column is this column.
    pub parameter: String,
    /// Its index in the robot's standard parameter vector.
    pub index: usize,
    /// The combination of standard parameters this column's coefficient
    /// estimates (θ_b,j = Σ k_i θ_i), as (parameter, k_i) pairs.
    pub combination: Vec<(String, f64)>,
    /// The same, readable.
    pub grouping: String,
    /// Nominal value of the combination.
    pub nominal: f64,
}

/// One reported condition number (or criterion) and what it is computed from.
#[derive(Debug, Clone, Serialize)]
pub struct Figure {
    /// Which figure of report.txt / report.json this is.
    pub label: String,
    /// Samples used.
    pub samples: SampleSet,
    /// Column scaling: `unit_column`, `nominal` or `none`.
    pub scaling: Scaling,
    /// ‖column j of W½C‖ over the samples (the reference of unit-column scaling).
    pub column_norms: Vec<f64>,
    /// Column factors D_jj: the matrix is W½ C D.
    pub scale: Vec<f64>,
    /// Criterion, for the design's criterion figure.
    pub criterion: Option<Criterion>,
    /// Criterion value, for the design's criterion figure.
    pub value: Option<f64>,
    /// σ_1/σ_m of W½ C D (capped at 10¹² for the design criterion, ∞ in the
    /// identifiability figures when rank deficient).
    pub cond: f64,
    /// Singular values of W½ C D, decreasing.
    pub singular_values: Vec<f64>,
}

/// criterion.json: everything needed to recompute every reported condition
/// number from the written files with any rigid-body regressor.
#[derive(Debug, Clone, Serialize)]
pub struct CriterionRecord {
    /// What this file is.
    pub about: String,
    /// The robot file.
    pub robot: String,
    /// Joint names, in the order of the columns q1..qn of the sample files.
    pub joints: Vec<String>,
    /// Gravity (m/s², base frame).
    pub gravity: [f64; 3],
    /// How the rows of C are formed, in words.
    pub regressor: String,
    /// |q̇_j| below this counts as 0 (the Coulomb column sign(q̇_j) is then 0).
    pub zero_velocity: f64,
    /// The columns of C, in order.
    pub columns: Vec<ColumnRecord>,
    /// Torque noise σ_j per joint (N·m or N); row r of joint j is weighted by 1/σ_j.
    pub noise: Vec<f64>,
    /// The reported figures.
    pub figures: Vec<Figure>,
}

impl CriterionRecord {
    /// The columns, weights and regressor description of `base` on `robot`
    /// (figures to be added).
    pub fn new(robot: &Robot, robot_file: &str, base: &BaseParams, noise: &[f64], about: String) -> CriterionRecord {
        let pn = robot.param_names();
        let theta = robot.nominal_params();
        let nominal = base.base_values(theta.as_slice());
        let columns = (0..base.n_base())
            .map(|j| ColumnRecord {
                name: base.names[j].clone(),
                parameter: pn[base.independent[j]].clone(),
                index: base.independent[j],
                combination: (0..base.n_std)
                    .filter(|&i| base.k[(j, i)] != 0.0)
                    .map(|i| (pn[i].clone(), base.k[(j, i)]))
                    .collect(),
                grouping: base.groupings[j].clone(),
                nominal: nominal[j],
            })
            .collect();
        let g = robot.gravity;
        CriterionRecord {
            about,
            robot: robot_file.to_string(),
            joints: robot.joints.iter().map(|j| j.name.clone()).collect(),
            gravity: [g.x, g.y, g.z],
            regressor: "one row per joint j and sample: the joint-side torque regressor τ = Y(q, q̇, q̈) θ; column `parameter` \
                        of Y for each column; inertial parameters per link about the link (joint) frame origin in the link frame, \
                        as the URDF's joint frames; Coulomb friction Fc_j: sign(q̇_j) on joint j's row, viscous Fv_j: q̇_j; \
                        samples stacked in time order, joints in order within a sample"
                .into(),
            zero_velocity: crate::excitation::objective::ZERO_VELOCITY,
            columns,
            noise: noise.to_vec(),
            figures: Vec::new(),
        }
    }
}

impl SampleSet {
    /// Describes the samples taken every `every`-th row of `file` with times
    /// `t` (those used, if the file has them); `note` is added in words.
    pub fn new(file: &str, every: usize, t: Option<&[f64]>, note: &str) -> SampleSet {
        let mut times = TimeStats::default();
        t.unwrap_or_default().iter().for_each(|&v| times.add(v));
        SampleSet::from_parts(file, every, times.count, times.range(), times.rate(), note)
    }

    /// As [`SampleSet::new`] from the count, time range and rate.
    pub fn from_parts(file: &str, every: usize, count: usize, t_range: Option<[f64; 2]>, rate_hz: Option<f64>, note: &str) -> SampleSet {
        let mut description = format!(
            "{file}: {}{count} rows",
            if every > 1 {
                format!("every {} data row from the first, ", ordinal(every))
            } else {
                "all ".into()
            }
        );
        if let Some(r) = rate_hz {
            let _ = write!(description, " at {r} Hz");
        }
        if let Some([a, b]) = t_range {
            let _ = write!(description, ", t = {} … {} s", seconds_text(a), seconds_text(b));
        }
        if !note.is_empty() {
            let _ = write!(description, " ({note})");
        }
        SampleSet {
            file: file.to_string(),
            segment: None,
            every,
            count,
            rate_hz,
            t_range,
            description,
        }
    }
}

/// Everything `idexp excite` writes, in one JSON document (report.json).
#[derive(Debug, Serialize)]
struct ExciteReport<'a> {
    design: &'a crate::excitation::design::ExciteDesign,
    robot: &'a str,
    result: &'a ExciteResult,
    identifiability: &'a Identifiability,
    delivered_identifiability: &'a Identifiability,
    /// The criterion's samples read from trajectory.csv (segment 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    period_identifiability: Option<&'a Identifiability>,
    criterion_samples: &'a SampleSet,
    verification_rate: f64,
    applied_limits: &'a [crate::excitation::limits::AppliedLimit],
    /// Which clock `result.margins[].at` is on, in words.
    margins_at_clock: &'static str,
    /// Every margin's worst instant on both clocks, labelled by key.
    worst_instants: Vec<WorstInstant>,
}

/// A margin's worst instant on the period's clock and on the delivered one.
#[derive(Debug, Serialize)]
struct WorstInstant {
    /// The constraint (as `result.margins[].name`).
    name: String,
    /// Seconds from the start of the period (the whole motion of a rest-to-rest shape): `result.margins[].at`.
    at_period_s: f64,
    /// The same instant on the delivered clock of trajectory.csv and the preview (t = 0 at the start of the lead-in), in period 1; absent without a delivered trajectory.
    #[serde(skip_serializing_if = "Option::is_none")]
    at_delivered_s: Option<f64>,
}

/// What [`write_outputs`] computed for the reports.
#[derive(Debug, Clone)]
pub struct Written {
    /// Identifiability on the criterion's samples (criterion_samples.csv).
    pub identifiability: Identifiability,
    /// Identifiability of the delivered trajectory (every row of trajectory.csv).
    pub delivered: Identifiability,
    /// The contents of criterion.json.
    pub record: CriterionRecord,
}

/// The samples of the criterion: one period on the design's grid, as a [`SampleSet`].
pub fn criterion_sample_set(p: &Problem) -> SampleSet {
    let d = &p.design;
    let ratio = d.trajectory.controller_rate / d.objective.sample_rate;
    let k = ratio.round();
    let what = match p.shape.ends() {
        Ends::Periodic => "one period of the periodic trajectory",
        Ends::RestToRest => "the whole rest-to-rest motion",
    };
    let note = if (ratio - k).abs() < 1e-9 && k >= 1.0 {
        format!(
            "{what}, t_i = i/{} s; the times of rows 0, {k}, {}, … of periodic.csv",
            d.objective.sample_rate,
            2.0 * k
        )
    } else {
        format!("{what}, t_i = i/{} s", d.objective.sample_rate)
    };
    SampleSet::new("criterion_samples.csv", 1, Some(&p.objective.times), &note)
}

/// The samples of the delivered trajectory as written to trajectory.csv, as a [`SampleSet`].
fn delivered_sample_set(t: &[f64], periods: usize, ends: Ends, leads: bool) -> SampleSet {
    let what = match (ends, leads) {
        (Ends::Periodic, _) => format!("the delivered trajectory: lead-in, {periods} period(s), lead-out, rest to rest"),
        // a motion with free start or end poses: leads from and to the home pose
        (Ends::RestToRest, true) => {
            format!("the delivered trajectory: a lead-in from the home pose, {periods} repetition(s) of the rest-to-rest motion, a lead-out to the home pose")
        }
        (Ends::RestToRest, false) => format!("the delivered trajectory: {periods} repetition(s) of the rest-to-rest motion, no lead-in or lead-out"),
    };
    SampleSet::new("trajectory.csv", 1, Some(t), &what)
}

/// Writes the outputs of a design run into `dir`: coefficients.json,
/// trajectory.csv (the delivered trajectory, rest to rest, with a `segment`
/// column: 0 lead-in, k period k, −1 lead-out), periodic.csv (one period,
/// `t, q, qd, qdd`), criterion_samples.csv (the samples of the criterion:
/// one period on its grid, exactly as evaluated), criterion.json (the base
/// columns by name with their combinations, the weights, the column norms
/// and scaling, every reported condition number with the samples it is
/// computed from), report.json, report.txt, design.json, status.json and the
/// SVG plots (joints.svg, singular_values.svg, ee_path.svg).
pub fn write_outputs(p: &Problem, r: &ExciteResult, dir: &Path) -> Result<Written> {
    write_outputs_with(p, r, dir, |_| Ok(()))
}

/// [`write_outputs`], with `extra` writing further files into `dir` after
/// every other file and before the final `status.json` (the command line's
/// `preview.html`), so the folder is complete only with them.
pub fn write_outputs_with(p: &Problem, r: &ExciteResult, dir: &Path, extra: impl FnOnce(&Path) -> Result<()>) -> Result<Written> {
    let d = &p.design;
    crate::io::folder::begin(dir, "excite", &crate::io::status::fingerprint_of(d)?)?;
    let noise = d.objective.noise.clone().unwrap_or_else(|| vec![1.0; p.robot.dof()]);
    // the criterion's own samples (not a re-evaluation at other times)
    let grid = p.objective.record(&r.trajectory)?;
    let grid_set = criterion_sample_set(p);
    let mut ident = assess(&p.robot, &p.base, &grid.samples, &noise)?;
    ident.source = Some(grid_set.clone());
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
        "layout": p.shape,
        "x": r.x,
        "trajectory": r.trajectory,
        "joint_names": p.robot.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
        "revolute": p.robot.joints.iter().map(|j| j.kind == crate::robot::JointKind::Revolute).collect::<Vec<_>>(),
        "controller_rate": d.trajectory.controller_rate,
        "delivered": r.execution.delivered,
        "safety": r.execution.safety,
    });
    let mut coeff = coeff;
    if p.shape.fourier().is_none() {
        // the shape's name (absent: the Fourier series, as before the B-splines)
        coeff["shape"] = serde_json::json!(p.shape.name());
    }
    crate::io::write_json(&dir.join("coefficients.json"), &coeff)?;
    // trajectory.csv: the delivered trajectory (lead-in, periods, lead-out)
    // with its segment column; periodic.csv: one period, the former layout
    let delivered = match &r.execution.delivered {
        Some(dl) => dl.clone(),
        None => crate::trajectory::lead::Delivered {
            home: crate::trajectory::Motion::rest_pose(&r.trajectory),
            lead_in: None,
            periodic: r.trajectory.clone(),
            periods: 1,
            lead_out: None,
        },
    };
    let ds = delivered.sample(d.trajectory.controller_rate)?;
    // the delivered trajectory's identifiability (every row) while its CSV
    // is written: the two longest steps of the writing, side by side
    let (written_csv, delivered_ident) = rayon::join(
        || -> Result<()> {
            ds.write_csv(&dir.join("trajectory.csv"))?;
            r.trajectory.sample(d.trajectory.controller_rate)?.write(&dir.join("periodic.csv"))?;
            grid.samples.write(&dir.join("criterion_samples.csv"))
        },
        || assess_delivered(&p.robot, &p.base, &ds, &noise),
    );
    written_csv?;
    let mut delivered_ident = delivered_ident?;
    // segment 0 is the lead-in, −1 the lead-out (a rest-to-rest motion has them when its ends are free)
    let leads = ds.segment.iter().any(|&g| g <= 0);
    let delivered_set = delivered_sample_set(&ds.t, delivered.periods, p.shape.ends(), leads);
    // the criterion's samples as rows of trajectory.csv: period 1 (segment 1,
    // which starts after the lead-in, not at t = 0), every k-th row, when the
    // criterion's rate divides the controller's
    let ratio = d.trajectory.controller_rate / d.objective.sample_rate;
    let period_ident = match ratio.round() as usize {
        k if k >= 1 && (ratio - k as f64).abs() < 1e-9 => 'period: {
            let rows: Vec<usize> = (0..ds.t.len()).filter(|&i| ds.segment[i] == 1).step_by(k).collect();
            if rows.is_empty() {
                break 'period None;
            }
            let states = crate::io::States {
                t: None,
                q: rows.iter().map(|&i| ds.q[i].clone()).collect(),
                qd: rows.iter().map(|&i| ds.qd[i].clone()).collect(),
                qdd: rows.iter().map(|&i| ds.qdd[i].clone()).collect(),
            };
            let t: Vec<f64> = rows.iter().map(|&i| ds.t[i]).collect();
            let mut set = SampleSet::new(
                "trajectory.csv",
                k,
                Some(&t),
                match (p.shape.ends(), leads) {
                    (Ends::Periodic, _) => "segment 1 only: period 1 of the delivered trajectory, which starts after the lead-in (trajectory.csv's t = 0 is the start of the lead-in, not of a period); the criterion's samples",
                    (Ends::RestToRest, true) => "segment 1 only: the first repetition of the rest-to-rest motion, which starts after the lead-in from the home pose (trajectory.csv's t = 0 is the start of the lead-in); the criterion's samples",
                    (Ends::RestToRest, false) => "segment 1 only: the first repetition of the rest-to-rest motion, from t = 0 (no lead-in); the criterion's samples",
                },
            );
            set.segment = Some(1);
            let mut id = assess(&p.robot, &p.base, &states, &noise)?;
            id.source = Some(set);
            Some(id)
        }
        _ => None,
    };
    delivered_ident.source = Some(delivered_set.clone());
    let mut record = CriterionRecord::new(
        &p.robot,
        &d.robot.display().to_string(),
        &p.base,
        &noise,
        format!(
            "what every condition number of `idexp excite {}` is computed from: the matrix W½·C·D, C the stacked base \
             regressor (rows: samples × joints; columns: `columns`), W½ = diag(1/noise_j) per joint row, D = diag(scale)",
            d.name
        ),
    );
    record.figures = vec![
        Figure {
            label: "criterion value and condition number (report.txt `criterion value`, `condition number`; \
                    report.json result.criterion, result.spectrum)"
                .into(),
            samples: grid_set.clone(),
            scaling: d.objective.scaling,
            column_norms: grid.column_norms.clone(),
            scale: grid.scale.clone(),
            criterion: Some(d.objective.criterion),
            value: Some(r.criterion),
            cond: r.spectrum.cond,
            singular_values: r.spectrum.singular_values.clone(),
        },
        ident_figure(
            "identifiability on the design grid (report.txt `identifiability`; report.json identifiability)",
            grid_set.clone(),
            &ident,
        ),
        ident_figure(
            "identifiability of the delivered trajectory (report.txt `delivered trajectory`; report.json delivered_identifiability)",
            delivered_set,
            &delivered_ident,
        ),
    ];
    if let Some((id, set)) = period_ident.as_ref().and_then(|id| id.source.as_ref().map(|s| (id, s))) {
        record.figures.push(ident_figure(
            "the criterion's samples read from trajectory.csv (report.txt `the same samples in trajectory.csv`; \
             report.json period_identifiability): segment 1 (period 1), every k-th row",
            set.clone(),
            id,
        ));
    }
    crate::io::write_json(&dir.join("criterion.json"), &record)?;
    crate::io::write_json(&dir.join("design.json"), d)?;
    let summary = serde_json::json!({
        "design_status": r.status,
        "stopped_by": r.stopped_by,
        "violated": r.violated.iter().map(|m| format!("{}: {} {} beyond the limit", m.name, fmt_num(-m.margin), m.unit)).collect::<Vec<_>>(),
        "cond": r.spectrum.cond,
        "seconds": r.seconds,
        "execution_problem": r.execution.problem,
        "delivered_seconds": r.execution.delivered.as_ref().map(|dl| dl.duration()),
        "safe_to_play": r.execution.safety.safe,
    });
    let interrupted = r
        .stopped_by
        .as_ref()
        .is_some_and(|b| b.ga == Some(Termination::Interrupted) || b.refine == Some(Termination::Interrupted));
    let (state, detail) = match (r.status, interrupted) {
        (crate::excitation::Status::Infeasible, _) => (
            RunState::Infeasible,
            match (&r.execution.problem, r.violated.len()) {
                _ if r.unexcited().is_some() => format!("infeasible: {}", r.unexcited().unwrap_or_default()),
                (Some(e), 0) => format!("infeasible: not playable rest to rest: {e}"),
                (_, k) => format!("infeasible: {k} constraint(s) violated"),
            },
        ),
        (crate::excitation::Status::Feasible, true) => (RunState::Interrupted, "interrupted; the best feasible design so far".to_string()),
        (crate::excitation::Status::Feasible, false) => (
            RunState::Complete,
            format!(
                "feasible, condition number {:.4}{}",
                r.spectrum.cond,
                if r.execution.safety.safe == Some(false) {
                    "; NOT safe to play (collides: see report.txt)"
                } else {
                    ""
                }
            ),
        ),
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
            delivered_identifiability: &delivered_ident,
            period_identifiability: period_ident.as_ref(),
            criterion_samples: &grid_set,
            verification_rate: d.limits.check_rate,
            applied_limits: &p.applied_limits,
            margins_at_clock: "result.margins[].at and result.violated[].at: seconds from the start of the period (of the whole motion for a rest-to-rest shape); trajectory.csv and the preview run on the delivered clock, t = 0 at the start of the lead-in: see worst_instants[].at_delivered_s",
            worst_instants: {
                let clock = super::text::Clock::of(p, r);
                r.margins
                    .iter()
                    .map(|m| WorstInstant {
                        name: m.name.clone(),
                        at_period_s: m.at,
                        at_delivered_s: clock.delivered(m.at),
                    })
                    .collect()
            },
        },
    )?;
    crate::io::write_atomic(
        &dir.join("report.txt"),
        excite_report_text(p, r, &ident, Some(&delivered_ident), period_ident.as_ref()).as_bytes(),
    )?;
    spectrum_svg(
        &dir.join("singular_values.svg"),
        &r.spectrum.singular_values,
        &format!("{}: singular values", d.name),
    )?;
    progress_svg(
        &dir.join("search_progress.svg"),
        r,
        &serde_json::to_value(d.objective.criterion)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default(),
        &format!("{} (seed {}): search progress", d.name, d.seed),
    )?;
    joints_svg(p, r, &dir.join("joints.svg"))?;
    ee_svg(p, r, &dir.join("ee_path.svg"))?;
    extra(dir)?;
    // the final status last: a folder without it is marked `running`
    crate::io::status::write_status(dir, "excite", state, detail, started, crate::io::status::fingerprint_of(d)?, summary)?;
    Ok(Written {
        identifiability: ident,
        delivered: delivered_ident,
        record,
    })
}

/// The unit-column figure of an identifiability report.
pub fn ident_figure(label: &str, samples: SampleSet, id: &Identifiability) -> Figure {
    Figure {
        label: label.into(),
        samples,
        scaling: Scaling::UnitColumn,
        column_norms: id.column_norms.clone(),
        scale: unit_scale(&id.column_norms),
        criterion: None,
        value: None,
        cond: id.cond,
        singular_values: id.singular_values.clone(),
    }
}

/// The unit-column factors of the identifiability report: 1/‖c_j‖, 0 for a
/// column below 10⁻¹⁴ of the largest norm (a zero column).
pub fn unit_scale(norms: &[f64]) -> Vec<f64> {
    let maxn = norms.iter().cloned().fold(0.0, f64::max);
    norms.iter().map(|&v| if v > 1e-14 * maxn.max(1e-300) { 1.0 / v } else { 0.0 }).collect()
}

impl Identifiability {
    /// Writes report.json, report.txt and singular_values.svg into `dir`.
    pub fn write(&self, dir: &Path, title: &str) -> Result<()> {
        crate::io::write_json(&dir.join("report.json"), self)?;
        crate::io::write_atomic(&dir.join("report.txt"), format!("{title}\n\n{}", self.text()).as_bytes())?;
        spectrum_svg(&dir.join("singular_values.svg"), &self.singular_values, title)
    }
}
