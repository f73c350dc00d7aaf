//! The immutable robot model: joints, links with inertial parameters, drives
//! (rotor inertia, gear ratio, friction), joint coupling, named frames, and the
//! layout of the standard parameter vector.
//!
//! Size (~980 lines, above the house's ~800): the model's types, their
//! construction checks and the parameter layout are one concern (what a
//! valid `Robot` is); the drive-parameter walk itself lives in
//! `dynamics/friction.rs` (`visit_drive_params`).

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Unit, Vector3};
use serde::Serialize;

/// Joint type of an actuated joint (fixed joints are merged at load time).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation about the axis, q in rad.
    Revolute,
    /// Translation along the axis, q in m.
    Prismatic,
}

/// Joint limits (SI units; rad or m). Unknown limits are `f64::INFINITY`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct JointLimits {
    /// Lower position limit.
    pub lower: f64,
    /// Upper position limit.
    pub upper: f64,
    /// Velocity limit (symmetric).
    pub velocity: f64,
    /// Acceleration limit (symmetric).
    pub acceleration: f64,
    /// Effort (torque/force) limit (symmetric), on the motor side referred to the joint.
    pub effort: f64,
}

impl Default for JointLimits {
    fn default() -> Self {
        JointLimits {
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            velocity: f64::INFINITY,
            acceleration: f64::INFINITY,
            effort: f64::INFINITY,
        }
    }
}

/// An actuated joint. The transform from the parent link frame to this joint's
/// link frame is `placement · motion(q + offset) · post`, where `motion` is a
/// rotation about (revolute) or translation along (prismatic) `axis`.
/// `post` is the identity except for standard-DH robots.
#[derive(Debug, Clone)]
pub struct Joint {
    /// Joint name.
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Parent link index (`None`: the robot base).
    pub parent: Option<usize>,
    /// Parent link frame → joint frame, before the motion.
    pub placement: Isometry3<f64>,
    /// Unit axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Joint frame after the motion → link frame.
    pub post: Isometry3<f64>,
    /// Constant added to q before the motion (DH θ or d offset).
    pub offset: f64,
    /// Limits.
    pub limits: JointLimits,
}

/// Inertial parameters of a link about the link frame origin, in link coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Inertial {
    /// Mass m (kg).
    pub mass: f64,
    /// First moment m·c (kg·m), c the centre of mass in link coordinates.
    pub first_moment: Vector3<f64>,
    /// Inertia tensor about the link frame origin (kg·m²).
    pub inertia: Matrix3<f64>,
}

impl Inertial {
    /// Zero inertia (massless link).
    pub fn zero() -> Self {
        Inertial {
            mass: 0.0,
            first_moment: Vector3::zeros(),
            inertia: Matrix3::zeros(),
        }
    }

    /// From mass, centre of mass (link coordinates) and the inertia tensor about
    /// the centre of mass expressed in a frame rotated by `rot` from the link frame.
    pub fn from_com(mass: f64, com: Vector3<f64>, inertia_com: Matrix3<f64>, rot: Matrix3<f64>) -> Self {
        let ic = rot * inertia_com * rot.transpose();
        // parallel-axis theorem to the link origin: I_O = I_C + m (|c|² 1 − c cᵀ)
        let io = ic + mass * (com.norm_squared() * Matrix3::identity() - com * com.transpose());
        Inertial {
            mass,
            first_moment: mass * com,
            inertia: io,
        }
    }

    /// The 10 standard parameters XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M.
    pub fn to_params(&self) -> [f64; 10] {
        let i = &self.inertia;
        let h = &self.first_moment;
        [i[(0, 0)], i[(0, 1)], i[(0, 2)], i[(1, 1)], i[(1, 2)], i[(2, 2)], h.x, h.y, h.z, self.mass]
    }

    /// Inverse of [`Inertial::to_params`].
    pub fn from_params(p: &[f64]) -> Self {
        let inertia = Matrix3::new(p[0], p[1], p[2], p[1], p[3], p[4], p[2], p[4], p[5]);
        Inertial {
            mass: p[9],
            first_moment: Vector3::new(p[6], p[7], p[8]),
            inertia,
        }
    }

    /// Expresses these parameters (given in frame B) in frame A, where `a_t_b`
    /// maps B coordinates to A coordinates (used to merge fixed links, place a
    /// payload): Pinocchio's `a_t_b.act(Y)`, the spatial inertia transformed
    /// as Xᵀ I X. Linear in the ten parameters (also for a zero mass with a
    /// non-zero first moment, as the columns of a payload's T are).
    pub fn transformed(&self, a_t_b: &Isometry3<f64>) -> Self {
        let r = a_t_b.rotation.to_rotation_matrix().into_inner();
        let p = a_t_b.translation.vector;
        let m = self.mass;
        // inertia about B origin, in A orientation
        let io_b = r * self.inertia * r.transpose();
        let h_b = r * self.first_moment; // m c_B (c relative to B origin), A orientation
                                         // I_A = I_B + m(|p|²1 − ppᵀ) + (S(p)ᵀ S(h) + S(h)ᵀ S(p)) with c_A = p + c_B
        let sp = p.cross_matrix();
        let sh = h_b.cross_matrix();
        let io_a = io_b + m * (p.norm_squared() * Matrix3::identity() - p * p.transpose()) - (sp * sh + sh * sp);
        Inertial {
            mass: m,
            first_moment: m * p + h_b,
            inertia: io_a,
        }
    }

    /// Sum of two inertials expressed in the same frame.
    pub fn add(&self, o: &Inertial) -> Inertial {
        Inertial {
            mass: self.mass + o.mass,
            first_moment: self.first_moment + o.first_moment,
            inertia: self.inertia + o.inertia,
        }
    }
}

/// A moving link (one per actuated joint, same index).
#[derive(Debug, Clone)]
pub struct Link {
    /// Link name.
    pub name: String,
    /// Nominal inertial parameters (fixed children already merged).
    pub inertial: Inertial,
}

/// Friction model of one drive, torque referred to the joint side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum Friction {
    /// No friction parameters.
    None,
    /// τ_f = Fc·sign(q̇) + Fv·q̇ (+ F0 when `offset` is Some): paper 000 eq. 2.
    Symmetric {
        /// Coulomb coefficient Fc.
        fc: f64,
        /// Viscous coefficient Fv.
        fv: f64,
        /// Constant offset F0, if modelled.
        offset: Option<f64>,
    },
    /// Paper 002 eq. 2: Fv⁺q̇ + Fc⁺ for q̇ > 0, Fv⁻q̇ + Fc⁻ for q̇ < 0, 0 at rest.
    Asymmetric {
        /// Coulomb term for positive velocity.
        fc_pos: f64,
        /// Coulomb term for negative velocity (a negative number for the usual model).
        fc_neg: f64,
        /// Viscous coefficient for positive velocity.
        fv_pos: f64,
        /// Viscous coefficient for negative velocity.
        fv_neg: f64,
        /// Constant offset F0, if modelled.
        offset: Option<f64>,
    },
}

/// Shape of the Coulomb (velocity-sign) part of a drive's friction: how the
/// Coulomb coefficients Fc (or Fc⁺, Fc⁻) switch with the motor velocity w.
///
/// Every shape keeps the friction model linear in its parameters: the
/// velocity scale and the Stribeck velocity are fixed (robot file), not
/// identified.
///
/// * [`Coulomb::Sign`] (default): s(w) = sign(w) (paper 000 eq. 2); at rest
///   s = 0, but measured velocities at standstill are encoder noise and the
///   sign flips, so identification drops slow rows of such a joint.
/// * [`Coulomb::Tanh`]: s(w) = tanh(w / v_s) (paper 000 §IV, "tanh(1000 q̇)",
///   i.e. v_s = 1 mrad/s): smooth and ≈ 0 at rest, so slow rows may stay in
///   the estimate and a feedforward does not chatter.
/// * [`Coulomb::Stribeck`]: s(w) = tanh(w / v_s) plus one Stribeck column per
///   side, s(w)·exp(−(w/v_st)²), with coefficient Fs (parameter `Fs`, or
///   `Fsp`/`Fsn` for the asymmetric model): the static friction in excess of
///   Fc, decaying with speed.
///
/// For the asymmetric model (paper 002 eq. 2) the sides are weighted by
/// σ⁺(w), σ⁻(w): for `Sign` the indicators of w > 0 and w < 0 (as before),
/// for the smooth shapes σ± = (1 ± tanh(w/v_s))/2, so
/// τ_f = σ⁺(Fc⁺ + Fv⁺ w) + σ⁻(Fc⁻ + Fv⁻ w) (+ F0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
#[serde(tag = "shape", rename_all = "snake_case")]
pub enum Coulomb {
    /// sign(w).
    #[default]
    Sign,
    /// tanh(w / velocity_scale).
    Tanh {
        /// v_s > 0 (rad/s or m/s, motor velocity referred to the joint side).
        velocity_scale: f64,
    },
    /// tanh(w / velocity_scale) and a Stribeck column exp(−(w/stribeck_velocity)²)·tanh(w/v_s).
    Stribeck {
        /// v_s > 0.
        velocity_scale: f64,
        /// v_st > 0, fixed (not identified).
        stribeck_velocity: f64,
        /// Nominal Stribeck coefficients: `[Fs]` (symmetric model, second entry
        /// unused) or `[Fs⁺, Fs⁻]` (asymmetric model; Fs⁻ ≤ 0 for the usual sign).
        fs: [f64; 2],
    },
}

impl Coulomb {
    /// The name in robot files (`sign`, `tanh`, `stribeck`).
    pub fn name(&self) -> &'static str {
        match self {
            Coulomb::Sign => "sign",
            Coulomb::Tanh { .. } => "tanh",
            Coulomb::Stribeck { .. } => "stribeck",
        }
    }

    /// True for the discontinuous sign shape (slow rows are dropped in identification).
    pub fn is_sign(&self) -> bool {
        matches!(self, Coulomb::Sign)
    }

    /// A one-line description with the scales (`tanh(w/0.001)`).
    pub fn describe(&self) -> String {
        match *self {
            Coulomb::Sign => "sign(w)".into(),
            Coulomb::Tanh { velocity_scale } => format!("tanh(w/{velocity_scale})"),
            Coulomb::Stribeck {
                velocity_scale,
                stribeck_velocity,
                ..
            } => format!("tanh(w/{velocity_scale}), Stribeck exp(-(w/{stribeck_velocity})^2)"),
        }
    }
}

/// Drive-side data of one joint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Drive {
    /// Reflected rotor inertia Ia (kg·m², joint side); `None`: not modelled.
    pub rotor_inertia: Option<f64>,
    /// Gear ratio N (motor turns per joint turn). Ia is already reflected;
    /// N converts motor currents to joint torques (τ = sign·k_t·N·i).
    pub gear_ratio: f64,
    /// Friction model and nominal coefficients.
    pub friction: Friction,
    /// Shape of the Coulomb term (default: sign).
    #[serde(skip_serializing_if = "Coulomb::is_sign")]
    pub coulomb: Coulomb,
    /// Motor torque constant k_t (N·m/A, motor side; N/A for linear motors), if known.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub torque_constant: Option<f64>,
    /// Sign of the logged current relative to the joint torque (+1 or −1).
    #[serde(skip_serializing_if = "is_plus_one")]
    pub current_sign: f64,
}

fn is_plus_one(x: &f64) -> bool {
    *x == 1.0
}

impl Drive {
    /// Joint-side torque per ampere of logged current, sign·k_t·N, if k_t is known.
    pub fn torque_per_ampere(&self) -> Option<f64> {
        self.torque_constant.map(|k| self.current_sign * k * self.gear_ratio)
    }

    /// True when the friction torque is discontinuous at rest (a Coulomb or
    /// asymmetric term with the sign shape): identification then drops the
    /// joint's slow rows.
    pub fn discontinuous_at_rest(&self) -> bool {
        !matches!(self.friction, Friction::None) && self.coulomb.is_sign()
    }
}

impl Default for Drive {
    fn default() -> Self {
        Drive {
            rotor_inertia: None,
            gear_ratio: 1.0,
            friction: Friction::Symmetric {
                fc: 0.0,
                fv: 0.0,
                offset: None,
            },
            coulomb: Coulomb::Sign,
            torque_constant: None,
            current_sign: 1.0,
        }
    }
}

/// A named frame rigidly attached to a link (or the base): end effector, tool,
/// merged fixed links.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Frame name.
    pub name: String,
    /// Link it is attached to (`None`: base).
    pub link: Option<usize>,
    /// Link frame → this frame.
    pub placement: Isometry3<f64>,
}

/// What a standard parameter is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum ParamKind {
    /// Inertia tensor element XX about the link origin.
    XX,
    /// Product of inertia XY.
    XY,
    /// Product of inertia XZ.
    XZ,
    /// Inertia YY.
    YY,
    /// Product of inertia YZ.
    YZ,
    /// Inertia ZZ.
    ZZ,
    /// First moment m·cx.
    MX,
    /// First moment m·cy.
    MY,
    /// First moment m·cz.
    MZ,
    /// Mass.
    M,
    /// Reflected rotor inertia.
    Ia,
    /// Coulomb friction (symmetric).
    Fc,
    /// Viscous friction (symmetric).
    Fv,
    /// Friction offset.
    F0,
    /// Coulomb friction, positive velocity.
    FcPos,
    /// Coulomb friction, negative velocity.
    FcNeg,
    /// Viscous friction, positive velocity.
    FvPos,
    /// Viscous friction, negative velocity.
    FvNeg,
    /// Stribeck coefficient (symmetric model, [`Coulomb::Stribeck`]).
    Fs,
    /// Stribeck coefficient, positive velocity (asymmetric model).
    FsPos,
    /// Stribeck coefficient, negative velocity (asymmetric model).
    FsNeg,
}

impl ParamKind {
    /// Short label used in parameter names (`ZZ2`, `Fc3`, ...).
    pub fn label(self) -> &'static str {
        use ParamKind::*;
        match self {
            XX => "XX",
            XY => "XY",
            XZ => "XZ",
            YY => "YY",
            YZ => "YZ",
            ZZ => "ZZ",
            MX => "MX",
            MY => "MY",
            MZ => "MZ",
            M => "M",
            Ia => "Ia",
            Fc => "Fc",
            Fv => "Fv",
            F0 => "F0",
            FcPos => "Fcp",
            FcNeg => "Fcn",
            FvPos => "Fvp",
            FvNeg => "Fvn",
            Fs => "Fs",
            FsPos => "Fsp",
            FsNeg => "Fsn",
        }
    }
    /// Symbol in the robot summary (`Fc+` where the label is `Fcp`).
    pub fn symbol(self) -> &'static str {
        use ParamKind::*;
        match self {
            FcPos => "Fc+",
            FcNeg => "Fc-",
            FvPos => "Fv+",
            FvNeg => "Fv-",
            FsPos => "Fs+",
            FsNeg => "Fs-",
            k => k.label(),
        }
    }

    /// Key of a drive parameter in a robot file's `[[drive]]` table (`ia`,
    /// `fc`, `fc_pos`, ...); `None` for the inertial kinds.
    pub fn drive_key(self) -> Option<&'static str> {
        use ParamKind::*;
        Some(match self {
            Ia => "ia",
            Fc => "fc",
            Fv => "fv",
            F0 => "f0",
            FcPos => "fc_pos",
            FcNeg => "fc_neg",
            FvPos => "fv_pos",
            FvNeg => "fv_neg",
            Fs => "fs",
            FsPos => "fs_pos",
            FsNeg => "fs_neg",
            _ => return None,
        })
    }

    /// The sign of this kind's value in any physical robot ([`ParamSign`]):
    /// masses, the inertias XX/YY/ZZ about the link origin, rotor inertias,
    /// symmetric Coulomb and viscous friction, Fc⁺, Fv⁺ and Fv⁻ are ≥ 0, Fc⁻
    /// is ≤ 0, the rest (products of inertia, first moments, offsets F0,
    /// Stribeck coefficients) are free. The one statement of these signs: the
    /// robot file's checks, the plausibility flags of an estimate and the
    /// bounds of the consistent fit read it.
    pub fn sign(self) -> ParamSign {
        use ParamKind::*;
        match self {
            XX | YY | ZZ | M | Ia | Fc | Fv | FcPos | FvPos | FvNeg => ParamSign::NonNegative,
            FcNeg => ParamSign::NonPositive,
            XY | XZ | YZ | MX | MY | MZ | F0 | Fs | FsPos | FsNeg => ParamSign::Free,
        }
    }

    /// True for the 10 rigid-body inertial parameters.
    pub fn is_inertial(self) -> bool {
        matches!(self as u8, 0..=9)
    }
    /// True for friction parameters.
    pub fn is_friction(self) -> bool {
        use ParamKind::*;
        matches!(self, Fc | Fv | F0 | FcPos | FcNeg | FvPos | FvNeg | Fs | FsPos | FsNeg)
    }
    /// The 10 inertial kinds in the standard order.
    pub const INERTIAL: [ParamKind; 10] = [
        ParamKind::XX,
        ParamKind::XY,
        ParamKind::XZ,
        ParamKind::YY,
        ParamKind::YZ,
        ParamKind::ZZ,
        ParamKind::MX,
        ParamKind::MY,
        ParamKind::MZ,
        ParamKind::M,
    ];
}

/// The sign a parameter's value has in any physical robot ([`ParamKind::sign`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamSign {
    /// ≥ 0.
    NonNegative,
    /// ≤ 0 (Fc⁻ of the asymmetric model: the Coulomb term opposes negative velocity).
    NonPositive,
    /// Either sign.
    Free,
}

/// One entry of the standard parameter vector.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamInfo {
    /// Name such as `ZZ2` or `Fc3` (1-based joint number).
    pub name: String,
    /// Joint/link index (0-based).
    pub joint: usize,
    /// Kind.
    pub kind: ParamKind,
}

/// The robot: built once, never mutated; algorithms take it by reference.
#[derive(Debug, Clone)]
pub struct Robot {
    /// Robot name.
    pub name: String,
    /// Actuated joints; joint i moves link i. Parents come before children.
    pub joints: Vec<Joint>,
    /// Moving links.
    pub links: Vec<Link>,
    /// Drives, one per joint.
    pub drives: Vec<Drive>,
    /// Coupling matrix C: motor positions (joint-side units) θ = C q. `None`: identity.
    pub coupling: Option<DMatrix<f64>>,
    /// Named frames (end effector, tool, merged fixed links).
    pub frames: Vec<Frame>,
    /// Gravity acceleration vector in base coordinates (default (0, 0, −9.81)).
    pub gravity: Vector3<f64>,
    /// Where the model came from (file names, references).
    pub source: String,
    /// Collision geometry (URDF `<collision>` elements, robot-file shapes), if any.
    pub collision: Option<std::sync::Arc<super::collision::RobotGeometry>>,
    /// Why the collision geometry the robot file describes could not be
    /// loaded (each link's mesh not found or not readable, with the folders
    /// searched); `None` when it loaded or there is none. Commands that need
    /// no geometry warn with it; collision checks refuse to run without it
    /// ([`super::collision::CollisionScene::new`]).
    pub geometry_error: Option<String>,
    pub(crate) coupling_inv_t: Option<DMatrix<f64>>,
    pub(crate) params: Vec<ParamInfo>,
    pub(crate) drive_offset: Vec<usize>,
    pub(crate) s_ang: Vec<Vector3<f64>>,
    pub(crate) s_lin: Vec<Vector3<f64>>,
    /// Precomputed joint geometry (rotation matrices of placement and post).
    pub(crate) geo: Vec<JointGeometry>,
    /// Non-zero entries (row, col, value) of C and C⁻ᵀ (empty: identity).
    pub(crate) c_sparse: Vec<(usize, usize, f64)>,
    pub(crate) cinvt_sparse: Vec<(usize, usize, f64)>,
    /// What the kernels read of the tree, classified once ([`super::dynamics::Topology`]).
    pub(crate) topology: super::dynamics::Topology,
}

/// Joint geometry as matrices, precomputed once for the kernels.
#[derive(Debug, Clone)]
pub(crate) struct JointGeometry {
    pub pl_r: Matrix3<f64>,
    pub pl_p: Vector3<f64>,
    pub po_r: Matrix3<f64>,
    pub po_p: Vector3<f64>,
    pub post_identity: bool,
    /// The joint axis is exactly ±e_k: (k, ±1) (the kernels' shortcut).
    pub coord: Option<(usize, f64)>,
}

impl JointGeometry {
    /// The cached placement and post-transform parts of a joint.
    fn of(j: &Joint) -> JointGeometry {
        JointGeometry {
            pl_r: j.placement.rotation.to_rotation_matrix().into_inner(),
            pl_p: j.placement.translation.vector,
            po_r: j.post.rotation.to_rotation_matrix().into_inner(),
            po_p: j.post.translation.vector,
            post_identity: j.post == Isometry3::identity(),
            coord: crate::robot::kinematics::coordinate_axis(&j.axis.into_inner()),
        }
    }
}

/// Checks the topology (parents before children) and the limits of every joint.
fn check_joints(name: &str, joints: &[Joint]) -> crate::Result<()> {
    use crate::Error;
    let ctx = || format!("robot `{name}`");
    for (i, j) in joints.iter().enumerate() {
        if let Some(p) = j.parent {
            if p >= i {
                return Err(Error::invalid(
                    ctx(),
                    format!("joints[{}].parent", j.name),
                    "a joint's parent link must come before it",
                ));
            }
        }
        let l = &j.limits;
        if l.lower.is_nan() || l.upper.is_nan() || l.lower > l.upper {
            return Err(Error::invalid(
                ctx(),
                format!("joint `{}` limits", j.name),
                format!("lower ({}) must be ≤ upper ({})", l.lower, l.upper),
            ));
        }
        for (what, v) in [("velocity", l.velocity), ("acceleration", l.acceleration), ("effort", l.effort)] {
            if v.is_nan() || v <= 0.0 {
                return Err(Error::invalid(
                    ctx(),
                    format!("joint `{}` {what} limit", j.name),
                    format!("expected a positive number, found {v}"),
                ));
            }
        }
    }
    Ok(())
}

/// Checks masses (finite, ≥ 0) and inertias (finite) of every link.
fn check_links(name: &str, links: &[Link]) -> crate::Result<()> {
    use crate::Error;
    let ctx = || format!("robot `{name}`");
    for l in links {
        let m = l.inertial.mass;
        if !m.is_finite() || m < 0.0 {
            return Err(Error::invalid(
                ctx(),
                format!("link `{}` mass", l.name),
                format!("expected a non-negative finite mass, found {m}"),
            ));
        }
        if l.inertial.inertia.iter().chain(l.inertial.first_moment.iter()).any(|v| !v.is_finite()) {
            return Err(Error::invalid(ctx(), format!("link `{}` inertia", l.name), "expected finite values"));
        }
    }
    Ok(())
}

/// C⁻ᵀ of the coupling matrix C (n×n, invertible), if any.
fn coupling_inverse_transpose(name: &str, coupling: Option<&DMatrix<f64>>, n: usize) -> crate::Result<Option<DMatrix<f64>>> {
    use crate::Error;
    let ctx = || format!("robot `{name}`");
    Ok(match coupling {
        None => None,
        Some(c) => {
            if c.nrows() != n || c.ncols() != n {
                return Err(Error::invalid(
                    ctx(),
                    "coupling",
                    format!("expected a {n}×{n} matrix, found {}×{}", c.nrows(), c.ncols()),
                ));
            }
            let inv = c
                .clone()
                .try_inverse()
                .ok_or_else(|| Error::invalid(ctx(), "coupling", "the coupling matrix is singular"))?;
            Some(inv.transpose())
        }
    })
}

/// The standard-parameter layout: per joint the ten inertial parameters, then
/// its drive's (Ia if modelled, then the friction coefficients); returns the
/// parameters and the offset of each drive's first parameter.
fn param_layout(drives: &[Drive]) -> (Vec<ParamInfo>, Vec<usize>) {
    let n = drives.len();
    let mut params = Vec::new();
    let mut drive_offset = Vec::with_capacity(n);
    for i in 0..n {
        for k in ParamKind::INERTIAL {
            params.push(ParamInfo {
                name: format!("{}{}", k.label(), i + 1),
                joint: i,
                kind: k,
            });
        }
        drive_offset.push(params.len());
        let d = &drives[i];
        let mut push = |k: ParamKind| {
            params.push(ParamInfo {
                name: format!("{}{}", k.label(), i + 1),
                joint: i,
                kind: k,
            })
        };
        for &(k, _) in super::dynamics::drive_params(d).as_slice() {
            push(k);
        }
    }
    (params, drive_offset)
}

/// Checks the drive data a robot file cannot express wrongly but a library
/// caller can: velocity scales and Stribeck velocities positive and finite,
/// torque constants positive and finite, current signs ±1.
fn check_drives(name: &str, joints: &[Joint], drives: &[Drive]) -> crate::Result<()> {
    let ctx = || format!("robot `{name}`");
    for (j, d) in drives.iter().enumerate() {
        let field = |s: &str| format!("drive of joint `{}`.{s}", joints[j].name);
        let positive = |s: &str, v: f64| -> crate::Result<()> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(crate::Error::invalid(ctx(), field(s), format!("expected a positive finite number, found {v}")))
            }
        };
        match d.coulomb {
            Coulomb::Sign => {}
            Coulomb::Tanh { velocity_scale } => positive("velocity_scale", velocity_scale)?,
            Coulomb::Stribeck {
                velocity_scale,
                stribeck_velocity,
                fs,
            } => {
                positive("velocity_scale", velocity_scale)?;
                positive("stribeck_velocity", stribeck_velocity)?;
                if fs.iter().any(|v| !v.is_finite()) {
                    return Err(crate::Error::invalid(ctx(), field("fs"), "expected finite Stribeck coefficients"));
                }
            }
        }
        if let Some(k) = d.torque_constant {
            positive("torque_constant", k)?;
        }
        if d.current_sign != 1.0 && d.current_sign != -1.0 {
            return Err(crate::Error::invalid(
                ctx(),
                field("current_sign"),
                format!("expected 1 or -1, found {}", d.current_sign),
            ));
        }
    }
    Ok(())
}

/// Entries (row, column, value) of the non-zero elements of `m`.
fn sparse(m: &DMatrix<f64>) -> Vec<(usize, usize, f64)> {
    let mut v = Vec::new();
    for r in 0..m.nrows() {
        for c in 0..m.ncols() {
            if m[(r, c)] != 0.0 {
                v.push((r, c, m[(r, c)]));
            }
        }
    }
    v
}

/// Motion subspace of a joint in its child frame: (angular, linear) parts.
fn motion_subspace(j: &Joint) -> (Vector3<f64>, Vector3<f64>) {
    let r = j.post.rotation.to_rotation_matrix().into_inner().transpose();
    let p = j.post.translation.vector;
    let a = j.axis.into_inner();
    match j.kind {
        JointKind::Revolute => (r * a, r * a.cross(&p)),
        JointKind::Prismatic => (Vector3::zeros(), r * a),
    }
}

/// The pieces a robot is assembled from (what a loader produces).
#[derive(Debug, Clone)]
pub struct RobotParts {
    /// Robot name.
    pub name: String,
    /// Actuated joints, parents before children.
    pub joints: Vec<Joint>,
    /// One link per joint (the body the joint moves).
    pub links: Vec<Link>,
    /// One drive per joint.
    pub drives: Vec<Drive>,
    /// Coupling matrix C (n×n, motor positions θ = C q), if any.
    pub coupling: Option<DMatrix<f64>>,
    /// Named frames (tool, sensors).
    pub frames: Vec<Frame>,
    /// Gravity vector in the base frame (m/s²).
    pub gravity: Vector3<f64>,
    /// Where the model came from (for reports).
    pub source: String,
}

impl Robot {
    /// Assembles and checks a robot. Called by the loaders; validates the
    /// topology (parents before children), the coupling matrix (n×n,
    /// invertible), masses (≥ 0) and builds the parameter layout.
    pub fn new(parts: RobotParts) -> crate::Result<Robot> {
        use crate::Error;
        let RobotParts {
            name,
            joints,
            links,
            drives,
            coupling,
            frames,
            gravity,
            source,
        } = parts;
        let n = joints.len();
        let ctx = || format!("robot `{name}`");
        if n == 0 {
            return Err(Error::invalid(ctx(), "joints", "the robot has no actuated joint"));
        }
        if links.len() != n || drives.len() != n {
            return Err(Error::invalid(
                ctx(),
                "links",
                format!("expected {n} links and drives, found {} and {}", links.len(), drives.len()),
            ));
        }
        check_joints(&name, &joints)?;
        check_links(&name, &links)?;
        check_drives(&name, &joints, &drives)?;
        let coupling_inv_t = coupling_inverse_transpose(&name, coupling.as_ref(), n)?;
        let (params, drive_offset) = param_layout(&drives);
        let geo = joints.iter().map(JointGeometry::of).collect();
        let c_sparse = coupling.as_ref().map(sparse).unwrap_or_default();
        let cinvt_sparse = coupling_inv_t.as_ref().map(sparse).unwrap_or_default();
        let (s_ang, s_lin) = joints.iter().map(motion_subspace).unzip();
        let mut robot = Robot {
            name,
            joints,
            links,
            drives,
            coupling,
            frames,
            gravity,
            source,
            collision: None,
            geometry_error: None,
            coupling_inv_t,
            geo,
            c_sparse,
            cinvt_sparse,
            params,
            drive_offset,
            s_ang,
            s_lin,
            topology: Default::default(),
        };
        robot.topology = super::dynamics::Topology::of(&robot);
        Ok(robot)
    }

    /// The same robot with its collision geometry (one body per moving link plus the base).
    pub fn with_collision(mut self, geometry: super::collision::RobotGeometry) -> crate::Result<Robot> {
        if geometry.bodies.len() != self.dof() + 1 {
            return Err(crate::Error::dim(
                "collision bodies (base + one per link)",
                self.dof() + 1,
                geometry.bodies.len(),
            ));
        }
        self.collision = Some(std::sync::Arc::new(geometry));
        Ok(self)
    }

    /// The same robot with the reason its collision geometry could not be
    /// loaded (and no geometry).
    pub fn with_geometry_error(mut self, why: String) -> Robot {
        self.collision = None;
        self.geometry_error = Some(why);
        self
    }

    /// Number of actuated joints n.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The standard parameter layout: per joint XX..M, then Ia, friction terms.
    pub fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    /// Number of standard parameters p.
    pub fn n_params(&self) -> usize {
        self.params.len()
    }

    /// Parameter names in order.
    pub fn param_names(&self) -> Vec<String> {
        self.params.iter().map(|p| p.name.clone()).collect()
    }

    /// Nominal values of the standard parameters, in layout order.
    pub fn nominal_params(&self) -> DVector<f64> {
        let mut v = Vec::with_capacity(self.params.len());
        for (i, l) in self.links.iter().enumerate() {
            v.extend_from_slice(&l.inertial.to_params());
            v.extend(super::dynamics::drive_params(&self.drives[i]).as_slice().iter().map(|&(_, x)| x));
        }
        DVector::from_vec(v)
    }

    /// Index of the first drive parameter of joint `j` in the layout.
    pub fn drive_param_offset(&self, j: usize) -> usize {
        self.drive_offset[j]
    }

    /// Index of the first inertial parameter of link `i` in the layout.
    pub fn link_param_offset(&self, i: usize) -> usize {
        if i == 0 {
            0
        } else {
            self.drive_offset[i - 1] + self.n_drive_params(i - 1)
        }
    }

    /// Number of drive (Ia + friction) parameters of joint `j`.
    pub fn n_drive_params(&self, j: usize) -> usize {
        let end = if j + 1 < self.dof() {
            self.drive_offset[j + 1] - 10
        } else {
            self.params.len()
        };
        end - self.drive_offset[j]
    }

    /// Mask of the inertial (rigid-body) parameters in the layout.
    pub fn inertial_mask(&self) -> Vec<bool> {
        self.params.iter().map(|p| p.kind.is_inertial()).collect()
    }

    /// Coupling matrix C (identity when the robot has none).
    pub fn coupling_matrix(&self) -> DMatrix<f64> {
        self.coupling.clone().unwrap_or_else(|| DMatrix::identity(self.dof(), self.dof()))
    }

    /// Index of a frame or link by name: links first (`Some(link)` frames with
    /// identity placement), then named frames.
    pub fn find_frame(&self, name: &str) -> Option<Frame> {
        if let Some(i) = self.links.iter().position(|l| l.name == name) {
            return Some(Frame {
                name: name.to_string(),
                link: Some(i),
                placement: Isometry3::identity(),
            });
        }
        self.frames.iter().find(|f| f.name == name).cloned()
    }

    /// The default end-effector frame: a frame named `ee`, `tool0`, `flange` or
    /// `end_effector` if present, otherwise the origin of the last link.
    pub fn end_effector(&self) -> Frame {
        for n in ["ee", "end_effector", "tool0", "flange", "tool", "ee_link"] {
            if let Some(f) = self.frames.iter().find(|f| f.name == n) {
                return f.clone();
            }
        }
        // the last frame attached to the last link, if any
        let last = self.dof() - 1;
        if let Some(f) = self.frames.iter().rev().find(|f| f.link == Some(last)) {
            return f.clone();
        }
        Frame {
            name: self.links[last].name.clone(),
            link: Some(last),
            placement: Isometry3::identity(),
        }
    }

    /// Joint position limits as (lower, upper) vectors.
    pub fn position_limits(&self) -> (Vec<f64>, Vec<f64>) {
        (
            self.joints.iter().map(|j| j.limits.lower).collect(),
            self.joints.iter().map(|j| j.limits.upper).collect(),
        )
    }

    /// A copy of this robot with different standard parameters (for simulation
    /// with perturbed "true" parameters). Friction/Ia entries update the drives.
    pub fn with_params(&self, theta: &[f64]) -> crate::Result<Robot> {
        if theta.len() != self.n_params() {
            return Err(crate::Error::dim("parameter vector", self.n_params(), theta.len()));
        }
        let mut r = self.clone();
        for i in 0..self.dof() {
            let o = self.link_param_offset(i);
            r.links[i].inertial = Inertial::from_params(&theta[o..o + 10]);
            let mut k = self.drive_offset[i];
            super::dynamics::visit_drive_params(&mut r.drives[i], |_, v| {
                *v = theta[k];
                k += 1;
            });
        }
        Ok(r)
    }
}
