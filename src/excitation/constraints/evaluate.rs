//! Evaluation of the constraints and their Jacobian: the grids, one value
//! function per constraint kind, and the pull-back of the state gradient to x.

use super::{frame_point, joint_extremum_scanned, ConstraintInfo, ConstraintWorkspace, Constraints, Item, DISTANCE_SCALE};
use crate::robot::collision::DistanceSeries;
use crate::robot::kinematics::forward_kinematics;
use crate::robot::{frame_jacobian, id_derivatives, inverse_dynamics, motor_inertia};
use crate::trajectory::{Motion, ShapeMotion, TimeGrid, TrajectoryShape};
use rayon::prelude::*;

impl Constraints {
    fn clear_grad(cw: &mut ConstraintWorkspace) {
        cw.grad.clear();
    }

    /// As [`Self::eval`] for a trajectory (the Jacobian is still w.r.t. the layout's x).
    ///
    /// In steps: the torques on the constraint grid (`torque_grid`),
    /// the body poses and per-pair distance series (`distance_grid`),
    /// then each constraint's value and, with `jac`, its gradient with
    /// respect to the state at the time of its worst value (joint, torque,
    /// Cartesian or distance), pulled back to x (`pull_back`).
    pub fn eval_traj(&self, tr: &ShapeMotion, cw: &mut ConstraintWorkspace, c: &mut [f64], mut jac: Option<&mut [f64]>) {
        assert_eq!(c.len(), self.len(), "constraint output length");
        let nv = self.shape.n_vars();
        self.torque_grid(tr, cw);
        self.distance_grid(tr, cw);
        let mut last_cart = usize::MAX;
        let want_grad = jac.is_some();
        cw.scanned.iter_mut().for_each(|v| *v = false);
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
    fn torque_grid(&self, tr: &ShapeMotion, cw: &mut ConstraintWorkspace) {
        if !self.items.iter().any(|i| matches!(i, Item::Torque { .. })) {
            return;
        }
        for g in 0..self.grid.len() {
            self.shape.grid_state(&self.grid, tr, g, &mut cw.q, &mut cw.qd, &mut cw.qdd);
            inverse_dynamics(&self.robot, &mut cw.ws, &self.theta, &cw.q, &cw.qd, &cw.qdd, &mut cw.tau);
            cw.tau_grid[g].copy_from_slice(&cw.tau);
        }
    }

    /// Body poses once per grid time, then per pair the exact distance only
    /// where it can be the pair's minimum over the grid (when collisions are checked).
    fn distance_grid(&self, tr: &ShapeMotion, cw: &mut ConstraintWorkspace) {
        let Some(sc) = self.scene.as_deref() else {
            return;
        };
        for g in 0..self.grid.len() {
            self.shape.grid_state(&self.grid, tr, g, &mut cw.q, &mut cw.qd, &mut cw.qdd);
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
    fn margin_grid(&self, tr: &ShapeMotion, idx: usize, cw: &mut ConstraintWorkspace) {
        let ci = &self.cart[idx];
        for g in 0..self.grid.len() {
            self.shape.grid_state(&self.grid, tr, g, &mut cw.q, &mut cw.qd, &mut cw.qdd);
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
    fn joint_value(&self, tr: &ShapeMotion, inf: &ConstraintInfo, j: usize, order: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
        let sgn = if inf.upper { 1.0 } else { -1.0 };
        let k = 3 * j + order;
        if !cw.scanned[k] {
            self.shape.grid_series(&self.scan, tr, j, order, &mut cw.scan_raw[k]);
            cw.scanned[k] = true;
        }
        let (v, t) = joint_extremum_scanned(tr, &self.scan, &cw.scan_raw[k], j, order, inf.upper);
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
    fn torque_value(&self, tr: &ShapeMotion, inf: &ConstraintInfo, j: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
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
    fn cartesian_value(&self, tr: &ShapeMotion, idx: usize, margin: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
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
    fn distance_value(&self, tr: &ShapeMotion, pair: usize, want_grad: bool, cw: &mut ConstraintWorkspace) -> (f64, Option<f64>) {
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

    /// Pulls the state gradient `cw.grad` at time t back to x into `row`
    /// through the shape's Jacobian ([`TrajectoryShape::pull_back`]).
    fn pull_back(&self, tr: &ShapeMotion, t: f64, cw: &mut ConstraintWorkspace, row: &mut [f64]) {
        self.shape.pull_back(tr, t, &cw.grad, &mut cw.pull, row);
    }

    /// Maximum of a function sampled on the constraint grid (taken as
    /// periodic: a rest-to-rest motion ends where it starts), refined
    /// by a parabola through the best grid point and its neighbours. Returns (value, time).
    fn refine_grid(&self, vals: &[f64], f: impl Fn(f64, &mut ConstraintWorkspace) -> f64, cw: &mut ConstraintWorkspace) -> (f64, f64) {
        let ng = vals.len();
        let mut ib = 0;
        for i in 1..ng {
            if vals[i] > vals[ib] {
                ib = i;
            }
        }
        let grid = self.grid.times();
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
}
