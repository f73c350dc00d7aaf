//! The collision scene of a design: the robot's bodies and the obstacles,
//! the checked pairs, distances along paths and their gradients.

use super::narrow::{part_capsule_bound, part_lower_bound, proximity_sep, world_plane};
use super::shape::{pose, Body, ConvexPart, GeometrySpec, MeshMode, Primitive, ShapeSpec};
use super::spec::{CollisionSpec, ExcludedPair, PairClass, PairInfo};
use super::{proximity_with, NarrowPhase, Proximity};
use crate::error::{Error, Result};
use crate::robot::kinematics::Kin;
use crate::robot::model::Robot;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;
use std::path::Path;

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
                    primitive: Primitive::Plane {
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
