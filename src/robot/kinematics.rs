//! Forward kinematics: link and frame poses, frame Jacobians.
//!
//! All kernels are generic over the scalar [`Real`] (f64, or a forward-mode dual
//! number for derivatives) and write into a caller-owned [`Kin`] buffer, so
//! inner loops do not allocate.

use super::model::{Frame, JointKind, Robot};
use nalgebra::{Isometry3, Matrix3, RealField, Translation3, UnitQuaternion, Vector3};
use num_dual::Dual64;

/// Scalar type of the generic kernels: f64 or a dual number.
pub trait Real: RealField + Copy {
    /// The real (value) part.
    fn re_(&self) -> f64;
    /// Lifts a constant.
    fn c(x: f64) -> Self;
    /// (sin x, cos x) of the joint angles, by the `libm` crate's sincos
    /// (musl's kernels, no rounding-mode switches: about half the time of
    /// the platform's), the same arithmetic in every scalar type.
    fn sincos(self) -> (Self, Self);
}

impl Real for f64 {
    #[inline(always)]
    fn sincos(self) -> (f64, f64) {
        libm::sincos(self)
    }
    #[inline(always)]
    fn re_(&self) -> f64 {
        *self
    }
    #[inline(always)]
    fn c(x: f64) -> Self {
        x
    }
}

impl Real for Dual64 {
    #[inline(always)]
    fn sincos(self) -> (Dual64, Dual64) {
        let (s, c) = libm::sincos(self.re);
        (Dual64::new(s, c * self.eps), Dual64::new(c, -s * self.eps))
    }
    #[inline(always)]
    fn re_(&self) -> f64 {
        self.re
    }
    #[inline(always)]
    fn c(x: f64) -> Self {
        Dual64::from(x)
    }
}

/// Per-link kinematic buffers for one scalar type.
#[derive(Debug, Clone)]
pub struct Kin<T: Real> {
    /// parent_R_i: link i orientation in parent coordinates.
    pub rot: Vec<Matrix3<T>>,
    /// Position of link i's origin in parent coordinates.
    pub pos: Vec<Vector3<T>>,
    /// Angular velocity ω_i (link coordinates).
    pub w: Vec<Vector3<T>>,
    /// Linear velocity of the link origin (link coordinates).
    pub v: Vec<Vector3<T>>,
    /// Angular acceleration (link coordinates).
    pub dw: Vec<Vector3<T>>,
    /// Spatial linear acceleration (link coordinates), gravity included.
    pub dv: Vec<Vector3<T>>,
    /// Moment about the link origin (backward pass accumulator).
    pub n: Vec<Vector3<T>>,
    /// Force (backward pass accumulator).
    pub f: Vec<Vector3<T>>,
    /// Joint-space scratch vectors (length n).
    pub s1: Vec<T>,
    /// Second joint-space scratch vector.
    pub s2: Vec<T>,
    /// Motion-subspace vectors propagated down the tree (regressor), angular part.
    pub sa: Vec<Vector3<T>>,
    /// Linear part of the above.
    pub sl: Vec<Vector3<T>>,
    /// World orientation of each link (forward kinematics).
    pub wrot: Vec<Matrix3<T>>,
    /// World position of each link origin.
    pub wpos: Vec<Vector3<T>>,
}

impl<T: Real> Kin<T> {
    /// Buffers for `n` links.
    pub fn new(n: usize) -> Self {
        let z3 = Vector3::zeros();
        Kin {
            rot: vec![Matrix3::identity(); n],
            pos: vec![z3; n],
            w: vec![z3; n],
            v: vec![z3; n],
            dw: vec![z3; n],
            dv: vec![z3; n],
            n: vec![z3; n],
            f: vec![z3; n],
            s1: vec![T::zero(); n],
            s2: vec![T::zero(); n],
            sa: vec![z3; n],
            sl: vec![z3; n],
            wrot: vec![Matrix3::identity(); n],
            wpos: vec![z3; n],
        }
    }
}

#[inline]
pub(crate) fn lift3<T: Real>(v: &Vector3<f64>) -> Vector3<T> {
    Vector3::new(T::c(v.x), T::c(v.y), T::c(v.z))
}

#[inline]
pub(crate) fn lift33<T: Real>(m: &Matrix3<f64>) -> Matrix3<T> {
    m.map(T::c)
}

/// Rotation matrix about unit axis `a` by angle `th` (Rodrigues).
#[inline]
pub(crate) fn axis_angle<T: Real>(a: &Vector3<f64>, th: T) -> Matrix3<T> {
    let (s, c) = th.sincos();
    let v = T::one() - c;
    let (x, y, z) = (T::c(a.x), T::c(a.y), T::c(a.z));
    Matrix3::new(
        c + x * x * v,
        x * y * v - z * s,
        x * z * v + y * s,
        y * x * v + z * s,
        c + y * y * v,
        y * z * v - x * s,
        z * x * v - y * s,
        z * y * v + x * s,
        c + z * z * v,
    )
}

/// The axis is exactly ±e_k: returns (k, ±1).
#[inline]
pub(crate) fn coordinate_axis(a: &Vector3<f64>) -> Option<(usize, f64)> {
    (0..3).find_map(|k| {
        let others_zero = (0..3).all(|c| c == k || a[c] == 0.0);
        (others_zero && a[k].abs() == 1.0).then_some((k, a[k]))
    })
}

/// `P · axis_angle(±e_k, th)` without the products with the rotation's
/// zeros: with (i, j, k) cyclic, the rotation keeps e_k and sends
/// e_i → c e_i + s e_j, e_j → −s e_i + c e_j (s = ±sin th), so column k of
/// the product is P's, column i is c P_i + s P_j, column j is c P_j − s P_i.
///
/// The columns are placed with literal indices: a runtime index would send
/// the matrix through memory (a store-forwarding stall on every call).
#[inline]
fn placed_rotation_axis<T: Real>(p: &Matrix3<f64>, k: usize, sign: f64, th: T) -> Matrix3<T> {
    let (s, c) = th.sincos();
    let s = s * T::c(sign);
    let col = |x: usize| Vector3::new(T::c(p[(0, x)]), T::c(p[(1, x)]), T::c(p[(2, x)]));
    let (pi, pj, pk) = match k {
        0 => (col(1), col(2), col(0)),
        1 => (col(2), col(0), col(1)),
        _ => (col(0), col(1), col(2)),
    };
    let ci = pi * c + pj * s;
    let cj = pj * c - pi * s;
    match k {
        0 => Matrix3::from_columns(&[pk, ci, cj]),
        1 => Matrix3::from_columns(&[cj, pk, ci]),
        _ => Matrix3::from_columns(&[ci, cj, pk]),
    }
}

/// Fills `kin.rot`, `kin.pos` (parent-relative transforms) for configuration `q`.
pub fn joint_transforms<T: Real>(robot: &Robot, q: &[T], kin: &mut Kin<T>) {
    for i in 0..robot.joints.len() {
        let (r, p) = joint_transform(robot, i, q[i]);
        kin.rot[i] = r;
        kin.pos[i] = p;
    }
}

/// Orientation and position of joint `i`'s child frame in its parent's at
/// joint coordinate `qi`. Always inlined: an outlined call returns the
/// matrix through memory (measured: the CRBA 12 % slower on the UR5).
#[inline(always)]
pub(crate) fn joint_transform<T: Real>(robot: &Robot, i: usize, qi: T) -> (Matrix3<T>, Vector3<T>) {
    let j = &robot.joints[i];
    let g = &robot.geo[i];
    let th = qi + T::c(j.offset);
    let a = j.axis.into_inner();
    match j.kind {
        JointKind::Revolute => {
            // a coordinate axis ±e_k (found once, at load): the shortcut,
            // the same arithmetic in every scalar type, so that passes over
            // shared f64 transforms equal independent dual passes
            let r_plm = match g.coord {
                Some((k, sign)) => placed_rotation_axis(&g.pl_r, k, sign, th),
                None => lift33::<T>(&g.pl_r) * axis_angle(&a, th),
            };
            if g.post_identity {
                (r_plm, lift3::<T>(&g.pl_p))
            } else {
                (r_plm * lift33::<T>(&g.po_r), lift3::<T>(&g.pl_p) + r_plm * lift3::<T>(&g.po_p))
            }
        }
        JointKind::Prismatic => (
            lift33::<T>(&(g.pl_r * g.po_r)),
            lift3::<T>(&g.pl_p) + lift33::<T>(&g.pl_r) * (lift3::<T>(&a) * th + lift3::<T>(&g.po_p)),
        ),
    }
}

/// Forward kinematics: world (base) orientation and position of every link
/// origin, into `kin.wrot`, `kin.wpos`.
pub fn forward_kinematics<T: Real>(robot: &Robot, q: &[T], kin: &mut Kin<T>) {
    joint_transforms(robot, q, kin);
    for i in 0..robot.dof() {
        match robot.joints[i].parent {
            None => {
                kin.wrot[i] = kin.rot[i];
                kin.wpos[i] = kin.pos[i];
            }
            Some(p) => {
                kin.wrot[i] = kin.wrot[p] * kin.rot[i];
                kin.wpos[i] = kin.wpos[p] + kin.wrot[p] * kin.pos[i];
            }
        }
    }
}

/// World position and orientation of a frame, given a `kin` filled by [`forward_kinematics`].
pub fn frame_position<T: Real>(kin: &Kin<T>, frame: &Frame) -> (Vector3<T>, Matrix3<T>) {
    let pr = frame.placement.rotation.to_rotation_matrix().into_inner();
    let pp = frame.placement.translation.vector;
    match frame.link {
        None => (lift3(&pp), lift33(&pr)),
        Some(l) => (kin.wpos[l] + kin.wrot[l] * lift3::<T>(&pp), kin.wrot[l] * lift33::<T>(&pr)),
    }
}

fn to_iso(p: &Vector3<f64>, r: &Matrix3<f64>) -> Isometry3<f64> {
    let rot = UnitQuaternion::from_matrix(r);
    Isometry3::from_parts(Translation3::from(*p), rot)
}

/// World pose of every link (f64 convenience over [`forward_kinematics`]).
pub fn link_poses(robot: &Robot, ws: &mut super::Workspace, q: &[f64]) -> Vec<Isometry3<f64>> {
    forward_kinematics(robot, q, &mut ws.kin);
    (0..robot.dof()).map(|i| to_iso(&ws.kin.wpos[i], &ws.kin.wrot[i])).collect()
}

/// World pose of a frame at configuration `q`.
pub fn frame_pose(robot: &Robot, ws: &mut super::Workspace, q: &[f64], frame: &Frame) -> Isometry3<f64> {
    forward_kinematics(robot, q, &mut ws.kin);
    let (p, r) = frame_position(&ws.kin, frame);
    to_iso(&p, &r)
}

/// Geometric Jacobian of a frame in world coordinates: 6×n, rows 0..3 the
/// linear velocity of the frame origin, rows 3..6 the angular velocity.
pub fn frame_jacobian(robot: &Robot, ws: &mut super::Workspace, q: &[f64], frame: &Frame) -> nalgebra::Matrix6xX<f64> {
    forward_kinematics(robot, q, &mut ws.kin);
    let (pf, _) = frame_position(&ws.kin, frame);
    let n = robot.dof();
    let mut jac = nalgebra::Matrix6xX::zeros(n);
    // joint j moves the frame iff link j is the frame's link or one of its ancestors
    let mut on_path = vec![false; n];
    let mut cur = frame.link;
    while let Some(l) = cur {
        on_path[l] = true;
        cur = robot.joints[l].parent;
    }
    for j in 0..n {
        if !on_path[j] {
            continue;
        }
        // motion subspace of joint j in world coordinates, at link j's origin
        let wa = ws.kin.wrot[j] * robot.s_ang[j];
        let wl = ws.kin.wrot[j] * robot.s_lin[j];
        // velocity of the frame point: v_O + ω × (p_f − p_j)
        let lin = wl + wa.cross(&(pf - ws.kin.wpos[j]));
        jac.fixed_view_mut::<3, 1>(0, j).copy_from(&lin);
        jac.fixed_view_mut::<3, 1>(3, j).copy_from(&wa);
    }
    jac
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The coordinate-axis shortcut equals the general Rodrigues formula and
    /// 3×3 product to 1e-15, for ±e_x, ±e_y, ±e_z, placements of the shipped
    /// robots and random angles, in f64 and in the dual numbers (value and
    /// derivative).
    #[test]
    fn coordinate_axis_rotation_equals_the_general_product() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut placements = vec![Matrix3::identity()];
        for f in ["ur5", "panda", "iiwa14", "puma560", "industrial6"] {
            let r = crate::robot::load(&root.join(format!("designs/robots/{f}.toml"))).unwrap();
            placements.extend(r.geo.iter().map(|g| g.pl_r));
        }
        let mut checked = 0;
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                let mut a = Vector3::zeros();
                a[k] = sign;
                assert_eq!(coordinate_axis(&a), Some((k, sign)));
                for p in &placements {
                    for t in 0..50 {
                        let th = -3.5 + 0.1437 * t as f64;
                        let got = placed_rotation_axis(p, k, sign, th);
                        let want = p * axis_angle(&a, th);
                        assert!((got - want).amax() <= 1e-15, "axis {a:?} at {th}: {got} vs {want}");
                        let gd = placed_rotation_axis(p, k, sign, Dual64::new(th, 1.0));
                        let wd = lift33::<Dual64>(p) * axis_angle(&a, Dual64::new(th, 1.0));
                        for (x, y) in gd.iter().zip(wd.iter()) {
                            assert!((x.re - y.re).abs() <= 1e-15 && (x.eps - y.eps).abs() <= 1e-15, "dual, axis {a:?} at {th}");
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1000);
        assert_eq!(coordinate_axis(&Vector3::new(0.6, 0.8, 0.0)), None);
    }
}
