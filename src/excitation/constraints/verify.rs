//! Every constraint on a uniform verification grid, in natural units.

use super::{frame_point, Constraints, Item, Margin};
use crate::error::Result;
use crate::robot::collision::DistanceSeries;
use crate::robot::kinematics::forward_kinematics;
use crate::robot::{inverse_dynamics, Workspace};
use crate::trajectory::{period_grid, Motion, ShapeMotion};
use rayon::prelude::*;

impl Constraints {
    /// Every constraint evaluated on a uniform grid at `rate` Hz over one
    /// period (the whole motion of a rest-to-rest shape), in natural units.
    pub fn verify(&self, tr: &ShapeMotion, rate: f64) -> Result<Vec<Margin>> {
        let times = period_grid(tr.duration(), rate)?;
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
}
