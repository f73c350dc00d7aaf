//! Physical plausibility of a robot as its file describes it, checked once
//! when the file is read (before [`Robot::new`]), with messages that name the
//! file, the joint/link/frame/drive field, the value and what is allowed:
//! finite joint placements, position limits that are either both finite with
//! lower < upper or both absent, positive velocity/acceleration/effort limits,
//! link inertias that are positive semidefinite at the centre of mass
//! (the triangle inequality is a warning: see [`check_com_inertia`]), non-negative friction coefficients,
//! uniquely named joints, links and frames with finite placements, a
//! well-conditioned coupling matrix and a gravity of sane magnitude.

use super::dynamics::drive_params;
use super::model::{Inertial, ParamSign, Robot, RobotParts};
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix3};
use std::path::Path;

/// Largest condition number accepted for the coupling matrix C: beyond it,
/// C⁻ᵀ amplifies rounding by more than 1e8 and base parameters are lost to
/// numerical rank decisions rather than to the robot's structure.
pub const MAX_COUPLING_CONDITION: f64 = 1e8;

/// Largest accepted gravity magnitude (m/s²): 100 g.
pub const MAX_GRAVITY: f64 = 981.0;

/// Checks `parts` (read from `file`) and assembles the robot; an error of the
/// assembly that names only the robot is given the file as well.
pub fn checked(file: &Path, parts: RobotParts) -> Result<Robot> {
    check(file, &parts)?;
    let name = parts.name.clone();
    Robot::new(parts).map_err(|e| match e {
        Error::Invalid { context, field, msg } if !context.contains(&file.display().to_string()) => Error::Invalid {
            context: format!("{} (robot `{name}`)", file.display()),
            field,
            msg,
        },
        other => other,
    })
}

fn finite_iso(p: &Isometry3<f64>) -> bool {
    p.translation.vector.iter().chain(p.rotation.coords.iter()).all(|v| v.is_finite())
}

/// Checks a rigid body's inertia about its centre of mass `ic` (mass `m`):
/// finite and positive semidefinite (no negative principal moment; a
/// relative tolerance of 1e-9 of the trace absorbs the rounding of file
/// values). A principal moment above the sum of the other two (the triangle
/// inequality) is legal input but no rigid body has it: published lumped
/// models do (link 3 of Corke's PUMA 560 by 10 %), so it is a warning
/// (`robot::export::inertial_warnings`, shown by `robot info` and
/// `identify`), not an error.
pub fn check_com_inertia(ctx: &str, field: &str, m: f64, ic: &Matrix3<f64>) -> Result<()> {
    if !m.is_finite() || m < 0.0 {
        return Err(Error::invalid(ctx, field, format!("expected a non-negative finite mass, found {m}")));
    }
    if ic.iter().any(|v| !v.is_finite()) {
        return Err(Error::invalid(ctx, field, format!("expected finite inertia values, found {ic:?}")));
    }
    let sym = (ic + ic.transpose()) * 0.5;
    let ev = sym.symmetric_eigenvalues();
    let tol = 1e-9 * ev.iter().map(|v| v.abs()).sum::<f64>().max(f64::MIN_POSITIVE);
    let mut e: Vec<f64> = ev.iter().copied().collect();
    e.sort_by(f64::total_cmp);
    if e[0] < -tol {
        return Err(Error::invalid(
            ctx,
            field,
            format!(
                "the inertia at the centre of mass is not positive semidefinite (principal moments {:.6e}, {:.6e}, {:.6e}); expected moments ≥ 0",
                e[0], e[1], e[2]
            ),
        ));
    }
    Ok(())
}

/// The inertia about the centre of mass of an inertial given about the link
/// origin: I_c = I_o − (|h|² 1 − h hᵀ)/m with h = m c (I_o itself when m = 0).
fn com_inertia(i: &Inertial) -> Matrix3<f64> {
    if i.mass > 0.0 {
        let h = i.first_moment;
        i.inertia - (Matrix3::identity() * h.norm_squared() - h * h.transpose()) / i.mass
    } else {
        i.inertia
    }
}

/// Checks the pieces read from `file` (see the module documentation).
pub fn check(file: &Path, p: &RobotParts) -> Result<()> {
    let ctx = file.display().to_string();
    let ctx = ctx.as_str();
    for (i, j) in p.joints.iter().enumerate() {
        let field = |s: &str| format!("joint `{}` {s}", j.name);
        if p.joints[..i].iter().any(|o| o.name == j.name) {
            return Err(Error::invalid(ctx, field("name"), "duplicate joint name; every joint needs its own name"));
        }
        if !finite_iso(&j.placement) || !finite_iso(&j.post) || !j.offset.is_finite() {
            return Err(Error::invalid(
                ctx,
                field("origin"),
                format!("expected a finite placement, found xyz {:?}", j.placement.translation.vector.as_slice()),
            ));
        }
        if j.axis.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(ctx, field("axis"), "expected a finite, non-zero axis"));
        }
        let l = &j.limits;
        let (lo, up) = (l.lower, l.upper);
        if lo.is_nan() || up.is_nan() {
            return Err(Error::invalid(ctx, field("limits"), format!("lower {lo}, upper {up}: expected numbers")));
        }
        match (lo.is_finite(), up.is_finite()) {
            (true, true) => {
                if lo >= up {
                    return Err(Error::invalid(
                        ctx,
                        field("limits"),
                        format!("lower {lo} ≥ upper {up}: expected lower < upper (a joint that cannot move is a fixed joint)"),
                    ));
                }
            }
            (false, false) => {
                if lo != f64::NEG_INFINITY || up != f64::INFINITY {
                    return Err(Error::invalid(ctx, field("limits"), format!("lower {lo}, upper {up}: expected lower < upper")));
                }
            }
            _ => {
                return Err(Error::invalid(
                    ctx,
                    field("limits"),
                    format!("lower {lo}, upper {up}: give both position limits as finite numbers, or neither for an unbounded (continuous) joint"),
                ))
            }
        }
        for (what, v) in [("velocity", l.velocity), ("acceleration", l.acceleration), ("effort", l.effort)] {
            if v.is_nan() || v <= 0.0 {
                return Err(Error::invalid(
                    ctx,
                    field(&format!("{what} limit")),
                    format!("expected a positive limit (or none), found {v}"),
                ));
            }
        }
    }
    for (i, l) in p.links.iter().enumerate() {
        if p.links[..i].iter().any(|o| o.name == l.name) {
            return Err(Error::invalid(ctx, format!("link `{}`", l.name), "duplicate link name"));
        }
        let m = l.inertial.mass;
        if !m.is_finite() || m < 0.0 {
            return Err(Error::invalid(
                ctx,
                format!("link `{}` mass", l.name),
                format!("expected a non-negative finite mass, found {m}"),
            ));
        }
        if l.inertial.first_moment.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(ctx, format!("link `{}` com", l.name), "expected a finite centre of mass"));
        }
        check_com_inertia(ctx, &format!("link `{}` inertia", l.name), m, &com_inertia(&l.inertial))?;
    }
    for (i, d) in p.drives.iter().enumerate() {
        let jn = p.joints.get(i).map(|j| j.name.as_str()).unwrap_or("?");
        // the friction coefficients with a sign (`ParamKind::sign`), by their
        // file keys, in the layout order of the drive-parameter walk
        let params = drive_params(d);
        let coeffs = params.friction().iter().filter_map(|&(k, v)| match k.sign() {
            ParamSign::NonNegative => Some((k.drive_key().unwrap_or(k.label()), v, true)),
            ParamSign::NonPositive => Some((k.drive_key().unwrap_or(k.label()), v, false)),
            ParamSign::Free => None,
        });
        for (name, v, nonneg) in coeffs {
            let ok = v.is_finite() && if nonneg { v >= 0.0 } else { v <= 0.0 };
            if !ok {
                let allowed = if nonneg {
                    "≥ 0 (friction dissipates)"
                } else {
                    "≤ 0 (the Coulomb term opposes negative velocity)"
                };
                return Err(Error::invalid(
                    ctx,
                    format!("drive of joint `{jn}` {name}"),
                    format!("expected a finite coefficient {allowed}, found {v}"),
                ));
            }
        }
    }
    for (k, f) in p.frames.iter().enumerate() {
        if p.frames[..k].iter().any(|o| o.name == f.name) {
            return Err(Error::invalid(
                ctx,
                format!("frame `{}`", f.name),
                "duplicate frame name (a [[frame]] entry or a fixed URDF link already has it)",
            ));
        }
        if p.links.iter().any(|l| l.name == f.name) {
            return Err(Error::invalid(ctx, format!("frame `{}`", f.name), "a moving link already has this name"));
        }
        if !finite_iso(&f.placement) {
            return Err(Error::invalid(
                ctx,
                format!("frame `{}` xyz/rpy", f.name),
                format!("expected a finite placement, found xyz {:?}", f.placement.translation.vector.as_slice()),
            ));
        }
    }
    if let Some(c) = &p.coupling {
        if c.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(ctx, "coupling", "expected finite numbers"));
        }
        if c.is_square() && c.nrows() == p.joints.len() {
            // the condition number does not change with scale; scaling by the
            // largest entry keeps the SVD away from overflow (entries of 1e308)
            let scale = c.amax();
            let s = if scale > 0.0 {
                crate::linalg::singular_values(&(c / scale))
                    .map_err(|e| Error::invalid(ctx, "coupling", format!("cannot take the singular values of the coupling matrix: {e}")))?
            } else {
                vec![0.0]
            };
            let (smax, smin) = (s[0], *s.last().unwrap_or(&0.0));
            let cond = if smin > 0.0 { smax / smin } else { f64::INFINITY };
            if cond.is_nan() || cond > MAX_COUPLING_CONDITION {
                return Err(Error::invalid(
                    ctx,
                    "coupling",
                    format!(
                        "the coupling matrix is singular or nearly so: condition number {cond:.3e} (singular values {smax:.3e} … {smin:.3e}); expected ≤ {MAX_COUPLING_CONDITION:.0e}"
                    ),
                ));
            }
        }
    }
    let g = p.gravity.norm();
    if !(g.is_finite() && g <= MAX_GRAVITY) {
        return Err(Error::invalid(
            ctx,
            "gravity",
            format!(
                "{:?} (|g| = {g:.3e} m/s²): expected finite components with a magnitude ≤ {MAX_GRAVITY} m/s² (100 g)",
                p.gravity.as_slice()
            ),
        ));
    }
    Ok(())
}
