//! The convex parts idexp builds from the shipped collision meshes hold every
//! vertex of the meshes (a hull that lost a vertex would report distances
//! larger than the mesh's: unsafe).

use idexp::robot::collision::{read_stl, Body, GeometrySpec, MeshMode, Primitive};
use nalgebra::{Isometry3, Vector3};
use rand::{RngExt, SeedableRng};
use std::path::Path;

fn meshes() -> Vec<std::path::PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("designs/robots/meshes");
    let mut out = Vec::new();
    for robot in ["ur5", "panda"] {
        let dir = root.join(robot).join("collision");
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "stl") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn every_mesh_vertex_lies_in_its_hull() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let files = meshes();
    assert!(files.len() >= 17, "{} meshes", files.len());
    for f in files {
        let (pts, tris) = read_stl(&f, [1.0; 3]).unwrap();
        let spec = GeometrySpec {
            primitive: Primitive::Mesh {
                path: f.clone(),
                scale: [1.0; 3],
            },
            origin: Isometry3::identity(),
        };
        let body = Body::new("m", &[spec], MeshMode::Hull, "test").unwrap();
        let hull: Vec<_> = body.polyhedron_points().concat();
        // directions: the mesh's face normals (where a lost vertex sticks out
        // most) and random ones
        let mut dirs: Vec<Vector3<f64>> = tris
            .iter()
            .filter_map(|t| {
                let [a, b, c] = t.map(|i| pts[i as usize]);
                (b - a).cross(&(c - a)).try_normalize(0.0)
            })
            .collect();
        for _ in 0..2000 {
            let d = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            dirs.push(d.normalize());
        }
        let mut worst = 0.0f64;
        for d in &dirs {
            let h = hull.iter().map(|p| p.coords.dot(d)).fold(f64::NEG_INFINITY, f64::max);
            let m = pts.iter().map(|p| p.coords.dot(d)).fold(f64::NEG_INFINITY, f64::max);
            worst = worst.max(m - h);
        }
        assert!(worst <= 1e-9, "{}: a mesh vertex lies {worst} m outside the hull", f.display());
    }
}
