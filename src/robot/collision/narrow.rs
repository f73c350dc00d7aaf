//! The narrow phase: bounding capsules and spheres, support-function bounds,
//! and the exact signed distance between two bodies (GJK/EPA or hill climbing).

use super::hull::Climbing;
use super::shape::{Body, ConvexPart};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::HalfSpace;

/// Which narrow phase computes the exact distances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NarrowPhase {
    /// parry's GJK/EPA with support points of convex hulls by hill climbing
    /// on their vertex adjacency ([`ClimbHull`](super::ClimbHull); default).
    #[default]
    Climb,
    /// parry's `query::contact` as it is: support points by a scan over every
    /// hull vertex (the reference the climbing is tested against).
    Scan,
}

/// A capsule enclosing a convex part: the points within `r` of the segment [a, b].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct BoundCapsule {
    pub(super) a: Point3<f64>,
    pub(super) b: Point3<f64>,
    pub(super) r: f64,
}

impl BoundCapsule {
    pub(super) fn moved(&self, x: &Isometry3<f64>) -> BoundCapsule {
        BoundCapsule {
            a: x * self.a,
            b: x * self.b,
            r: self.r,
        }
    }

    /// The tightest capsule about the principal axis of `pts` that holds every
    /// point: radius the largest distance from the axis, the segment as short
    /// as that radius allows (every point within r of it).
    pub(super) fn enclosing(pts: &[Point3<f64>]) -> Option<BoundCapsule> {
        if pts.is_empty() {
            return None;
        }
        let nf = pts.len() as f64;
        let c = pts.iter().fold(Vector3::zeros(), |acc, p| acc + p.coords) / nf;
        let mut cov = Matrix3::zeros();
        for p in pts {
            let d = p.coords - c;
            cov += d * d.transpose();
        }
        let eig = nalgebra::SymmetricEigen::new(cov / nf);
        let imax = eig.eigenvalues.imax();
        let u: Vector3<f64> = eig.eigenvectors.column(imax).into_owned();
        let un = u.norm();
        if !(un.is_finite() && un > 0.0) {
            return None;
        }
        let u = u / un;
        let axial: Vec<(f64, f64)> = pts
            .iter()
            .map(|p| {
                let d = p.coords - c;
                let s = d.dot(&u);
                (s, (d - u * s).norm())
            })
            .collect();
        let rho = axial.iter().fold(0.0f64, |m, v| m.max(v.1));
        let span = axial.iter().fold(0.0f64, |m, v| m.max(v.0.abs())) + rho;
        // padded against rounding (the bound is used with the broad phase's tolerance)
        let r = rho + 1e-12 * (1.0 + span);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (s, rh) in &axial {
            let w = (r * r - rh * rh).max(0.0).sqrt();
            hi = hi.max(s - w);
            lo = lo.min(s + w);
        }
        if lo > hi {
            // every point lies within r of any axial position in [hi, lo]
            let m = 0.5 * (lo + hi);
            lo = m;
            hi = m;
        }
        let cp = Point3::from(c);
        let cap = BoundCapsule {
            a: cp + u * lo,
            b: cp + u * hi,
            r,
        };
        cap.r.is_finite().then_some(cap)
    }
}

/// Closest distance between the segments [p1, q1] and [p2, q2] (Ericson,
/// *Real-Time Collision Detection*, §5.1.9).
fn segment_distance(p1: &Point3<f64>, q1: &Point3<f64>, p2: &Point3<f64>, q2: &Point3<f64>) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let tiny = 1e-300;
    let (s, t) = if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let den = a * e - b * b;
            let mut s = if den > 0.0 { ((b * f - c * e) / den).clamp(0.0, 1.0) } else { 0.0 };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

/// Signed distance between two bodies with its witness points (world frame)
/// and the unit normal from the first body toward the second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Signed distance (m): negative when the bodies overlap (penetration depth).
    pub distance: f64,
    /// Witness point on the first body (world frame).
    pub p1: Point3<f64>,
    /// Witness point on the second body (world frame).
    pub p2: Point3<f64>,
    /// Unit normal from the first body toward the second (world frame).
    pub normal: Vector3<f64>,
}

/// Lower bound on the distance between two parts from their bounding spheres
/// (or the plane), in the world frame, paddings included.
pub(super) fn part_lower_bound(a: &ConvexPart, xa: &Isometry3<f64>, b: &ConvexPart, xb: &Isometry3<f64>) -> f64 {
    shape_lower_bound(a, xa, b, xb) - a.pad - b.pad
}

/// [`part_lower_bound`] of the shapes without their paddings.
fn shape_lower_bound(a: &ConvexPart, xa: &Isometry3<f64>, b: &ConvexPart, xb: &Isometry3<f64>) -> f64 {
    match (&a.halfspace, &b.halfspace) {
        (None, None) => ((xa * a.centre) - (xb * b.centre)).norm() - a.radius - b.radius,
        (Some((n, off)), None) => {
            let (n, off) = world_plane(xa, n, *off);
            n.dot(&(xb * b.centre).coords) - off - b.radius
        }
        (None, Some((n, off))) => {
            let (n, off) = world_plane(xb, n, *off);
            n.dot(&(xa * a.centre).coords) - off - a.radius
        }
        (Some(_), Some(_)) => f64::NEG_INFINITY,
    }
}

/// Lower bound on the signed distance between two parts from their bounding
/// capsules (or the plane), in the world frame, paddings included; −∞ when a
/// part has none.
pub(super) fn part_capsule_bound(a: &ConvexPart, xa: &Isometry3<f64>, b: &ConvexPart, xb: &Isometry3<f64>) -> f64 {
    shape_capsule_bound(a, xa, b, xb) - a.pad - b.pad
}

/// [`part_capsule_bound`] of the shapes without their paddings.
fn shape_capsule_bound(a: &ConvexPart, xa: &Isometry3<f64>, b: &ConvexPart, xb: &Isometry3<f64>) -> f64 {
    let plane_bound = |hp: &ConvexPart, xh: &Isometry3<f64>, cp: &BoundCapsule, xc: &Isometry3<f64>| -> f64 {
        let Some((n, off)) = &hp.halfspace else {
            return f64::NEG_INFINITY;
        };
        let (n, off) = world_plane(xh, n, *off);
        let (pa, pb) = (xc * cp.a, xc * cp.b);
        n.dot(&pa.coords).min(n.dot(&pb.coords)) - off - cp.r
    };
    match (&a.capsule, &b.capsule) {
        (Some(ca), Some(cb)) => segment_distance(&(xa * ca.a), &(xa * ca.b), &(xb * cb.a), &(xb * cb.b)) - ca.r - cb.r,
        (None, Some(cb)) => plane_bound(a, xa, cb, xb),
        (Some(ca), None) => plane_bound(b, xb, ca, xa),
        (None, None) => f64::NEG_INFINITY,
    }
}

pub(super) fn world_plane(x: &Isometry3<f64>, n: &Vector3<f64>, off: f64) -> (Vector3<f64>, f64) {
    let nw = x.rotation * n;
    (nw, off + nw.dot(&x.translation.vector))
}

/// Signed distance of two convex parts at world poses, if below `cap`
/// (paddings included: the shapes' distance less both paddings, the witness
/// points moved onto the grown surfaces along the normal).
/// `sep` receives, when GJK proves the parts farther apart than `cap`, its
/// separating direction (world frame, from `a` toward `b`; see
/// [`CollisionScene::pair_query`]); the result itself does not depend on it.
fn part_proximity(
    a: &ConvexPart,
    xa: &Isometry3<f64>,
    b: &ConvexPart,
    xb: &Isometry3<f64>,
    cap: f64,
    np: NarrowPhase,
    sep: &mut Option<Vector3<f64>>,
) -> Option<Proximity> {
    if part_lower_bound(a, xa, b, xb) > cap {
        return None;
    }
    let pa = xa * a.local;
    let pb = xb * b.local;
    let off = a.pad + b.pad;
    let pred = (cap + off).max(0.0);
    // parry 0.25's (support map, half-space) contact measures from the wrong
    // side (found by tests/collision.rs); the (half-space, support map) order
    // is right, so a half-space always goes first and the result is flipped.
    let c = match np {
        NarrowPhase::Scan => {
            if b.halfspace.is_some() && a.halfspace.is_none() {
                query::contact(&pb, &*b.shape, &pa, &*a.shape, pred).ok()??.flipped()
            } else {
                query::contact(&pa, &*a.shape, &pb, &*b.shape, pred).ok()??
            }
        }
        NarrowPhase::Climb => {
            if b.halfspace.is_some() && a.halfspace.is_none() {
                climb_contact(&pb, b, &pa, a, pred, &mut None)?.flipped()
            } else {
                climb_contact(&pa, a, &pb, b, pred, sep)?
            }
        }
    };
    if c.dist - off > cap {
        return None;
    }
    let normal = c.normal1.into_inner();
    Some(Proximity {
        distance: c.dist - off,
        p1: c.point1 + normal * a.pad,
        p2: c.point2 - normal * b.pad,
        normal,
    })
}

/// `query::contact` with the same dispatch as parry's default query
/// dispatcher for the shapes of a collision model (half-space first, balls
/// by their special cases, every other pair by GJK/EPA on support maps), the
/// support points of convex hulls by hill climbing ([`ClimbHull`]).
///
/// Between two hulls the contact is that of parry's
/// `contact_support_map_support_map` (the same GJK/EPA call and result
/// mapping), and when GJK proves the distance above `pred` its separating
/// direction goes to `sep` (world frame).
fn climb_contact(
    p1: &Isometry3<f64>,
    a: &ConvexPart,
    p2: &Isometry3<f64>,
    b: &ConvexPart,
    pred: f64,
    sep: &mut Option<Vector3<f64>>,
) -> Option<query::Contact> {
    use parry3d_f64::query::details::{contact_halfspace_support_map, contact_support_map_support_map, contact_support_map_support_map_with_params};
    use parry3d_f64::query::gjk::{GJKResult, VoronoiSimplex};
    let (Some(ha), Some(hb)) = (&a.climb, &b.climb) else {
        if (a.climb.is_none() && b.climb.is_none()) || a.shape.as_ball().is_some() || b.shape.as_ball().is_some() {
            return query::contact(p1, &*a.shape, p2, &*b.shape, pred).ok()?;
        }
        let pos12 = p1.inv_mul(p2);
        let mut c = if let Some(hs) = a.shape.as_shape::<HalfSpace>() {
            let hb = b.climb.as_deref()?;
            contact_halfspace_support_map(&pos12, hs, &Climbing::new(hb), pred)?
        } else if let Some(ha) = &a.climb {
            contact_support_map_support_map(&pos12, &Climbing::new(ha), b.shape.as_support_map()?, pred)?
        } else {
            let hb = b.climb.as_deref()?;
            contact_support_map_support_map(&pos12, a.shape.as_support_map()?, &Climbing::new(hb), pred)?
        };
        c.transform_by_mut(p1, p2);
        return Some(c);
    };
    let pos12 = p1.inv_mul(p2);
    let simplex = &mut VoronoiSimplex::new();
    match contact_support_map_support_map_with_params(&pos12, &Climbing::new(ha), &Climbing::new(hb), pred, simplex, None) {
        GJKResult::ClosestPoints(point1, point2_1, normal1) => {
            let dist = (point2_1 - point1).dot(&normal1);
            let point2 = pos12.inverse_transform_point(&point2_1);
            let normal2 = pos12.inverse_transform_unit_vector(&-normal1);
            let mut c = query::Contact::new(point1, point2, normal1, normal2, dist);
            c.transform_by_mut(p1, p2);
            Some(c)
        }
        GJKResult::NoIntersection(dir) => {
            *sep = Some(p1.rotation * dir.into_inner());
            None
        }
        // parry never returns these from this call (its wrapper: unreachable)
        GJKResult::Intersection | GJKResult::Proximity(_) => None,
    }
}

/// Signed distance between bodies `a` and `b` at world poses `xa`, `xb`:
/// the closest pair of parts, or `None` if every pair is farther than `cap`
/// (then the capped distance is `cap`). Bodies without shapes never collide.
pub fn proximity(a: &Body, xa: &Isometry3<f64>, b: &Body, xb: &Isometry3<f64>, cap: f64) -> Option<Proximity> {
    proximity_with(a, xa, b, xb, cap, NarrowPhase::default())
}

/// [`proximity`] with a chosen narrow phase.
pub fn proximity_with(a: &Body, xa: &Isometry3<f64>, b: &Body, xb: &Isometry3<f64>, cap: f64, np: NarrowPhase) -> Option<Proximity> {
    proximity_sep(a, xa, b, xb, cap, np, &mut None)
}

/// [`proximity_with`], with a separating direction (world frame, `a` toward
/// `b`) into `sep` when GJK proves a pair of parts beyond its cap.
pub(super) fn proximity_sep(
    a: &Body,
    xa: &Isometry3<f64>,
    b: &Body,
    xb: &Isometry3<f64>,
    cap: f64,
    np: NarrowPhase,
    sep: &mut Option<Vector3<f64>>,
) -> Option<Proximity> {
    let mut best: Option<Proximity> = None;
    let mut lim = cap;
    for pa in &a.parts {
        for pb in &b.parts {
            if let Some(p) = part_proximity(pa, xa, pb, xb, lim, np, sep) {
                if best.is_none_or(|b| p.distance < b.distance) {
                    lim = p.distance.max(0.0).min(lim);
                    best = Some(p);
                }
            }
        }
    }
    best
}
