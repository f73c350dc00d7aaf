//! What the kernels read of the robot's tree, classified once when the
//! [`Robot`] is built (it lives in `Robot::topology`, so a [`Workspace`](super::Workspace)
//! holds buffers only).

use super::crba::{Axis, Need, Placed};
use crate::robot::model::Robot;

/// The joints' motion subspaces and rotations, the CRBA's dispatch and the
/// subtree relation.
#[derive(Debug, Clone, Default)]
pub(crate) struct Topology {
    /// The joints' motion subspaces, classified once ([`Axis`]).
    pub(crate) axes: Vec<Axis>,
    /// The joints' rotations, classified once ([`Placed`]).
    pub(crate) placed: Vec<Placed>,
    /// Most non-root joints are [`Placed::RxZ`]: the CRBA dispatches on them.
    pub(crate) rxz_crba: bool,
    /// What the Rx(α) Rz(θ) CRBA needs of each joint's transform ([`Need`]).
    pub(crate) need: Vec<Need>,
    /// A serial chain: joint i's parent is i − 1 (the CRBA's index walk).
    pub(crate) chain: bool,
    /// `s * n + i`: link i is in the subtree of joint s (s itself included).
    pub(crate) sub: Vec<bool>,
}

impl Topology {
    /// The topology of `robot` (its joints, placements and motion subspaces).
    pub(crate) fn of(robot: &Robot) -> Self {
        let n = robot.dof();
        let placed: Vec<Placed> = (0..n).map(|i| Placed::of(robot, i)).collect();
        // the dispatch on `placed` pays when most non-root joints take the shortcut
        let non_root: Vec<usize> = (0..n).filter(|&i| robot.joints[i].parent.is_some()).collect();
        let rxz = non_root.iter().filter(|&&i| matches!(placed[i], Placed::RxZ(_))).count();
        let need = (0..n).map(|i| Need::of(robot, &placed, i)).collect();
        Topology {
            axes: (0..n).map(|i| Axis::of(robot, i)).collect(),
            placed,
            chain: (0..n).all(|i| robot.joints[i].parent == i.checked_sub(1)),
            rxz_crba: 2 * rxz > non_root.len(),
            need,
            sub: (0..n * n)
                .map(|si| {
                    let (s, mut i) = (si / n, si % n);
                    loop {
                        if i == s {
                            break true;
                        }
                        match robot.joints[i].parent {
                            Some(a) => i = a,
                            None => break false,
                        }
                    }
                })
                .collect(),
        }
    }
}
