//! The text reports: report.txt of `idexp excite`, the identifiability
//! summary, violated constraints and the collision lines.

use super::assess::{column_parameters, Identifiability};
use super::outputs::criterion_sample_set;
use crate::excitation::constraints::{ConstraintKind, Margin};
use crate::excitation::{ExciteResult, Problem, Scaling, Status};
use crate::trajectory::{seconds_text, TrajectoryShape};
use std::fmt::Write as _;

/// `2nd`, `3rd`, `7th`, `11th`, `21st`, ...
pub(super) fn ordinal(k: usize) -> String {
    let suffix = match (k % 10, k % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{k}{suffix}")
}

impl Identifiability {
    /// A short text summary.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let m = self.names.len();
        if let Some(src) = &self.source {
            let _ = writeln!(s, "samples used: {}", src.description);
        }
        let _ = writeln!(s, "samples: {} ({} rows), base parameters: {m}, rank: {}", self.samples, self.rows, self.rank);
        let _ = writeln!(
            s,
            "base columns (the regressor column of each of these standard parameters; groupings in report.json): {}",
            self.parameters.join(" ")
        );
        let _ = writeln!(
            s,
            "matrix: C_w = rows of joint j divided by its torque noise σ_j, then every column divided by its norm over these \
             samples (norms: column_norms in report.json); |q̇_j| < {:e} counts as 0 (Coulomb column sign(q̇_j), viscous q̇_j)",
            crate::excitation::objective::ZERO_VELOCITY
        );
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
}

fn fmt_list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}

pub(super) fn fmt_num(v: f64) -> String {
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

/// The text summary of a design run (report.txt) without the delivered
/// trajectory's identifiability ([`excite_report_text`]).
pub fn excite_text(p: &Problem, r: &ExciteResult, ident: &Identifiability) -> String {
    excite_report_text(p, r, ident, None, None)
}

/// The text summary of a design run (report.txt): `ident` on the criterion's
/// samples, `delivered` on every row of the delivered trajectory.
/// `period`: the criterion's samples read from trajectory.csv (segment 1).
///
/// The sections, in order: what was designed and what the criterion is
/// computed from (`design_section`), the outcome (`outcome_section`),
/// the violated constraints (`violations_section`), the collision lines
/// ([`collision_text`]), the delivered trajectory (`delivered_section`),
/// the limits and margins (`limits_section`), the solver
/// (`solver_section`) and the identifiability on the criterion's samples.
pub fn excite_report_text(
    p: &Problem,
    r: &ExciteResult,
    ident: &Identifiability,
    delivered: Option<&Identifiability>,
    period: Option<&Identifiability>,
) -> String {
    let check_rate = p.design.limits.check_rate;
    let mut s = String::new();
    design_section(&mut s, p);
    outcome_section(&mut s, p, r, delivered, period);
    let clock = Clock::of(p, r);
    violations_section(&mut s, r, check_rate, clock);
    s.push_str(&collision_text_on(p, &r.margins, check_rate, clock));
    delivered_section(&mut s, p, r);
    limits_section(&mut s, p, r);
    solver_section(&mut s, r);
    let _ = writeln!(
        s,
        "\nidentifiability (on the criterion's samples, unit columns whatever the criterion's scaling; predicted for the stated torque noise):"
    );
    s.push_str(&ident.text());
    s
}

/// The design, its trajectory, and the matrix W½·C·D the criterion is
/// computed from (samples, weights, scaling, columns), then a blank line.
fn design_section(s: &mut String, p: &Problem) {
    let d = &p.design;
    let _ = writeln!(s, "excitation design `{}` for robot `{}` ({})", d.name, p.robot.name, d.robot.display());
    match &p.shape {
        crate::trajectory::Shape::BSpline(b) => {
            let _ = writeln!(
                s,
                "trajectory: B-spline of degree {}, {} segments over {} s, starts and ends at rest at q0, {} design variables",
                b.degree,
                b.segments,
                seconds_text(b.duration),
                crate::trajectory::TrajectoryShape::n_vars(&p.shape)
            );
        }
        crate::trajectory::Shape::Fourier(_) => {
            let _ = writeln!(
                s,
                "trajectory: {} harmonics of {} Hz (period {} s), {} design variables{}{}",
                d.trajectory.harmonics,
                d.trajectory.frequency,
                seconds_text(1.0 / d.trajectory.frequency),
                crate::trajectory::TrajectoryShape::n_vars(&p.shape),
                if d.trajectory.vary_q0 { ", q0 free" } else { "" },
                if d.trajectory.at_rest { ", starts and ends at rest" } else { "" }
            );
        }
    }
    let grid_set = criterion_sample_set(p);
    let noise = d.objective.noise.clone().unwrap_or_else(|| vec![1.0; p.robot.dof()]);
    let _ = writeln!(
        s,
        "criterion: {} of W½·C·D, C the stacked base regressor ({} columns × {} rows)",
        d.objective.criterion.words(),
        p.objective.n_cols(),
        p.objective.n_rows(),
    );
    let _ = writeln!(s, "  samples: {}", grid_set.description);
    let _ = writeln!(
        s,
        "  W½ = diag(1/σ_j) per joint row, σ = {:?} N·m{}",
        noise,
        if d.objective.noise.is_none() { " (objective.noise not given)" } else { "" }
    );
    let _ = writeln!(
        s,
        "  D: {}",
        match d.objective.scaling {
            Scaling::UnitColumn => "every column of W½C divided by its norm over these samples (norms in criterion.json)",
            Scaling::Nominal => "every column times the nominal value of its base parameter (floored at 10⁻³ of the largest; criterion.json)",
            Scaling::None => "none (D = I)",
        }
    );
    if d.objective.columns == crate::excitation::Columns::Gains {
        let _ = writeln!(
            s,
            "  columns (a drive-gain calibration with the [payload] as the known mass): per joint j the nominal payload's torque \
             on joint j's rows only, then the payload's nine unknown parameters about its frame's origin (docs/payload.md): {}",
            p.objective.column_names.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "  {}columns: the regressor column of each of these standard parameters (base parameters and their groupings in \
         criterion.json; Coulomb column sign(q̇_j), 0 for |q̇_j| < {:e}; viscous q̇_j): {}",
        if d.objective.columns == crate::excitation::Columns::Gains {
            "identifiability figures' "
        } else {
            ""
        },
        crate::excitation::objective::ZERO_VELOCITY,
        column_parameters(&p.robot, &p.base).join(" ")
    );
    let _ = writeln!(
        s,
        "  to recompute: criterion.json (columns, weights, column norms, every figure below with its samples) and the sample files it names"
    );
    let _ = writeln!(s);
}

/// Status, safety, the criterion value and the condition numbers: on the
/// criterion's samples, on the same samples read from trajectory.csv
/// (`period`) and on the delivered trajectory (`delivered`).
fn outcome_section(s: &mut String, p: &Problem, r: &ExciteResult, delivered: Option<&Identifiability>, period: Option<&Identifiability>) {
    let status = match r.status {
        Status::Feasible => "FEASIBLE".to_string(),
        Status::Infeasible => "INFEASIBLE".to_string(),
    };
    let _ = writeln!(
        s,
        "status: {status}{}",
        r.stopped_by.as_ref().map(|b| format!(" (stopped early: {b})")).unwrap_or_default()
    );
    if r.execution.delivered.is_some() && r.status == Status::Feasible {
        let _ = writeln!(s, "safety: {}", r.execution.safety.statement);
    }
    let _ = writeln!(s, "criterion value: {}", fmt_num(r.criterion));
    let _ = writeln!(s, "condition number: {} (on the criterion's samples above)", fmt_num(r.spectrum.cond));
    if let Some((pi, src)) = period.and_then(|pi| pi.source.as_ref().map(|src| (pi, src))) {
        let start = match p.shape.ends() {
            crate::trajectory::Ends::Periodic => match src.t_range {
                Some([a, _]) if a > 0.0 => {
                    format!(
                        "trajectory.csv starts with the lead-in at t = 0: its first {} s are not part of a period",
                        seconds_text(a)
                    )
                }
                _ => "trajectory.csv has no lead-in: segment 1 starts at t = 0".to_string(),
            },
            crate::trajectory::Ends::RestToRest => match src.t_range {
                // free start pose: a lead-in from home comes first
                Some([a, _]) if a > 0.0 => format!(
                    "trajectory.csv starts with the lead-in from the home pose at t = 0: segment 1 starts at t = {} s",
                    seconds_text(a)
                ),
                _ => "a rest-to-rest motion from the home pose has no lead-in: segment 1 starts at t = 0".to_string(),
            },
        };
        let _ = writeln!(
            s,
            "  the same samples in trajectory.csv: segment 1, every {} row, t = {} s: condition number {} (unit columns; \
             `idexp assess {} trajectory.csv --segment 1 --every {}`). {start}",
            ordinal(src.every),
            src.t_range
                .map_or("?".to_string(), |[a, b]| format!("{} … {}", seconds_text(a), seconds_text(b))),
            fmt_num(pi.cond),
            p.design.robot.display(),
            src.every,
        );
    }
    if let Some(dl) = delivered {
        let _ = writeln!(
            s,
            "condition number of the delivered trajectory: {} (same columns and weights, unit columns over {}; rank {}/{})",
            fmt_num(dl.cond),
            dl.source.as_ref().map_or("", |s| s.description.as_str()),
            dl.rank,
            dl.names.len()
        );
    }
}

/// The clocks of the times in the report: the margins' worst instants are
/// found on one period of the design (t = 0 at the period's start; the
/// whole motion for a rest-to-rest shape), trajectory.csv and the preview
/// run on the delivered clock (t = 0 at the start of the lead-in).
#[derive(Debug, Clone, Copy)]
pub struct Clock {
    /// Lead-in duration (s): period 1 starts at this time on the delivered
    /// clock (`None`: no delivered trajectory, so no delivered clock).
    pub lead_in: Option<f64>,
    /// Periodic (a period) or rest-to-rest (the whole motion).
    pub periodic: bool,
}

impl Clock {
    /// The clocks of a design run.
    pub fn of(p: &Problem, r: &ExciteResult) -> Clock {
        Clock {
            lead_in: r.execution.delivered.as_ref().map(|dl| dl.lead_in_duration()),
            periodic: p.shape.ends() == crate::trajectory::Ends::Periodic,
        }
    }

    /// A worst instant `at` (s, on the period's clock) in words, with the same
    /// instant on the delivered clock when there is one.
    pub fn at_text(&self, at: f64) -> String {
        let on = if self.periodic { "into the period" } else { "into the motion" };
        match self.lead_in {
            Some(l) => format!(
                "t = {at:.3} s {on} (t = {:.3} s on the delivered clock of trajectory.csv and the preview, {} 1)",
                at + l,
                if self.periodic { "period" } else { "repetition" }
            ),
            None => format!("t = {at:.3} s {on}"),
        }
    }

    /// The same instant on the delivered clock (s), when there is one.
    pub fn delivered(&self, at: f64) -> Option<f64> {
        self.lead_in.map(|l| at + l)
    }
}

/// The violated constraints on the verification grid (`check_rate` Hz), worst first.
fn violations_section(s: &mut String, r: &ExciteResult, check_rate: f64, clock: Clock) {
    if r.violated.is_empty() {
        return;
    }
    let _ = writeln!(s, "\nviolated constraints (on the {check_rate} Hz verification grid), worst first:");
    for m in &r.violated {
        if is_distance(m) {
            let _ = writeln!(s, "  {}", distance_violation(m, clock));
            continue;
        }
        let _ = writeln!(
            s,
            "  {}: reaches {} {} at {}, {} {} beyond the limit",
            m.name,
            fmt_num(m.worst),
            m.unit,
            clock.at_text(m.at),
            fmt_num(-m.margin),
            m.unit
        );
    }
    let _ = writeln!(s, "  (no trajectory found by the search meets these; relax them or move q0 / the workspace)");
}

/// The delivered trajectory (lead-in, periods, lead-out) and whether it is playable.
fn delivered_section(s: &mut String, p: &Problem, r: &ExciteResult) {
    let _ = writeln!(s, "\ndelivered trajectory (what trajectory.csv and the exports hold):");
    match (&r.execution.delivered, &r.execution.problem) {
        (Some(dl), problem) => {
            let _ = writeln!(
                s,
                "  from home {} at rest: lead-in {:.2} s, {} {} of {} s, lead-out {:.2} s back to home at rest; total {:.2} s",
                fmt_list(&dl.home),
                dl.lead_in_duration(),
                dl.periods,
                match crate::trajectory::Motion::ends(&dl.periodic) {
                    crate::trajectory::Ends::Periodic => "period(s)",
                    crate::trajectory::Ends::RestToRest => "rest-to-rest motion(s)",
                },
                dl.periodic.duration_text(),
                dl.lead_out_duration(),
                dl.duration()
            );
            match problem {
                None => {
                    let _ = writeln!(
                        s,
                        "  every sample within every joint limit{} on the {} Hz grid",
                        if p.design.workspace.is_empty() { "" } else { " and workspace constraint" },
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
}

/// The limits applied (value and source) and the worst margin per constraint.
fn limits_section(s: &mut String, p: &Problem, r: &ExciteResult) {
    let _ = writeln!(s, "\nlimits applied (value imposed; source):");
    for a in &p.applied_limits {
        let v = if a.class == "position" {
            format!("[{}, {}]", fmt_num(a.imposed[0]), fmt_num(a.imposed[1]))
        } else {
            format!("±{}", fmt_num(a.imposed[1]))
        };
        let _ = writeln!(s, "  {:<22} {:<13} {:>24} {:<7} {}", a.joint, a.class, v, a.unit, a.source);
    }
    let _ = writeln!(s, "\nworst margin per constraint ({} Hz grid; ≥ 0 holds):", p.design.limits.check_rate);
    for m in &r.margins {
        let _ = writeln!(s, "  {:<60} margin {:>12} {}", m.name, fmt_num(m.margin), m.unit);
    }
}

/// The GA, every refinement, the chosen design and the total time.
fn solver_section(s: &mut String, r: &ExciteResult) {
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
    let _ = writeln!(s, "search progress (best feasible criterion on the design grid; search_progress.svg):");
    for q in &r.progress {
        let _ = writeln!(s, "  {:>9.2} s {:>10} evaluations  {}  ({})", q.seconds, q.evaluations, fmt_num(q.best), q.from);
    }
    let _ = writeln!(s, "chosen: {}; total {:.2} s on {} threads", r.chosen, r.seconds, r.threads);
}

/// The margins that are violated, as readable lines.
pub fn violation_lines(m: &[Margin]) -> Vec<String> {
    m.iter()
        .filter(|m| m.margin < 0.0)
        .map(|m| {
            if is_distance(m) {
                distance_violation(m, Clock { lead_in: None, periodic: true })
            } else {
                format!("{}: {} {} beyond the limit", m.name, fmt_num(-m.margin), m.unit)
            }
        })
        .collect()
}

fn is_distance(m: &Margin) -> bool {
    matches!(m.kind, ConstraintKind::SelfCollision | ConstraintKind::WorldCollision)
}

/// `collision self: forearm_link – wrist_2_link at t = 3.141 s into the period
/// (…on the delivered clock…): distance −0.0130 m (penetration 0.0130 m),
/// 0.0330 m inside the 0.02 m margin`.
fn distance_violation(m: &Margin, clock: Clock) -> String {
    let pair = m.name.trim_start_matches("distance ").split(" ≥ ").next().unwrap_or(&m.name);
    let pen = if m.worst < 0.0 {
        format!("penetration depth {:.4} m", -m.worst)
    } else {
        "no contact".to_string()
    };
    format!(
        "collision {pair} at {}: distance {:.4} m ({pen}), {:.4} m inside the {} m margin",
        clock.at_text(m.at),
        m.worst,
        -m.margin,
        m.limit
    )
}

/// The collision lines of the report: geometry, checked and excluded pairs,
/// the worst distance per class on the verification grid (its instant on
/// the period's clock, `Clock`).
pub fn collision_text(p: &Problem, margins: &[Margin], rate: f64) -> String {
    collision_text_on(
        p,
        margins,
        rate,
        Clock {
            lead_in: None,
            periodic: p.shape.ends() == crate::trajectory::Ends::Periodic,
        },
    )
}

/// [`collision_text`] with each instant also on the delivered clock.
pub fn collision_text_on(p: &Problem, margins: &[Margin], rate: f64, clock: Clock) -> String {
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
    let padded: Vec<String> = sc
        .bodies()
        .iter()
        .filter(|b| b.padding() > 0.0)
        .map(|b| format!("{} {:.1} mm", b.name, b.padding() * 1e3))
        .collect();
    if padded.is_empty() {
        let _ = writeln!(
            s,
            "  distances between convex parts (primitives, convex hulls of the meshes): a hull holds its mesh, so the \
             mesh distance is at least the one reported (replay on the full meshes: scripts/safety-replay.py)"
        );
    } else {
        let _ = writeln!(
            s,
            "  distances between convex parts (primitives, convex hulls of the collision meshes) grown by the robot \
             file's collision_padding ({}), which holds the vendor's full visual meshes: the distance of the full meshes \
             is at least the one reported (replay: scripts/safety-replay.py --meshes visual)",
            padded.join(", ")
        );
    }
    for (kind, label) in [(ConstraintKind::SelfCollision, "self"), (ConstraintKind::WorldCollision, "world")] {
        if let Some(w) = margins.iter().filter(|m| m.kind == kind).min_by(|a, b| a.worst.total_cmp(&b.worst)) {
            let pair = w.name.trim_start_matches("distance ").split(" ≥ ").next().unwrap_or(&w.name);
            let _ = writeln!(
                s,
                "  worst {label} distance on the {rate} Hz grid: {:.4} m ({pair}, {}){}",
                w.worst,
                clock.at_text(w.at),
                if w.margin < 0.0 { " — VIOLATES the margin" } else { "" }
            );
        }
    }
    s
}
