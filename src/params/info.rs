//! What `idexp robot info|torques|regressor` reports: the robot summary with
//! its base parameters ([`RobotInfo`]), and the inverse-dynamics torque and
//! regressor tables of a states CSV ([`torques_table`], [`regressor_table`]).
//! It sits at the params layer because the summary and the base regressor use
//! [`BaseParams`].

use crate::error::Result;
use crate::io::States;
use crate::params::{BaseOptions, BaseParams};
use crate::robot::{regressor_rows, rnea, JointKind, Robot, Workspace};
use serde::Serialize;

/// Torques for every state: header (`t` if present, `tau1..taun`) and rows.
pub fn torques_table(r: &Robot, s: &States) -> (Vec<String>, Vec<Vec<f64>>) {
    let n = r.dof();
    let mut ws = Workspace::new(r);
    let mut header = Vec::new();
    if s.t.is_some() {
        header.push("t".to_string());
    }
    header.extend((1..=n).map(|i| format!("tau{i}")));
    let mut tau = vec![0.0; n];
    let rows = (0..s.len())
        .map(|k| {
            rnea(r, &mut ws, &s.q[k], &s.qd[k], &s.qdd[k], &mut tau);
            let mut row = Vec::with_capacity(n + 1);
            if let Some(t) = &s.t {
                row.push(t[k]);
            }
            row.extend_from_slice(&tau);
            row
        })
        .collect();
    (header, rows)
}

/// Regressor rows for every state: columns `sample, joint, <parameter names>`.
pub fn regressor_table(r: &Robot, s: &States, base: Option<&BaseParams>) -> (Vec<String>, Vec<Vec<f64>>) {
    let (n, p) = (r.dof(), r.n_params());
    let mut ws = Workspace::new(r);
    let mut header = vec!["sample".to_string(), "joint".to_string()];
    match base {
        Some(b) => header.extend(b.names.iter().cloned()),
        None => header.extend(r.param_names()),
    }
    let mut y = vec![0.0; n * p];
    let nb = base.map(|b| b.n_base()).unwrap_or(p);
    let mut yb = vec![0.0; n * nb];
    let mut rows = Vec::with_capacity(s.len() * n);
    for k in 0..s.len() {
        regressor_rows(r, &mut ws, &s.q[k], &s.qd[k], &s.qdd[k], &mut y);
        let src: &[f64] = match base {
            Some(b) => {
                b.select_rows(&y, n, &mut yb);
                &yb
            }
            None => &y,
        };
        for j in 0..n {
            let mut row = Vec::with_capacity(nb + 2);
            row.push(k as f64);
            row.push((j + 1) as f64);
            row.extend_from_slice(&src[j * nb..(j + 1) * nb]);
            rows.push(row);
        }
    }
    (header, rows)
}

/// Summary of a robot for `robot info`.
#[derive(Debug, Serialize)]
pub struct RobotInfo {
    /// Name.
    pub name: String,
    /// Source of the model.
    pub source: String,
    /// Joints.
    pub joints: Vec<JointInfo>,
    /// Coupling matrix rows (if any).
    pub coupling: Option<Vec<Vec<f64>>>,
    /// Named frames.
    pub frames: Vec<String>,
    /// End-effector frame used by default.
    pub end_effector: String,
    /// Standard parameter names.
    pub standard_parameters: Vec<String>,
    /// Number of standard parameters (all).
    pub n_standard: usize,
    /// Number of standard inertial parameters (10 per link).
    pub n_standard_inertial: usize,
    /// Base parameters of the full model (inertial + drive + friction).
    pub base: BaseParams,
    /// Number of base parameters of the rigid-body (inertial) part alone.
    pub n_base_inertial: usize,
    /// Base parameter names (rows of `k`).
    pub base_names: Vec<String>,
    /// K (rows: base parameters, columns: `standard_parameters`): θ_base = K θ_standard.
    pub k: Vec<Vec<f64>>,
    /// Physical-consistency warnings about the nominal inertials (triangle
    /// inequalities, positive semi-definite pseudo-inertia, zero mass with inertia).
    pub warnings: Vec<String>,
}

/// One joint in [`RobotInfo`].
#[derive(Debug, Serialize)]
pub struct JointInfo {
    /// Name.
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Link moved by the joint.
    pub link: String,
    /// Parent link (None: base).
    pub parent: Option<String>,
    /// Limits (null for unlimited).
    pub lower: Option<f64>,
    /// Upper limit.
    pub upper: Option<f64>,
    /// Velocity limit.
    pub velocity: Option<f64>,
    /// Acceleration limit.
    pub acceleration: Option<f64>,
    /// Effort limit.
    pub effort: Option<f64>,
    /// Drive data.
    pub drive: crate::robot::Drive,
}

fn fin(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

impl RobotInfo {
    /// Collects the summary; computes base parameters with tolerance `tol`.
    pub fn new(r: &Robot, tol: f64, samples: usize) -> Result<RobotInfo> {
        let opts = BaseOptions {
            tol,
            samples,
            ..Default::default()
        };
        let base = BaseParams::compute(r, &opts)?;
        let inertial = BaseParams::compute(r, &BaseOptions { inertial_only: true, ..opts })?;
        Ok(RobotInfo {
            name: r.name.clone(),
            source: r.source.clone(),
            joints: r
                .joints
                .iter()
                .enumerate()
                .map(|(i, j)| JointInfo {
                    name: j.name.clone(),
                    kind: j.kind,
                    link: r.links[i].name.clone(),
                    parent: j.parent.map(|p| r.links[p].name.clone()),
                    lower: fin(j.limits.lower),
                    upper: fin(j.limits.upper),
                    velocity: fin(j.limits.velocity),
                    acceleration: fin(j.limits.acceleration),
                    effort: fin(j.limits.effort),
                    drive: r.drives[i],
                })
                .collect(),
            coupling: r.coupling.as_ref().map(|c| c.row_iter().map(|row| row.iter().copied().collect()).collect()),
            frames: r.frames.iter().map(|f| f.name.clone()).collect(),
            end_effector: r.end_effector().name,
            standard_parameters: r.param_names(),
            n_standard: r.n_params(),
            n_standard_inertial: 10 * r.dof(),
            n_base_inertial: inertial.n_base(),
            base_names: base.names.clone(),
            k: base.k.row_iter().map(|row| row.iter().copied().collect()).collect(),
            warnings: crate::robot::export::inertial_warnings(r),
            base,
        })
    }

    /// Human-readable text.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "robot: {}", self.name);
        let _ = writeln!(s, "source: {}", self.source);
        for w in &self.warnings {
            let _ = writeln!(s, "WARNING: {w}");
        }
        let _ = writeln!(s, "\njoints ({}):", self.joints.len());
        let _ = writeln!(
            s,
            "  {:<3} {:<22} {:<9} {:>9} {:>9} {:>8} {:>8} {:>8}  drive",
            "#", "name", "type", "lower", "upper", "vel", "acc", "effort"
        );
        let f = |v: Option<f64>| v.map(|x| format!("{x:.4}")).unwrap_or_else(|| "-".into());
        for (i, j) in self.joints.iter().enumerate() {
            let d = &j.drive;
            // the coefficients in layout order (robot::drive_params), Stribeck ones apart
            let params = crate::robot::drive_params(d);
            let show = |stribeck: bool| {
                let kinds = [crate::robot::ParamKind::Fs, crate::robot::ParamKind::FsPos, crate::robot::ParamKind::FsNeg];
                let v: Vec<String> = params
                    .friction()
                    .iter()
                    .filter(|(k, _)| kinds.contains(k) == stribeck)
                    .map(|(k, v)| format!("{}={v}", k.symbol()))
                    .collect();
                v.join(" ")
            };
            let fr = match d.friction {
                crate::robot::Friction::None => "no friction".to_string(),
                _ => show(false),
            };
            let fr = match d.coulomb {
                crate::robot::Coulomb::Sign => fr,
                crate::robot::Coulomb::Stribeck { .. } if !matches!(d.friction, crate::robot::Friction::None) => {
                    format!("{fr} {} coulomb={}", show(true), d.coulomb.describe())
                }
                c => format!("{fr} coulomb={}", c.describe()),
            };
            let fr = match d.torque_constant {
                Some(kt) => format!("{fr} kt={kt} N={} sign={}", d.gear_ratio, d.current_sign),
                None => fr,
            };
            let ia = d.rotor_inertia.map(|v| format!("Ia={v} ")).unwrap_or_default();
            let kind = match j.kind {
                JointKind::Revolute => "revolute",
                JointKind::Prismatic => "prismatic",
            };
            let _ = writeln!(
                s,
                "  {:<3} {:<22} {:<9} {:>9} {:>9} {:>8} {:>8} {:>8}  {ia}{fr}",
                i + 1,
                j.name,
                kind,
                f(j.lower),
                f(j.upper),
                f(j.velocity),
                f(j.acceleration),
                f(j.effort)
            );
        }
        if let Some(c) = &self.coupling {
            let _ = writeln!(s, "\ncoupling (motor positions θ = C q):");
            for row in c {
                let _ = writeln!(s, "  [{}]", row.iter().map(|v| format!("{v:7.3}")).collect::<Vec<_>>().join(" "));
            }
        }
        let _ = writeln!(s, "\nend effector: {}", self.end_effector);
        let b = &self.base;
        let _ = writeln!(
            s,
            "\nstandard parameters: {} ({} inertial, {} drive/friction)",
            self.n_standard,
            self.n_standard_inertial,
            self.n_standard - self.n_standard_inertial
        );
        let _ = writeln!(s, "base parameters: {} (inertial part alone: {})", b.n_base(), self.n_base_inertial);
        let _ = writeln!(
            s,
            "rank tolerance: {:.1e} (relative residual); smallest kept {:.2e}, largest dropped {:.2e}; pivoted-QR rank {}; {} random states",
            b.tol, b.smallest_kept, b.largest_dropped, b.rank_qr, b.samples
        );
        let _ = writeln!(s, "\nbase parameters as combinations of standard ones:");
        for (i, (n, g)) in b.names.iter().zip(&b.groupings).enumerate() {
            let _ = writeln!(s, "  {:>3} {:<8} = {}", i + 1, n, g);
        }
        let un: Vec<&str> = b.unidentifiable.iter().map(|&i| self.standard_parameters[i].as_str()).collect();
        let _ = writeln!(s, "\nno effect on the torques ({}): {}", un.len(), un.join(" "));
        s
    }
}
