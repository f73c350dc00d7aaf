//! Shapes as robot and design files describe them, the convex parts they
//! become (hulls, decompositions, primitives) and the bodies made of them.

use super::hull::ClimbHull;
use super::narrow::BoundCapsule;
use super::read_mesh;
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use parry3d_f64::shape::{HalfSpace, SharedShape};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A shape of the collision model, in the body frame: one type for the
/// robot and design files (TOML, `{ type = "box", size = [..] }`) and for the
/// geometry built from them. Read from a file, a mesh path is relative to
/// that file; [`ShapeSpec::primitive`] resolves it (what [`GeometrySpec`]
/// holds). `plane` is for obstacles only.
pub type Primitive = ShapeSpec;

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
    pub(super) shape: SharedShape,
    pub(super) local: Isometry3<f64>,
    /// Bounding-sphere centre (body frame) and radius; radius ∞ for half-spaces.
    pub(super) centre: Point3<f64>,
    pub(super) radius: f64,
    pub(super) halfspace: Option<(Vector3<f64>, f64)>,
    /// Bounding capsule (body frame) for the broad phase; `None` for half-spaces.
    pub(super) capsule: Option<BoundCapsule>,
    /// Vertex adjacency of a convex polyhedron, for support points by hill climbing.
    pub(super) climb: Option<std::sync::Arc<ClimbHull>>,
    /// Padding (m): the part is its shape grown by a ball of this radius
    /// (the Minkowski sum), so every distance to it is the shape's less `pad`
    /// and its support function is the shape's plus `pad` (both exact).
    pub(super) pad: f64,
}

impl ConvexPart {
    /// The support function h(d) = max over the part of dᵀx in the world
    /// frame, the body at `x` (`d` a unit vector); +∞ for a half-space.
    /// A hull's support vertex is climbed from `start` (a previous call's
    /// vertex, unless that lies inside a face or is `u32::MAX`: then from the
    /// best seed), and `start` becomes the new support vertex.
    pub(super) fn world_support(&self, x: &Isometry3<f64>, d: &Vector3<f64>, start: &mut u32) -> f64 {
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
    pub(super) parts: Vec<ConvexPart>,
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
    /// grown shapes (see [`RobotGeometry`](super::RobotGeometry) and the robot file's
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
                Primitive::Mesh { file: path, scale } => {
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
                Primitive::Plane { normal, offset } => {
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
    /// Plane: everything with nᵀx < offset is solid, the half-space below
    /// it (obstacles only: floor, walls).
    Plane {
        /// Normal toward the free side.
        normal: [f64; 3],
        /// Offset along the normal (m).
        #[serde(default)]
        offset: f64,
    },
    /// A triangle mesh (STL, OBJ or Collada, [`read_mesh`]) scaled per axis,
    /// used as its convex hull or convex decomposition; in a file, the path is
    /// relative to the file naming it.
    Mesh {
        /// File.
        file: PathBuf,
        /// Scale per axis.
        #[serde(default = "ones")]
        scale: [f64; 3],
    },
}

impl ShapeSpec {
    /// The same shape with a mesh path resolved against `dir` (the folder of
    /// the file that names it; an absolute path stays as it is).
    pub fn primitive(&self, dir: &Path) -> Primitive {
        match self {
            ShapeSpec::Mesh { file, scale } => ShapeSpec::Mesh {
                file: dir.join(file),
                scale: *scale,
            },
            s => s.clone(),
        }
    }
}

/// Pose from xyz (m) and roll-pitch-yaw (rad), URDF convention.
pub fn pose(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    let rot = Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    Isometry3::from_parts(Translation3::new(xyz[0], xyz[1], xyz[2]), UnitQuaternion::from_rotation_matrix(&rot))
}
