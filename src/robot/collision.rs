//! Collision geometry: convex shapes fixed to the robot's bodies and to the
//! world, signed distances between them, their witness points and normals.
//!
//! A body (the fixed base, a moving link, an obstacle of the cell) is a set of
//! convex parts, each a [parry3d](https://parry.rs) shape at a fixed pose in
//! the body frame: URDF `<collision>` primitives (box, cylinder, sphere,
//! capsule) as they are, meshes (STL) as their convex hull, or as a convex
//! decomposition (V-HACD) where one hull is too coarse.
//!
//! **Why parry3d-f64 0.25.** It is the maintained geometry crate of the Rust
//! ecosystem (dimforge: GJK/EPA distance and penetration for any pair of
//! convex shapes, convex hulls, V-HACD), in double precision, and 0.25 is its
//! last release on nalgebra 0.34 — the version idexp pins — so poses and
//! points cross the boundary without conversion (0.26 and later moved to glam).
//!
//! **Distance.** For two bodies A, B at poses X_A, X_B the signed distance is
//! d = min over part pairs of the GJK distance, negative (the penetration
//! depth, EPA) when the parts overlap. With the witness points p_A, p_B
//! (world frame) and the unit normal n from A to B, d = nᵀ(p_B − p_A), and when
//! A and B move rigidly, ḋ = nᵀ(v_B(p_B) − v_A(p_A)): the gradient of a
//! distance with respect to the joint positions is nᵀ(J_B(p_B) − J_A(p_A)),
//! J the point Jacobian of the witness point fixed on its body.
//!
//! **Cap.** Queries take a cap c: a pair farther apart than c reports c
//! (d̃ = min(d, c)), which lets a bounding-sphere test skip exact queries
//! without changing any value at or below the cap.
//!
//! **Support-function bound.** For convex A, B and any unit m,
//! sd(A, B) ≥ min_{b∈B} mᵀb − max_{a∈A} mᵀa = −h_B(−m) − h_A(m) (h the
//! support function), with equality at the normal of the closest (or
//! deepest) points. Along a sampled path the normal of the previous exact
//! query (kept in the first body's frame), or the separating direction with
//! which GJK proved a pair beyond its cap, gives a lower bound that is
//! within second order of the normal's turn of the distance, for the price
//! of two support points (hill climbing from the previous ones) instead of a
//! GJK/EPA query ([`CollisionScene::pair_support_bound`]). Against a
//! half-space the bound is its normal's (the signed distance itself). The
//! bound only decides where an exact query is needed: every value reported
//! is still an exact query's (or the cap).

use crate::error::{Error, Result};
use crate::robot::kinematics::Kin;
use crate::robot::model::Robot;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::{HalfSpace, SharedShape, SupportMap};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A shape as a robot or design file describes it, in the body frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Primitive {
    /// Box with full side lengths (m), centred on its origin.
    Box {
        /// Side lengths along x, y, z (m).
        size: [f64; 3],
    },
    /// Cylinder along its z axis, centred (m).
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length along z (m).
        length: f64,
    },
    /// Sphere (m).
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// Capsule: a cylinder of `length` along z with hemispherical caps (m).
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part along z (m).
        length: f64,
    },
    /// A triangle mesh (STL, OBJ or Collada, [`read_mesh`]) scaled per axis;
    /// used as its convex hull or convex decomposition.
    Mesh {
        /// Resolved file path.
        path: PathBuf,
        /// Scale factors along x, y, z.
        scale: [f64; 3],
    },
    /// The half-space below a plane: points x with nᵀx ≤ offset are inside
    /// (obstacles only: floor, walls).
    HalfSpace {
        /// Outward unit normal (pointing to the free side).
        normal: [f64; 3],
        /// Offset of the plane along the normal (m).
        offset: f64,
    },
}

/// How a mesh becomes convex parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MeshMode {
    /// One convex hull per mesh (default: conservative, fast).
    #[default]
    Hull,
    /// Approximate convex decomposition (V-HACD), for concave links where the
    /// hull would report contacts that do not exist.
    Decomposition,
}

/// One shape of a body, with its pose in the body frame.
#[derive(Debug, Clone, PartialEq)]
pub struct GeometrySpec {
    /// The shape.
    pub primitive: Primitive,
    /// Pose of the shape in the body frame.
    pub origin: Isometry3<f64>,
}

/// A convex part of a body, ready for distance queries.
#[derive(Clone)]
pub struct ConvexPart {
    shape: SharedShape,
    local: Isometry3<f64>,
    /// Bounding-sphere centre (body frame) and radius; radius ∞ for half-spaces.
    centre: Point3<f64>,
    radius: f64,
    halfspace: Option<(Vector3<f64>, f64)>,
    /// Bounding capsule (body frame) for the broad phase; `None` for half-spaces.
    capsule: Option<BoundCapsule>,
    /// Vertex adjacency of a convex polyhedron, for support points by hill climbing.
    climb: Option<std::sync::Arc<ClimbHull>>,
    /// Padding (m): the part is its shape grown by a ball of this radius
    /// (the Minkowski sum), so every distance to it is the shape's less `pad`
    /// and its support function is the shape's plus `pad` (both exact).
    pad: f64,
}

/// A convex polyhedron's vertices with their adjacency on its boundary
/// (the edges of a triangulation of its faces): support points by hill
/// climbing instead of a scan over every vertex.
///
/// **Why it is exact.** On a triangulated convex surface, a vertex v none of
/// whose neighbours has a larger dᵀx is a maximiser of dᵀx over the whole
/// polyhedron P, except when v lies inside a face and d points into P along
/// that face's normal: the incident triangles cover v's neighbourhood in ∂P,
/// so at a corner or on an edge the cone of the edge directions from v is the
/// tangent cone of P at v, which holds P − v. Climbing moves only to strictly
/// better neighbours, so it never reaches such a face-interior vertex as a
/// false maximum; it starts at a vertex that is not one (a seed, or the
/// previous support vertex of the same query when that is not inside a face).
/// The support value is the scan's to rounding (tested on every shipped hull
/// against the scan for random directions).
#[derive(Debug, Clone)]
pub struct ClimbHull {
    pts: Vec<Point3<f64>>,
    /// CSR adjacency: neighbours of vertex i are `adj[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    adj: Vec<u32>,
    /// Start vertices: the best vertex (not inside a face) along 14 fixed directions.
    seeds: Vec<u32>,
    /// Vertices inside a face (all incident triangles coplanar): never a start.
    flat: Vec<bool>,
    /// Vertices of the polyhedron outside the triangulation (normally none): scanned.
    orphans: Vec<Point3<f64>>,
}

impl ClimbHull {
    /// From the vertices of a convex polyhedron: the triangulation of their
    /// convex hull (parry's, the one `SharedShape::convex_hull` builds the
    /// polyhedron from) gives the adjacency; a vertex the triangulation does
    /// not use is kept aside and scanned at every support call.
    pub fn new(points: &[Point3<f64>]) -> Option<ClimbHull> {
        let (pts, tris) = parry3d_f64::transformation::try_convex_hull(points).ok()?;
        let orphans: Vec<Point3<f64>> = points.iter().filter(|p| !pts.contains(p)).copied().collect();
        let nv = pts.len();
        if nv == 0 || tris.is_empty() {
            return None;
        }
        let mut nb: Vec<Vec<u32>> = vec![Vec::new(); nv];
        // incident triangle normals: a vertex all of whose triangles are coplanar lies inside a face
        let mut normals: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); nv];
        for t in &tris {
            let [a, b, c] = t.map(|i| i as usize);
            if a >= nv || b >= nv || c >= nv {
                return None;
            }
            let n = (pts[b] - pts[a]).cross(&(pts[c] - pts[a]));
            let nn = n.norm();
            for (i, j) in [(a, b), (b, c), (c, a)] {
                nb[i].push(j as u32);
                nb[j].push(i as u32);
            }
            if nn > 0.0 {
                for i in [a, b, c] {
                    normals[i].push(n / nn);
                }
            }
        }
        let mut start = Vec::with_capacity(nv + 1);
        let mut adj = Vec::new();
        for l in &mut nb {
            l.sort_unstable();
            l.dedup();
            start.push(adj.len() as u32);
            adj.extend_from_slice(l);
        }
        start.push(adj.len() as u32);
        let face_interior = |i: usize| -> bool {
            let ns = &normals[i];
            nb[i].is_empty() || ns.is_empty() || ns.iter().all(|n| (n - ns[0]).norm() < 1e-9)
        };
        let usable: Vec<usize> = (0..nv).filter(|&i| !face_interior(i)).collect();
        if usable.is_empty() {
            return None;
        }
        let mut seeds = Vec::new();
        for d in seed_directions() {
            let mut best = usable[0];
            for &i in &usable {
                if pts[i].coords.dot(&d) > pts[best].coords.dot(&d) {
                    best = i;
                }
            }
            if !seeds.contains(&(best as u32)) {
                seeds.push(best as u32);
            }
        }
        let flat = (0..nv).map(face_interior).collect();
        Some(ClimbHull {
            pts,
            start,
            adj,
            seeds,
            flat,
            orphans,
        })
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    /// True without vertices (never for a built hull).
    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// The vertices of the triangulation.
    pub fn points(&self) -> &[Point3<f64>] {
        &self.pts
    }

    /// The polyhedron's vertices outside the triangulation (scanned at every support call).
    pub fn orphans(&self) -> &[Point3<f64>] {
        &self.orphans
    }

    /// Index of the best seed along `dir`.
    fn seed(&self, dir: &Vector3<f64>) -> u32 {
        let mut best = self.seeds[0];
        let mut bv = self.pts[best as usize].coords.dot(dir);
        for &s in &self.seeds[1..] {
            let v = self.pts[s as usize].coords.dot(dir);
            if v > bv {
                bv = v;
                best = s;
            }
        }
        best
    }

    /// A vertex maximising dᵀx, climbing from vertex `from` (steepest ascent
    /// over the neighbours, strict improvements only).
    pub fn support_from(&self, dir: &Vector3<f64>, from: u32) -> u32 {
        let mut v = from as usize;
        let mut best = self.pts[v].coords.dot(dir);
        loop {
            let mut next = v;
            for &u in &self.adj[self.start[v] as usize..self.start[v + 1] as usize] {
                let d = self.pts[u as usize].coords.dot(dir);
                if d > best {
                    best = d;
                    next = u as usize;
                }
            }
            if next == v {
                return v as u32;
            }
            v = next;
        }
    }

    /// A vertex maximising dᵀx, climbing from the best seed.
    pub fn support_index(&self, dir: &Vector3<f64>) -> u32 {
        self.support_from(dir, self.seed(dir))
    }

    /// The support point along `dir`: vertex `v` (a climb's result) or a
    /// vertex outside the triangulation if that is farther along `dir`.
    pub fn support_point(&self, dir: &Vector3<f64>, v: u32) -> Point3<f64> {
        let mut best = self.pts[v as usize];
        let mut bv = best.coords.dot(dir);
        for p in &self.orphans {
            let d = p.coords.dot(dir);
            if d > bv {
                bv = d;
                best = *p;
            }
        }
        best
    }
}

/// The 14 seed directions of [`ClimbHull`]: the axes and the cube diagonals,
/// slightly tilted (ties between coplanar vertices are then unlikely).
fn seed_directions() -> Vec<Vector3<f64>> {
    let mut v = Vec::with_capacity(14);
    for a in 0..3 {
        for s in [-1.0, 1.0] {
            let mut d = Vector3::new(0.013, 0.007, 0.011);
            d[a] = s;
            v.push(d);
        }
    }
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                v.push(Vector3::new(sx * 1.013, sy * 0.993, sz * 1.007));
            }
        }
    }
    v
}

/// A [`ClimbHull`] as a parry support map for one query: each support call
/// climbs from the previous call's vertex (GJK's directions change little
/// from one iteration to the next), the first from the best seed.
struct Climbing<'a> {
    hull: &'a ClimbHull,
    last: std::cell::Cell<Option<u32>>,
}

impl<'a> Climbing<'a> {
    fn new(hull: &'a ClimbHull) -> Self {
        Climbing {
            hull,
            last: std::cell::Cell::new(None),
        }
    }
}

impl SupportMap for Climbing<'_> {
    fn local_support_point(&self, dir: &Vector3<f64>) -> Point3<f64> {
        let from = match self.last.get() {
            Some(v) if !self.hull.flat[v as usize] => v,
            _ => self.hull.seed(dir),
        };
        let v = self.hull.support_from(dir, from);
        self.last.set(Some(v));
        self.hull.support_point(dir, v)
    }
}

/// Which narrow phase computes the exact distances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NarrowPhase {
    /// parry's GJK/EPA with support points of convex hulls by hill climbing
    /// on their vertex adjacency ([`ClimbHull`]; default).
    #[default]
    Climb,
    /// parry's `query::contact` as it is: support points by a scan over every
    /// hull vertex (the reference the climbing is tested against).
    Scan,
}

/// A capsule enclosing a convex part: the points within `r` of the segment [a, b].
#[derive(Debug, Clone, Copy, PartialEq)]
struct BoundCapsule {
    a: Point3<f64>,
    b: Point3<f64>,
    r: f64,
}

impl BoundCapsule {
    fn moved(&self, x: &Isometry3<f64>) -> BoundCapsule {
        BoundCapsule {
            a: x * self.a,
            b: x * self.b,
            r: self.r,
        }
    }

    /// The tightest capsule about the principal axis of `pts` that holds every
    /// point: radius the largest distance from the axis, the segment as short
    /// as that radius allows (every point within r of it).
    fn enclosing(pts: &[Point3<f64>]) -> Option<BoundCapsule> {
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

impl ConvexPart {
    /// The support function h(d) = max over the part of dᵀx in the world
    /// frame, the body at `x` (`d` a unit vector); +∞ for a half-space.
    /// A hull's support vertex is climbed from `start` (a previous call's
    /// vertex, unless that lies inside a face or is `u32::MAX`: then from the
    /// best seed), and `start` becomes the new support vertex.
    fn world_support(&self, x: &Isometry3<f64>, d: &Vector3<f64>, start: &mut u32) -> f64 {
        if self.halfspace.is_some() {
            return f64::INFINITY;
        }
        self.pad + self.shape_support(x, d, start)
    }

    /// [`Self::world_support`] of the shape without its padding.
    fn shape_support(&self, x: &Isometry3<f64>, d: &Vector3<f64>, start: &mut u32) -> f64 {
        let pose = x * self.local;
        let dl = pose.rotation.inverse_transform_vector(d);
        let local = if let Some(h) = &self.climb {
            let from = match h.flat.get(*start as usize) {
                Some(false) => *start,
                _ => h.seed(&dl),
            };
            let v = h.support_from(&dl, from);
            *start = v;
            h.support_point(&dl, v).coords.dot(&dl)
        } else if let Some(sm) = self.shape.as_support_map() {
            sm.local_support_point(&dl).coords.dot(&dl)
        } else {
            return f64::INFINITY;
        };
        local + d.dot(&pose.translation.vector)
    }
}

impl std::fmt::Debug for ConvexPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ConvexPart")
            .field("shape", &self.shape.shape_type())
            .field("local", &self.local)
            .field("radius", &self.radius)
            .finish()
    }
}

/// A rigid body of the collision model: its name and convex parts.
#[derive(Debug, Clone)]
pub struct Body {
    /// Name (URDF link, obstacle or attached-shape name).
    pub name: String,
    parts: Vec<ConvexPart>,
}

impl Body {
    /// Adds the parts of `other` (given in `other`'s frame) placed at `at` in this body's frame.
    pub fn merge(&mut self, other: &Body, at: &Isometry3<f64>) {
        for p in &other.parts {
            let mut q = p.clone();
            q.local = at * p.local;
            q.centre = at * p.centre;
            q.capsule = p.capsule.map(|c| c.moved(at));
            if let Some((n, off)) = p.halfspace {
                let nw = at.rotation * n;
                q.halfspace = Some((nw, off + nw.dot(&at.translation.vector)));
            }
            self.parts.push(q);
        }
    }

    /// Grows every bounded part by a ball of radius `pad` (m; the largest
    /// padding given wins): distances to the body become those of the
    /// grown shapes (see [`RobotGeometry`] and the robot file's
    /// `collision_padding`).
    pub fn pad_parts(&mut self, pad: f64) {
        for p in self.parts.iter_mut().filter(|p| p.halfspace.is_none()) {
            p.pad = p.pad.max(pad);
        }
    }

    /// The largest padding of the body's parts (m).
    pub fn padding(&self) -> f64 {
        self.parts.iter().map(|p| p.pad).fold(0.0, f64::max)
    }

    /// True if the body contains an unbounded part (a half-space).
    pub fn is_unbounded(&self) -> bool {
        self.parts.iter().any(|p| p.halfspace.is_some())
    }
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

pub use super::resolve::{read_mesh, MeshData};

fn rot_y_to_z() -> UnitQuaternion<f64> {
    // parry's cylinders are along y; URDF's along z: rotate y onto z.
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
}

fn part(shape: SharedShape, local: Isometry3<f64>) -> ConvexPart {
    let bs = shape.compute_local_bounding_sphere();
    let capsule = bound_capsule(&shape).map(|c| c.moved(&local));
    let climb = shape.as_convex_polyhedron().and_then(|c| ClimbHull::new(c.points())).map(std::sync::Arc::new);
    ConvexPart {
        centre: local * bs.center(),
        radius: bs.radius(),
        shape,
        local,
        halfspace: None,
        capsule,
        climb,
        pad: 0.0,
    }
}

/// A capsule holding `shape` (shape frame): the shape itself for balls and
/// capsules, the axis for cylinders, the principal-axis capsule of the
/// vertices for boxes and convex hulls.
fn bound_capsule(shape: &SharedShape) -> Option<BoundCapsule> {
    if let Some(b) = shape.as_ball() {
        let o = Point3::origin();
        return Some(BoundCapsule { a: o, b: o, r: b.radius });
    }
    if let Some(c) = shape.as_capsule() {
        return Some(BoundCapsule {
            a: c.segment.a,
            b: c.segment.b,
            r: c.radius,
        });
    }
    if let Some(c) = shape.as_cylinder() {
        // parry's cylinders are along y: the rim is at distance `radius` from the axis' end points
        let h = c.half_height;
        return Some(BoundCapsule {
            a: Point3::new(0.0, -h, 0.0),
            b: Point3::new(0.0, h, 0.0),
            r: c.radius * (1.0 + 1e-12),
        });
    }
    if let Some(c) = shape.as_cuboid() {
        let h = c.half_extents;
        let mut v = Vec::with_capacity(8);
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    v.push(Point3::new(sx * h.x, sy * h.y, sz * h.z));
                }
            }
        }
        return BoundCapsule::enclosing(&v);
    }
    shape.as_convex_polyhedron().and_then(|c| BoundCapsule::enclosing(c.points()))
}

fn positive(ctx: &str, what: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(ctx, what, format!("{v} must be positive and finite")))
    }
}

impl Body {
    /// Builds a body from its shapes. `ctx` names the file and element for
    /// messages (e.g. `ur5.urdf: link `forearm_link` collision 1`).
    pub fn new(name: &str, specs: &[GeometrySpec], mode: MeshMode, ctx: &str) -> Result<Body> {
        let mut parts = Vec::with_capacity(specs.len());
        for (k, s) in specs.iter().enumerate() {
            let here = format!("{ctx}: `{name}` shape {}", k + 1);
            let o = s.origin;
            match &s.primitive {
                Primitive::Box { size } => {
                    for (a, v) in ["x", "y", "z"].iter().zip(size) {
                        positive(&here, &format!("box size {a}"), *v)?;
                    }
                    parts.push(part(SharedShape::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0), o));
                }
                Primitive::Cylinder { radius, length } => {
                    positive(&here, "cylinder radius", *radius)?;
                    positive(&here, "cylinder length", *length)?;
                    let local = o * Isometry3::from_parts(Translation3::identity(), rot_y_to_z());
                    parts.push(part(SharedShape::cylinder(length / 2.0, *radius), local));
                }
                Primitive::Sphere { radius } => {
                    positive(&here, "sphere radius", *radius)?;
                    parts.push(part(SharedShape::ball(*radius), o));
                }
                Primitive::Capsule { radius, length } => {
                    positive(&here, "capsule radius", *radius)?;
                    if !(length.is_finite() && *length >= 0.0) {
                        return Err(Error::invalid(&here, "capsule length", format!("{length} must be ≥ 0 and finite")));
                    }
                    parts.push(part(SharedShape::capsule_z(length / 2.0, *radius), o));
                }
                Primitive::Mesh { path, scale } => {
                    for (a, v) in ["x", "y", "z"].iter().zip(scale) {
                        if !(v.is_finite() && *v != 0.0) {
                            return Err(Error::invalid(&here, format!("mesh scale {a}"), format!("{v} must be finite and non-zero")));
                        }
                    }
                    let (pts, tris) = read_mesh(path, *scale).map_err(|e| Error::invalid(&here, "mesh", e.to_string()))?;
                    match mode {
                        MeshMode::Hull => {
                            let hull = SharedShape::convex_hull(&pts).ok_or_else(|| {
                                Error::invalid(
                                    &here,
                                    "mesh",
                                    format!("{}: the vertices are flat or degenerate: no convex hull", path.display()),
                                )
                            })?;
                            parts.push(part(hull, o));
                        }
                        MeshMode::Decomposition => {
                            let dec = SharedShape::convex_decomposition(&pts, &tris);
                            let compound = dec.as_compound().ok_or_else(|| Error::invalid(&here, "mesh", "convex decomposition failed"))?;
                            for (iso, sh) in compound.shapes() {
                                parts.push(part(sh.clone(), o * iso));
                            }
                        }
                    }
                }
                Primitive::HalfSpace { normal, offset } => {
                    let n = Vector3::from(*normal);
                    let len = n.norm();
                    if !(len.is_finite() && len > 0.0 && offset.is_finite()) {
                        return Err(Error::invalid(
                            &here,
                            "plane",
                            "the normal must be a finite non-zero vector and the offset finite",
                        ));
                    }
                    let n = n / len;
                    // parry's half-space: {x : nᵀx ≤ 0} in its frame; move the plane by offset along n.
                    let local = o * Isometry3::from_parts(Translation3::from(n * *offset), UnitQuaternion::identity());
                    let hs = SharedShape::new(HalfSpace::new(Unit::new_unchecked(n)));
                    let nw = o.rotation * n;
                    let offw = nw.dot(&(local.translation.vector));
                    parts.push(ConvexPart {
                        shape: hs,
                        local,
                        centre: Point3::origin(),
                        radius: f64::INFINITY,
                        halfspace: Some((nw, offw)),
                        capsule: None,
                        climb: None,
                        pad: 0.0,
                    });
                }
            }
        }
        Ok(Body { name: name.to_string(), parts })
    }

    /// A body with no shapes (a link without collision geometry).
    pub fn empty(name: &str) -> Body {
        Body {
            name: name.to_string(),
            parts: Vec::new(),
        }
    }

    /// True if the body has no shapes.
    pub fn is_empty(&self) -> bool {
        self.parts.is_empty()
    }

    /// The hill-climbing hulls of the body's convex polyhedra with their
    /// poses in the body frame (for tests).
    pub fn climb_hulls(&self) -> Vec<(&ClimbHull, Isometry3<f64>)> {
        self.parts.iter().filter_map(|p| p.climb.as_deref().map(|h| (h, p.local))).collect()
    }

    /// The parts as drawn: each part's shape, its pose in the body frame and
    /// its padding (m; the part is the shape grown by a ball of that radius).
    pub fn part_shapes(&self) -> impl Iterator<Item = (&SharedShape, &Isometry3<f64>, f64)> {
        self.parts.iter().map(|p| (&p.shape, &p.local, p.pad))
    }

    /// Number of convex parts.
    pub fn n_parts(&self) -> usize {
        self.parts.len()
    }

    /// Vertices of every convex polyhedral part in the body frame (meshes and
    /// boxes; for tests and plots).
    pub fn polyhedron_points(&self) -> Vec<Vec<Point3<f64>>> {
        self.parts
            .iter()
            .filter_map(|p| {
                if let Some(c) = p.shape.as_convex_polyhedron() {
                    Some(c.points().iter().map(|q| p.local * q).collect())
                } else {
                    p.shape.as_cuboid().map(|c| {
                        let h = c.half_extents;
                        let mut v = Vec::with_capacity(8);
                        for sx in [-1.0, 1.0] {
                            for sy in [-1.0, 1.0] {
                                for sz in [-1.0, 1.0] {
                                    v.push(p.local * Point3::new(sx * h.x, sy * h.y, sz * h.z));
                                }
                            }
                        }
                        v
                    })
                }
            })
            .collect()
    }
}

/// Lower bound on the distance between two parts from their bounding spheres
/// (or the plane), in the world frame, paddings included.
fn part_lower_bound(a: &ConvexPart, xa: &Isometry3<f64>, b: &ConvexPart, xb: &Isometry3<f64>) -> f64 {
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
fn part_capsule_bound(a: &ConvexPart, xa: &Isometry3<f64>, b: &ConvexPart, xb: &Isometry3<f64>) -> f64 {
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

fn world_plane(x: &Isometry3<f64>, n: &Vector3<f64>, off: f64) -> (Vector3<f64>, f64) {
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
fn proximity_sep(a: &Body, xa: &Isometry3<f64>, b: &Body, xb: &Isometry3<f64>, cap: f64, np: NarrowPhase, sep: &mut Option<Vector3<f64>>) -> Option<Proximity> {
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

// ---------------------------------------------------------------------------
// Shapes as files describe them
// ---------------------------------------------------------------------------

fn ones() -> [f64; 3] {
    [1.0; 3]
}

/// A shape in a robot or design file (TOML): `{ type = "box", size = [..] }`,
/// `cylinder` (radius, length along z), `sphere`, `capsule` (radius, length of
/// the cylindrical part along z), `plane` (obstacles only: the free side is
/// nᵀx ≥ offset), `mesh` (an STL, OBJ or Collada file, relative to the file that names it; its
/// convex hull).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Box with full side lengths (m).
    Box {
        /// Side lengths (m).
        size: [f64; 3],
    },
    /// Cylinder along z, centred.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length (m).
        length: f64,
    },
    /// Sphere.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// Capsule along z.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part (m).
        length: f64,
    },
    /// Plane: everything with nᵀx < offset is solid.
    Plane {
        /// Normal toward the free side.
        normal: [f64; 3],
        /// Offset along the normal (m).
        #[serde(default)]
        offset: f64,
    },
    /// Mesh file (STL, OBJ or Collada; convex hull), path relative to the file naming it.
    Mesh {
        /// File.
        file: PathBuf,
        /// Scale per axis.
        #[serde(default = "ones")]
        scale: [f64; 3],
    },
}

impl ShapeSpec {
    /// The primitive, resolving a mesh path against `dir`.
    pub fn primitive(&self, dir: &Path) -> Primitive {
        match self {
            ShapeSpec::Box { size } => Primitive::Box { size: *size },
            ShapeSpec::Cylinder { radius, length } => Primitive::Cylinder {
                radius: *radius,
                length: *length,
            },
            ShapeSpec::Sphere { radius } => Primitive::Sphere { radius: *radius },
            ShapeSpec::Capsule { radius, length } => Primitive::Capsule {
                radius: *radius,
                length: *length,
            },
            ShapeSpec::Plane { normal, offset } => Primitive::HalfSpace {
                normal: *normal,
                offset: *offset,
            },
            ShapeSpec::Mesh { file, scale } => Primitive::Mesh {
                path: dir.join(file),
                scale: *scale,
            },
        }
    }
}

/// Pose from xyz (m) and roll-pitch-yaw (rad), URDF convention.
pub fn pose(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    let rot = Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    Isometry3::from_parts(Translation3::new(xyz[0], xyz[1], xyz[2]), UnitQuaternion::from_rotation_matrix(&rot))
}

/// A pair of bodies the robot file declares as never to be checked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AllowedCollision {
    /// First link.
    pub a: String,
    /// Second link.
    pub b: String,
    /// Why the pair cannot collide or may touch (required).
    pub reason: String,
}

// ---------------------------------------------------------------------------
// The robot's geometry
// ---------------------------------------------------------------------------

/// The collision geometry of a robot, built once at load: one body per moving
/// link (everything fixed to it merged in: fixed child links, tool flanges,
/// the hand and fingers) and one for the base.
#[derive(Debug, Clone)]
pub struct RobotGeometry {
    /// Body 0 is the base, body i + 1 moves with link i.
    pub bodies: Vec<Body>,
    /// URDF link names merged into each body (for `allowed_collision` and messages).
    pub members: Vec<Vec<String>>,
    /// Pairs the robot file excludes, with their reasons.
    pub allowed: Vec<AllowedCollision>,
    /// Where the geometry came from (for reports).
    pub source: String,
}

impl RobotGeometry {
    /// Body index of a link name (a moving link, the base or any link merged into one).
    pub fn body_of(&self, name: &str) -> Option<usize> {
        self.members.iter().position(|m| m.iter().any(|x| x == name))
    }
}

/// Which class a checked pair belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PairClass {
    /// Two bodies of the robot.
    SelfCollision,
    /// A robot body and an obstacle (floor, cell).
    World,
}

impl PairClass {
    /// `self` or `world`.
    pub fn label(self) -> &'static str {
        match self {
            PairClass::SelfCollision => "self",
            PairClass::World => "world",
        }
    }
}

/// One checked pair of a scene.
#[derive(Debug, Clone, Serialize)]
pub struct PairInfo {
    /// Name of the first body.
    pub a: String,
    /// Name of the second body.
    pub b: String,
    /// Self or world.
    pub class: PairClass,
    #[serde(skip)]
    ia: usize,
    #[serde(skip)]
    ib: usize,
}

impl PairInfo {
    /// `self: forearm_link – wrist_2_link`.
    pub fn label(&self) -> String {
        format!("{}: {} – {}", self.class.label(), self.a, self.b)
    }
}

/// A pair left out, and why.
#[derive(Debug, Clone, Serialize)]
pub struct ExcludedPair {
    /// First body.
    pub a: String,
    /// Second body.
    pub b: String,
    /// Why.
    pub reason: String,
}

fn yes() -> bool {
    true
}

fn default_margin() -> f64 {
    0.02
}

fn default_band() -> f64 {
    0.1
}

/// A fixed obstacle of the cell (`[[collision.obstacle]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Name in reports.
    pub name: String,
    /// Shape.
    pub shape: ShapeSpec,
    /// Position in the base frame (m).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation (roll, pitch, yaw; rad).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// A tool or payload shape fixed to a frame of the robot (`[[collision.attached]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttachedSpec {
    /// Name in reports.
    pub name: String,
    /// Frame or link it is fixed to.
    pub frame: String,
    /// Shape (not a plane).
    pub shape: ShapeSpec,
    /// Position in the frame (m).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation in the frame (rad).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// The `[collision]` section of a design file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSpec {
    /// Check collisions at all (default true; without robot geometry there is nothing to check).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Required minimum distance (m) for every checked pair.
    #[serde(default = "default_margin")]
    pub margin: f64,
    /// Distances above margin + band count as margin + band (m): the broad phase skips those pairs exactly.
    #[serde(default = "default_band")]
    pub band: f64,
    /// Self-collision between the robot's bodies.
    #[serde(default = "yes", rename = "self")]
    pub self_collision: bool,
    /// The mounting plane z = 0 of the base frame for every body but the base.
    #[serde(default = "yes")]
    pub floor: bool,
    /// Obstacles of the cell.
    #[serde(default)]
    pub obstacle: Vec<ObstacleSpec>,
    /// Tool or payload shapes on robot frames.
    #[serde(default)]
    pub attached: Vec<AttachedSpec>,
    /// True when the design file writes a `[collision]` section (set when
    /// the section is read; false for the default of a design without one):
    /// such a design asks for collision checks, and a robot without
    /// collision geometry is then an error instead of `collisions NOT checked`.
    #[serde(skip_serializing, skip_deserializing, default = "yes")]
    pub requested: bool,
}

impl Default for CollisionSpec {
    fn default() -> Self {
        CollisionSpec {
            enabled: true,
            margin: default_margin(),
            band: default_band(),
            self_collision: true,
            floor: true,
            obstacle: Vec::new(),
            attached: Vec::new(),
            requested: false,
        }
    }
}

/// The robot's bodies (with attached shapes) and the world's obstacles, the
/// checked pairs, the margin and the cap.
#[derive(Debug, Clone)]
pub struct CollisionScene {
    bodies: Vec<Body>,
    /// Moving link of each body (`None`: fixed in the base frame).
    owner: Vec<Option<usize>>,
    /// Checked pairs.
    pub pairs: Vec<PairInfo>,
    /// Pairs not checked and why.
    pub excluded: Vec<ExcludedPair>,
    /// Required distance (m).
    pub margin: f64,
    /// Cap of the distances in the optimisation (m): margin + band.
    pub cap: f64,
    /// The exact distance computation.
    narrow: NarrowPhase,
}

/// Tolerance of the broad phase (m): a configuration (or pair) is left
/// without an exact query only if its lower bound exceeds the minimum found so
/// far by more than this, which covers the rounding of the bound and of the
/// GJK/EPA distance; the minimum and the first configuration attaining it are
/// therefore exactly those of the exhaustive evaluation.
pub const CULL_TOL: f64 = 1e-7;

/// The capped distance of one pair over a sequence of configurations
/// ([`CollisionScene::pair_series`]): `value[g]` is the exact capped distance
/// where `exact[g]`, elsewhere a lower bound that exceeds the minimum of the
/// sequence by more than [`CULL_TOL`]. So the minimum of `value` and its first
/// index are those of the exact distances.
#[derive(Debug, Clone, Default)]
pub struct DistanceSeries {
    /// Exact capped distance or lower bound (m), per configuration.
    pub value: Vec<f64>,
    /// Whether `value[g]` is exact.
    pub exact: Vec<bool>,
    /// Number of exact (narrow-phase) queries made.
    pub queries: usize,
    /// Unit normal of the last exact query (or the separating direction
    /// that put the pair beyond the cap), in the first body's frame: the direction of the support-function
    /// bound ([`CollisionScene::pair_support_bound`]) at the other configurations.
    pub hint: Option<Vector3<f64>>,
    /// Configurations ruled out by the support-function bound alone (no exact query).
    pub support_skips: usize,
    /// Support vertices of the last support-function bound (climbing starts).
    starts: Vec<u32>,
}

impl DistanceSeries {
    /// The first configuration of least distance and that distance (exact).
    pub fn argmin(&self) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for (g, v) in self.value.iter().enumerate() {
            if best.is_none_or(|(_, b)| *v < b) {
                best = Some((g, *v));
            }
        }
        best
    }

    /// Makes `value[g]` exact (one query if it is not yet) and returns it.
    /// Its direction ([`CollisionScene::pair_query`]) becomes the [`Self::hint`].
    pub fn make_exact(&mut self, sc: &CollisionScene, k: usize, g: usize, poses: &[Vec<Isometry3<f64>>], cap: f64) -> f64 {
        if !self.exact[g] {
            let (prox, dir) = sc.pair_query(k, &poses[g], cap);
            self.value[g] = prox.map_or(cap, |p| p.distance);
            if dir.is_some() {
                self.hint = dir;
            }
            self.exact[g] = true;
            self.queries += 1;
        }
        self.value[g]
    }
}

/// Distance of one pair at one configuration.
#[derive(Debug, Clone, Serialize)]
pub struct PairDistance {
    /// Index into [`CollisionScene::pairs`].
    pub pair: usize,
    /// `self: a – b`.
    pub label: String,
    /// Signed distance (m; negative: penetration), capped at the query's cap.
    pub distance: f64,
}

impl CollisionScene {
    /// Builds the scene of `robot` under `spec`; `dir` resolves mesh paths of
    /// the design file, `ctx` names it in messages. `None` when nothing is
    /// checked (disabled, or the robot has no geometry, the design writes no
    /// `[collision]` section and there is no pair).
    ///
    /// A design never runs without the checks it asks for: an error when the
    /// robot's collision geometry could not be loaded (a mesh not found:
    /// [`Robot::geometry_error`] names the link, the mesh and the folders
    /// searched), or when the design writes a `[collision]` section
    /// ([`CollisionSpec::requested`]) for a robot without collision geometry
    /// and attaches no shape to it (`[[collision.attached]]` shapes on a DH
    /// robot are checked as they are).
    pub fn new(robot: &Robot, spec: &CollisionSpec, dir: &Path, ctx: &str) -> Result<Option<CollisionScene>> {
        if !spec.enabled {
            return Ok(None);
        }
        if let Some(why) = &robot.geometry_error {
            return Err(Error::invalid(
                ctx,
                "collision",
                format!(
                    "collisions are checked ([collision] enabled, the default) but robot `{}` ({}) has no usable collision geometry: {why}; make the meshes findable, or set [collision] enabled = false to design without collision checks",
                    robot.name, robot.source
                ),
            ));
        }
        if spec.requested && robot.collision.is_none() && spec.attached.is_empty() {
            return Err(Error::invalid(
                ctx,
                "collision",
                format!(
                    "the design asks for collision checks ([collision]: margin {} m{}{}) but robot `{}` ({}) has no collision geometry: give its URDF <collision> elements or its robot file [[collision]] shapes, or set [collision] enabled = false",
                    spec.margin,
                    if spec.floor { ", the floor" } else { "" },
                    if spec.obstacle.is_empty() { String::new() } else { format!(", {} obstacle(s)", spec.obstacle.len()) },
                    robot.name,
                    robot.source
                ),
            ));
        }
        if !(spec.margin.is_finite() && spec.margin >= 0.0) {
            return Err(Error::invalid(ctx, "collision.margin", format!("{} must be ≥ 0 m and finite", spec.margin)));
        }
        if !(spec.band.is_finite() && spec.band > 0.0) {
            return Err(Error::invalid(ctx, "collision.band", format!("{} must be > 0 m and finite", spec.band)));
        }
        let n = robot.dof();
        let (mut bodies, members, allowed) = match &robot.collision {
            Some(g) => (g.bodies.clone(), g.members.clone(), g.allowed.clone()),
            None => {
                let mut b = vec![Body::empty("base")];
                let mut m = vec![vec!["base".to_string()]];
                for l in &robot.links {
                    b.push(Body::empty(&l.name));
                    m.push(vec![l.name.clone()]);
                }
                (b, m, Vec::new())
            }
        };
        for (k, a) in spec.attached.iter().enumerate() {
            let field = format!("collision.attached[{k}] (`{}`)", a.name);
            if matches!(a.shape, ShapeSpec::Plane { .. }) {
                return Err(Error::invalid(ctx, &field, "an attached shape cannot be a plane"));
            }
            let frame = robot.find_frame(&a.frame).ok_or_else(|| {
                Error::invalid(
                    ctx,
                    format!("{field}.frame"),
                    format!("no frame or link named `{}` on robot `{}`", a.frame, robot.name),
                )
            })?;
            let spec = GeometrySpec {
                primitive: a.shape.primitive(dir),
                origin: pose(a.xyz, a.rpy),
            };
            let body = Body::new(&a.name, &[spec], MeshMode::Hull, &format!("{ctx}: {field}"))?;
            let idx = frame.link.map_or(0, |l| l + 1);
            bodies[idx].merge(&body, &frame.placement);
        }
        let mut owner: Vec<Option<usize>> = (0..=n).map(|i| i.checked_sub(1)).collect();
        let mut pairs = Vec::new();
        let mut excluded = Vec::new();
        if spec.self_collision {
            for a in 0..=n {
                for b in a + 1..=n {
                    if bodies[a].is_empty() || bodies[b].is_empty() {
                        continue;
                    }
                    // b > a ≥ 0, b a moving link: joined by one joint if a is b's parent body
                    let parent_b = robot.joints[b - 1].parent.map_or(0, |p| p + 1);
                    let parent_a = if a == 0 {
                        None
                    } else {
                        Some(robot.joints[a - 1].parent.map_or(0, |p| p + 1))
                    };
                    if parent_b == a || parent_a == Some(b) {
                        excluded.push(ExcludedPair {
                            a: bodies[a].name.clone(),
                            b: bodies[b].name.clone(),
                            reason: "adjacent: joined by one joint".into(),
                        });
                        continue;
                    }
                    if let Some(al) = allowed.iter().find(|al| {
                        let (x, y) = (members[a].contains(&al.a), members[b].contains(&al.b));
                        let (x2, y2) = (members[a].contains(&al.b), members[b].contains(&al.a));
                        (x && y) || (x2 && y2)
                    }) {
                        excluded.push(ExcludedPair {
                            a: bodies[a].name.clone(),
                            b: bodies[b].name.clone(),
                            reason: format!("allowed by the robot file: {}", al.reason),
                        });
                        continue;
                    }
                    pairs.push(PairInfo {
                        a: bodies[a].name.clone(),
                        b: bodies[b].name.clone(),
                        class: PairClass::SelfCollision,
                        ia: a,
                        ib: b,
                    });
                }
            }
        }
        let mut obstacles: Vec<Body> = Vec::new();
        if spec.floor {
            let floor = Body::new(
                "floor",
                &[GeometrySpec {
                    primitive: Primitive::HalfSpace {
                        normal: [0.0, 0.0, 1.0],
                        offset: 0.0,
                    },
                    origin: Isometry3::identity(),
                }],
                MeshMode::Hull,
                ctx,
            )?;
            obstacles.push(floor);
        }
        for (k, o) in spec.obstacle.iter().enumerate() {
            let field = format!("collision.obstacle[{k}] (`{}`)", o.name);
            let g = GeometrySpec {
                primitive: o.shape.primitive(dir),
                origin: pose(o.xyz, o.rpy),
            };
            obstacles.push(Body::new(&o.name, &[g], MeshMode::Hull, &format!("{ctx}: {field}"))?);
        }
        for (k, ob) in obstacles.into_iter().enumerate() {
            let oi = bodies.len();
            let is_floor = spec.floor && k == 0;
            bodies.push(ob);
            owner.push(None);
            for b in 0..=n {
                if bodies[b].is_empty() {
                    continue;
                }
                if b == 0 {
                    // the base stands on the floor (its mesh may reach below
                    // the mounting plane: the UR5's by 3 mm); against a cell
                    // obstacle the distance is constant in q: checked all the same
                    if is_floor {
                        excluded.push(ExcludedPair {
                            a: bodies[0].name.clone(),
                            b: bodies[oi].name.clone(),
                            reason: "the base is mounted on it (fixed: the distance does not change with the motion)".into(),
                        });
                        continue;
                    }
                }
                pairs.push(PairInfo {
                    a: bodies[b].name.clone(),
                    b: bodies[oi].name.clone(),
                    class: PairClass::World,
                    ia: b,
                    ib: oi,
                });
            }
        }
        Ok(Some(CollisionScene {
            bodies,
            owner,
            pairs,
            excluded,
            margin: spec.margin,
            cap: spec.margin + spec.band,
            narrow: NarrowPhase::default(),
        }))
    }

    /// Number of checked pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Chooses the narrow phase (default [`NarrowPhase::Climb`]).
    pub fn set_narrow_phase(&mut self, np: NarrowPhase) {
        self.narrow = np;
    }

    /// The narrow phase in use.
    pub fn narrow_phase(&self) -> NarrowPhase {
        self.narrow
    }

    /// True when no pair is checked.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// World poses of every body from the forward kinematics in `kin` (`out` resized).
    pub fn poses(&self, kin: &Kin<f64>, out: &mut Vec<Isometry3<f64>>) {
        out.clear();
        for o in &self.owner {
            out.push(match o {
                None => Isometry3::identity(),
                Some(l) => iso(&kin.wpos[*l], &kin.wrot[*l]),
            });
        }
    }

    /// Signed distance of pair `k` at body poses `poses`, capped at `cap`
    /// (`None`: farther than the cap).
    pub fn pair_proximity(&self, k: usize, poses: &[Isometry3<f64>], cap: f64) -> Option<Proximity> {
        let p = &self.pairs[k];
        proximity_with(&self.bodies[p.ia], &poses[p.ia], &self.bodies[p.ib], &poses[p.ib], cap, self.narrow)
    }

    /// [`Self::pair_proximity`] (the same result) and a direction for the
    /// support-function bound ([`Self::pair_support_bound`]), in the pair's
    /// first body's frame: the normal of the result, or, when the pair is
    /// beyond the cap, the separating direction with which GJK proved it
    /// (convex hulls; `None` when no part pair went that far).
    pub fn pair_query(&self, k: usize, poses: &[Isometry3<f64>], cap: f64) -> (Option<Proximity>, Option<Vector3<f64>>) {
        let p = &self.pairs[k];
        let mut sep = None;
        let prox = proximity_sep(&self.bodies[p.ia], &poses[p.ia], &self.bodies[p.ib], &poses[p.ib], cap, self.narrow, &mut sep);
        let dir = prox.map(|x| x.normal).or(sep).map(|n| self.normal_in_first_body(k, poses, &n));
        (prox, dir)
    }

    /// Adds `scale · ∂d/∂q` of pair `k` to `grad` (length n): nᵀ(J_B(p_B) − J_A(p_A)),
    /// the point Jacobians of the witness points fixed on their bodies. `kin`
    /// must hold the forward kinematics of the configuration of `prox`.
    pub fn add_gradient(&self, robot: &Robot, kin: &Kin<f64>, k: usize, prox: &Proximity, scale: f64, grad: &mut [f64]) {
        let p = &self.pairs[k];
        if let Some(l) = self.owner[p.ib] {
            point_jacobian_t(robot, kin, l, &prox.p2, &prox.normal, scale, grad);
        }
        if let Some(l) = self.owner[p.ia] {
            point_jacobian_t(robot, kin, l, &prox.p1, &prox.normal, -scale, grad);
        }
    }

    /// Capped distance of pair `k` at body poses `poses`: the signed
    /// distance, or `cap` if the bodies are farther apart than `cap`.
    pub fn pair_distance(&self, k: usize, poses: &[Isometry3<f64>], cap: f64) -> f64 {
        self.pair_proximity(k, poses, cap).map_or(cap, |p| p.distance)
    }

    /// The broad phase of pair `k` at `poses`: `(sphere, bound)` where
    /// `sphere` is the bounding-sphere bound [`Self::pair_distance`] itself
    /// tests (above `cap` the pair reports `cap` without an exact query), and
    /// `bound ≥ sphere` is the tighter bound of the spheres and the bounding
    /// capsules: the signed distance is at least `bound` (up to
    /// [`CULL_TOL`]). The capsules are only tried when the spheres do not
    /// already put the pair beyond `cap` (then `bound = sphere`). +∞ when a
    /// body has no shape.
    pub fn pair_bounds(&self, k: usize, poses: &[Isometry3<f64>], cap: f64) -> (f64, f64) {
        let sphere = self.pair_sphere_bound(k, poses);
        if sphere > cap {
            return (sphere, sphere);
        }
        (sphere, self.pair_capsule_bound(k, poses))
    }

    /// The capped distance of pair `k` over a sequence of configurations
    /// (`poses[g]`: the body poses of configuration g), computed exactly
    /// wherever it can be the minimum over the sequence and bounded from
    /// below elsewhere (see [`DistanceSeries`]). With `exhaustive` every
    /// configuration gets the exact query (the reference the culling is
    /// tested against).
    pub fn pair_series(&self, k: usize, poses: &[Vec<Isometry3<f64>>], cap: f64, exhaustive: bool, out: &mut DistanceSeries) {
        out.value.clear();
        out.exact.clear();
        out.queries = 0;
        out.support_skips = 0;
        // no normal carried over from another call: the queries made depend
        // on this call only; against a half-space the bound needs none
        // (any direction: the plane's normal is used)
        out.hint = self.halfspace_hint(k);
        if exhaustive {
            for x in poses {
                out.value.push(self.pair_distance(k, x, cap));
                out.exact.push(true);
            }
            out.queries = poses.len();
            return;
        }
        out.starts.clear();
        let mut best = f64::INFINITY;
        let mut first: Option<(usize, f64)> = None;
        // the bounding spheres first (cheapest); the capsules and the
        // support-function bound only where the spheres leave the
        // configuration a candidate for the minimum
        for (g, x) in poses.iter().enumerate() {
            let sphere = self.pair_sphere_bound(k, x);
            // exactly what the exact query returns without querying: every
            // part pair fails its sphere test
            if sphere > cap {
                out.value.push(cap);
                out.exact.push(true);
                best = best.min(cap);
            } else {
                out.value.push(sphere);
                out.exact.push(false);
                if first.is_none_or(|(_, b)| sphere < b) {
                    first = Some((g, sphere));
                }
            }
        }
        // the most promising configuration first: its distance prunes the rest
        if let Some((g, _)) = first {
            best = best.min(out.make_exact(self, k, g, poses, cap));
        }
        for g in 0..poses.len() {
            if out.exact[g] || out.value[g] > best + CULL_TOL {
                continue;
            }
            if let Some(n) = out.hint {
                // the support-function bound along the last exact normal
                let sb = self.support_bound_from(k, &poses[g], &n, &mut out.starts);
                if sb > cap + CULL_TOL {
                    // the exact query would report the cap
                    out.value[g] = cap;
                    out.exact[g] = true;
                    out.support_skips += 1;
                    best = best.min(cap);
                    continue;
                }
                if sb > best + CULL_TOL {
                    out.value[g] = out.value[g].max(sb);
                    out.support_skips += 1;
                    continue;
                }
            }
            let caps = self.pair_capsule_bound(k, &poses[g]);
            if caps > cap + CULL_TOL {
                // the true distance is above the cap: the exact query reports the cap
                out.value[g] = cap;
                out.exact[g] = true;
                best = best.min(cap);
                continue;
            }
            if caps > best + CULL_TOL {
                out.value[g] = out.value[g].max(caps);
                continue;
            }
            best = best.min(out.make_exact(self, k, g, poses, cap));
        }
    }

    /// The minimum over the part pairs of pair `k` at `poses` of a per-part
    /// lower bound `f` (the body distance is the minimum over its part pairs).
    fn part_pairs_min(&self, k: usize, poses: &[Isometry3<f64>], f: impl Fn(&ConvexPart, &Isometry3<f64>, &ConvexPart, &Isometry3<f64>) -> f64) -> f64 {
        let p = &self.pairs[k];
        let (a, b) = (&self.bodies[p.ia], &self.bodies[p.ib]);
        let (xa, xb) = (&poses[p.ia], &poses[p.ib]);
        let mut bound = f64::INFINITY;
        for pa in &a.parts {
            for pb in &b.parts {
                bound = bound.min(f(pa, xa, pb, xb));
            }
        }
        bound
    }

    /// The bounding-sphere bound of pair `k` at `poses` (the first value of
    /// [`Self::pair_bounds`]).
    fn pair_sphere_bound(&self, k: usize, poses: &[Isometry3<f64>]) -> f64 {
        self.part_pairs_min(k, poses, part_lower_bound)
    }

    /// The sphere-and-capsule bound of pair `k` at `poses` (the second value
    /// of [`Self::pair_bounds`] when the spheres leave the pair within the cap).
    fn pair_capsule_bound(&self, k: usize, poses: &[Isometry3<f64>]) -> f64 {
        self.part_pairs_min(k, poses, |pa, xa, pb, xb| {
            part_lower_bound(pa, xa, pb, xb).max(part_capsule_bound(pa, xa, pb, xb))
        })
    }

    /// The direction of the support-function bound of pair `k` before any
    /// exact query: against a half-space (floor, wall) the bound takes the
    /// plane's normal whatever the direction ([`Self::pair_support_bound`]),
    /// so any one will do; `None` for two bounded bodies.
    fn halfspace_hint(&self, k: usize) -> Option<Vector3<f64>> {
        let p = &self.pairs[k];
        (self.bodies[p.ia].is_unbounded() || self.bodies[p.ib].is_unbounded()).then(Vector3::z)
    }

    /// A world direction `n` (e.g. a [`Proximity`] normal of pair `k` at
    /// `poses`) in the pair's first body's frame: the direction
    /// [`Self::pair_support_bound`] takes, which turns with that body.
    pub fn normal_in_first_body(&self, k: usize, poses: &[Isometry3<f64>], n: &Vector3<f64>) -> Vector3<f64> {
        poses[self.pairs[k].ia].rotation.inverse_transform_vector(n)
    }

    /// The support-function lower bound of pair `k` at `poses` along the
    /// unit direction `n_a`, given in the first body's frame (world
    /// direction n = R_A n_a): for convex parts P ⊂ A, Q ⊂ B the signed
    /// distance (negative: minus the penetration depth) is
    /// sd(P, Q) = max over unit m of [min_{q∈Q} mᵀq − max_{p∈P} mᵀp]
    /// = max_m [−h_Q(−m) − h_P(m)], h the support function; any one m gives
    /// the lower bound −h_Q(−n) − h_P(n), exact when n is the normal of the
    /// closest (or deepest) pair of points. With the normal of an exact query
    /// at a nearby configuration the bound is within second order of the
    /// normal's rotation of the distance. The body distance is the minimum
    /// over the part pairs. A part pair with a half-space (floor, wall)
    /// {x : mᵀx ≤ off} takes m itself (its support function is unbounded
    /// along any other direction): min over the part of mᵀx − off, the
    /// signed distance itself. The bound is
    /// computed with the same support points as the narrow phase (vertices
    /// of the hulls by hill climbing, parry's support maps otherwise), so it
    /// is a lower bound of the exact distance up to rounding (≪ [`CULL_TOL`]).
    pub fn pair_support_bound(&self, k: usize, poses: &[Isometry3<f64>], n_a: &Vector3<f64>) -> f64 {
        self.support_bound_from(k, poses, n_a, &mut Vec::new())
    }

    /// [`Self::pair_support_bound`], the hulls' support vertices climbed
    /// from those of the previous call (`starts`: one per part of the first
    /// body, then of the second; filled on the first call). The climb's
    /// result does not depend on its start (see [`ClimbHull`]).
    fn support_bound_from(&self, k: usize, poses: &[Isometry3<f64>], n_a: &Vector3<f64>, starts: &mut Vec<u32>) -> f64 {
        let p = &self.pairs[k];
        let (a, b) = (&self.bodies[p.ia], &self.bodies[p.ib]);
        let (xa, xb) = (&poses[p.ia], &poses[p.ib]);
        let na = a.parts.len();
        starts.resize(na + b.parts.len(), u32::MAX);
        let n = xa.rotation * n_a;
        let mut bound = f64::INFINITY;
        for (ia, pa) in a.parts.iter().enumerate() {
            for (ib, pb) in b.parts.iter().enumerate() {
                let b_pp = match (&pa.halfspace, &pb.halfspace) {
                    // a plane nᵀx = off (free side nᵀx ≥ off) against a part:
                    // sd = min over the part of nᵀx − off, whatever `n_a`
                    (Some((hn, hoff)), None) => {
                        let (nw, off) = world_plane(xa, hn, *hoff);
                        -pb.world_support(xb, &-nw, &mut starts[na + ib]) - off
                    }
                    (None, Some((hn, hoff))) => {
                        let (nw, off) = world_plane(xb, hn, *hoff);
                        -pa.world_support(xa, &-nw, &mut starts[ia]) - off
                    }
                    (Some(_), Some(_)) => f64::NEG_INFINITY,
                    (None, None) => -pa.world_support(xa, &n, &mut starts[ia]) - pb.world_support(xb, &-n, &mut starts[na + ib]),
                };
                bound = bound.min(b_pp);
            }
        }
        bound
    }

    /// Distances of every pair at configuration `q` (forward kinematics into
    /// `kin`), capped at `cap`.
    pub fn distances(&self, robot: &Robot, kin: &mut Kin<f64>, q: &[f64], cap: f64) -> Vec<PairDistance> {
        crate::robot::kinematics::forward_kinematics(robot, q, kin);
        let mut poses = Vec::with_capacity(self.bodies.len());
        self.poses(kin, &mut poses);
        (0..self.pairs.len())
            .map(|k| PairDistance {
                pair: k,
                label: self.pairs[k].label(),
                distance: self.pair_proximity(k, &poses, cap).map_or(cap, |p| p.distance),
            })
            .collect()
    }

    /// The pair closest to violating the margin at `q` and its distance
    /// (capped at `cap`; the first such pair on ties): the minimum of
    /// [`Self::distances`], with exact queries only for the pairs whose
    /// broad-phase bound does not rule them out.
    pub fn worst_at(&self, robot: &Robot, kin: &mut Kin<f64>, q: &[f64], cap: f64) -> Option<PairDistance> {
        crate::robot::kinematics::forward_kinematics(robot, q, kin);
        let mut poses = Vec::with_capacity(self.bodies.len());
        self.poses(kin, &mut poses);
        let np = self.pairs.len();
        let mut value = Vec::with_capacity(np);
        let mut exact = Vec::with_capacity(np);
        let mut best = f64::INFINITY;
        let mut first: Option<(usize, f64)> = None;
        for k in 0..np {
            let (sphere, bound) = self.pair_bounds(k, &poses, cap);
            if sphere > cap || bound > cap + CULL_TOL {
                value.push(cap);
                exact.push(true);
                best = best.min(cap);
            } else {
                value.push(bound);
                exact.push(false);
                if first.is_none_or(|(_, b)| bound < b) {
                    first = Some((k, bound));
                }
            }
        }
        let order = first.map(|(k, _)| k).into_iter().chain(0..np);
        for k in order {
            if !exact[k] && value[k] <= best + CULL_TOL {
                value[k] = self.pair_distance(k, &poses, cap);
                exact[k] = true;
                best = best.min(value[k]);
            }
        }
        // the first pair of least distance (the pairs not queried are farther)
        let mut kb: Option<usize> = None;
        for k in 0..np {
            if kb.is_none_or(|b| value[k] < value[b]) {
                kb = Some(k);
            }
        }
        kb.map(|k| PairDistance {
            pair: k,
            label: self.pairs[k].label(),
            distance: value[k],
        })
    }

    /// The closest of the pairs that `keep` selects at body poses `poses`,
    /// with its witness points: `(k, proximity)` of least capped distance
    /// (the first pair on ties), `None` when every selected pair is farther
    /// than `cap`. The distance is [`Self::pair_distance`]'s (an exact query
    /// wherever the broad phase, [`Self::pair_bounds`], leaves a pair a
    /// candidate for the minimum), so it agrees with [`Self::worst_at`] and
    /// the report's margins to the bit.
    pub fn closest_where(&self, poses: &[Isometry3<f64>], cap: f64, keep: impl Fn(&PairInfo) -> bool) -> Option<(usize, Proximity)> {
        let mut cand: Vec<(f64, usize)> = Vec::new();
        for (k, p) in self.pairs.iter().enumerate() {
            if !keep(p) {
                continue;
            }
            let (sphere, bound) = self.pair_bounds(k, poses, cap);
            if sphere <= cap && bound <= cap + CULL_TOL {
                cand.push((bound, k));
            }
        }
        cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut best: Option<(usize, Proximity)> = None;
        for (bound, k) in cand {
            if best.as_ref().is_some_and(|(_, b)| bound > b.distance + CULL_TOL) {
                break;
            }
            if let Some(x) = self.pair_proximity(k, poses, cap) {
                if best
                    .as_ref()
                    .is_none_or(|(kb, b)| x.distance < b.distance || (x.distance == b.distance && k < *kb))
                {
                    best = Some((k, x));
                }
            }
        }
        best
    }

    /// The moving link of body `i` of [`Self::bodies`] (`None`: fixed in the base frame).
    pub fn owner(&self, i: usize) -> Option<usize> {
        self.owner.get(i).copied().flatten()
    }

    /// The indices into [`Self::bodies`] of the two bodies of pair `k`.
    pub fn pair_bodies(&self, k: usize) -> (usize, usize) {
        (self.pairs[k].ia, self.pairs[k].ib)
    }

    /// True when every pair keeps at least `limit` (≤ the cap) at `poses`,
    /// i.e. exactly when the least capped distance of [`Self::worst_at`] is
    /// ≥ `limit`: a pair counts as clear when its sphere or capsule bound
    /// ([`Self::pair_bounds`]), or its support-function bound along `hints[k]` (the normal of the
    /// pair's last exact query, first body's frame), exceeds `limit` by more
    /// than [`CULL_TOL`]; otherwise its exact distance decides, and its
    /// normal becomes the new hint. Along a finely sampled path (the 1 kHz
    /// check of a delivered trajectory) the hints of consecutive poses are
    /// nearly the exact normals, so almost no pair needs an exact query.
    /// `hints` is resized to the number of pairs.
    pub fn clear_at(&self, poses: &[Isometry3<f64>], limit: f64, hints: &mut Vec<Option<Vector3<f64>>>) -> bool {
        let np = self.pairs.len();
        hints.resize(np, None);
        // support vertices of the bound: climbed from the seeds for each pair
        // (cleared), one buffer for the call
        let mut starts = Vec::new();
        for (k, hint) in hints.iter_mut().enumerate() {
            let (_, bound) = self.pair_bounds(k, poses, limit);
            if bound > limit + CULL_TOL {
                continue;
            }
            if let Some(n) = hint.or_else(|| self.halfspace_hint(k)) {
                starts.clear();
                if self.support_bound_from(k, poses, &n, &mut starts) > limit + CULL_TOL {
                    continue;
                }
            }
            let (prox, dir) = self.pair_query(k, poses, self.cap);
            if dir.is_some() {
                *hint = dir;
            }
            if prox.map_or(self.cap, |p| p.distance) < limit {
                return false;
            }
        }
        true
    }

    /// The bodies (robot bodies first, index i + 1 for link i, then obstacles).
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }
}

fn iso(p: &Vector3<f64>, r: &Matrix3<f64>) -> Isometry3<f64> {
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    Isometry3::from_parts(Translation3::from(*p), rot)
}

/// grad += s · nᵀ J(p), J the linear point Jacobian of point p fixed on link `link`.
fn point_jacobian_t(robot: &Robot, kin: &Kin<f64>, link: usize, p: &Point3<f64>, n: &Vector3<f64>, s: f64, grad: &mut [f64]) {
    let mut cur = Some(link);
    while let Some(j) = cur {
        let wa = kin.wrot[j] * robot.s_ang[j];
        let wl = kin.wrot[j] * robot.s_lin[j];
        let lin = wl + wa.cross(&(p.coords - kin.wpos[j]));
        grad[j] += s * n.dot(&lin);
        cur = robot.joints[j].parent;
    }
}
