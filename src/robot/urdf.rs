//! URDF loader: revolute, continuous, prismatic and fixed joints; arbitrary
//! joint origins and axes; fixed children merged into their parent body's
//! inertia (and kept as named frames); joint limits.

use super::model::{Drive, Frame, Friction, Inertial, Joint, JointKind, JointLimits, Link};
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::HashMap;
use std::path::Path;

/// Pieces of a robot read from a URDF, before the robot file adds drives.
#[derive(Debug)]
pub struct UrdfParts {
    /// Robot name in the URDF.
    pub name: String,
    /// Actuated joints (parents first).
    pub joints: Vec<Joint>,
    /// Moving links with merged inertia.
    pub links: Vec<Link>,
    /// Drives from `<dynamics damping friction>` (Fv, Fc).
    pub drives: Vec<Drive>,
    /// Frames of links attached by fixed joints (and of links moved by a
    /// locked joint, see [`UrdfParts::left_out`]).
    pub frames: Vec<Frame>,
    /// What of the URDF is not part of the model, and why: joints below the
    /// tip (`tip_link`) or beside the chain to it, and `<mimic>` groups (a
    /// gripper's fingers) locked at their reference position with their
    /// bodies merged into the link that carries them. One sentence each.
    pub left_out: Vec<String>,
}

pub(crate) fn pose_to_iso(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    let rot = Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    Isometry3::from_parts(Translation3::new(xyz[0], xyz[1], xyz[2]), UnitQuaternion::from_rotation_matrix(&rot))
}

/// 1-based line and column (in characters) of byte `pos` of `text`.
pub(crate) fn line_col(text: &str, pos: usize) -> (usize, usize) {
    let pos = pos.min(text.len());
    let mut p = pos;
    while !text.is_char_boundary(p) {
        p -= 1;
    }
    let before = &text[..p];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// A `<joint>` element as written (what urdf-rs fills with defaults).
#[derive(Debug, Default)]
struct RawJoint {
    /// Where the element starts (line, column).
    at: (usize, usize),
    /// The `<limit>` element's attributes, if the element is present.
    limit: Option<Vec<(String, String)>>,
    /// Line and column of a `<mimic>` element, and the joint it names.
    mimic: Option<(usize, usize)>,
    /// The `joint` attribute of the `<mimic>` element (the leader).
    mimic_of: Option<String>,
}

/// What urdf-rs does not tell from the URDF text: which links have an
/// `<inertial>` element, which `<limit>` attributes and `<mimic>` elements
/// a joint has, where each element is, and duplicate names. Malformed XML
/// (an unclosed tag, mismatched end tags) is an error with line and column.
#[derive(Debug, Default)]
struct RawUrdf {
    links_with_inertial: Vec<String>,
    links: Vec<(String, (usize, usize))>,
    joints: Vec<(String, RawJoint)>,
}

impl RawUrdf {
    fn joint(&self, name: &str) -> Option<&RawJoint> {
        self.joints.iter().find(|(n, _)| n == name).map(|(_, j)| j)
    }
}

fn scan_urdf(path: &Path, text: &str) -> Result<RawUrdf> {
    use quick_xml::events::{BytesStart, Event};
    let mut reader = quick_xml::Reader::from_str(text);
    let mut out = RawUrdf::default();
    // open elements: (name, start byte)
    let mut open: Vec<(String, usize)> = Vec::new();
    let attr = |e: &BytesStart, key: &str| -> Option<String> {
        e.try_get_attribute(key)
            .ok()
            .flatten()
            .and_then(|a| a.unescape_value().ok().map(|v| v.into_owned()))
    };
    loop {
        let before = reader.buffer_position() as usize;
        let ev = match reader.read_event() {
            Ok(ev) => ev,
            Err(e) => {
                let (l, c) = line_col(text, reader.error_position() as usize);
                return Err(Error::parse(path, format!("malformed URDF at line {l}, column {c}: {e}")));
            }
        };
        let (start, empty) = match &ev {
            Event::Start(e) => (Some(e.clone()), false),
            Event::Empty(e) => (Some(e.clone()), true),
            Event::End(_) => {
                open.pop();
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let Some(e) = start else { continue };
        let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
        let parent = open.last().map(|(n, _)| n.as_str());
        let at = line_col(text, before);
        match (name.as_str(), parent) {
            ("link", Some("robot")) => out.links.push((attr(&e, "name").unwrap_or_default(), at)),
            ("inertial", Some("link")) => {
                if let Some((n, _)) = out.links.last() {
                    out.links_with_inertial.push(n.clone());
                }
            }
            ("joint", Some("robot")) => out.joints.push((attr(&e, "name").unwrap_or_default(), RawJoint { at, ..Default::default() })),
            ("limit", Some("joint")) => {
                if let Some((_, j)) = out.joints.last_mut() {
                    let attrs = e
                        .attributes()
                        .filter_map(|a| a.ok())
                        .map(|a| {
                            let k = String::from_utf8_lossy(a.key.as_ref()).into_owned();
                            let v = a.unescape_value().map(|v| v.into_owned()).unwrap_or_default();
                            (k, v)
                        })
                        .collect();
                    j.limit = Some(attrs);
                }
            }
            ("mimic", Some("joint")) => {
                if let Some((_, j)) = out.joints.last_mut() {
                    j.mimic = Some(at);
                    j.mimic_of = attr(&e, "joint");
                }
            }
            _ => {}
        }
        if !empty {
            open.push((name, before));
        }
    }
    if let Some((n, pos)) = open.last() {
        let (l, c) = line_col(text, *pos);
        return Err(Error::parse(
            path,
            format!("malformed URDF: element <{n}> opened at line {l}, column {c} is never closed"),
        ));
    }
    for (k, (n, at)) in out.links.iter().enumerate() {
        if let Some((_, first)) = out.links[..k].iter().find(|(o, _)| o == n) {
            return Err(Error::parse(
                path,
                format!("line {}, column {}: link `{n}` is defined twice (first at line {})", at.0, at.1, first.0),
            ));
        }
    }
    for (k, (n, j)) in out.joints.iter().enumerate() {
        if let Some((_, first)) = out.joints[..k].iter().find(|(o, _)| o == n) {
            return Err(Error::parse(
                path,
                format!(
                    "line {}, column {}: joint `{n}` is defined twice (first at line {})",
                    j.at.0, j.at.1, first.at.0
                ),
            ));
        }
    }
    Ok(out)
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Reads a URDF file. `base_link` and `tip_link` restrict the model to the
/// chain between them (default: the root link and the whole tree).
pub fn load_urdf(path: &Path, base_link: Option<&str>, tip_link: Option<&str>) -> Result<UrdfParts> {
    let text = crate::io::read_to_string(path)?;
    parse_urdf(path, &text, base_link, tip_link)
}

/// Parses URDF text (see [`load_urdf`]); `path` is used in messages.
pub fn parse_urdf(path: &Path, text: &str, base_link: Option<&str>, tip_link: Option<&str>) -> Result<UrdfParts> {
    let raw = scan_urdf(path, text)?;
    let u = urdf_rs::read_from_string(text).map_err(|e| Error::parse(path, format!("malformed URDF: {e}")))?;
    let has_inertial = &raw.links_with_inertial;
    let link_idx: HashMap<&str, usize> = u.links.iter().enumerate().map(|(i, l)| (l.name.as_str(), i)).collect();
    let ctx = path.display().to_string();
    // children of each link
    let mut children: HashMap<&str, Vec<usize>> = HashMap::new();
    let mut is_child = vec![false; u.links.len()];
    for (k, j) in u.joints.iter().enumerate() {
        let c = *link_idx
            .get(j.child.link.as_str())
            .ok_or_else(|| Error::invalid(&ctx, format!("joint `{}` child", j.name), format!("unknown link `{}`", j.child.link)))?;
        if !link_idx.contains_key(j.parent.link.as_str()) {
            return Err(Error::invalid(
                &ctx,
                format!("joint `{}` parent", j.name),
                format!("unknown link `{}`", j.parent.link),
            ));
        }
        if is_child[c] {
            return Err(Error::invalid(
                &ctx,
                format!("joint `{}`", j.name),
                format!("link `{}` has two parent joints", j.child.link),
            ));
        }
        is_child[c] = true;
        children.entry(j.parent.link.as_str()).or_default().push(k);
    }
    let root = match base_link {
        Some(b) => {
            if !link_idx.contains_key(b) {
                return Err(Error::invalid(&ctx, "base_link", format!("no link named `{b}` in the URDF")));
            }
            b.to_string()
        }
        None => {
            let roots: Vec<&str> = u
                .links
                .iter()
                .enumerate()
                .filter(|(i, _)| !is_child[*i])
                .map(|(_, l)| l.name.as_str())
                .collect();
            if roots.len() != 1 {
                return Err(Error::invalid(
                    &ctx,
                    "links",
                    format!("expected exactly one root link, found {}: {}", roots.len(), roots.join(", ")),
                ));
            }
            roots[0].to_string()
        }
    };
    // restrict to the root→tip chain when a tip is given
    let allowed: Option<Vec<String>> = match tip_link {
        None => None,
        Some(t) => {
            if !link_idx.contains_key(t) {
                return Err(Error::invalid(&ctx, "tip_link", format!("no link named `{t}` in the URDF")));
            }
            let mut chain = vec![t.to_string()];
            let mut cur = t.to_string();
            while cur != root {
                let j = u
                    .joints
                    .iter()
                    .find(|j| j.child.link == cur)
                    .ok_or_else(|| Error::invalid(&ctx, "tip_link", format!("`{t}` is not below `{root}`")))?;
                cur = j.parent.link.clone();
                chain.push(cur.clone());
            }
            Some(chain)
        }
    };

    let locked = mimic_groups(&ctx, &raw, &u, &children)?;
    // what is left out: (locked joint, its group, position, the link carrying it); joints off the chain to the tip
    let mut locked_seen: Vec<(String, usize, f64, String)> = Vec::new();
    let mut off_chain: Vec<String> = Vec::new();
    let mut joints = Vec::new();
    let mut links: Vec<Link> = Vec::new();
    let mut drives = Vec::new();
    let mut frames = Vec::new();
    // DFS stack: (urdf link name, moving link index it belongs to, placement of this urdf link in that moving link's frame)
    let mut stack: Vec<(String, Option<usize>, Isometry3<f64>)> = vec![(root.clone(), None, Isometry3::identity())];
    while let Some((lname, owner, placement)) = stack.pop() {
        let li = link_idx[lname.as_str()];
        let ul = &u.links[li];
        // inertia of this urdf link, expressed in the owner's frame
        let ine = &ul.inertial;
        let rot = Rotation3::from_euler_angles(ine.origin.rpy[0], ine.origin.rpy[1], ine.origin.rpy[2]).into_inner();
        let i = &ine.inertia;
        let ic = Matrix3::new(i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz);
        let m = ine.mass.value;
        if !m.is_finite() || m < 0.0 {
            return Err(Error::invalid(
                &ctx,
                format!("link `{lname}` <mass>"),
                format!("expected a non-negative mass, found {m}"),
            ));
        }
        if !all_finite(&ine.origin.xyz.0) || !all_finite(&ine.origin.rpy.0) {
            return Err(Error::invalid(
                &ctx,
                format!("link `{lname}` <inertial><origin>"),
                format!("expected finite xyz and rpy, found xyz {:?} rpy {:?}", ine.origin.xyz.0, ine.origin.rpy.0),
            ));
        }
        super::validate::check_com_inertia(&ctx, &format!("link `{lname}` <inertia>"), m, &ic)?;
        // zero mass with a non-zero inertia (Robotics Toolbox's PUMA 560 link 1, a
        // rotor-only body) is accepted as the TOML reader accepts it; the
        // warning comes from `robot::export::inertial_warnings` (robot info, identify)
        let local = Inertial::from_com(m, Vector3::from(ine.origin.xyz.0), ic, rot);
        if let Some(o) = owner {
            let add = local.transformed(&placement);
            links[o].inertial = links[o].inertial.add(&add);
        }
        for &k in children.get(lname.as_str()).map(|v| v.as_slice()).unwrap_or(&[]).iter().rev() {
            let j = &u.joints[k];
            if let Some(a) = &allowed {
                if !a.contains(&j.child.link) {
                    off_chain.push(j.name.clone());
                    continue;
                }
            }
            if !all_finite(&j.origin.xyz.0) || !all_finite(&j.origin.rpy.0) {
                return Err(Error::invalid(
                    &ctx,
                    format!("joint `{}` <origin>", j.name),
                    format!("expected finite xyz and rpy, found xyz {:?} rpy {:?}", j.origin.xyz.0, j.origin.rpy.0),
                ));
            }
            let origin = pose_to_iso(j.origin.xyz.0, j.origin.rpy.0);
            let kind = match j.joint_type {
                _ if locked.contains_key(&j.name) => None,
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => Some(JointKind::Revolute),
                urdf_rs::JointType::Prismatic => Some(JointKind::Prismatic),
                urdf_rs::JointType::Fixed => None,
                ref other => {
                    return Err(Error::invalid(
                        &ctx,
                        format!("joint `{}` type", j.name),
                        format!("unsupported joint type {other:?}; expected revolute, continuous, prismatic or fixed"),
                    ))
                }
            };
            match kind {
                None => {
                    // a joint of a <mimic> group: fixed at its reference position
                    let motion = match (locked.get(&j.name), &j.joint_type) {
                        (Some(&(group, q0)), t) => {
                            let carrier = owner.map_or(root.clone(), |o| links[o].name.clone());
                            locked_seen.push((j.name.clone(), group, q0, carrier));
                            let axis = Vector3::from(j.axis.xyz.0);
                            if axis.iter().any(|v| !v.is_finite()) || axis.norm() <= 1e-12 {
                                return Err(Error::invalid(&ctx, format!("joint `{}` <axis>", j.name), "expected a non-zero axis"));
                            }
                            let axis = Unit::new_normalize(axis);
                            if *t == urdf_rs::JointType::Prismatic {
                                Isometry3::from_parts(Translation3::from(axis.into_inner() * q0), UnitQuaternion::identity())
                            } else {
                                Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&axis, q0))
                            }
                        }
                        _ => Isometry3::identity(),
                    };
                    let pl = placement * origin * motion;
                    frames.push(Frame {
                        name: j.child.link.clone(),
                        link: owner,
                        placement: pl,
                    });
                    stack.push((j.child.link.clone(), owner, pl));
                }
                Some(kind) => {
                    let axis = Vector3::from(j.axis.xyz.0);
                    if axis.iter().any(|v| !v.is_finite()) || axis.norm() <= 1e-12 {
                        return Err(Error::invalid(&ctx, format!("joint `{}` <axis>", j.name), "expected a non-zero axis"));
                    }
                    let continuous = j.joint_type == urdf_rs::JointType::Continuous;
                    let rj = raw.joint(&j.name);
                    let line = rj.map_or(0, |r| r.at.0);
                    if let Some((ml, mc)) = rj.and_then(|r| r.mimic) {
                        return Err(Error::invalid(
                            &ctx,
                            format!("joint `{}` <mimic> (line {ml}, column {mc})", j.name),
                            "mimic joints are not supported: every revolute, continuous or prismatic joint is an independent coordinate with its own drive; make the mimicking joint fixed, or model it as an actuated joint without <mimic>",
                        ));
                    }
                    let l = &j.limit;
                    let given = rj.and_then(|r| r.limit.as_ref());
                    if given.is_none() && !continuous {
                        return Err(Error::invalid(
                            &ctx,
                            format!("joint `{}` (line {line})", j.name),
                            "a revolute or prismatic joint needs a <limit lower upper effort velocity> element (URDF requires it; use type=\"continuous\" for an unbounded revolute joint)",
                        ));
                    }
                    let has = |k: &str| given.is_some_and(|a| a.iter().any(|(n, _)| n == k));
                    // a limit that is written must be positive (0 is not "no limit");
                    // one not written (or an infinite acceleration) is no limit
                    let positive = |what: &str, v: f64| -> Result<f64> {
                        if !has(what) && what != "acceleration" {
                            return Ok(f64::INFINITY);
                        }
                        if v.is_nan() || v <= 0.0 {
                            return Err(Error::invalid(
                                &ctx,
                                format!("joint `{}` <limit {what}> (line {line})", j.name),
                                format!("expected a positive {what} limit, found {v} (omit the attribute where there is no limit; 0 is not \"no limit\")"),
                            ));
                        }
                        Ok(v)
                    };
                    if !continuous && (!l.lower.is_finite() || !l.upper.is_finite()) {
                        return Err(Error::invalid(
                            &ctx,
                            format!("joint `{}` <limit> (line {line})", j.name),
                            format!("expected finite lower and upper, found lower {} upper {}", l.lower, l.upper),
                        ));
                    }
                    if !continuous && l.lower >= l.upper {
                        return Err(Error::invalid(
                            &ctx,
                            format!("joint `{}` <limit> (line {line})", j.name),
                            format!(
                                "lower {} ≥ upper {}: expected lower < upper (a joint that cannot move is a fixed joint)",
                                l.lower, l.upper
                            ),
                        ));
                    }
                    let limits = JointLimits {
                        lower: if continuous { f64::NEG_INFINITY } else { l.lower },
                        upper: if continuous { f64::INFINITY } else { l.upper },
                        velocity: positive("velocity", l.velocity)?,
                        acceleration: if l.acceleration.is_infinite() {
                            f64::INFINITY
                        } else {
                            positive("acceleration", l.acceleration)?
                        },
                        effort: positive("effort", l.effort)?,
                    };
                    let idx = joints.len();
                    joints.push(Joint {
                        name: j.name.clone(),
                        kind,
                        parent: owner,
                        placement: placement * origin,
                        axis: Unit::new_normalize(axis),
                        post: Isometry3::identity(),
                        offset: 0.0,
                        limits,
                    });
                    links.push(Link {
                        name: j.child.link.clone(),
                        inertial: Inertial::zero(),
                    });
                    let (fv, fc) = j.dynamics.as_ref().map(|d| (d.damping, d.friction)).unwrap_or((0.0, 0.0));
                    for (what, v) in [("damping", fv), ("friction", fc)] {
                        if !(v.is_finite() && v >= 0.0) {
                            return Err(Error::invalid(
                                &ctx,
                                format!("joint `{}` <dynamics {what}> (line {line})", j.name),
                                format!("expected a finite coefficient ≥ 0 (friction dissipates), found {v}"),
                            ));
                        }
                    }
                    drives.push(Drive {
                        rotor_inertia: None,
                        gear_ratio: 1.0,
                        friction: Friction::Symmetric { fc, fv, offset: None },
                        ..Drive::default()
                    });
                    stack.push((j.child.link.clone(), Some(idx), Isometry3::identity()));
                }
            }
        }
    }
    // a moving link with no inertial data at all (its own or merged) is an error
    for (i, l) in links.iter().enumerate() {
        if l.inertial.mass == 0.0 && l.inertial.inertia == Matrix3::zeros() {
            let own = if has_inertial.contains(&l.name) {
                "has zero mass and inertia"
            } else {
                "has no <inertial> block"
            };
            return Err(Error::invalid(
                &ctx,
                format!("link `{}`", l.name),
                format!("moving link (joint `{}`) {own}; expected its mass, centre of mass and inertia", joints[i].name),
            ));
        }
    }
    if joints.is_empty() {
        return Err(Error::invalid(&ctx, "joints", "no revolute, continuous or prismatic joint found"));
    }
    let mut left_out = Vec::new();
    let mut groups: Vec<usize> = locked_seen.iter().map(|l| l.1).collect();
    groups.sort_unstable();
    groups.dedup();
    for g in groups {
        let mut members: Vec<&(String, usize, f64, String)> = locked_seen.iter().filter(|l| l.1 == g).collect();
        // in the URDF's order
        members.sort_by_key(|l| raw.joints.iter().position(|(n, _)| n == &l.0));
        let names = members.iter().map(|l| format!("`{}`", l.0)).collect::<Vec<_>>().join(", ");
        let at = members.iter().map(|l| format!("{}", l.2)).collect::<Vec<_>>();
        let at = if at.iter().all(|a| *a == at[0]) { at[0].clone() } else { at.join(", ") };
        let follows = raw
            .joints
            .iter()
            .filter(|(n, r)| r.mimic_of.is_some() && members.iter().any(|l| &l.0 == n))
            .map(|(n, r)| format!("`{n}` follows `{}`", r.mimic_of.as_deref().unwrap_or("")))
            .collect::<Vec<_>>()
            .join(", ");
        left_out.push(format!(
            "joints {names} locked at {at}: a <mimic> group ({follows}) at the end of the tree, e.g. a gripper's fingers, is not part of the arm; their links are merged into `{}` as fixed bodies (their mass and collision geometry stay)",
            members[0].3
        ));
    }
    if !off_chain.is_empty() {
        off_chain.sort_by_key(|n| raw.joints.iter().position(|(r, _)| r == n));
        left_out.push(format!(
            "joint{} {} and everything below {}: not on the chain from `{root}` to tip_link `{}` (their links' mass is not in the model)",
            if off_chain.len() == 1 { "" } else { "s" },
            off_chain.iter().map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", "),
            if off_chain.len() == 1 { "it" } else { "them" },
            tip_link.unwrap_or("")
        ));
    }
    // topological order is guaranteed by the DFS (parents pushed before children)
    Ok(UrdfParts {
        name: u.name.clone(),
        joints,
        links,
        drives,
        frames,
        left_out,
    })
}

/// The joints of `<mimic>` groups that are locked, each with its group's
/// number and the position it is locked at (0, or the limit nearest to 0).
///
/// A group is a mimicking joint and the joint it follows (groups sharing a
/// joint are one). It is locked when it is all that moves below the link
/// carrying the joint the others follow: a gripper's fingers at the end of
/// the arm (example-robot-data's Panda: `panda_finger_joint2` follows
/// `panda_finger_joint1`, both on `panda_hand`). Any other `<mimic>` joint is
/// refused, naming the `<mimic>` element.
fn mimic_groups(ctx: &str, raw: &RawUrdf, u: &urdf_rs::Robot, children: &HashMap<&str, Vec<usize>>) -> Result<HashMap<String, (usize, f64)>> {
    let mut groups: Vec<Vec<String>> = Vec::new();
    for (name, r) in &raw.joints {
        let Some(_) = r.mimic else { continue };
        let mut g = vec![name.clone()];
        if let Some(l) = &r.mimic_of {
            if u.joints.iter().any(|j| &j.name == l) && l != name {
                g.push(l.clone());
            }
        }
        // merge with the groups it shares a joint with
        let mut k = 0;
        while k < groups.len() {
            if groups[k].iter().any(|x| g.contains(x)) {
                for x in groups.swap_remove(k) {
                    if !g.contains(&x) {
                        g.push(x);
                    }
                }
            } else {
                k += 1;
            }
        }
        groups.push(g);
    }
    let mut out = HashMap::new();
    for (gi, g) in groups.iter().enumerate() {
        // the link carrying the group: the parent of the joint the others follow
        let leader = g.iter().find(|n| raw.joint(n).is_some_and(|r| r.mimic.is_none())).unwrap_or(&g[0]);
        let carrier = u.joints.iter().find(|j| &j.name == leader).map(|j| j.parent.link.as_str()).unwrap_or("");
        // every joint moving below the carrier must belong to the group
        let (follower, r) = raw
            .joints
            .iter()
            .find(|(n, r)| r.mimic.is_some() && g.contains(n))
            .expect("a group holds a mimicking joint");
        let (ml, mc) = r.mimic.unwrap_or_default();
        let mut inside = Vec::new();
        let mut stack = vec![carrier];
        while let Some(l) = stack.pop() {
            for &k in children.get(l).map(|v| v.as_slice()).unwrap_or(&[]) {
                let below = &u.joints[k];
                inside.push(below.name.as_str());
                if below.joint_type != urdf_rs::JointType::Fixed && !g.contains(&below.name) {
                    return Err(Error::invalid(
                        ctx,
                        format!("joint `{follower}` <mimic> (line {ml}, column {mc})"),
                        format!(
                            "a <mimic> group ({}) is left out of the model only when it is all that moves below the link carrying it (a gripper's fingers on `{carrier}`), but joint `{}` moves below `{carrier}` too: every joint of the arm is an independent coordinate with its own drive; make the mimicking joint fixed, or model it as an actuated joint without <mimic>",
                            g.iter().map(|x| format!("`{x}`")).collect::<Vec<_>>().join(", "),
                            below.name
                        ),
                    ));
                }
                stack.push(below.child.link.as_str());
            }
        }
        if let Some(outside) = g.iter().find(|n| !inside.contains(&n.as_str())) {
            return Err(Error::invalid(
                ctx,
                format!("joint `{follower}` <mimic> (line {ml}, column {mc})"),
                format!("joint `{outside}` of the <mimic> group is not below `{carrier}`, the link carrying the joint `{leader}` it follows: a <mimic> group is left out only as a gripper's fingers on one link"),
            ));
        }
        for name in g {
            let Some(j) = u.joints.iter().find(|j| &j.name == name) else { continue };
            let l = &j.limit;
            let q0 = if j.joint_type == urdf_rs::JointType::Continuous || !(l.lower <= 0.0 && 0.0 <= l.upper) {
                if j.joint_type == urdf_rs::JointType::Continuous || !(l.lower.is_finite() && l.upper.is_finite()) {
                    0.0
                } else if l.lower > 0.0 {
                    l.lower
                } else {
                    l.upper
                }
            } else {
                0.0
            };
            out.insert(name.clone(), (gi, q0));
        }
    }
    Ok(out)
}

/// Collision geometry of a URDF robot, as [`load_collision`] reads it.
#[derive(Debug)]
pub struct UrdfGeometry {
    /// Body 0 is the base, body i + 1 moves with link i.
    pub bodies: Vec<super::collision::Body>,
    /// URDF link names merged into each body.
    pub members: Vec<Vec<String>>,
    /// Links whose `<collision>` elements could not be loaded: what (file,
    /// link, mesh name) and why (folders searched, or why the file is not
    /// readable); their bodies are left without those shapes.
    pub problems: Vec<(String, String)>,
    /// Every `<collision>` element of the model, where it came from.
    pub sources: Vec<CollisionSource>,
}

/// Where one collision shape of a robot came from (`robot info`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct CollisionSource {
    /// The body it belongs to: the base link or a moving link.
    pub body: String,
    /// The URDF link (or robot-file `[[collision]]` link) that writes it.
    pub link: String,
    /// Where it is written: `URDF <collision>` or `robot file [[collision]] k`.
    pub written_in: String,
    /// `mesh`, `box`, `cylinder`, `capsule` or `sphere`.
    pub shape: String,
    /// A mesh's name as written (`package://…`, `file://…` or a path).
    pub uri: Option<String>,
    /// The mesh file read (`None`: a primitive, or a mesh not found).
    pub file: Option<std::path::PathBuf>,
    /// Why the mesh was not found or not read.
    pub problem: Option<String>,
}

/// Collision geometry of a URDF robot: the `<collision>` elements of every
/// link in the model (moving links, the base, links fixed to either) merged
/// into one body per moving link plus the base, in that link's frame. Mesh
/// names resolve through `resolver` ([`super::resolve::MeshResolver`]: ROS
/// packages, `file://`, the robot file's `mesh_path`); a mesh not found or
/// not readable is a problem of its link ([`UrdfGeometry::problems`]), not
/// an error, so that what needs no geometry still loads the robot.
pub fn load_collision(
    path: &Path,
    parts: &UrdfParts,
    base_link: Option<&str>,
    resolver: &super::resolve::MeshResolver,
    mode: super::collision::MeshMode,
) -> Result<UrdfGeometry> {
    use super::collision::{Body, GeometrySpec, Primitive};
    let text = crate::io::read_to_string(path)?;
    let u = urdf_rs::read_from_string(&text).map_err(|e| Error::parse(path, format!("malformed URDF: {e}")))?;
    let ctx = path.display().to_string();
    let root = match base_link {
        Some(b) => b.to_string(),
        None => u
            .links
            .iter()
            .find(|l| !u.joints.iter().any(|j| j.child.link == l.name))
            .map(|l| l.name.clone())
            .unwrap_or_default(),
    };
    let n = parts.links.len();
    let mut bodies: Vec<Body> = std::iter::once(Body::empty(&root))
        .chain(parts.links.iter().map(|l| Body::empty(&l.name)))
        .collect();
    let mut members: Vec<Vec<String>> = bodies.iter().map(|b| vec![b.name.clone()]).collect();
    let mut problems = Vec::new();
    let mut sources = Vec::new();
    'links: for ul in &u.links {
        // which body and where in its frame
        let (idx, at) = if ul.name == root {
            (0, Isometry3::identity())
        } else if let Some(i) = parts.links.iter().position(|l| l.name == ul.name) {
            (i + 1, Isometry3::identity())
        } else if let Some(f) = parts.frames.iter().find(|f| f.name == ul.name) {
            let idx = f.link.map_or(0, |l| l + 1);
            if !members[idx].contains(&ul.name) {
                members[idx].push(ul.name.clone());
            }
            (idx, f.placement)
        } else {
            continue; // outside the modelled chain
        };
        let mut specs = Vec::new();
        let first_source = sources.len();
        for c in &ul.collision {
            let origin = pose_to_iso(c.origin.xyz.0, c.origin.rpy.0);
            let mut source = CollisionSource {
                body: bodies[idx].name.clone(),
                link: ul.name.clone(),
                written_in: "URDF <collision>".into(),
                shape: match &c.geometry {
                    urdf_rs::Geometry::Box { .. } => "box",
                    urdf_rs::Geometry::Cylinder { .. } => "cylinder",
                    urdf_rs::Geometry::Capsule { .. } => "capsule",
                    urdf_rs::Geometry::Sphere { .. } => "sphere",
                    urdf_rs::Geometry::Mesh { .. } => "mesh",
                }
                .into(),
                uri: None,
                file: None,
                problem: None,
            };
            let primitive = match &c.geometry {
                urdf_rs::Geometry::Box { size } => Primitive::Box { size: size.0 },
                urdf_rs::Geometry::Cylinder { radius, length } => Primitive::Cylinder {
                    radius: *radius,
                    length: *length,
                },
                urdf_rs::Geometry::Capsule { radius, length } => Primitive::Capsule {
                    radius: *radius,
                    length: *length,
                },
                urdf_rs::Geometry::Sphere { radius } => Primitive::Sphere { radius: *radius },
                urdf_rs::Geometry::Mesh { filename, scale } => {
                    source.uri = Some(filename.clone());
                    match resolver.resolve(filename) {
                        Ok(p) => {
                            source.file = Some(p.clone());
                            Primitive::Mesh {
                                file: p,
                                scale: scale.map_or([1.0; 3], |s| s.0),
                            }
                        }
                        Err(why) => {
                            source.problem = Some(why.clone());
                            sources.push(source);
                            problems.push((format!("{ctx}: link `{}` <collision> mesh `{filename}`", ul.name), why));
                            continue 'links;
                        }
                    }
                }
            };
            sources.push(source);
            specs.push(GeometrySpec { primitive, origin });
        }
        if specs.is_empty() {
            continue;
        }
        match Body::new(&ul.name, &specs, mode, &format!("{ctx}: link `{}` <collision>", ul.name)) {
            Ok(b) => bodies[idx].merge(&b, &at),
            Err(e) => {
                for s in &mut sources[first_source..] {
                    s.problem = Some(e.to_string());
                }
                problems.push((format!("{ctx}: link `{}` <collision>", ul.name), e.to_string()))
            }
        }
    }
    debug_assert_eq!(bodies.len(), n + 1);
    Ok(UrdfGeometry {
        bodies,
        members,
        problems,
        sources,
    })
}
