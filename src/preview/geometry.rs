//! The drawn geometry: every convex part of the collision scene as a
//! triangle mesh in its body's frame, grown by its padding.
//!
//! A part is checked as its shape grown by a ball of radius `pad` (the
//! Minkowski sum, [`crate::robot::collision::Body::pad_parts`]). The page
//! draws balls and capsules with the padding added to their radius (exact),
//! and every other part as the convex hull of its vertices moved by `pad`
//! along the 42 directions of a once-subdivided icosahedron: an inner
//! approximation of the grown shape whose surface is within
//! pad·(1 − cos 21°) ≈ 0.066·pad of the checked one (0.13 mm for the
//! shipped robots' paddings of at most 2 mm). Half-spaces (floor, walls) are
//! drawn as planes.

use crate::robot::collision::{Body, MeshData};
use nalgebra::{Isometry3, Point3, Vector3};
use parry3d_f64::shape::{HalfSpace, SharedShape};
use serde::Serialize;

/// One convex part as a triangle mesh (body frame).
#[derive(Debug, Clone, Serialize)]
pub struct PartMesh {
    /// Vertex coordinates x, y, z (m), body frame.
    pub vertices: Vec<f32>,
    /// Triangles (vertex indices, counter-clockwise seen from outside).
    pub triangles: Vec<u32>,
    /// Padding included in the drawn surface (m).
    pub pad: f64,
}

/// A plane of the scene: the free side is nᵀx ≥ offset (body frame).
#[derive(Debug, Clone, Serialize)]
pub struct PlaneView {
    /// Unit normal toward the free side.
    pub normal: [f64; 3],
    /// Offset along the normal (m).
    pub offset: f64,
}

/// The unit directions of a once-subdivided icosahedron (42 points).
fn icosphere() -> Vec<Vector3<f64>> {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Vector3<f64>> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vector3::from(*p).normalize())
    .collect();
    // the 30 edges of the icosahedron join the vertices at the shortest distance
    let n = v.len();
    let edge = (v[0] - v[11]).norm();
    for i in 0..n {
        for j in i + 1..n {
            if ((v[i] - v[j]).norm() - edge).abs() < 1e-9 {
                v.push((v[i] + v[j]).normalize());
            }
        }
    }
    v
}

fn push_mesh(out: &mut PartMesh, at: &Isometry3<f64>, pts: &[Point3<f64>], tris: &[[u32; 3]]) {
    for p in pts {
        let w = at * p;
        out.vertices.extend([w.x as f32, w.y as f32, w.z as f32]);
    }
    out.triangles.extend(tris.iter().flatten());
}

/// The drawn meshes of a body's bounded parts, and its planes.
pub fn body_meshes(body: &Body) -> (Vec<PartMesh>, Vec<PlaneView>) {
    let dirs = icosphere();
    let mut meshes = Vec::new();
    let mut planes = Vec::new();
    for (shape, local, pad) in body.part_shapes() {
        if let Some(h) = shape.as_shape::<HalfSpace>() {
            let n = local.rotation * h.normal.into_inner();
            planes.push(PlaneView {
                normal: [n.x, n.y, n.z],
                offset: n.dot(&local.translation.vector),
            });
            continue;
        }
        let (pts, tris) = if let Some(b) = shape.as_ball() {
            parry3d_f64::shape::Ball::new(b.radius + pad).to_trimesh(16, 24)
        } else if let Some(c) = shape.as_capsule() {
            let mut grown = *c;
            grown.radius += pad;
            grown.to_trimesh(16, 24)
        } else {
            let Some((pts, tris)) = raw_mesh(shape) else {
                continue;
            };
            if pad > 0.0 {
                let grown: Vec<Point3<f64>> = pts.iter().flat_map(|p| dirs.iter().map(move |d| p + d * pad)).collect();
                parry3d_f64::transformation::convex_hull(&grown)
            } else {
                (pts, tris)
            }
        };
        let mut m = PartMesh {
            vertices: Vec::with_capacity(3 * pts.len()),
            triangles: Vec::with_capacity(3 * tris.len()),
            pad,
        };
        push_mesh(&mut m, local, &pts, &tris);
        if !m.triangles.is_empty() {
            meshes.push(m);
        }
    }
    (meshes, planes)
}

/// The triangle mesh of a polyhedral or cylindrical part (before padding).
fn raw_mesh(shape: &SharedShape) -> Option<MeshData> {
    if let Some(c) = shape.as_convex_polyhedron() {
        Some(c.to_trimesh())
    } else if let Some(c) = shape.as_cuboid() {
        Some(c.to_trimesh())
    } else {
        shape.as_cylinder().map(|c| c.to_trimesh(32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_icosphere_has_42_unit_directions_within_21_degrees_of_every_direction() {
        let v = icosphere();
        assert_eq!(v.len(), 42);
        assert!(v.iter().all(|u| (u.norm() - 1.0).abs() < 1e-12));
        // every direction of the sphere (a Fibonacci lattice of 20 000) is
        // within 21° of one of them: the drawn padding is ≥ cos 21° of the checked
        let m = 20_000;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut worst = f64::INFINITY;
        for i in 0..m {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
            let r = (1.0 - z * z).sqrt();
            let d = Vector3::new(r * (golden * i as f64).cos(), r * (golden * i as f64).sin(), z);
            let best = v.iter().map(|u| u.dot(&d)).fold(f64::NEG_INFINITY, f64::max);
            worst = worst.min(best);
        }
        assert!(worst >= 21f64.to_radians().cos(), "{}", worst.acos().to_degrees());
        assert!(worst <= 20f64.to_radians().cos(), "the bound is tight: {}", worst.acos().to_degrees());
    }
}
