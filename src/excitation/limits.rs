//! The joint limits a design imposes, resolved against its robot: every
//! limit class the design asks for (`[limits]` fractions > 0) must exist in
//! the robot for every joint, or the design says `missing = "skip"`; each
//! applied limit is listed with its source (robot file, URDF, design
//! override).
//!
//! Before this check, a URDF without `<limit acceleration=...>` (the UR5 one)
//! silently dropped the design's `acceleration = 1.0`.

use super::constraints::JointLimitSpec;
use super::design::{LimitsSpec, MissingLimits};
use crate::error::{Error, Result};
use crate::robot::{JointKind, Robot};
use serde::Serialize;
use std::path::Path;

/// One limit as imposed on one joint.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AppliedLimit {
    /// Joint name.
    pub joint: String,
    /// `position`, `velocity`, `acceleration` or `torque`.
    pub class: String,
    /// The imposed bound(s): [lower, upper] for positions, [−v, v] otherwise
    /// (infinite: not imposed).
    pub imposed: [f64; 2],
    /// Unit of `imposed`.
    pub unit: String,
    /// The robot's own value ([lower, upper] or the symmetric limit).
    pub robot_value: [f64; 2],
    /// The design's fraction applied to it (1 for overrides).
    pub fraction: f64,
    /// Where the value comes from: `robot file <path> [[drive]] <joint>`,
    /// `URDF <path>`, `design limits.position_range[j]`, or `not imposed (...)`.
    pub source: String,
}

/// Where each joint's limits come from in the robot file `path` (its
/// `[[drive]]` or `[[joint]]` entries override the URDF it points to).
fn source_of(path: &Path, joint: &str, keys: &[&str]) -> String {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext != "toml" {
        return format!("URDF {}", path.display());
    }
    let v: Option<toml::Table> = crate::io::read_to_string(path).ok().and_then(|t| t.parse::<toml::Table>().ok());
    let Some(v) = v else {
        return format!("robot file {}", path.display());
    };
    for (section, name_key) in [("drive", "joint"), ("joint", "name")] {
        if let Some(arr) = v.get(section).and_then(|a| a.as_array()) {
            for e in arr {
                if e.get(name_key).and_then(|n| n.as_str()) == Some(joint) && keys.iter().any(|k| e.get(*k).is_some()) {
                    return format!("robot file {} [[{section}]] {joint}", path.display());
                }
            }
        }
    }
    match v.get("urdf").and_then(|u| u.as_str()) {
        Some(u) => format!("URDF {}", path.parent().unwrap_or(Path::new("")).join(u).display()),
        None => format!("robot file {}", path.display()),
    }
}

/// Resolves `[limits]` against `robot` (loaded from `robot_path`): the joint
/// limits the constraints impose and the list of what was applied and why.
///
/// A class asked for (fraction > 0; positions always) but missing for a joint
/// (infinite in the robot) is an error naming the file, the joint and the key
/// to set, unless `missing = "skip"`, which leaves it out and says so in the
/// list.
pub fn resolve(l: &LimitsSpec, robot: &Robot, robot_path: &Path, ctx: &str) -> Result<(JointLimitSpec, Vec<AppliedLimit>)> {
    let n = robot.dof();
    let mut applied = Vec::new();
    let skip = l.missing == MissingLimits::Skip;
    let missing = |joint: &str, class: &str, key: &str| -> Error {
        Error::invalid(
            ctx,
            format!("limits.{class}"),
            format!(
                "the design imposes {class} limits (limits.{class} = {}), but joint `{joint}` of {} has none: set `{key}` for it in the robot file ([[drive]] joint = \"{joint}\"), or set limits.{class} = 0 (not imposed), or limits.missing = \"skip\" to leave out the missing ones",
                match class {
                    "velocity" => l.velocity,
                    "acceleration" => l.acceleration,
                    _ => l.torque,
                },
                robot_path.display()
            ),
        )
    };
    let mut position = Vec::with_capacity(n);
    for (j, jt) in robot.joints.iter().enumerate() {
        let unit = if jt.kind == JointKind::Prismatic { "m" } else { "rad" };
        let (range, src) = match &l.position_range {
            Some(r) => (r[j], format!("design limits.position_range[{j}]")),
            None => ([jt.limits.lower, jt.limits.upper], source_of(robot_path, &jt.name, &["lower", "upper"])),
        };
        let [lo, hi] = range;
        let (imposed, source) = if lo.is_finite() && hi.is_finite() {
            let (c, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
            ([c - l.position * h, c + l.position * h], src)
        } else if skip {
            (
                [lo, hi],
                format!("not imposed (joint without a finite range in {src}; limits.missing = \"skip\")"),
            )
        } else {
            return Err(Error::invalid(
                ctx,
                "limits.position",
                format!(
                    "joint `{}` of {} has no finite position range ([{lo}, {hi}]): set `lower`/`upper` for it in the robot file, or limits.position_range in the design, or limits.missing = \"skip\" to leave it unbounded",
                    jt.name,
                    robot_path.display()
                ),
            ));
        };
        applied.push(AppliedLimit {
            joint: jt.name.clone(),
            class: "position".into(),
            imposed,
            unit: unit.into(),
            robot_value: range,
            fraction: if l.position_range.is_some() { 1.0 } else { l.position },
            source,
        });
        position.push(imposed);
    }
    let mut classes: Vec<Vec<f64>> = Vec::with_capacity(3);
    for (class, fraction, key, unit_r, unit_p) in [
        ("velocity", l.velocity, "velocity", "rad/s", "m/s"),
        ("acceleration", l.acceleration, "acceleration", "rad/s²", "m/s²"),
        ("torque", l.torque, "effort", "N·m", "N"),
    ] {
        let mut v = Vec::with_capacity(n);
        for jt in &robot.joints {
            let value = match class {
                "velocity" => jt.limits.velocity,
                "acceleration" => jt.limits.acceleration,
                _ => jt.limits.effort,
            };
            let unit = if jt.kind == JointKind::Prismatic { unit_p } else { unit_r };
            let (imposed, source) = if fraction <= 0.0 {
                (f64::INFINITY, format!("not imposed (limits.{class} = 0)"))
            } else if value.is_finite() {
                (fraction * value, source_of(robot_path, &jt.name, &[key]))
            } else if skip {
                (f64::INFINITY, "not imposed (missing in the robot; limits.missing = \"skip\")".to_string())
            } else {
                return Err(missing(&jt.name, class, key));
            };
            applied.push(AppliedLimit {
                joint: jt.name.clone(),
                class: class.into(),
                imposed: [-imposed, imposed],
                unit: unit.into(),
                robot_value: [-value, value],
                fraction,
                source,
            });
            v.push(imposed);
        }
        classes.push(v);
    }
    let torque = classes.pop().unwrap_or_default();
    let acceleration = classes.pop().unwrap_or_default();
    let velocity = classes.pop().unwrap_or_default();
    Ok((
        JointLimitSpec {
            position,
            velocity,
            acceleration,
            torque,
        },
        applied,
    ))
}
