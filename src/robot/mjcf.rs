//! MJCF (MuJoCo's model format) writer: any [`Robot`], e.g. the consistent
//! model an identification gives, as a body tree MuJoCo loads.
//!
//! # What is written
//!
//! * one `<body>` per moving link, nested as the joints are. The body frame
//!   is idexp's joint frame after the motion (parent link frame ·
//!   `placement` · motion(q)); the link frame is that frame moved by the
//!   constant motion(offset) · `post` (DH offsets and the standard-DH
//!   `post`), so MuJoCo's `qpos` equals idexp's q, with no `ref`;
//! * `<inertial>`: `mass`, `pos` = the centre of mass and `fullinertia` =
//!   the inertia about it, in the body frame; an inertia on the
//!   triangle-inequality boundary (principal moments A + B = C: a flat body,
//!   which a physically consistent fit gives where the data allow it) is
//!   lifted by the smallest δ·1 that gives A + B − C ≥ 10⁻⁹ (A + B + C)
//!   ([`TRIANGLE_MARGIN`]), said in a comment at the body: MuJoCo refuses
//!   the exact boundary by rounding;
//! * `<joint>`: `type` = `hinge` (revolute) or `slide` (prismatic), `axis`,
//!   `range` when both position limits are finite, `armature` = the
//!   reflected rotor inertia Ia (idexp's Ia is already referred to the joint
//!   side through the gear, `Ia = N² J_motor`: it is MuJoCo's armature as it
//!   stands), `damping` = the viscous coefficient Fv, `frictionloss` = the
//!   Coulomb coefficient Fc;
//! * one `<motor>` per joint (gear 1: the control is the joint torque or
//!   force), `ctrlrange` = ± the effort limit when finite;
//! * `<option gravity>`: the robot's gravity; `<site>`s for the named frames.
//!
//! What MJCF cannot express is stated in XML comments at the top of the file
//! and at each joint concerned: a coupling matrix (MuJoCo's armature,
//! damping and friction loss act on each joint's own velocity; idexp's on
//! the motor velocities C q̇, with τ = C⁻ᵀ τ_rb + Ia ⊙ C q̈ + f(C q̇)),
//! asymmetric friction (written as its symmetric part), a friction offset
//! F0, the tanh and Stribeck Coulomb shapes (MuJoCo's `frictionloss` is a
//! dry-friction constraint force of at most Fc, solved with the other
//! constraints, not Fc·sign(q̇) nor a tanh), and the torque constant.
//!
//! MuJoCo's `mj_inverse` torques of the written model equal idexp's
//! [`rnea`](super::rnea) to rounding on states within the joint ranges,
//! with the friction loss disabled and the Coulomb term added
//! (`python/tests/test_mjcf.py`).

use super::model::{Coulomb, Friction, Inertial, JointKind, Robot};
use crate::error::Result;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// A number as MJCF reads it back exactly (shortest round-trip form).
fn num(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 {
        "0".into()
    } else if (1e-4..1e6).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn nums(v: &[f64]) -> String {
    v.iter().map(|&x| num(x)).collect::<Vec<_>>().join(" ")
}

/// Text safe inside an XML comment (no `--`).
fn comment_text(s: &str) -> String {
    let mut t = s.replace("--", "- -");
    if t.ends_with('-') {
        t.push(' ');
    }
    t
}

fn attr(s: &str) -> String {
    quick_xml::escape::escape(s).into_owned()
}

fn pose_attrs(x: &Isometry3<f64>) -> String {
    let p = x.translation.vector;
    let q = x.rotation;
    format!(" pos=\"{}\" quat=\"{}\"", nums(&[p.x, p.y, p.z]), nums(&[q.w, q.i, q.j, q.k]))
}

/// The constant transform from MuJoCo's body frame of joint `j` to idexp's
/// link frame: motion(offset) · post.
fn body_to_link(robot: &Robot, j: usize) -> Isometry3<f64> {
    let jt = &robot.joints[j];
    let m = match jt.kind {
        JointKind::Revolute => Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&jt.axis, jt.offset)),
        JointKind::Prismatic => Isometry3::from_parts(Translation3::from(jt.axis.into_inner() * jt.offset), UnitQuaternion::identity()),
    };
    m * jt.post
}

/// Relative margin of the triangle inequality in the written inertias:
/// every principal moment pair satisfies A + B − C ≥ `TRIANGLE_MARGIN`·(A + B + C).
///
/// MuJoCo (4.0.1) refuses a `fullinertia` whose principal moments, as its
/// own eigen-decomposition finds them, violate A + B ≥ C ("inertia must
/// satisfy A + B >= C") or are not positive; a body on the boundary (a flat
/// body, a rod: what a physically consistent fit gives when the data allow
/// it) is refused in about 4 cases out of 10 by rounding alone. 1e-10 was
/// enough in 1000 random flat bodies over eight decades of size; 1e-9 is
/// written.
pub const TRIANGLE_MARGIN: f64 = 1e-9;

/// The inertia about the centre of mass as written to MuJoCo: `ic` when its
/// principal moments keep [`TRIANGLE_MARGIN`], else `ic + δ·1` with the
/// smallest δ that makes them keep it (the same δ added to all three
/// principal moments, the axes unchanged); returns δ (0: unchanged).
pub fn mujoco_inertia(ic: &nalgebra::Matrix3<f64>) -> (nalgebra::Matrix3<f64>, f64) {
    let sym = (ic + ic.transpose()) * 0.5;
    let ev = nalgebra::SymmetricEigen::new(sym).eigenvalues;
    let mut e = [ev[0], ev[1], ev[2]];
    e.sort_by(f64::total_cmp);
    let tr = e[0] + e[1] + e[2];
    if !(tr.is_finite() && tr > 0.0) {
        return (*ic, 0.0);
    }
    // the tightest of A + B − C over the permutations, and the smallest moment
    let gap = e[0] + e[1] - e[2];
    let want = TRIANGLE_MARGIN * tr;
    // adding δ to each moment adds δ to A + B − C and to the trace's 3δ: solve gap + δ ≥ margin·(tr + 3δ)
    let delta_gap = ((want - gap) / (1.0 - 3.0 * TRIANGLE_MARGIN)).max(0.0);
    let delta_pos = (want - e[0]).max(0.0);
    let delta = delta_gap.max(delta_pos);
    if delta == 0.0 {
        (*ic, 0.0)
    } else {
        (ic + nalgebra::Matrix3::identity() * delta, delta)
    }
}

/// `<inertial>` of an inertial given in the body frame, and the δ added to
/// its principal moments ([`mujoco_inertia`]; 0: written as it is).
fn inertial_xml(ine: &Inertial) -> (String, f64) {
    let m = ine.mass;
    let (c, ic) = super::export::com_inertia(ine);
    let (ic, delta) = mujoco_inertia(&ic);
    (
        format!(
            "<inertial pos=\"{}\" mass=\"{}\" fullinertia=\"{}\"/>",
            nums(&[c.x, c.y, c.z]),
            num(m),
            nums(&[ic[(0, 0)], ic[(1, 1)], ic[(2, 2)], ic[(0, 1)], ic[(0, 2)], ic[(1, 2)]])
        ),
        delta,
    )
}

/// The joint attributes MJCF takes from a drive, and what it cannot express.
fn drive_attrs(robot: &Robot, j: usize) -> (String, Vec<String>) {
    let d = &robot.drives[j];
    let mut a = String::new();
    let mut notes = Vec::new();
    if let Some(ia) = d.rotor_inertia {
        let _ = write!(a, " armature=\"{}\"", num(ia));
    }
    // not a walk over the drive parameters (`dynamics::visit_drive_params`):
    // MJCF has one symmetric dry and one viscous coefficient, so the model is
    // translated by its meaning (the symmetric part of the asymmetric model),
    // which needs the variant, and each coefficient it cannot express is named
    let (fc, fv) = match d.friction {
        Friction::None => (0.0, 0.0),
        Friction::Symmetric { fc, fv, offset } => {
            if let Some(o) = offset {
                notes.push(format!("friction offset F0 = {} not expressed", num(o)));
            }
            (fc, fv)
        }
        Friction::Asymmetric {
            fc_pos,
            fc_neg,
            fv_pos,
            fv_neg,
            offset,
        } => {
            notes.push(format!(
                "asymmetric friction Fc+ = {}, Fc- = {}, Fv+ = {}, Fv- = {} written as its symmetric part (Fc+ - Fc-)/2, (Fv+ + Fv-)/2; the odd part (Fc+ + Fc-)/2 = {} and the viscous difference are not expressed",
                num(fc_pos),
                num(fc_neg),
                num(fv_pos),
                num(fv_neg),
                num(0.5 * (fc_pos + fc_neg))
            ));
            if let Some(o) = offset {
                notes.push(format!("friction offset F0 = {} not expressed", num(o)));
            }
            (0.5 * (fc_pos - fc_neg), 0.5 * (fv_pos + fv_neg))
        }
    };
    match d.coulomb {
        Coulomb::Sign => {}
        Coulomb::Tanh { .. } | Coulomb::Stribeck { .. } => notes.push(format!(
            "Coulomb shape {} written as MuJoCo's dry friction (frictionloss){}",
            d.coulomb.describe(),
            if let Coulomb::Stribeck { fs, .. } = d.coulomb {
                format!("; the Stribeck coefficients {} are not expressed", nums(&fs))
            } else {
                String::new()
            }
        )),
    }
    if fv != 0.0 {
        let _ = write!(a, " damping=\"{}\"", num(fv));
    }
    if fc != 0.0 {
        let _ = write!(a, " frictionloss=\"{}\"", num(fc));
    }
    (a, notes)
}

/// The MJCF text of `robot` (see the module documentation).
pub fn mjcf_string(robot: &Robot) -> String {
    let n = robot.dof();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n + 1]; // 0: world
    for (j, jt) in robot.joints.iter().enumerate() {
        children[jt.parent.map_or(0, |p| p + 1)].push(j);
    }
    let mut x = String::new();
    let _ = writeln!(x, "<mujoco model=\"{}\">", attr(&robot.name));
    let _ = writeln!(
        x,
        "  <!-- written by idexp {} from {}: inertials, joints, drives (armature = Ia, damping = Fv, frictionloss = Fc); no geometry (an inertial model) -->",
        env!("CARGO_PKG_VERSION"),
        comment_text(&robot.source.replace('\n', " "))
    );
    let mut global = Vec::new();
    if let Some(c) = &robot.coupling {
        let rows: Vec<String> = c.row_iter().map(|r| format!("[{}]", nums(&r.iter().copied().collect::<Vec<_>>()))).collect();
        global.push(format!(
            "NOT EXPRESSED: the coupling matrix C = [{}] (motor positions C q): idexp's drive terms act on the motor velocities, tau = C^-T tau_rb + Ia (C qdd) + f(C qd); here armature, damping and frictionloss act on each joint's own velocity, and the torques are joint torques (tau_joint = C^T tau_motor)",
            rows.join(", ")
        ));
    }
    for (j, d) in robot.drives.iter().enumerate() {
        if d.torque_constant.is_some() {
            global.push(format!(
                "not expressed: joint `{}`'s torque constant and gear ratio (currents); the motor's control is the joint torque",
                robot.joints[j].name
            ));
            break;
        }
    }
    for g in &global {
        let _ = writeln!(x, "  <!-- {} -->", comment_text(g));
    }
    let _ = writeln!(x, "  <compiler angle=\"radian\" autolimits=\"true\" inertiafromgeom=\"false\"/>");
    let g = robot.gravity;
    let _ = writeln!(x, "  <option gravity=\"{}\"/>", nums(&[g.x, g.y, g.z]));
    let _ = writeln!(x, "  <worldbody>");
    let mut sites_of: Vec<Vec<String>> = vec![Vec::new(); n + 1];
    let mut seen = std::collections::HashSet::new();
    for f in &robot.frames {
        if !seen.insert(f.name.clone()) {
            continue;
        }
        let at = match f.link {
            Some(l) => body_to_link(robot, l) * f.placement,
            None => f.placement,
        };
        sites_of[f.link.map_or(0, |l| l + 1)].push(format!("<site name=\"{}\"{}/>", attr(&f.name), pose_attrs(&at)));
    }
    for s in &sites_of[0] {
        let _ = writeln!(x, "    {s}");
    }
    // depth-first, parents first
    fn body(robot: &Robot, j: usize, children: &[Vec<usize>], sites_of: &[Vec<String>], depth: usize, x: &mut String) {
        let ind = "  ".repeat(depth + 2);
        let jt = &robot.joints[j];
        let parent_e = jt.parent.map_or_else(Isometry3::identity, |p| body_to_link(robot, p));
        let e = body_to_link(robot, j);
        let _ = writeln!(
            x,
            "{ind}<body name=\"{}\"{}>",
            attr(&robot.links[j].name),
            pose_attrs(&(parent_e * jt.placement))
        );
        let (inertial, delta) = inertial_xml(&robot.links[j].inertial.transformed(&e));
        if delta > 0.0 {
            let _ = writeln!(
                x,
                "{ind}  <!-- link `{}`: its inertia lies on the triangle-inequality boundary (a flat body or a rod, as a physically consistent fit may give): {} kg m^2 added to each principal moment so that MuJoCo accepts it (A + B - C >= {} (A + B + C)) -->",
                comment_text(&robot.links[j].name),
                num(delta),
                num(TRIANGLE_MARGIN)
            );
        }
        let _ = writeln!(x, "{ind}  {inertial}");
        let (drive, notes) = drive_attrs(robot, j);
        for note in notes {
            let _ = writeln!(x, "{ind}  <!-- joint `{}`: {} -->", comment_text(&jt.name), comment_text(&note));
        }
        let l = &jt.limits;
        let range = if l.lower.is_finite() && l.upper.is_finite() {
            format!(" range=\"{}\"", nums(&[l.lower, l.upper]))
        } else {
            String::new()
        };
        let a = jt.axis;
        let _ = writeln!(
            x,
            "{ind}  <joint name=\"{}\" type=\"{}\" axis=\"{}\"{range}{drive}/>",
            attr(&jt.name),
            match jt.kind {
                JointKind::Revolute => "hinge",
                JointKind::Prismatic => "slide",
            },
            nums(&[a.x, a.y, a.z])
        );
        for s in &sites_of[j + 1] {
            let _ = writeln!(x, "{ind}  {s}");
        }
        for &c in &children[j + 1] {
            body(robot, c, children, sites_of, depth + 1, x);
        }
        let _ = writeln!(x, "{ind}</body>");
    }
    for &c in &children[0] {
        body(robot, c, &children, &sites_of, 0, &mut x);
    }
    let _ = writeln!(x, "  </worldbody>");
    let _ = writeln!(x, "  <actuator>");
    for jt in &robot.joints {
        let e = jt.limits.effort;
        let range = if e.is_finite() {
            format!(" ctrlrange=\"{}\"", nums(&[-e, e]))
        } else {
            String::new()
        };
        let _ = writeln!(x, "    <motor name=\"{}\" joint=\"{}\" gear=\"1\"{range}/>", attr(&jt.name), attr(&jt.name));
    }
    let _ = writeln!(x, "  </actuator>");
    let _ = writeln!(x, "</mujoco>");
    x
}

/// Writes `robot.xml` (the MJCF of `robot`, [`mjcf_string`]) into `dir`
/// (created if missing; written atomically) and returns its path.
pub fn write_mjcf(robot: &Robot, dir: &Path) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| crate::Error::io(dir, e))?;
    let p = dir.join("robot.xml");
    crate::io::write_atomic(&p, mjcf_string(robot).as_bytes())?;
    Ok(p)
}
