//! The columns of `objective.columns = "gains"`: an excitation for the
//! drive-gain calibration with a known mass (`idexp payload identify` with a
//! `[gains]` table, [`crate::payload::gains`]).
//!
//! The calibration's rows are τ_file,j = γ_j·(Y_b,j θ_b + A'_j φ' + m·A_M,j + u_j)
//! (γ_j the ratio of the file's gain to the true one). Scaling every γ_j and
//! every robot parameter together leaves the robot's own torques unchanged:
//! only the known mass's torque tells the gains apart from the robot's
//! parameters (which the unloaded runs determine up to that scale). So the
//! criterion's columns are, on the trajectory with the mass mounted:
//!
//! * per joint j the gain's column: the nominal payload's torque
//!   τ_P,j = Y_L,j T φ_P (Y_L the regressor columns of the link carrying the
//!   mass's frame, T the frame → link map, φ_P the design's `[payload]`), on
//!   joint j's rows only, zero on the others — ∂τ_j/∂γ_j of the mass's part;
//! * the payload's nine unknown parameters (first moments and inertia about
//!   the frame's origin): the columns Y_L T e_k, k ≠ M, on every row.
//!
//! The robot's own parameters are taken as known (the unloaded runs'), as
//! with `columns = "payload"`. A joint the mass does not load has a zero
//! gain column: the criterion is then at its cap, as the calibration would
//! name that joint undetermined.

use super::ColumnMix;
use crate::robot::payload::{Mount, Payload, PARAM_NAMES};
use crate::robot::Robot;

/// The columns of a gain calibration's criterion on `robot` (already
/// carrying the payload) with the known mass `payload` on `mount`: n gain
/// columns then the payload's nine unknown parameters; their names and
/// nominal coefficients (1 for a gain, φ_P,k for a payload parameter).
pub fn gains_columns(robot: &Robot, mount: &Mount, payload: &Payload) -> (Vec<ColumnMix>, Vec<String>, Vec<f64>) {
    let o = robot.link_param_offset(mount.link);
    let phi = payload.params();
    let phi_link = mount.to_link(&phi);
    let mut mixes = Vec::new();
    let mut names = Vec::new();
    let mut nominal = Vec::new();
    for (j, joint) in robot.joints.iter().enumerate() {
        mixes.push(ColumnMix {
            row: Some(j),
            terms: (0..10).filter(|&k| phi_link[k] != 0.0).map(|k| (o + k, phi_link[k])).collect(),
        });
        names.push(format!("gain {}", joint.name));
        nominal.push(1.0);
    }
    // φ_F's mass is the last of the ten: known, not a column
    for (k, name) in PARAM_NAMES.iter().enumerate().take(9) {
        mixes.push(ColumnMix {
            row: None,
            terms: (0..10).filter(|&i| mount.t[(i, k)] != 0.0).map(|i| (o + i, mount.t[(i, k)])).collect(),
        });
        names.push(format!("payload {name}"));
        nominal.push(phi[k]);
    }
    (mixes, names, nominal)
}
