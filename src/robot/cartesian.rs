//! Cartesian workspace constraints on named frames (end effector or any link
//! origin): inside a box, inside a sphere, on one side of a plane, outside an
//! obstacle box, inside a cylindrical sector (paper 000's restrained
//! workspace: a sector of the reachable half-sphere).
//!
//! Each shape is a set of scalar margins g_k(p) ≥ 0 (in metres, positive
//! inside the allowed region) with gradients ∂g_k/∂p, so optimisers can chain
//! them with the frame Jacobian.

use crate::error::{Error, Result};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The allowed region for a frame origin (base coordinates, metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// Inside the axis-aligned box [min, max].
    Box {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
    /// Inside the ball |p − center| ≤ radius.
    Sphere {
        /// Centre.
        center: [f64; 3],
        /// Radius.
        radius: f64,
    },
    /// On the side of the plane where normal·p ≥ offset (the normal need not be unit;
    /// it is normalised, so the margin is a distance). "Above a table at z = h":
    /// normal = `[0, 0, 1]`, offset = h.
    HalfSpace {
        /// Plane normal, pointing into the allowed side.
        normal: [f64; 3],
        /// Offset: allowed where n̂·p ≥ offset (with n̂ the unit normal).
        offset: f64,
    },
    /// Outside the axis-aligned obstacle box [min, max] (inflated by `clearance`).
    OutsideBox {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
        /// Extra clearance (m), default 0.
        #[serde(default)]
        clearance: f64,
    },
    /// Cylindrical sector about the vertical axis through `center`: azimuth
    /// φ = atan2(y − cy, x − cx) in `[azimuth[0], azimuth[1]]` (rad, within (−π, π]),
    /// horizontal distance ρ in `[radius[0], radius[1]]`, height z − cz in `[z[0], z[1]]`.
    Sector {
        /// Axis position.
        #[serde(default)]
        center: [f64; 3],
        /// Azimuth range (rad).
        azimuth: [f64; 2],
        /// Radial range (m).
        radius: [f64; 2],
        /// Height range relative to the centre (m).
        z: [f64; 2],
    },
}

/// A constraint: the origin of `frame` must stay in `shape`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CartesianConstraint {
    /// Frame or link name; `None`: the robot's end effector.
    #[serde(default)]
    pub frame: Option<String>,
    /// Allowed region.
    pub shape: Shape,
}

impl Shape {
    /// Checks the numbers (finite, ordered ranges, positive radius, non-zero normal).
    pub fn validate(&self, ctx: &str, field: &str) -> Result<()> {
        let all_finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let bad = |m: &str| Err(Error::invalid(ctx, field, m.to_string()));
        match self {
            Shape::Box { min, max } | Shape::OutsideBox { min, max, .. } => {
                if !all_finite(min) || !all_finite(max) {
                    return bad("box corners must be finite");
                }
                if (0..3).any(|i| min[i] >= max[i]) {
                    return bad("box needs min < max on every axis");
                }
                if let Shape::OutsideBox { clearance, .. } = self {
                    if !(clearance.is_finite() && *clearance >= 0.0) {
                        return bad("clearance must be ≥ 0");
                    }
                }
            }
            Shape::Sphere { center, radius } => {
                if !(all_finite(center) && radius.is_finite() && *radius > 0.0) {
                    return bad("sphere needs a finite centre and a positive radius");
                }
            }
            Shape::HalfSpace { normal, offset } => {
                if !all_finite(normal) || !offset.is_finite() || Vector3::from(*normal).norm() < 1e-12 {
                    return bad("half space needs a non-zero finite normal and a finite offset");
                }
            }
            Shape::Sector { center, azimuth, radius, z } => {
                if !all_finite(center) || !all_finite(azimuth) || !all_finite(radius) || !all_finite(z) {
                    return bad("sector values must be finite");
                }
                if azimuth[0] >= azimuth[1] || azimuth[0] < -std::f64::consts::PI - 1e-12 || azimuth[1] > std::f64::consts::PI + 1e-12 {
                    return bad("sector azimuth must satisfy −π ≤ azimuth[0] < azimuth[1] ≤ π");
                }
                if radius[0] < 0.0 || radius[0] >= radius[1] || z[0] >= z[1] {
                    return bad("sector needs 0 ≤ radius[0] < radius[1] and z[0] < z[1]");
                }
            }
        }
        Ok(())
    }

    /// Number of scalar margins this shape produces.
    pub fn n_margins(&self) -> usize {
        match self {
            Shape::Box { .. } => 6,
            Shape::Sphere { .. } | Shape::HalfSpace { .. } | Shape::OutsideBox { .. } => 1,
            Shape::Sector { .. } => 6,
        }
    }

    /// Appends the margins g_k(p) (≥ 0 allowed) and their gradients w.r.t. p.
    pub fn margins(&self, p: &Vector3<f64>, out: &mut Vec<(f64, Vector3<f64>)>) {
        match self {
            Shape::Box { min, max } => {
                for i in 0..3 {
                    let mut e = Vector3::zeros();
                    e[i] = 1.0;
                    out.push((p[i] - min[i], e));
                    out.push((max[i] - p[i], -e));
                }
            }
            Shape::Sphere { center, radius } => {
                let d = p - Vector3::from(*center);
                let r = d.norm();
                let g = if r > 1e-15 { -d / r } else { Vector3::zeros() };
                out.push((radius - r, g));
            }
            Shape::HalfSpace { normal, offset } => {
                let n = Vector3::from(*normal).normalize();
                out.push((n.dot(p) - offset, n));
            }
            Shape::OutsideBox { min, max, clearance } => {
                // signed distance to the inflated box along the best face (max over faces)
                let mut best = (f64::NEG_INFINITY, Vector3::zeros());
                for i in 0..3 {
                    let mut e = Vector3::zeros();
                    e[i] = 1.0;
                    let lo = min[i] - clearance - p[i];
                    let hi = p[i] - max[i] - clearance;
                    if lo > best.0 {
                        best = (lo, -e);
                    }
                    if hi > best.0 {
                        best = (hi, e);
                    }
                }
                out.push(best);
            }
            Shape::Sector { center, azimuth, radius, z } => {
                let d = p - Vector3::from(*center);
                let rho = (d.x * d.x + d.y * d.y).sqrt();
                let phi = d.y.atan2(d.x);
                let (gr, gphi) = if rho > 1e-12 {
                    (
                        Vector3::new(d.x / rho, d.y / rho, 0.0),
                        Vector3::new(-d.y / (rho * rho), d.x / (rho * rho), 0.0),
                    )
                } else {
                    (Vector3::zeros(), Vector3::zeros())
                };
                // azimuth margins as arc lengths at the current radius: ρ(φ − φmin)
                out.push((rho * (phi - azimuth[0]), gr * (phi - azimuth[0]) + gphi * rho));
                out.push((rho * (azimuth[1] - phi), gr * (azimuth[1] - phi) - gphi * rho));
                out.push((rho - radius[0], gr));
                out.push((radius[1] - rho, -gr));
                out.push((d.z - z[0], Vector3::z()));
                out.push((z[1] - d.z, -Vector3::z()));
            }
        }
    }

    /// The smallest margin (≥ 0: inside the allowed region).
    pub fn margin(&self, p: &Vector3<f64>) -> f64 {
        let mut v = Vec::with_capacity(6);
        self.margins(p, &mut v);
        v.iter().map(|m| m.0).fold(f64::INFINITY, f64::min)
    }

    /// A short human description for reports.
    pub fn describe(&self) -> String {
        match self {
            Shape::Box { min, max } => format!("inside box {min:?}–{max:?}"),
            Shape::Sphere { center, radius } => format!("inside sphere centre {center:?} radius {radius}"),
            Shape::HalfSpace { normal, offset } => format!("half space n·p ≥ {offset}, n = {normal:?}"),
            Shape::OutsideBox { min, max, clearance } => format!("outside obstacle box {min:?}–{max:?} (clearance {clearance})"),
            Shape::Sector { center, azimuth, radius, z } => format!("sector about {center:?}: azimuth {azimuth:?} rad, radius {radius:?} m, z {z:?} m"),
        }
    }
}

impl CartesianConstraint {
    /// Validates the shape and resolves the frame on `robot`.
    pub fn resolve(&self, robot: &super::Robot, ctx: &str, field: &str) -> Result<super::Frame> {
        self.shape.validate(ctx, field)?;
        match &self.frame {
            None => Ok(robot.end_effector()),
            Some(name) => robot.find_frame(name).ok_or_else(|| {
                let mut names: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
                names.extend(robot.frames.iter().map(|f| f.name.clone()));
                Error::invalid(
                    ctx,
                    format!("{field}.frame"),
                    format!("no frame or link named `{name}`; known: {}", names.join(", ")),
                )
            }),
        }
    }
}
