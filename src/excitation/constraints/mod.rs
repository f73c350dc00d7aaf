//! Constraints of the excitation design and their analytic gradients.
//!
//! Every constraint is a scalar c_i(x) ≤ 0 (feasible), scaled to be
//! dimensionless: c_i = (worst value over the period − limit) / scale.
//!
//! * **Joint position, velocity, acceleration** (per joint, upper and lower):
//!   the extremum over the *continuous* motion of q_j^(m)(t), m = 0, 1, 2.
//!   It is found by scanning the shape's scan grid
//!   ([`TrajectoryShape::scan_times`]: for the Fourier series
//!   [`SCAN_PER_HARMONIC`] points per period of the highest harmonic), then
//!   Newton steps on d/dt q_j^(m) = 0 from the best grid local extrema
//!   (analytic derivatives up to order 4). By the envelope theorem the
//!   gradient is ∂q_j^(m)(t*)/∂x — the shape's Jacobian at t*. Scale: half the
//!   allowed position range, the velocity or acceleration limit.
//! * **Joint torque** (per joint, upper and lower): τ_j(t) of inverse dynamics
//!   with the nominal parameters (motor side, friction included) on the
//!   constraint grid, the extremum refined by a parabola through the grid
//!   neighbours; gradient ∂τ/∂q · ∂q/∂x + ∂τ/∂q̇ · ∂q̇/∂x + (∂τ/∂q̈) ∂q̈/∂x at
//!   t* from [`crate::robot::id_derivatives`] and [`crate::robot::motor_inertia`].
//!   Scale: the effort limit.
//! * **Cartesian** ([`CartesianConstraint`]): each margin g_k(p) ≥ 0 of the
//!   shape at the frame origin p(q(t)); the minimum over the constraint grid,
//!   refined like torques; gradient ∂g_k/∂p · J_v(q(t*)) · ∂q/∂x. Scale 1 m.
//!
//! [`Constraints::verify`] evaluates every constraint on a uniform grid (1 kHz
//! by default) in natural units, for the report.

mod evaluate;
mod joint;
mod verify;

pub use joint::{joint_extremum, joint_extremum_scanned, series_derivative, series_derivatives};

use crate::error::{Error, Result};
use crate::robot::cartesian::{CartesianConstraint, Shape};
use crate::robot::collision::{CollisionScene, DistanceSeries, NarrowPhase, PairClass};
use crate::robot::kinematics::forward_kinematics;
use crate::robot::{Frame, Robot, Workspace};
use crate::trajectory::shapes::{ShapeGrid, ShapeScratch};
pub use crate::trajectory::SCAN_PER_HARMONIC;
use crate::trajectory::{period_grid, Shape as TrajShape, StateGradient, TimeGrid, TrajectoryShape};
use nalgebra::Vector3;
use serde::Serialize;
use std::sync::Arc;

/// What a constraint limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ConstraintKind {
    /// Joint position.
    Position,
    /// Joint velocity.
    Velocity,
    /// Joint acceleration.
    Acceleration,
    /// Joint (motor-side) torque.
    Torque,
    /// Cartesian workspace margin of a frame.
    Cartesian,
    /// Minimum distance between two bodies of the robot.
    SelfCollision,
    /// Minimum distance between a robot body and an obstacle (floor, cell).
    WorldCollision,
}

/// Description of one scalar constraint.
#[derive(Debug, Clone, Serialize)]
pub struct ConstraintInfo {
    /// Readable name, e.g. `q3 ≤ upper`, `tool0 inside box: z ≤ max`.
    pub name: String,
    /// Kind.
    pub kind: ConstraintKind,
    /// Joint index (0-based) for joint constraints.
    pub joint: Option<usize>,
    /// The limit (natural units: rad, rad/s, rad/s², N·m, m of margin).
    pub limit: f64,
    /// True for an upper limit (value ≤ limit), false for a lower limit (value ≥ limit).
    pub upper: bool,
    /// Scale of the dimensionless constraint value.
    pub scale: f64,
    /// Unit of `limit`.
    pub unit: String,
}

#[derive(Debug, Clone)]
enum Item {
    Joint { j: usize, order: usize },
    Torque { j: usize },
    Cart { idx: usize, margin: usize },
    Distance { pair: usize },
}

/// Scale of the dimensionless distance constraints (m).
pub const DISTANCE_SCALE: f64 = 0.1;

/// The worst pair of a configuration (see [`Constraints::collision_at`]).
#[derive(Debug, Clone, Serialize)]
pub struct CollisionReport {
    /// `self: forearm_link – wrist_2_link` or `world: wrist_3_link – floor`.
    pub pair: String,
    /// Self or world.
    pub kind: ConstraintKind,
    /// Signed distance (m; negative: the bodies overlap), capped at margin + band.
    pub distance: f64,
    /// Required distance (m).
    pub margin: f64,
    /// Penetration depth max(0, −distance) (m).
    pub depth: f64,
}

#[derive(Debug, Clone)]
struct CartItem {
    frame: Frame,
    shape: Shape,
    label: String,
}

/// The constraint set of a design.
#[derive(Debug, Clone)]
pub struct Constraints {
    robot: Arc<Robot>,
    shape: TrajShape,
    /// One entry per scalar constraint.
    pub info: Vec<ConstraintInfo>,
    items: Vec<Item>,
    cart: Vec<CartItem>,
    scene: Option<std::sync::Arc<CollisionScene>>,
    grid: ShapeGrid,
    scan: ShapeGrid,
    theta: Vec<f64>,
}

/// Per-thread buffers for constraint evaluations.
#[derive(Debug, Clone)]
pub struct ConstraintWorkspace {
    ws: Workspace,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
    tau_grid: Vec<Vec<f64>>,
    marg_grid: Vec<Vec<f64>>,
    margins: Vec<(f64, Vector3<f64>)>,
    /// Body poses at every grid time (computed once per evaluation, shared by the pairs).
    pose_grid: Vec<Vec<nalgebra::Isometry3<f64>>>,
    /// Per pair: the capped distance on the grid, exact where it can be the minimum.
    series: Vec<DistanceSeries>,
    poses: Vec<nalgebra::Isometry3<f64>>,
    /// The gradient of the constraint being evaluated with respect to the
    /// state at its time t* (pulled back to x by [`Constraints::pull_back`]).
    grad: StateGradient,
    /// Buffers of the shape's pull-back.
    pull: ShapeScratch,
    exhaustive: bool,
    /// Evaluation for the GA's selection ([`Constraints::eval_selection`]).
    selection: bool,
    /// The scan's values of q_j^(order) of the evaluated motion, at
    /// `j·3 + order` when `scanned` says so (shared by a joint's upper and
    /// lower limit; cleared at each evaluation).
    scan_raw: Vec<Vec<f64>>,
    scanned: Vec<bool>,
}

impl ConstraintWorkspace {
    /// With `true`, the distance constraints query every checked pair at
    /// every grid time (no broad-phase culling): the reference evaluation the
    /// culled one is tested against (both give the same values).
    pub fn set_exhaustive(&mut self, on: bool) {
        self.exhaustive = on;
    }

    /// Number of exact (narrow-phase) distance queries of the last
    /// evaluation's grid, over all pairs.
    pub fn distance_queries(&self) -> usize {
        self.series.iter().map(|s| s.queries).sum()
    }

    /// The exact distance queries of the last evaluation per checked pair.
    pub fn distance_queries_per_pair(&self) -> Vec<usize> {
        self.series.iter().map(|s| s.queries).collect()
    }

    /// Per checked pair, the grid times of the last evaluation ruled out by
    /// the support-function bound alone (no exact query).
    pub fn support_skips_per_pair(&self) -> Vec<usize> {
        self.series.iter().map(|s| s.support_skips).collect()
    }
}

/// Which joint limits are imposed and how much of each is usable.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimitSpec {
    /// Per joint allowed [lower, upper] position (rad or m); infinite: none.
    pub position: Vec<[f64; 2]>,
    /// Per joint velocity limit (infinite: none).
    pub velocity: Vec<f64>,
    /// Per joint acceleration limit (infinite: none).
    pub acceleration: Vec<f64>,
    /// Per joint torque limit (infinite: none).
    pub torque: Vec<f64>,
}

/// Worst margin of one constraint on a verification grid.
#[derive(Debug, Clone, Serialize)]
pub struct Margin {
    /// Constraint name.
    pub name: String,
    /// Kind.
    pub kind: ConstraintKind,
    /// The limit.
    pub limit: f64,
    /// The worst value reached (maximum for upper limits, minimum for lower).
    pub worst: f64,
    /// Margin in natural units: limit − worst (upper) or worst − limit (lower); ≥ 0 is feasible.
    pub margin: f64,
    /// Time of the worst value (s).
    pub at: f64,
    /// Unit.
    pub unit: String,
}

fn order_name(order: usize) -> (&'static str, ConstraintKind, &'static str) {
    match order {
        0 => ("q", ConstraintKind::Position, "rad"),
        1 => ("qd", ConstraintKind::Velocity, "rad/s"),
        _ => ("qdd", ConstraintKind::Acceleration, "rad/s²"),
    }
}

impl Constraints {
    /// Builds the constraint set: joint limits from `limits` (infinite entries
    /// are skipped), Cartesian constraints resolved on `robot`, `grid_rate`
    /// (Hz) the constraint grid for torques and Cartesian margins (over one
    /// period, or the whole rest-to-rest motion, of the shape).
    pub fn new(
        robot: impl Into<Arc<Robot>>,
        shape: impl Into<TrajShape>,
        limits: &JointLimitSpec,
        cartesian: &[CartesianConstraint],
        grid_rate: f64,
        ctx: &str,
    ) -> Result<Self> {
        let (robot, shape): (Arc<Robot>, TrajShape) = (robot.into(), shape.into());
        let robot = &robot;
        let n = robot.dof();
        for (name, len) in [
            ("position", limits.position.len()),
            ("velocity", limits.velocity.len()),
            ("acceleration", limits.acceleration.len()),
            ("torque", limits.torque.len()),
        ] {
            if len != n {
                return Err(Error::dim(format!("{name} limits (one per joint)"), n, len));
            }
        }
        let mut info = Vec::new();
        let mut items = Vec::new();
        let jn = |j: usize| robot.joints[j].name.clone();
        for j in 0..n {
            let [lo, hi] = limits.position[j];
            if lo.is_finite() && hi.is_finite() && lo >= hi {
                return Err(Error::invalid(
                    ctx,
                    "limits.position",
                    format!("joint `{}`: empty allowed range [{lo}, {hi}]", jn(j)),
                ));
            }
            let half = if lo.is_finite() && hi.is_finite() { 0.5 * (hi - lo) } else { 1.0 };
            for (order, lims) in [
                (0usize, [lo, hi]),
                (1, [-limits.velocity[j], limits.velocity[j]]),
                (2, [-limits.acceleration[j], limits.acceleration[j]]),
            ] {
                let (sym, kind, unit) = order_name(order);
                let scale = if order == 0 { half } else { lims[1] };
                for (upper, lim) in [(true, lims[1]), (false, lims[0])] {
                    if !lim.is_finite() {
                        continue;
                    }
                    info.push(ConstraintInfo {
                        name: format!("{sym}{} ({}) {} {lim:.4}", j + 1, jn(j), if upper { "≤" } else { "≥" }),
                        kind,
                        joint: Some(j),
                        limit: lim,
                        upper,
                        scale,
                        unit: unit.into(),
                    });
                    items.push(Item::Joint { j, order });
                }
            }
        }
        for j in 0..n {
            let tl = limits.torque[j];
            if !tl.is_finite() {
                continue;
            }
            if tl <= 0.0 {
                return Err(Error::invalid(
                    ctx,
                    "limits.torque",
                    format!("joint `{}`: expected a positive torque limit, got {tl}", jn(j)),
                ));
            }
            for (upper, lim) in [(true, tl), (false, -tl)] {
                info.push(ConstraintInfo {
                    name: format!("tau{} ({}) {} {lim:.4}", j + 1, jn(j), if upper { "≤" } else { "≥" }),
                    kind: ConstraintKind::Torque,
                    joint: Some(j),
                    limit: lim,
                    upper,
                    scale: tl,
                    unit: "N·m".into(),
                });
                items.push(Item::Torque { j });
            }
        }
        let mut cart = Vec::new();
        for (ci, c) in cartesian.iter().enumerate() {
            let field = format!("workspace[{ci}]");
            let frame = c.resolve(robot, ctx, &field)?;
            let label = format!("{} {}", frame.name, c.shape.describe());
            let nm = c.shape.n_margins();
            let names = margin_names(&c.shape);
            for k in 0..nm {
                info.push(ConstraintInfo {
                    name: format!("{}: {}", label, names[k]),
                    kind: ConstraintKind::Cartesian,
                    joint: None,
                    limit: 0.0,
                    upper: false,
                    scale: 1.0,
                    unit: "m".into(),
                });
                items.push(Item::Cart { idx: cart.len(), margin: k });
            }
            cart.push(CartItem {
                frame,
                shape: c.shape.clone(),
                label,
            });
        }
        let grid = shape.grid(period_grid(shape.duration(), grid_rate)?);
        let scan = shape.grid(shape.scan_times());
        Ok(Constraints {
            robot: Arc::clone(robot),
            shape,
            info,
            items,
            cart,
            scene: None,
            grid,
            scan,
            theta: robot.nominal_params().as_slice().to_vec(),
        })
    }

    /// Adds one minimum-distance constraint per checked pair of `scene`:
    /// c = (margin − min_t d̃(t)) / [`DISTANCE_SCALE`], d̃ = min(d, cap) on the
    /// constraint grid, the minimum refined by a parabola.
    pub fn with_collision(mut self, scene: CollisionScene) -> Self {
        for (k, p) in scene.pairs.iter().enumerate() {
            self.info.push(ConstraintInfo {
                name: format!("distance {} ≥ {:.4}", p.label(), scene.margin),
                kind: match p.class {
                    PairClass::SelfCollision => ConstraintKind::SelfCollision,
                    PairClass::World => ConstraintKind::WorldCollision,
                },
                joint: None,
                limit: scene.margin,
                upper: false,
                scale: DISTANCE_SCALE,
                unit: "m".into(),
            });
            self.items.push(Item::Distance { pair: k });
        }
        self.scene = Some(std::sync::Arc::new(scene));
        self
    }

    /// Chooses the narrow phase of the distance constraints (default
    /// [`NarrowPhase::Climb`]; [`NarrowPhase::Scan`] is the reference).
    pub fn with_narrow_phase(mut self, np: NarrowPhase) -> Self {
        if let Some(sc) = self.scene.as_mut() {
            std::sync::Arc::make_mut(sc).set_narrow_phase(np);
        }
        self
    }

    /// The collision scene, if collisions are checked.
    pub fn scene(&self) -> Option<&CollisionScene> {
        self.scene.as_deref()
    }

    /// Checks one configuration: the pair closest to the bodies' margin, if
    /// it is closer than the margin (`None`: every checked pair keeps the
    /// margin, or no collision is checked). For lead-in/out and pose checks.
    pub fn collision_at(&self, ws: &mut Workspace, q: &[f64]) -> Option<CollisionReport> {
        let sc = self.scene.as_deref()?;
        let w = sc.worst_at(&self.robot, &mut ws.kin, q, sc.cap)?;
        if w.distance >= sc.margin {
            return None;
        }
        Some(CollisionReport {
            pair: w.label,
            kind: match sc.pairs[w.pair].class {
                PairClass::SelfCollision => ConstraintKind::SelfCollision,
                PairClass::World => ConstraintKind::WorldCollision,
            },
            distance: w.distance,
            margin: sc.margin,
            depth: (-w.distance).max(0.0),
        })
    }

    /// [`Self::collision_at`] for a sequence of nearby configurations (a
    /// sampled path): the same result, with the normals of the pairs' last
    /// exact queries kept in `hints` (one per pair; start with an empty
    /// vector) so that a pose every pair provably keeps the margin at
    /// ([`CollisionScene::clear_at`]) needs few or no exact queries.
    pub fn collision_along(&self, ws: &mut Workspace, q: &[f64], hints: &mut Vec<Option<Vector3<f64>>>) -> Option<CollisionReport> {
        let sc = self.scene.as_deref()?;
        forward_kinematics(&self.robot, q, &mut ws.kin);
        let mut poses = Vec::with_capacity(sc.bodies().len());
        sc.poses(&ws.kin, &mut poses);
        if sc.clear_at(&poses, sc.margin, hints) {
            return None;
        }
        self.collision_at(ws, q)
    }

    /// Number of scalar constraints.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when there is no constraint.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Number of torque or Cartesian constraints (the ones that need the grid).
    pub fn needs_grid(&self) -> bool {
        self.items.iter().any(|i| !matches!(i, Item::Joint { .. }))
    }

    /// Descriptions of the Cartesian constraints (frame and shape).
    pub fn cartesian_labels(&self) -> Vec<String> {
        self.cart.iter().map(|c| c.label.clone()).collect()
    }

    /// A workspace (one per thread).
    pub fn workspace(&self) -> ConstraintWorkspace {
        let n = self.robot.dof();
        ConstraintWorkspace {
            ws: Workspace::new(&self.robot),
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
            tau: vec![0.0; n],
            tau_grid: vec![vec![0.0; n]; self.grid.len()],
            marg_grid: vec![Vec::new(); self.grid.len()],
            margins: Vec::with_capacity(6),
            pose_grid: vec![Vec::new(); self.grid.len()],
            series: vec![DistanceSeries::default(); self.scene.as_deref().map_or(0, |s| s.len())],
            poses: Vec::new(),
            grad: StateGradient::zeros(n),
            pull: Default::default(),
            exhaustive: false,
            selection: false,
            scan_raw: vec![Vec::new(); 3 * n],
            scanned: vec![false; 3 * n],
        }
    }

    /// Constraint values c(x) (≤ 0 feasible) into `c`, and if `jac` is given
    /// the Jacobian, row-major (`jac[i * n_vars + v]` = ∂c_i/∂x_v, the nlopt layout).
    pub fn eval(&self, x: &[f64], cw: &mut ConstraintWorkspace, c: &mut [f64], jac: Option<&mut [f64]>) {
        let tr = self.shape.motion(x);
        self.eval_traj(&tr, cw, c, jac)
    }

    /// The constraint values the GA's selection needs (feasibility first, then
    /// the total violation, [`Self::violation`]): as [`Self::eval`] without
    /// the Jacobian, except that a distance constraint that holds at every
    /// grid time reports 0 instead of its (negative) value. Its distances are
    /// capped at the margin instead of margin + band, so the broad phase skips
    /// every pair and grid time whose bound is above the margin; a pair closer
    /// than the margin somewhere on the grid gets the value of [`Self::eval`]
    /// (the grid minimum and its neighbours exact at the full cap, the same
    /// parabola). The violation therefore equals that of [`Self::eval`] except
    /// for a pair that keeps the margin at every grid time while the parabola
    /// through its grid minimum dips below it (then 0 here, a small positive
    /// value there): the selection counts a design feasible on the grid.
    pub fn eval_selection(&self, x: &[f64], cw: &mut ConstraintWorkspace, c: &mut [f64]) {
        let tr = self.shape.motion(x);
        cw.selection = true;
        self.eval_traj(&tr, cw, c, None);
        cw.selection = false;
    }

    /// Sum of positive constraint values (the violation measure of the GA).
    pub fn violation(c: &[f64]) -> f64 {
        c.iter().map(|v| v.max(0.0)).sum()
    }

    /// Scales each joint's motion about its centre (the shape's
    /// [`TrajectoryShape::joint_vars`]: the Fourier harmonics about q0, the
    /// B-spline's control points about q0) so that its position, velocity
    /// and acceleration constraints hold with relative slack `slack` (the
    /// GA's repair operator; torque and Cartesian constraints are left to the
    /// feasibility-first selection). `x` is changed in place; a centre that is
    /// a design variable (q0 with `vary_q0`) is first clamped into the allowed range.
    pub fn repair_joints(&self, x: &mut [f64], limits: &JointLimitSpec, slack: f64) {
        let n = self.robot.dof();
        self.shape.clamp_centre(x, &limits.position);
        let tr = self.shape.motion(x);
        let mut raw = Vec::new();
        for j in 0..n {
            let q0 = self.shape.centre(x, j);
            let mut s: f64 = 1.0;
            let [lo, hi] = limits.position[j];
            self.shape.grid_series(&self.scan, &tr, j, 0, &mut raw);
            let (mx, _) = joint_extremum_scanned(&tr, &self.scan, &raw, j, 0, true);
            let (mn, _) = joint_extremum_scanned(&tr, &self.scan, &raw, j, 0, false);
            if hi.is_finite() && mx - q0 > 0.0 {
                s = s.min(((hi - q0) / (mx - q0)).max(0.0));
            }
            if lo.is_finite() && q0 - mn > 0.0 {
                s = s.min(((q0 - lo) / (q0 - mn)).max(0.0));
            }
            for (order, lim) in [(1usize, limits.velocity[j]), (2, limits.acceleration[j])] {
                if !lim.is_finite() {
                    continue;
                }
                self.shape.grid_series(&self.scan, &tr, j, order, &mut raw);
                let (vmax, _) = joint_extremum_scanned(&tr, &self.scan, &raw, j, order, true);
                let (vmin, _) = joint_extremum_scanned(&tr, &self.scan, &raw, j, order, false);
                let amp = vmax.max(-vmin);
                if amp > 0.0 {
                    s = s.min(lim / amp);
                }
            }
            if s < 1.0 {
                let s = s * (1.0 - slack);
                for v in &mut x[self.shape.joint_vars(j)] {
                    *v *= s;
                }
            }
        }
    }

    /// The trajectory shape the constraints are evaluated for.
    pub fn shape(&self) -> &TrajShape {
        &self.shape
    }
}

/// World position of a frame origin at q (forward kinematics without the
/// rotation-to-quaternion conversion of [`crate::robot::frame_pose`]).
pub fn frame_point(robot: &Robot, ws: &mut Workspace, q: &[f64], frame: &Frame) -> Vector3<f64> {
    crate::robot::kinematics::forward_kinematics(robot, q, &mut ws.kin);
    let pp = frame.placement.translation.vector;
    match frame.link {
        None => pp,
        Some(l) => ws.kin.wpos[l] + ws.kin.wrot[l] * pp,
    }
}

fn margin_names(shape: &Shape) -> Vec<String> {
    let ax = ["x", "y", "z"];
    match shape {
        Shape::Box { .. } => (0..3).flat_map(|i| [format!("{} ≥ min", ax[i]), format!("{} ≤ max", ax[i])]).collect(),
        Shape::Sphere { .. } => vec!["inside radius".into()],
        Shape::HalfSpace { .. } => vec!["on the allowed side".into()],
        Shape::OutsideBox { .. } => vec!["outside the obstacle".into()],
        Shape::Sector { .. } => vec![
            "azimuth ≥ min".into(),
            "azimuth ≤ max".into(),
            "radius ≥ min".into(),
            "radius ≤ max".into(),
            "z ≥ min".into(),
            "z ≤ max".into(),
        ],
    }
}
