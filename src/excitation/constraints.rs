//! Constraints of the excitation design and their analytic gradients.
//!
//! Every constraint is a scalar c_i(x) ≤ 0 (feasible), scaled to be
//! dimensionless: c_i = (worst value over the period − limit) / scale.
//!
//! * **Joint position, velocity, acceleration** (per joint, upper and lower):
//!   the extremum over the *continuous* period of the trigonometric
//!   polynomial q_j^(m)(t), m = 0, 1, 2. It is found by scanning a grid of
//!   [`SCAN_PER_HARMONIC`] points per period of the highest harmonic, then
//!   Newton steps on d/dt q_j^(m) = 0 from the best grid local extrema
//!   (analytic derivatives up to order 4). By the envelope theorem the
//!   gradient is ∂q_j^(m)(t*)/∂x — the Fourier basis at t*. Scale: half the
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

use super::grid::TrigGrid;
use crate::error::{Error, Result};
use crate::robot::cartesian::{CartesianConstraint, Shape};
use crate::robot::collision::{CollisionScene, DistanceSeries, NarrowPhase, PairClass};
use crate::robot::kinematics::forward_kinematics;
use crate::robot::{frame_jacobian, id_derivatives, inverse_dynamics, motor_inertia, Frame, Robot, Workspace};
use crate::trajectory::{period_grid, Basis, FourierLayout, FourierTrajectory};
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

/// Grid points per period of the highest harmonic used to bracket joint extrema.
pub const SCAN_PER_HARMONIC: usize = 24;

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
    robot: Robot,
    layout: FourierLayout,
    /// One entry per scalar constraint.
    pub info: Vec<ConstraintInfo>,
    items: Vec<Item>,
    cart: Vec<CartItem>,
    scene: Option<std::sync::Arc<CollisionScene>>,
    grid: TrigGrid,
    scan: TrigGrid,
    theta: Vec<f64>,
}

/// Per-thread buffers for constraint evaluations.
#[derive(Debug, Clone)]
pub struct ConstraintWorkspace {
    ws: Workspace,
    basis: Basis,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
    tau_grid: Vec<Vec<f64>>,
    marg_grid: Vec<Vec<f64>>,
    margins: Vec<(f64, Vector3<f64>)>,
    g_q0: Vec<f64>,
    g_a: Vec<Vec<f64>>,
    g_b: Vec<Vec<f64>>,
    /// Body poses at every grid time (computed once per evaluation, shared by the pairs).
    pose_grid: Vec<Vec<nalgebra::Isometry3<f64>>>,
    /// Per pair: the capped distance on the grid, exact where it can be the minimum.
    series: Vec<DistanceSeries>,
    poses: Vec<nalgebra::Isometry3<f64>>,
    /// The gradient of the constraint being evaluated with respect to the
    /// state at its time t* (pulled back to x by [`Constraints::pull_back`]).
    grad: StateGradient,
    exhaustive: bool,
    /// Evaluation for the GA's selection ([`Constraints::eval_selection`]).
    selection: bool,
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

/// The gradient of a scalar with respect to the state at one time t: the
/// scalar's gradient with respect to x is
/// factor · Σ_a (q_a ∂q_a(t)/∂x + qd_a ∂q̇_a(t)/∂x + qdd_a ∂q̈_a(t)/∂x).
#[derive(Debug, Clone)]
struct StateGradient {
    factor: f64,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
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

/// m-th time derivative of q_j at t (m = 0 includes q0).
pub fn series_derivative(tr: &FourierTrajectory, j: usize, m: usize, t: f64) -> f64 {
    series_derivatives(tr, j, m, t)[0]
}

/// Time derivatives of orders m, m+1, m+2 of q_j at t (order 0 includes q0),
/// with one sin_cos and the angle-addition recurrence for the harmonics.
pub fn series_derivatives(tr: &FourierTrajectory, j: usize, m: usize, t: f64) -> [f64; 3] {
    let w = tr.omega;
    let (s1, c1) = (w * t).sin_cos();
    let (mut s, mut c) = (s1, c1);
    let mut out = [0.0; 3];
    if m == 0 {
        out[0] = tr.q0[j];
    }
    for (k0, (&a, &b)) in tr.a[j].iter().zip(&tr.b[j]).enumerate() {
        let kw = (k0 + 1) as f64 * w;
        for (d, o) in out.iter_mut().enumerate() {
            let order = m + d;
            let (sm, cm) = match order % 4 {
                0 => (s, c),
                1 => (c, -s),
                2 => (-s, -c),
                _ => (-c, s),
            };
            *o += kw.powi(order as i32 - 1) * (a * sm - b * cm);
        }
        let sn = s * c1 + c * s1;
        c = c * c1 - s * s1;
        s = sn;
    }
    out
}

/// Extremum of q_j^(order) over the continuous period: (value, time).
/// `upper`: maximum, else minimum. `scan` is a uniform grid over the period:
/// the best two grid local extrema are refined by Newton steps on
/// d/dt q_j^(order) = 0.
pub fn joint_extremum(tr: &FourierTrajectory, scan: &TrigGrid, j: usize, order: usize, upper: bool) -> (f64, f64) {
    let sgn = if upper { 1.0 } else { -1.0 };
    let ns = scan.len();
    let vals: Vec<f64> = (0..ns).map(|i| sgn * scan.derivative(tr, j, order, i)).collect();
    let scan = &scan.times;
    let mut cand: [Option<usize>; 2] = [None, None];
    for i in 0..ns {
        if vals[i] >= vals[(i + ns - 1) % ns] && vals[i] >= vals[(i + 1) % ns] {
            match cand {
                [None, _] => cand[0] = Some(i),
                [Some(a), None] => {
                    if vals[i] > vals[a] {
                        cand = [Some(i), Some(a)];
                    } else {
                        cand[1] = Some(i);
                    }
                }
                [Some(a), Some(b)] => {
                    if vals[i] > vals[a] {
                        cand = [Some(i), Some(a)];
                    } else if vals[i] > vals[b] {
                        cand[1] = Some(i);
                    }
                }
            }
        }
    }
    if cand[0].is_none() {
        return (sgn * vals[0], scan[0]);
    }
    let h = if ns > 1 { scan[1] - scan[0] } else { 1.0 };
    let (mut best, mut tbest) = (f64::NEG_INFINITY, 0.0);
    for i in cand.iter().flatten().copied() {
        let (mut t, mut fv) = (scan[i], vals[i]);
        let t_grid = t;
        let mut d = series_derivatives(tr, j, order, t);
        for _ in 0..8 {
            let (d1, d2) = (sgn * d[1], sgn * d[2]);
            if d2 >= 0.0 {
                break;
            }
            let step = -d1 / d2;
            let tn = t + step;
            if (tn - t_grid).abs() > 1.5 * h {
                break;
            }
            let dn = series_derivatives(tr, j, order, tn);
            let fnv = sgn * dn[0];
            if fnv < fv - 1e-15 * fv.abs().max(1.0) {
                break;
            }
            t = tn;
            fv = fnv;
            d = dn;
            if step.abs() < 1e-9 * h {
                break;
            }
        }
        if fv > best {
            best = fv;
            tbest = t;
        }
    }
    (sgn * best, tbest)
}

impl Constraints {
    /// Builds the constraint set: joint limits from `limits` (infinite entries
    /// are skipped), Cartesian constraints resolved on `robot`, `grid_rate`
    /// (Hz) the constraint grid for torques and Cartesian margins.
    pub fn new(robot: &Robot, layout: &FourierLayout, limits: &JointLimitSpec, cartesian: &[CartesianConstraint], grid_rate: f64, ctx: &str) -> Result<Self> {
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
        let period = std::f64::consts::TAU / layout.omega;
        let grid = TrigGrid::new(period_grid(period, grid_rate)?, layout.omega, layout.n_h);
        let ns = (SCAN_PER_HARMONIC * layout.n_h).max(32);
        let scan = TrigGrid::new((0..ns).map(|i| period * i as f64 / ns as f64).collect(), layout.omega, layout.n_h);
        Ok(Constraints {
            robot: robot.clone(),
            layout: layout.clone(),
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
        let nh = self.layout.n_h;
        ConstraintWorkspace {
            ws: Workspace::new(&self.robot),
            basis: Basis::default(),
            q: vec![0.0; n],
            qd: vec![0.0; n],
            qdd: vec![0.0; n],
            tau: vec![0.0; n],
            tau_grid: vec![vec![0.0; n]; self.grid.len()],
            marg_grid: vec![Vec::new(); self.grid.len()],
            margins: Vec::with_capacity(6),
            g_q0: vec![0.0; n],
            g_a: vec![vec![0.0; nh]; n],
            g_b: vec![vec![0.0; nh]; n],
            pose_grid: vec![Vec::new(); self.grid.len()],
            series: vec![DistanceSeries::default(); self.scene.as_deref().map_or(0, |s| s.len())],
            poses: Vec::new(),
            grad: StateGradient {
                factor: 0.0,
                q: vec![0.0; n],
                qd: vec![0.0; n],
                qdd: vec![0.0; n],
            },
            exhaustive: false,
            selection: false,
        }
    }

    fn clear_grad(cw: &mut ConstraintWorkspace) {
        let g = &mut cw.grad;
        for v in g.q.iter_mut().chain(g.qd.iter_mut()).chain(g.qdd.iter_mut()) {
            *v = 0.0;
        }
    }

    /// Constraint values c(x) (≤ 0 feasible) into `c`, and if `jac` is given
    /// the Jacobian, row-major (`jac[i * n_vars + v]` = ∂c_i/∂x_v, the nlopt layout).
    pub fn eval(&self, x: &[f64], cw: &mut ConstraintWorkspace, c: &mut [f64], jac: Option<&mut [f64]>) {
        let tr = self.layout.trajectory(x);
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
        let tr = self.layout.trajectory(x);
        cw.selection = true;
        self.eval_traj(&tr, cw, c, None);
        cw.selection = false;
    }

    /// As [`Self::eval`] for a trajectory (the Jacobian is still w.r.t. the layout's x).
    ///
    /// In steps: the torques on the constraint grid (`torque_grid`),
    /// the body poses and per-pair distance series (`distance_grid`),
    /// then each constraint's value and, with `jac`, its gradient with
    /// respect to the state at the time of its worst value (joint, torque,
    /// Cartesian or distance), pulled back to x (`pull_back`).
    pub fn eval_traj(&self, tr: &FourierTrajectory, cw: &mut ConstraintWorkspace, c: &mut [f64], mut jac: Option<&mut [f64]>) {
        assert_eq!(c.len(), self.len(), "constraint output length");
        let nv = self.layout.n_vars();
        self.torque_grid(tr, cw);
        self.distance_grid(tr, cw);
        let mut last_cart = usize::MAX;
        let want_grad = jac.is_some();
        for (i, item) in self.items.iter().enumerate() {
            let inf = &self.info[i];
            if want_grad {
                Self::clear_grad(cw);
            }
            let (value, at) = match *item {
                Item::Joint { j, order } => self.joint_value(tr, inf, j, order, want_grad, cw),
                Item::Torque { j } => self.torque_value(tr, inf, j, want_grad, cw),
                Item::Cart { idx, margin } => {
                    if last_cart != idx {
                        self.margin_grid(tr, idx, cw);
                        last_cart = idx;
                    }
                    self.cartesian_value(tr, idx, margin, want_grad, cw)
                }
                Item::Distance { pair } => self.distance_value(tr, pair, want_grad, cw),
            };
            c[i] = value;
            if let Some(jac) = jac.as_deref_mut() {
                let row = &mut jac[i * nv..(i + 1) * nv];
                match at {
                    Some(t) => self.pull_back(tr, t, cw, row),
                    None => row.iter_mut().for_each(|v| *v = 0.0),
                }
            }
        }
    }

    /// τ(t_g) of inverse dynamics at every constraint grid time (when a torque is limited).
    fn torque_grid(&self, tr: &FourierTrajectory, cw: &mut ConstraintWorkspace) {
        if !self.items.iter().any(|i| matches!(i, Item::Torque { .. })) {
            return;
        }
        for g in 0..self.grid.len() {
            self.grid.state(tr, g, &mut cw.q, &mut cw.qd, &mut cw.qdd);
            inverse_dynamics(&self.robot, &mut cw.ws, &self.theta, &cw.q, &cw.qd, &cw.qdd, &mut cw.tau);
            cw.tau_grid[g].copy_from_slice(&cw.tau);
        }
    }

    /// Body poses once per grid time, then per pair the exact distance only
    /// where it can be the pair's minimum over the grid (when collisions are checked).
    fn distance_grid(&self, tr: &FourierTrajectory, cw: &mut ConstraintWorkspace) {
        let Some(sc) = self.scene.as_deref() else {
            return;
        };
        for g in 0..self.grid.len() {
            self.grid.state(tr, g, &mut cw.q, &mut cw.qd, &mut cw.qdd);
            forward_kinematics(&self.robot, &cw.q, &mut cw.ws.kin);
            sc.poses(&cw.ws.kin, &mut cw.pose_grid[g]);
        }
        let cap = if cw.selection { sc.margin } else { sc.cap };
        // the pairs on the rayon pool when the evaluation runs outside it
        // (the refinement); inside it (the GA's evaluations, parallel
        // refinement starts) one after the other: nested, the pool's
        // threads are already busy and the fork-join only costs. Each
        // pair's series depends on that pair alone, so the values do not
        // depend on the thread count.
        let (pose_grid, exhaustive) = (&cw.pose_grid, cw.exhaustive);
        let one = |(k, out): (usize, &mut DistanceSeries)| sc.pair_series(k, pose_grid, cap, exhaustive, out);
        if rayon::current_thread_index().is_none() {
            cw.series.par_iter_mut().enumerate().for_each(one);
        } else {
            cw.series.iter_mut().enumerate().for_each(one);
        }
    }

    /// The margins of Cartesian constraint `idx` at every grid time.
    fn margin_grid(&self, tr: &FourierTrajectory, idx: usize, cw: &mut ConstraintWorkspace) {
        let ci = &self.cart[idx];
        for g in 0..self.grid.len() {
            self.grid.state(tr, g, &mut cw.q, &mut cw.qd, &mut cw.qdd);
            let p = frame_point(&self.robot, &mut cw.ws, &cw.q, &ci.frame);
            cw.margins.clear();
            ci.shape.margins(&p, &mut cw.margins);
            let row = &mut cw.marg_grid[g];
            row.clear();
            row.extend(cw.margins.iter().map(|m| m.0));
        }
    }

    /// Joint position, velocity or acceleration limit: the extremum of
    /// q_j^(order) over the continuous period; gradient ∂q_j^(order)(t*)/∂x.
    /// Returns (value, t* when the gradient was set).
    fn joint_value(
        &self,
        tr: &FourierTrajectory,
        inf: &ConstraintInfo,
        j: usize,
        order: usize,
        want_grad: bool,
        cw: &mut ConstraintWorkspace,
    ) -> (f64, Option<f64>) {
        let sgn = if inf.upper { 1.0 } else { -1.0 };
        let (v, t) = joint_extremum(tr, &self.scan, j, order, inf.upper);
        if !want_grad {
            return (sgn * (v - inf.limit) / inf.scale, None);
        }
        let g = &mut cw.grad;
        g.factor = sgn / inf.scale;
        [&mut g.q, &mut g.qd, &mut g.qdd][order.min(2)][j] = 1.0;
        (sgn * (v - inf.limit) / inf.scale, Some(t))
    }

    /// Joint torque limit: the extremum of τ_j on the grid refined by a
    /// parabola; gradient ∂τ_j/∂q · ∂q/∂x + ∂τ_j/∂q̇ · ∂q̇/∂x + M_j · ∂q̈/∂x at t*.
    fn torque_value(&self, tr: &FourierTrajectory, inf: &ConstraintInfo, j: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
        let sgn = if inf.upper { 1.0 } else { -1.0 };
        let vals: Vec<f64> = cw.tau_grid.iter().map(|r| sgn * r[j]).collect();
        let (fv, t) = self.refine_grid(
            &vals,
            |t, cw: &mut ConstraintWorkspace| {
                tr.eval(t, &mut cw.q, &mut cw.qd, &mut cw.qdd);
                inverse_dynamics(&self.robot, &mut cw.ws, &self.theta, &cw.q, &cw.qd, &cw.qdd, &mut cw.tau);
                sgn * cw.tau[j]
            },
            cw,
        );
        let value = (fv - sgn * inf.limit) / inf.scale;
        if !want_grad {
            return (value, None);
        }
        tr.eval(t, &mut cw.q, &mut cw.qd, &mut cw.qdd);
        let (dq, dqd) = id_derivatives(&self.robot, &mut cw.ws, &self.theta, &cw.q, &cw.qd, &cw.qdd);
        let mi = motor_inertia(&self.robot, &mut cw.ws, &self.theta, &cw.q);
        let g = &mut cw.grad;
        g.factor = sgn / inf.scale;
        for a in 0..self.robot.dof() {
            g.q[a] = dq[(j, a)];
            g.qd[a] = dqd[(j, a)];
            g.qdd[a] = mi[(j, a)];
        }
        (value, Some(t))
    }

    /// Cartesian margin `margin` of constraint `idx` (its grid from
    /// [`Self::margin_grid`]): the minimum on the grid refined by a parabola;
    /// gradient −∂g/∂p · J_v(q(t*)) · ∂q/∂x.
    fn cartesian_value(&self, tr: &FourierTrajectory, idx: usize, margin: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
        let ci = &self.cart[idx];
        // minimise the margin: maximise −g
        let vals: Vec<f64> = cw.marg_grid.iter().map(|r| -r[margin]).collect();
        let (fv, t) = self.refine_grid(
            &vals,
            |t, cw: &mut ConstraintWorkspace| {
                tr.eval(t, &mut cw.q, &mut cw.qd, &mut cw.qdd);
                let p = frame_point(&self.robot, &mut cw.ws, &cw.q, &ci.frame);
                cw.margins.clear();
                ci.shape.margins(&p, &mut cw.margins);
                -cw.margins[margin].0
            },
            cw,
        );
        if !want_grad {
            return (fv, None);
        }
        tr.eval(t, &mut cw.q, &mut cw.qd, &mut cw.qdd);
        let p = frame_point(&self.robot, &mut cw.ws, &cw.q, &ci.frame);
        cw.margins.clear();
        ci.shape.margins(&p, &mut cw.margins);
        let dgdp = cw.margins[margin].1;
        let jm = frame_jacobian(&self.robot, &mut cw.ws, &cw.q, &ci.frame);
        let g = &mut cw.grad;
        g.factor = -1.0;
        for a in 0..self.robot.dof() {
            g.q[a] = dgdp.x * jm[(0, a)] + dgdp.y * jm[(1, a)] + dgdp.z * jm[(2, a)];
        }
        (fv, Some(t))
    }

    /// Minimum distance of checked pair `pair` (its series from
    /// [`Self::distance_grid`]): the grid minimum refined by a parabola;
    /// gradient −∂d/∂q · ∂q/∂x / [`DISTANCE_SCALE`] at t*. In the GA's
    /// selection a pair that keeps the margin at every grid time gives 0.
    fn distance_value(&self, tr: &FourierTrajectory, pair: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
        let sc = self.scene.as_deref().expect("distance constraints have a scene");
        // the parabola through the grid minimum needs its neighbours exact
        let ng = cw.pose_grid.len();
        if let Some((ib, vmin)) = cw.series[pair].argmin() {
            if cw.selection && vmin >= sc.margin {
                // holds at every grid time: all the selection needs
                return (0.0, None);
            }
            for g in [(ib + ng - 1) % ng, (ib + 1) % ng] {
                let sr = &mut cw.series[pair];
                if cw.selection && sr.exact[g] && sr.value[g] >= sc.margin {
                    // capped at the margin: the full-cap value, as in `eval`
                    sr.value[g] = sc.pair_distance(pair, &cw.pose_grid[g], sc.cap);
                    sr.queries += 1;
                } else {
                    sr.make_exact(sc, pair, g, &cw.pose_grid, sc.cap);
                }
            }
        }
        let vals: Vec<f64> = cw.series[pair].value.iter().map(|v| -v).collect();
        let (fv, t) = self.refine_grid(
            &vals,
            |t, cw: &mut ConstraintWorkspace| {
                tr.eval(t, &mut cw.q, &mut cw.qd, &mut cw.qdd);
                forward_kinematics(&self.robot, &cw.q, &mut cw.ws.kin);
                sc.poses(&cw.ws.kin, &mut cw.poses);
                -sc.pair_proximity(pair, &cw.poses, sc.cap).map_or(sc.cap, |p| p.distance)
            },
            cw,
        );
        let value = (sc.margin + fv) / DISTANCE_SCALE;
        if !want_grad {
            return (value, None);
        }
        tr.eval(t, &mut cw.q, &mut cw.qd, &mut cw.qdd);
        forward_kinematics(&self.robot, &cw.q, &mut cw.ws.kin);
        sc.poses(&cw.ws.kin, &mut cw.poses);
        let Some(p) = sc.pair_proximity(pair, &cw.poses, sc.cap) else {
            // no proximity below the cap: a zero gradient
            return (value, None);
        };
        let g = &mut cw.grad;
        g.factor = 1.0;
        // c = (margin − d)/scale: ∂c/∂q = −∂d/∂q / scale
        sc.add_gradient(&self.robot, &cw.ws.kin, pair, &p, -1.0 / DISTANCE_SCALE, &mut g.q);
        (value, Some(t))
    }

    /// Pulls the state gradient `cw.grad` at time t back to x into `row`:
    /// row = factor · Σ_a (g_q,a ∂q_a(t)/∂x + g_q̇,a ∂q̇_a(t)/∂x + g_q̈,a ∂q̈_a(t)/∂x),
    /// through the Fourier basis at t and the layout.
    fn pull_back(&self, tr: &FourierTrajectory, t: f64, cw: &mut ConstraintWorkspace, row: &mut [f64]) {
        tr.basis(t, &mut cw.basis);
        let g = &cw.grad;
        let f = g.factor;
        for a in 0..self.robot.dof() {
            cw.g_q0[a] = f * g.q[a];
            for k in 0..self.layout.n_h {
                let b = &cw.basis.k[k];
                cw.g_a[a][k] = f * (g.q[a] * b[0] + g.qd[a] * b[2] + g.qdd[a] * b[4]);
                cw.g_b[a][k] = f * (g.q[a] * b[1] + g.qd[a] * b[3] + g.qdd[a] * b[5]);
            }
        }
        self.layout.pullback(&cw.g_q0, &cw.g_a, &cw.g_b, row);
    }

    /// Maximum of a function sampled on the constraint grid (periodic), refined
    /// by a parabola through the best grid point and its neighbours. Returns (value, time).
    fn refine_grid(&self, vals: &[f64], f: impl Fn(f64, &mut ConstraintWorkspace) -> f64, cw: &mut ConstraintWorkspace) -> (f64, f64) {
        let ng = vals.len();
        let mut ib = 0;
        for i in 1..ng {
            if vals[i] > vals[ib] {
                ib = i;
            }
        }
        let grid = &self.grid.times;
        let h = if ng > 1 { grid[1] - grid[0] } else { 0.0 };
        let (fm, f0, fp) = (vals[(ib + ng - 1) % ng], vals[ib], vals[(ib + 1) % ng]);
        let den = fm - 2.0 * f0 + fp;
        let (mut best, mut tb) = (f0, grid[ib]);
        if den < 0.0 && h > 0.0 {
            let d = (0.5 * (fm - fp) / den).clamp(-1.0, 1.0) * h;
            if d.abs() > 1e-12 * h.max(1.0) {
                let t = grid[ib] + d;
                let v = f(t, cw);
                if v > best {
                    best = v;
                    tb = t;
                }
            }
        }
        (best, tb)
    }

    /// Sum of positive constraint values (the violation measure of the GA).
    pub fn violation(c: &[f64]) -> f64 {
        c.iter().map(|v| v.max(0.0)).sum()
    }

    /// Every constraint evaluated on a uniform grid at `rate` Hz over one
    /// period, in natural units.
    pub fn verify(&self, tr: &FourierTrajectory, rate: f64) -> Result<Vec<Margin>> {
        let times = period_grid(tr.period(), rate)?;
        let n = self.robot.dof();
        let mut ws = Workspace::new(&self.robot);
        let s = tr.sample_at(&times);
        let mut tau_all = Vec::new();
        if self.items.iter().any(|i| matches!(i, Item::Torque { .. })) {
            let mut tau = vec![0.0; n];
            for k in 0..s.len() {
                inverse_dynamics(&self.robot, &mut ws, &self.theta, &s.q[k], &s.qd[k], &s.qdd[k], &mut tau);
                tau_all.push(tau.clone());
            }
        }
        let mut marg_all: Vec<Vec<Vec<f64>>> = vec![Vec::new(); self.cart.len()];
        for (ci, c) in self.cart.iter().enumerate() {
            let mut m = Vec::with_capacity(6);
            for k in 0..s.len() {
                let p = frame_point(&self.robot, &mut ws, &s.q[k], &c.frame);
                m.clear();
                c.shape.margins(&p, &mut m);
                marg_all[ci].push(m.iter().map(|v| v.0).collect());
            }
        }
        let mut dist_all: Vec<DistanceSeries> = Vec::new();
        if let Some(sc) = self.scene.as_deref() {
            // distances up to 1 m above the margin (the report's worst values
            // are exact below that); per pair exact wherever it can be the
            // minimum over the grid (the only value the margin reports)
            let cap = sc.margin + 1.0;
            let mut poses = vec![Vec::new(); s.len()];
            for (k, x) in poses.iter_mut().enumerate() {
                forward_kinematics(&self.robot, &s.q[k], &mut ws.kin);
                sc.poses(&ws.kin, x);
            }
            dist_all = vec![DistanceSeries::default(); sc.len()];
            let one = |(p, out): (usize, &mut DistanceSeries)| sc.pair_series(p, &poses, cap, false, out);
            if rayon::current_thread_index().is_none() {
                dist_all.par_iter_mut().enumerate().for_each(one);
            } else {
                dist_all.iter_mut().enumerate().for_each(one);
            }
        }
        let mut out = Vec::with_capacity(self.len());
        for (i, item) in self.items.iter().enumerate() {
            let inf = &self.info[i];
            let value = |k: usize| -> f64 {
                match *item {
                    Item::Joint { j, order } => match order {
                        0 => s.q[k][j],
                        1 => s.qd[k][j],
                        _ => s.qdd[k][j],
                    },
                    Item::Torque { j } => tau_all[k][j],
                    Item::Cart { idx, margin } => marg_all[idx][k][margin],
                    Item::Distance { pair } => dist_all[pair].value[k],
                }
            };
            let (mut worst, mut at) = (if inf.upper { f64::NEG_INFINITY } else { f64::INFINITY }, 0.0);
            for k in 0..s.len() {
                let v = value(k);
                if (inf.upper && v > worst) || (!inf.upper && v < worst) {
                    worst = v;
                    at = times[k];
                }
            }
            let margin = if inf.upper { inf.limit - worst } else { worst - inf.limit };
            out.push(Margin {
                name: inf.name.clone(),
                kind: inf.kind,
                limit: inf.limit,
                worst,
                margin,
                at,
                unit: inf.unit.clone(),
            });
        }
        Ok(out)
    }

    /// Scales each joint's harmonics (about q0) so that its position,
    /// velocity and acceleration constraints hold with relative slack
    /// `slack` (the GA's repair operator; torque and Cartesian constraints are
    /// left to the feasibility-first selection). `x` is changed in place; q0
    /// (if a design variable) is first clamped into the allowed range.
    pub fn repair_joints(&self, x: &mut [f64], limits: &JointLimitSpec, slack: f64) {
        let n = self.robot.dof();
        let vpj = self.layout.vars_per_joint();
        if self.layout.vary_q0 {
            for j in 0..n {
                let [lo, hi] = limits.position[j];
                let v = &mut x[j * vpj];
                if lo.is_finite() && hi.is_finite() {
                    let pad = 1e-3 * (hi - lo);
                    *v = v.clamp(lo + pad, hi - pad);
                }
            }
        }
        let tr = self.layout.trajectory(x);
        for j in 0..n {
            let q0 = tr.q0[j];
            let mut s: f64 = 1.0;
            let [lo, hi] = limits.position[j];
            let (mx, _) = joint_extremum(&tr, &self.scan, j, 0, true);
            let (mn, _) = joint_extremum(&tr, &self.scan, j, 0, false);
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
                let (vmax, _) = joint_extremum(&tr, &self.scan, j, order, true);
                let (vmin, _) = joint_extremum(&tr, &self.scan, j, order, false);
                let amp = vmax.max(-vmin);
                if amp > 0.0 {
                    s = s.min(lim / amp);
                }
            }
            if s < 1.0 {
                let s = s * (1.0 - slack);
                let base = j * vpj + usize::from(self.layout.vary_q0);
                for v in &mut x[base..(j + 1) * vpj] {
                    *v *= s;
                }
            }
        }
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
