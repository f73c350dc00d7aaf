//! Robot files in TOML: either a DH table (standard or modified convention)
//! with the inertial parameters of every link, or a pointer to a URDF; either
//! way with the drive side URDF lacks (rotor inertia, gear ratio, friction,
//! acceleration limits), a joint coupling matrix and named frames.
//! The format is documented in docs/robots.md.
//!
//! Size (~1k lines, above the house's ~800): the file's serde schema and the
//! checks that name its fields in their messages stay side by side (one
//! field, one check, one message). The collision-geometry part
//! (`collision_geometry` … `geometry_problems`) is the piece to move to
//! `robot/collision/` when this file grows.

use super::model::{Coulomb, Drive, Frame, Friction, Inertial, Joint, JointKind, JointLimits, Link, Robot, RobotParts};
use super::resolve::MeshResolver;
use super::urdf::{load_urdf, pose_to_iso};
use crate::error::{Error, Result};
use nalgebra::{DMatrix, Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::Deserialize;
use std::path::Path;

/// Friction model names in robot files.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum FrictionName {
    /// No friction parameters.
    None,
    /// Fc·sign(q̇) + Fv·q̇.
    Symmetric,
    /// Paper 002 eq. 2.
    Asymmetric,
}

/// Coulomb shape names in robot files (`coulomb = ...`, see [`Coulomb`]).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum CoulombName {
    /// sign(q̇) (default).
    Sign,
    /// tanh(q̇ / velocity_scale).
    Tanh,
    /// tanh(q̇ / velocity_scale) plus a Stribeck column with a fixed `stribeck_velocity`.
    Stribeck,
}

/// File-level defaults of the Coulomb shape (`coulomb`, `velocity_scale`, `stribeck_velocity`).
#[derive(Debug, Clone, Copy)]
struct CoulombDefaults {
    name: Option<CoulombName>,
    velocity_scale: Option<f64>,
    stribeck_velocity: Option<f64>,
}

/// DH conventions.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum DhConvention {
    /// T = Rz(θ) Tz(d) Tx(a) Rx(α) (Denavit–Hartenberg, as in Corke's toolbox).
    Standard,
    /// T = Rx(α) Tx(a) Rz(θ) Tz(d) (Craig / Khalil–Kleinfinger): row i holds a_{i−1}, α_{i−1}.
    Modified,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    name: Option<String>,
    source: Option<String>,
    gravity: Option<[f64; 3]>,
    friction: Option<FrictionName>,
    /// Default Coulomb shape of every drive: sign (default) | tanh | stribeck.
    coulomb: Option<CoulombName>,
    /// Default v_s of the tanh switch (rad/s or m/s).
    velocity_scale: Option<f64>,
    /// Default fixed Stribeck velocity v_st.
    stribeck_velocity: Option<f64>,
    urdf: Option<String>,
    base_link: Option<String>,
    tip_link: Option<String>,
    dh: Option<DhConvention>,
    #[serde(default)]
    joint: Vec<DhJoint>,
    #[serde(default)]
    drive: Vec<DriveSpec>,
    coupling: Option<Vec<Vec<f64>>>,
    #[serde(default)]
    frame: Vec<FrameSpec>,
    /// Directories (relative to the robot file) searched for URDF collision meshes.
    #[serde(default)]
    mesh_path: Vec<String>,
    /// `hull` (default) or `decomposition` for URDF meshes.
    mesh_mode: Option<MeshModeName>,
    /// Collision shapes per link (DH robots; added to a URDF's own).
    #[serde(default)]
    collision: Vec<CollisionShapeSpec>,
    /// Padding per link (m): its collision shapes grown by a ball of this
    /// radius, e.g. so that they hold the vendor's full (visual) meshes,
    /// which reach beyond the hulls of the collision meshes.
    #[serde(default)]
    collision_padding: std::collections::BTreeMap<String, f64>,
    /// Pairs never checked, each with its reason.
    #[serde(default)]
    allowed_collision: Vec<super::collision::AllowedCollision>,
    /// An SRDF whose `<disable_collisions>` entries with an accepted reason are allowed pairs.
    srdf: Option<String>,
    /// SRDF reasons accepted (default: only "Adjacent").
    srdf_reasons: Option<Vec<String>>,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum MeshModeName {
    Hull,
    Decomposition,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CollisionShapeSpec {
    /// Link name (a moving link, a frame on one, or the base: `base`).
    link: String,
    shape: super::collision::ShapeSpec,
    #[serde(default)]
    xyz: [f64; 3],
    #[serde(default)]
    rpy: [f64; 3],
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
enum JointType {
    #[default]
    Revolute,
    Prismatic,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DhJoint {
    name: String,
    link: Option<String>,
    #[serde(default, rename = "type")]
    kind: JointType,
    #[serde(default)]
    a: f64,
    #[serde(default)]
    alpha: f64,
    #[serde(default)]
    d: f64,
    #[serde(default)]
    theta: f64,
    lower: Option<f64>,
    upper: Option<f64>,
    velocity: Option<f64>,
    acceleration: Option<f64>,
    effort: Option<f64>,
    inertial: Option<InertialSpec>,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
enum InertiaAt {
    #[default]
    Com,
    Origin,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct InertialSpec {
    mass: f64,
    #[serde(default)]
    com: [f64; 3],
    #[serde(default)]
    inertia: [f64; 6],
    #[serde(default)]
    inertia_at: InertiaAt,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DriveSpec {
    joint: String,
    ia: Option<f64>,
    gear_ratio: Option<f64>,
    friction: Option<FrictionName>,
    fc: Option<f64>,
    fv: Option<f64>,
    f0: Option<f64>,
    fc_pos: Option<f64>,
    fc_neg: Option<f64>,
    fv_pos: Option<f64>,
    fv_neg: Option<f64>,
    coulomb: Option<CoulombName>,
    velocity_scale: Option<f64>,
    stribeck_velocity: Option<f64>,
    fs: Option<f64>,
    fs_pos: Option<f64>,
    fs_neg: Option<f64>,
    torque_constant: Option<f64>,
    current_sign: Option<f64>,
    lower: Option<f64>,
    upper: Option<f64>,
    velocity: Option<f64>,
    acceleration: Option<f64>,
    effort: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FrameSpec {
    name: String,
    link: Option<String>,
    #[serde(default)]
    xyz: [f64; 3],
    #[serde(default)]
    rpy: [f64; 3],
}

fn finite(ctx: &str, field: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::invalid(ctx, field, format!("expected a finite number, found {v}")))
    }
}

/// Loads a robot from a `.urdf` file (drives with zero friction) or a `.toml`
/// robot file.
pub fn load(path: &Path) -> Result<Robot> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "urdf" | "xml" => {
            let parts = load_urdf(path, None, None)?;
            // the URDF's <collision> elements, meshes found as ROS tools find them
            let resolver = MeshResolver::new(path.parent().unwrap_or(Path::new(".")), &[]);
            let g = super::urdf::load_collision(path, &parts, None, &resolver, super::collision::MeshMode::Hull)?;
            let robot = super::validate::checked(
                path,
                RobotParts {
                    name: parts.name,
                    joints: parts.joints,
                    links: parts.links,
                    drives: parts.drives,
                    coupling: None,
                    frames: parts.frames,
                    gravity: Vector3::new(0.0, 0.0, -9.81),
                    source: format!("URDF {}", path.display()),
                },
            )?;
            let loaded = if !g.problems.is_empty() {
                Loaded::Failed(g.problems)
            } else if g.bodies.iter().all(|b| b.is_empty()) {
                Loaded::None
            } else {
                let source = path.display().to_string();
                Loaded::Geometry(super::collision::RobotGeometry {
                    bodies: g.bodies,
                    members: g.members,
                    allowed: Vec::new(),
                    source,
                })
            };
            attach_geometry(robot, loaded)
        }
        "toml" => {
            let text = crate::io::read_to_string(path)?;
            parse_robot_toml(path, &text)
        }
        _ => Err(Error::parse(path, "unknown robot file type: expected a .urdf or a .toml robot file")),
    }
}

/// Parses a TOML robot file; `path` locates a referenced URDF and names the file in messages.
///
/// Steps: the kinematic structure (URDF or DH rows), the default friction
/// model, the `[[drive]]` entries, the coupling matrix, the `[[frame]]`
/// entries and gravity; then [`Robot::new`] checks the whole.
pub fn parse_robot_toml(path: &Path, text: &str) -> Result<Robot> {
    let f: RobotFile = crate::io::parse_toml(path, text)?;
    let ctx = path.display().to_string();
    let default_friction = f.friction.unwrap_or(FrictionName::Symmetric);
    let (name, mut joints, links, mut drives, mut frames) = structure(path, &f, &ctx)?;
    let n = joints.len();
    apply_default_friction(&mut drives, default_friction);
    let cdef = CoulombDefaults {
        name: f.coulomb,
        velocity_scale: f.velocity_scale,
        stribeck_velocity: f.stribeck_velocity,
    };
    let mut seen = vec![false; n];
    for (k, ds) in f.drive.iter().enumerate() {
        apply_drive(&ctx, k, ds, default_friction, &mut joints, &mut drives, &mut seen)?;
        let j = joints.iter().position(|j| j.name == ds.joint).expect("checked by apply_drive");
        apply_drive_electrics(&ctx, k, ds, &cdef, &mut drives[j])?;
    }
    for j in (0..n).filter(|&j| !seen[j]) {
        drives[j].coulomb = coulomb_shape(&ctx, "", None, &cdef, &drives[j].friction)?;
    }
    let coupling = coupling_matrix(&ctx, f.coupling.as_deref(), n)?;
    add_frames(&ctx, &f.frame, &links, &mut frames)?;
    let gravity = gravity_vector(&ctx, f.gravity)?;
    let name = f.name.clone().unwrap_or(if name.is_empty() {
        path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
    } else {
        name
    });
    let source = f.source.clone().unwrap_or_else(|| path.display().to_string());
    let robot = super::validate::checked(
        path,
        RobotParts {
            name,
            joints,
            links,
            drives,
            coupling,
            frames,
            gravity,
            source,
        },
    )?;
    let loaded = collision_geometry(path, &f, &robot, &ctx)?;
    attach_geometry(robot, loaded)
}

/// `<disable_collisions>` of an SRDF.
#[derive(Debug, Deserialize)]
struct Srdf {
    #[serde(default)]
    disable_collisions: Vec<SrdfDisable>,
}

#[derive(Debug, Deserialize)]
struct SrdfDisable {
    #[serde(rename = "@link1")]
    link1: String,
    #[serde(rename = "@link2")]
    link2: String,
    #[serde(rename = "@reason", default)]
    reason: Option<String>,
}

/// The robot's collision geometry: the URDF's `<collision>` elements (meshes
/// found through `mesh_path`), the file's `[[collision]]` shapes, the allowed
/// pairs (`[[allowed_collision]]`, SRDF entries with an accepted reason).
fn collision_geometry(path: &Path, f: &RobotFile, robot: &Robot, ctx: &str) -> Result<Loaded> {
    use super::collision::{AllowedCollision, Body, GeometrySpec, MeshMode, RobotGeometry};
    let dir = path.parent().unwrap_or(Path::new("."));
    let mesh_path: Vec<std::path::PathBuf> = f.mesh_path.iter().map(|m| dir.join(m)).collect();
    let mode = match f.mesh_mode {
        Some(MeshModeName::Decomposition) => MeshMode::Decomposition,
        _ => MeshMode::Hull,
    };
    let n = robot.dof();
    let mut problems: Vec<(String, String)> = Vec::new();
    let (mut bodies, mut members) = match &f.urdf {
        Some(u) => {
            let upath = crate::io::design_path(path, "urdf", Path::new(u))?;
            let parts = load_urdf(&upath, f.base_link.as_deref(), f.tip_link.as_deref())?;
            let resolver = MeshResolver::new(upath.parent().unwrap_or(Path::new(".")), &mesh_path);
            let g = super::urdf::load_collision(&upath, &parts, f.base_link.as_deref(), &resolver, mode)?;
            problems = g.problems;
            (g.bodies, g.members)
        }
        None => {
            let b: Vec<Body> = std::iter::once(Body::empty("base"))
                .chain(robot.links.iter().map(|l| Body::empty(&l.name)))
                .collect();
            let m = b.iter().map(|b| vec![b.name.clone()]).collect();
            (b, m)
        }
    };
    if !members[0].iter().any(|m| m == "base") {
        members[0].push("base".into());
    }
    for (k, c) in f.collision.iter().enumerate() {
        let field = format!("collision[{k}] (link `{}`)", c.link);
        if matches!(c.shape, super::collision::ShapeSpec::Plane { .. }) {
            return Err(Error::invalid(ctx, &field, "a robot body cannot be a plane"));
        }
        let (idx, at) = if let Some(i) = members.iter().position(|m| m.contains(&c.link)) {
            let at = if i == 0 || robot.links[i - 1].name == c.link {
                Isometry3::identity()
            } else {
                robot.find_frame(&c.link).map(|fr| fr.placement).unwrap_or_else(Isometry3::identity)
            };
            (i, at)
        } else if let Some(fr) = robot.find_frame(&c.link) {
            (fr.link.map_or(0, |l| l + 1), fr.placement)
        } else {
            return Err(Error::invalid(
                ctx,
                format!("{field}.link"),
                format!(
                    "no link or frame named `{}`; links are: base, {}",
                    c.link,
                    robot.links.iter().map(|l| l.name.as_str()).collect::<Vec<_>>().join(", ")
                ),
            ));
        };
        let spec = GeometrySpec {
            primitive: c.shape.primitive(dir),
            origin: pose_to_iso(c.xyz, c.rpy),
        };
        match Body::new(&c.link, &[spec], mode, &format!("{ctx}: {field}")) {
            Ok(b) => bodies[idx].merge(&b, &at),
            // a mesh file missing or unreadable: the geometry is not loaded, the robot is
            Err(e) if matches!(c.shape, super::collision::ShapeSpec::Mesh { .. }) => problems.push((format!("{ctx}: {field}"), e.to_string())),
            Err(e) => return Err(e),
        }
    }
    for (link, &pad) in &f.collision_padding {
        let field = format!("collision_padding.{link}");
        if !(pad.is_finite() && (0.0..=0.1).contains(&pad)) {
            return Err(Error::invalid(ctx, &field, format!("{pad} m: expected a padding between 0 and 0.1 m")));
        }
        let Some(i) = members.iter().position(|m| m.iter().any(|x| x == link)) else {
            return Err(Error::invalid(
                ctx,
                &field,
                format!(
                    "no link named `{link}`; links are: base, {}",
                    robot.links.iter().map(|l| l.name.as_str()).collect::<Vec<_>>().join(", ")
                ),
            ));
        };
        bodies[i].pad_parts(pad);
    }
    let known = |name: &str| members.iter().any(|m| m.iter().any(|x| x == name));
    let mut allowed = Vec::new();
    for (k, a) in f.allowed_collision.iter().enumerate() {
        for (key, l) in [("a", &a.a), ("b", &a.b)] {
            if !known(l) {
                return Err(Error::invalid(ctx, format!("allowed_collision[{k}].{key}"), format!("no link named `{l}`")));
            }
        }
        if a.reason.trim().is_empty() {
            return Err(Error::invalid(
                ctx,
                format!("allowed_collision[{k}].reason"),
                "give the reason the pair is not checked",
            ));
        }
        allowed.push(a.clone());
    }
    if let Some(s) = &f.srdf {
        let spath = crate::io::design_path(path, "srdf", Path::new(s))?;
        let text = crate::io::read_to_string(&spath)?;
        let srdf: Srdf = quick_xml::de::from_str(&text).map_err(|e| Error::parse(&spath, format!("malformed SRDF: {e}")))?;
        let accepted: Vec<String> = f.srdf_reasons.clone().unwrap_or_else(|| vec!["Adjacent".into()]);
        for d in srdf.disable_collisions {
            let reason = d.reason.unwrap_or_default();
            if accepted.contains(&reason) && known(&d.link1) && known(&d.link2) {
                allowed.push(AllowedCollision {
                    a: d.link1,
                    b: d.link2,
                    reason: format!("SRDF {} (reason=\"{reason}\")", spath.display()),
                });
            }
        }
    }
    if bodies.iter().all(|b| b.is_empty()) && problems.is_empty() {
        return Ok(Loaded::None);
    }
    debug_assert_eq!(bodies.len(), n + 1);
    if !problems.is_empty() {
        return Ok(Loaded::Failed(problems));
    }
    Ok(Loaded::Geometry(RobotGeometry {
        bodies,
        members,
        allowed,
        source: format!("{}", path.display()),
    }))
}

/// What [`collision_geometry`] found.
enum Loaded {
    /// The robot file describes no collision geometry.
    None,
    /// It describes some and every shape loaded.
    Geometry(super::collision::RobotGeometry),
    /// Some shapes could not be loaded: what and why, per link.
    Failed(Vec<(String, String)>),
}

/// `robot` with what [`collision_geometry`] (or the URDF's `<collision>` elements) gave.
fn attach_geometry(robot: Robot, loaded: Loaded) -> Result<Robot> {
    match loaded {
        Loaded::None => Ok(robot),
        Loaded::Geometry(g) => robot.with_collision(g),
        Loaded::Failed(p) => Ok(robot.with_geometry_error(geometry_problems(&p))),
    }
}

/// The problems of a geometry that did not load, as one message: each
/// link's, the reason written out once for those that share it.
fn geometry_problems(p: &[(String, String)]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut said: Vec<&str> = Vec::new();
    for (what, why) in p {
        // the same cause for another mesh of the same package: said once
        let key = why.split_once(';').map_or(why.as_str(), |(_, rest)| rest);
        if said.contains(&key) {
            parts.push(format!("{what}: likewise"));
        } else {
            said.push(key);
            parts.push(format!("{what} {why}"));
        }
    }
    format!("collision geometry not loaded: {}", parts.join("; "))
}

/// Joints, links, drives and frames of the kinematic structure: from the URDF
/// (`urdf`, optionally cut at `base_link`/`tip_link`) or from `dh` and the
/// `[[joint]]` rows.
#[allow(clippy::type_complexity)] // the loader's five parts, taken apart at once by the caller
fn structure(path: &Path, f: &RobotFile, ctx: &str) -> Result<(String, Vec<Joint>, Vec<Link>, Vec<Drive>, Vec<Frame>)> {
    Ok(match (&f.urdf, &f.dh) {
        (Some(_), Some(_)) => return Err(Error::invalid(ctx, "urdf", "give either `urdf` or a `dh` table, not both")),
        (None, None) => {
            return Err(Error::invalid(
                ctx,
                "urdf",
                "expected `urdf = \"file.urdf\"` or `dh = \"standard\"|\"modified\"` with [[joint]] rows",
            ))
        }
        (Some(u), None) => {
            if !f.joint.is_empty() {
                return Err(Error::invalid(
                    ctx,
                    "joint",
                    "[[joint]] rows are for DH robots; a URDF robot takes its joints from the URDF",
                ));
            }
            let upath = crate::io::design_path(path, "urdf", Path::new(u))?;
            let parts = load_urdf(&upath, f.base_link.as_deref(), f.tip_link.as_deref())?;
            (parts.name, parts.joints, parts.links, parts.drives, parts.frames)
        }
        (None, Some(conv)) => {
            if f.base_link.is_some() || f.tip_link.is_some() {
                return Err(Error::invalid(ctx, "base_link", "base_link/tip_link apply to URDF robots only"));
            }
            let (j, l) = dh_robot(ctx, *conv, &f.joint)?;
            let n = j.len();
            (String::new(), j, l, vec![Drive::default(); n], Vec::new())
        }
    })
}

/// Sets every drive's friction to the file's default model (`friction`).
fn apply_default_friction(drives: &mut [Drive], default_friction: FrictionName) {
    for d in drives.iter_mut() {
        d.friction = match default_friction {
            FrictionName::None => Friction::None,
            FrictionName::Symmetric => d.friction,
            FrictionName::Asymmetric => Friction::Asymmetric {
                fc_pos: 0.0,
                fc_neg: 0.0,
                fv_pos: 0.0,
                fv_neg: 0.0,
                offset: None,
            },
        };
    }
}

/// Applies one `[[drive]]` entry (k-th) to its joint: rotor inertia, gear
/// ratio, friction and joint limits; `seen` marks joints that had an entry.
fn apply_drive(
    ctx: &str,
    k: usize,
    ds: &DriveSpec,
    default_friction: FrictionName,
    joints: &mut [Joint],
    drives: &mut [Drive],
    seen: &mut [bool],
) -> Result<()> {
    let field = |s: &str| format!("drive[{k}] (joint `{}`).{s}", ds.joint);
    let j = joints.iter().position(|j| j.name == ds.joint).ok_or_else(|| {
        Error::invalid(
            ctx,
            format!("drive[{k}].joint"),
            format!(
                "no actuated joint named `{}`; joints are: {}",
                ds.joint,
                joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>().join(", ")
            ),
        )
    })?;
    if seen[j] {
        return Err(Error::invalid(
            ctx,
            format!("drive[{k}].joint"),
            format!("joint `{}` has two [[drive]] entries", ds.joint),
        ));
    }
    seen[j] = true;
    let d = &mut drives[j];
    if let Some(ia) = ds.ia {
        if !(ia.is_finite() && ia >= 0.0) {
            return Err(Error::invalid(ctx, field("ia"), format!("expected a non-negative rotor inertia, found {ia}")));
        }
        d.rotor_inertia = Some(ia);
    }
    if let Some(g) = ds.gear_ratio {
        if !(g.is_finite() && g != 0.0) {
            return Err(Error::invalid(ctx, field("gear_ratio"), format!("expected a non-zero finite ratio, found {g}")));
        }
        d.gear_ratio = g;
    }
    d.friction = drive_friction(ctx, k, ds, d.friction, default_friction)?;
    apply_limits(ctx, k, ds, &mut joints[j].limits)
}

/// The friction model of a `[[drive]]` entry; `current` (from the URDF or the
/// default) supplies symmetric coefficients not given.
///
/// Written per variant, not over the drive-parameter walk
/// (`dynamics::visit_drive_params`): the walk visits the coefficients of a
/// model that exists, while this decides which model the entry declares and
/// which keys it may carry (each misplaced key is an error naming it).
fn drive_friction(ctx: &str, k: usize, ds: &DriveSpec, current: Friction, default_friction: FrictionName) -> Result<Friction> {
    let field = |s: &str| format!("drive[{k}] (joint `{}`).{s}", ds.joint);
    let model = ds.friction.unwrap_or(default_friction);
    let val = |v: Option<f64>, s: &str| -> Result<f64> { finite(ctx, &field(s), v.unwrap_or(0.0)) };
    let offset = match ds.f0 {
        Some(v) => Some(finite(ctx, &field("f0"), v)?),
        None => None,
    };
    let asym_given = ds.fc_pos.is_some() || ds.fc_neg.is_some() || ds.fv_pos.is_some() || ds.fv_neg.is_some();
    Ok(match model {
        FrictionName::None => {
            if ds.fc.is_some() || ds.fv.is_some() || asym_given || offset.is_some() {
                return Err(Error::invalid(
                    ctx,
                    field("friction"),
                    "friction = \"none\" but friction coefficients are given",
                ));
            }
            Friction::None
        }
        FrictionName::Symmetric => {
            if asym_given {
                return Err(Error::invalid(
                    ctx,
                    field("fc_pos"),
                    "fc_pos/fc_neg/fv_pos/fv_neg need friction = \"asymmetric\"",
                ));
            }
            let (fc0, fv0) = match current {
                Friction::Symmetric { fc, fv, .. } => (fc, fv),
                _ => (0.0, 0.0),
            };
            Friction::Symmetric {
                fc: val(ds.fc.or(Some(fc0)), "fc")?,
                fv: val(ds.fv.or(Some(fv0)), "fv")?,
                offset,
            }
        }
        FrictionName::Asymmetric => {
            if ds.fc.is_some() || ds.fv.is_some() {
                return Err(Error::invalid(ctx, field("fc"), "the asymmetric model takes fc_pos, fc_neg, fv_pos, fv_neg"));
            }
            Friction::Asymmetric {
                fc_pos: val(ds.fc_pos, "fc_pos")?,
                fc_neg: val(ds.fc_neg, "fc_neg")?,
                fv_pos: val(ds.fv_pos, "fv_pos")?,
                fv_neg: val(ds.fv_neg, "fv_neg")?,
                offset,
            }
        }
    })
}

/// A positive finite value of `field`, or an error naming it.
fn positive(ctx: &str, field: &str, v: f64, what: &str) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(Error::invalid(ctx, field, format!("expected {what} > 0 and finite, found {v}")))
    }
}

/// The Coulomb shape of one drive from its entry `ds` (if any; `prefix`
/// names it in messages, empty for the file-level defaults) and the file
/// defaults; Stribeck coefficients from `fs` / `fs_pos`, `fs_neg`.
fn coulomb_shape(ctx: &str, prefix: &str, ds: Option<&DriveSpec>, def: &CoulombDefaults, friction: &Friction) -> Result<Coulomb> {
    let field = |s: &str| format!("{prefix}{s}");
    let name = ds.and_then(|d| d.coulomb).or(def.name).unwrap_or(CoulombName::Sign);
    let vs = ds
        .and_then(|d| d.velocity_scale)
        .map(|v| (v, field("velocity_scale")))
        .or(def.velocity_scale.map(|v| (v, "velocity_scale".to_string())));
    let vst = ds
        .and_then(|d| d.stribeck_velocity)
        .map(|v| (v, field("stribeck_velocity")))
        .or(def.stribeck_velocity.map(|v| (v, "stribeck_velocity".to_string())));
    let fs_given = ds.is_some_and(|d| d.fs.is_some() || d.fs_pos.is_some() || d.fs_neg.is_some());
    if matches!(friction, Friction::None) && name != CoulombName::Sign && ds.is_some_and(|d| d.coulomb.is_some()) {
        return Err(Error::invalid(ctx, field("coulomb"), "friction = \"none\": there is no Coulomb term to shape"));
    }
    let need_vs = |vs: Option<(f64, String)>| -> Result<f64> {
        match vs {
            Some((v, f)) => positive(ctx, &f, v, "the velocity scale v_s (rad/s or m/s)"),
            None => Err(Error::invalid(
                ctx,
                field("velocity_scale"),
                format!(
                    "coulomb = \"{}\" needs velocity_scale = v_s > 0 (rad/s; paper 000's tanh(1000 q̇) is 0.001), on the drive or at the top of the file",
                    if name == CoulombName::Tanh { "tanh" } else { "stribeck" }
                ),
            )),
        }
    };
    Ok(match name {
        CoulombName::Sign => {
            if let Some(d) = ds {
                if d.velocity_scale.is_some() || d.stribeck_velocity.is_some() {
                    return Err(Error::invalid(
                        ctx,
                        field("velocity_scale"),
                        "velocity_scale/stribeck_velocity need coulomb = \"tanh\" or \"stribeck\"",
                    ));
                }
            }
            if fs_given {
                return Err(Error::invalid(ctx, field("fs"), "Stribeck coefficients need coulomb = \"stribeck\""));
            }
            Coulomb::Sign
        }
        CoulombName::Tanh => {
            if fs_given {
                return Err(Error::invalid(ctx, field("fs"), "Stribeck coefficients need coulomb = \"stribeck\""));
            }
            if ds.is_some_and(|d| d.stribeck_velocity.is_some()) {
                return Err(Error::invalid(
                    ctx,
                    field("stribeck_velocity"),
                    "stribeck_velocity needs coulomb = \"stribeck\"",
                ));
            }
            Coulomb::Tanh { velocity_scale: need_vs(vs)? }
        }
        CoulombName::Stribeck => {
            let velocity_scale = need_vs(vs)?;
            let stribeck_velocity = match vst {
                Some((v, f)) => positive(ctx, &f, v, "the Stribeck velocity v_st (rad/s or m/s)")?,
                None => {
                    return Err(Error::invalid(
                        ctx,
                        field("stribeck_velocity"),
                        "coulomb = \"stribeck\" needs stribeck_velocity = v_st > 0 (fixed, not identified), on the drive or at the top of the file",
                    ))
                }
            };
            let val = |v: Option<f64>, s: &str| -> Result<f64> { finite(ctx, &field(s), v.unwrap_or(0.0)) };
            let fs = match friction {
                Friction::Asymmetric { .. } => {
                    if ds.is_some_and(|d| d.fs.is_some()) {
                        return Err(Error::invalid(ctx, field("fs"), "the asymmetric model takes fs_pos and fs_neg"));
                    }
                    [val(ds.and_then(|d| d.fs_pos), "fs_pos")?, val(ds.and_then(|d| d.fs_neg), "fs_neg")?]
                }
                _ => {
                    if ds.is_some_and(|d| d.fs_pos.is_some() || d.fs_neg.is_some()) {
                        return Err(Error::invalid(
                            ctx,
                            field("fs_pos"),
                            "fs_pos/fs_neg need friction = \"asymmetric\"; the symmetric model takes fs",
                        ));
                    }
                    [val(ds.and_then(|d| d.fs), "fs")?, 0.0]
                }
            };
            Coulomb::Stribeck {
                velocity_scale,
                stribeck_velocity,
                fs,
            }
        }
    })
}

/// The Coulomb shape, torque constant and current sign of a `[[drive]]` entry (k-th).
fn apply_drive_electrics(ctx: &str, k: usize, ds: &DriveSpec, def: &CoulombDefaults, d: &mut Drive) -> Result<()> {
    let prefix = format!("drive[{k}] (joint `{}`).", ds.joint);
    d.coulomb = coulomb_shape(ctx, &prefix, Some(ds), def, &d.friction)?;
    if let Some(kt) = ds.torque_constant {
        d.torque_constant = Some(positive(ctx, &format!("{prefix}torque_constant"), kt, "the motor torque constant k_t (N·m/A)")?);
    }
    if let Some(sg) = ds.current_sign {
        if sg != 1.0 && sg != -1.0 {
            return Err(Error::invalid(ctx, format!("{prefix}current_sign"), format!("expected 1 or -1, found {sg}")));
        }
        d.current_sign = sg;
    }
    Ok(())
}

/// Joint limits of a `[[drive]]` entry (lower/upper finite; velocity,
/// acceleration, effort positive).
fn apply_limits(ctx: &str, k: usize, ds: &DriveSpec, lim: &mut JointLimits) -> Result<()> {
    let field = |s: &str| format!("drive[{k}] (joint `{}`).{s}", ds.joint);
    if let Some(v) = ds.lower {
        lim.lower = finite(ctx, &field("lower"), v)?;
    }
    if let Some(v) = ds.upper {
        lim.upper = finite(ctx, &field("upper"), v)?;
    }
    for (s, src, dst) in [
        ("velocity", ds.velocity, &mut lim.velocity),
        ("acceleration", ds.acceleration, &mut lim.acceleration),
        ("effort", ds.effort, &mut lim.effort),
    ] {
        if let Some(v) = src {
            if v.is_nan() || v <= 0.0 {
                return Err(Error::invalid(ctx, field(s), format!("expected a positive limit, found {v}")));
            }
            *dst = v;
        }
    }
    Ok(())
}

/// The coupling matrix C (n×n, finite), if given.
fn coupling_matrix(ctx: &str, rows: Option<&[Vec<f64>]>, n: usize) -> Result<Option<DMatrix<f64>>> {
    Ok(match rows {
        None => None,
        Some(rows) => {
            if rows.len() != n || rows.iter().any(|r| r.len() != n) {
                return Err(Error::invalid(
                    ctx,
                    "coupling",
                    format!("expected {n} rows of {n} numbers (one per actuated joint)"),
                ));
            }
            let m = DMatrix::from_fn(n, n, |i, j| rows[i][j]);
            if m.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(ctx, "coupling", "expected finite numbers"));
            }
            Some(m)
        }
    })
}

/// Appends the `[[frame]]` entries (relative to a link, or to a merged fixed
/// URDF link through its frame).
fn add_frames(ctx: &str, specs: &[FrameSpec], links: &[Link], frames: &mut Vec<Frame>) -> Result<()> {
    for (k, fs) in specs.iter().enumerate() {
        let link = match &fs.link {
            None => None,
            Some(l) => Some(
                links
                    .iter()
                    .position(|x| &x.name == l)
                    .or_else(|| frames.iter().find(|fr| &fr.name == l).and_then(|fr| fr.link))
                    .ok_or_else(|| Error::invalid(ctx, format!("frame[{k}].link"), format!("no link named `{l}`")))?,
            ),
        };
        // a frame relative to a merged (fixed) URDF link composes with that link's placement
        let base = fs
            .link
            .as_ref()
            .and_then(|l| {
                if links.iter().any(|x| &x.name == l) {
                    None
                } else {
                    frames.iter().find(|fr| &fr.name == l).map(|fr| fr.placement)
                }
            })
            .unwrap_or_else(Isometry3::identity);
        frames.push(Frame {
            name: fs.name.clone(),
            link,
            placement: base * pose_to_iso(fs.xyz, fs.rpy),
        });
    }
    Ok(())
}

/// Gravity in the base frame (m/s²; default (0, 0, −9.81)).
fn gravity_vector(ctx: &str, g: Option<[f64; 3]>) -> Result<Vector3<f64>> {
    Ok(match g {
        Some(g) => {
            for (i, v) in g.iter().enumerate() {
                finite(ctx, &format!("gravity[{i}]"), *v)?;
            }
            Vector3::from(g)
        }
        None => Vector3::new(0.0, 0.0, -9.81),
    })
}

fn rot_x(a: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a))
}
fn rot_z(a: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a))
}
fn tr(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
}

fn dh_robot(ctx: &str, conv: DhConvention, rows: &[DhJoint]) -> Result<(Vec<Joint>, Vec<Link>)> {
    if rows.is_empty() {
        return Err(Error::invalid(ctx, "joint", "a DH robot needs at least one [[joint]] row"));
    }
    let mut joints = Vec::new();
    let mut links = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        let field = |s: &str| format!("joint[{i}] (`{}`).{s}", r.name);
        for (s, v) in [("a", r.a), ("alpha", r.alpha), ("d", r.d), ("theta", r.theta)] {
            finite(ctx, &field(s), v)?;
        }
        if rows[..i].iter().any(|o| o.name == r.name) {
            return Err(Error::invalid(ctx, field("name"), "duplicate joint name"));
        }
        let (placement, post, offset) = match (conv, r.kind) {
            (DhConvention::Standard, JointType::Revolute) => (Isometry3::identity(), tr(0.0, 0.0, r.d) * tr(r.a, 0.0, 0.0) * rot_x(r.alpha), r.theta),
            (DhConvention::Standard, JointType::Prismatic) => (rot_z(r.theta), tr(r.a, 0.0, 0.0) * rot_x(r.alpha), r.d),
            (DhConvention::Modified, JointType::Revolute) => (rot_x(r.alpha) * tr(r.a, 0.0, 0.0) * tr(0.0, 0.0, r.d), Isometry3::identity(), r.theta),
            (DhConvention::Modified, JointType::Prismatic) => (rot_x(r.alpha) * tr(r.a, 0.0, 0.0) * rot_z(r.theta), Isometry3::identity(), r.d),
        };
        let lower = r.lower.unwrap_or(f64::NEG_INFINITY);
        let upper = r.upper.unwrap_or(f64::INFINITY);
        if lower.is_nan() || upper.is_nan() || lower > upper {
            return Err(Error::invalid(ctx, field("lower"), format!("expected lower ≤ upper, found {lower} > {upper}")));
        }
        let pos_lim = |s: &str, v: Option<f64>| -> Result<f64> {
            match v {
                None => Ok(f64::INFINITY),
                Some(v) if v > 0.0 => Ok(v),
                Some(v) => Err(Error::invalid(ctx, field(s), format!("expected a positive limit, found {v}"))),
            }
        };
        let limits = JointLimits {
            lower,
            upper,
            velocity: pos_lim("velocity", r.velocity)?,
            acceleration: pos_lim("acceleration", r.acceleration)?,
            effort: pos_lim("effort", r.effort)?,
        };
        let spec = r.inertial.as_ref().ok_or_else(|| {
            Error::invalid(
                ctx,
                field("inertial"),
                "missing [joint.inertial] block: expected mass, com and inertia of the link",
            )
        })?;
        if !(spec.mass.is_finite() && spec.mass >= 0.0) {
            return Err(Error::invalid(
                ctx,
                field("inertial.mass"),
                format!("expected a non-negative mass, found {}", spec.mass),
            ));
        }
        for v in spec.com.iter().chain(spec.inertia.iter()) {
            finite(ctx, &field("inertial"), *v)?;
        }
        let [xx, xy, xz, yy, yz, zz] = spec.inertia;
        let im = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
        let com = Vector3::from(spec.com);
        let inertial = match spec.inertia_at {
            InertiaAt::Com => Inertial::from_com(spec.mass, com, im, Matrix3::identity()),
            InertiaAt::Origin => Inertial {
                mass: spec.mass,
                first_moment: spec.mass * com,
                inertia: im,
            },
        };
        joints.push(Joint {
            name: r.name.clone(),
            kind: match r.kind {
                JointType::Revolute => JointKind::Revolute,
                JointType::Prismatic => JointKind::Prismatic,
            },
            parent: if i == 0 { None } else { Some(i - 1) },
            placement,
            axis: Unit::new_unchecked(Vector3::z()),
            post,
            offset,
            limits,
        });
        links.push(Link {
            name: r.link.clone().unwrap_or_else(|| format!("link{}", i + 1)),
            inertial,
        });
    }
    let _ = Rotation3::<f64>::identity();
    Ok((joints, links))
}
