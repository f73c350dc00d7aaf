//! Convex hulls with vertex adjacency: support points by hill climbing.

use nalgebra::{Point3, Vector3};
use parry3d_f64::shape::SupportMap;

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
    pub(super) flat: Vec<bool>,
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
    pub(super) fn seed(&self, dir: &Vector3<f64>) -> u32 {
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
pub(super) struct Climbing<'a> {
    hull: &'a ClimbHull,
    last: std::cell::Cell<Option<u32>>,
}

impl<'a> Climbing<'a> {
    pub(super) fn new(hull: &'a ClimbHull) -> Self {
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
