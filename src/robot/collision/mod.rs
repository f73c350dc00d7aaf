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

mod hull;
mod narrow;
mod scene;
mod shape;
mod spec;

pub use super::resolve::{read_mesh, MeshData};
pub use hull::ClimbHull;
pub use narrow::{proximity, proximity_with, NarrowPhase, Proximity};
pub use scene::{CollisionScene, DistanceSeries, PairDistance, CULL_TOL};
pub use shape::{pose, Body, ConvexPart, GeometrySpec, MeshMode, Primitive, ShapeSpec};
pub use spec::{AllowedCollision, AttachedSpec, CollisionSpec, ExcludedPair, ObstacleSpec, PairClass, PairInfo, RobotGeometry};
