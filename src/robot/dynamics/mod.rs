//! Rigid-body dynamics: recursive Newton–Euler inverse dynamics (RNEA), the
//! joint-torque regressor, the composite-rigid-body mass matrix (CRBA),
//! forward dynamics, the derivatives of inverse dynamics (the recursive
//! algorithm of Carpentier and Mansard, [`id_derivatives_into`]) and of the
//! regressor with respect to q, q̇, q̈ (forward-mode tangents written out in
//! f64, [`regressor_derivatives`]).
//!
//! # Model
//!
//! Motor-side torques, referred to the joint side, with coupling matrix C
//! (motor positions θ = C q):
//!
//! τ = C⁻ᵀ τ_rb(q, q̇, q̈) + Ia ⊙ (C q̈) + f(C q̇),
//!
//! τ_rb the rigid-body joint torques, Ia the reflected rotor inertias and f
//! the friction model of each drive ([`friction_columns`]: the Coulomb term
//! switches by sign, tanh or tanh with a Stribeck column, [`Coulomb`](crate::robot::Coulomb)). The regressor Y (n × p) satisfies
//! τ = Y(q, q̇, q̈) θ for the standard parameter vector θ in the layout of
//! [`Robot::params`].
//!
//! Link quantities are expressed in link coordinates about the link origin
//! (Khalil–Gautier parameters XX…ZZ about the origin, first moments MX, MY, MZ,
//! mass M). Gravity enters as a base acceleration −g.

//!
//! # Files
//!
//! `rnea` inverse dynamics · `friction` the drives' friction columns ·
//! `regressor` Y and its derivatives · `tangents` their forward-mode kernel ·
//! `derivatives` ∂τ/∂q, ∂τ/∂q̇ · `crba` the mass matrix · `forward` forward
//! dynamics and the Runge–Kutta step. [`Workspace`] (here) holds the buffers
//! of all of them.

mod crba;
mod derivatives;
mod forward;
mod friction;
mod regressor;
mod rnea;
mod tangents;
#[cfg(test)]
mod tests;
mod topology;

pub use crba::{mass_matrix, mass_matrix_into, mass_matrix_with, mass_matrix_with_into, motor_inertia};
pub use derivatives::{id_derivative_rows, id_derivatives, id_derivatives_into};
pub use forward::{forward_dynamics, forward_dynamics_into, rk4_step};
pub use friction::{drive_params, friction_columns, friction_slopes, friction_torque, visit_drive_params, DriveParams, MAX_FRICTION_COLUMNS};
pub(crate) use regressor::regressor_generic;
pub use regressor::{regressor, regressor_derivatives, regressor_rows};
pub use rnea::{bias_forces, gravity, inverse_dynamics, rnea};
pub(crate) use tangents::regressor_dual_directions;
pub(crate) use topology::Topology;

use super::kinematics::Kin;
use super::model::{Inertial, Robot};
use crba::Ten;
use derivatives::DerivLink;
use nalgebra::DMatrix;
use tangents::Tangents;

/// Per-thread buffers for every kernel (buffers only: what the kernels read
/// of the tree is classified once in the robot, `Topology`). Create one per thread
/// (e.g. rayon `map_init`) and reuse it: the kernels do not allocate.
#[derive(Debug, Clone)]
pub struct Workspace {
    pub(crate) kin: Kin<f64>,
    pub(crate) y: Vec<f64>,
    /// Shared quantities and tangents of [`regressor_derivatives`].
    tan: Tangents,
    /// Scratch for the kernels that take a parameter vector θ (the link
    /// inertials of θ); the nominal kernels read `robot.links` instead.
    theta_inertials: Vec<Inertial>,
    /// Composite inertias of the CRBA (ten parameters each).
    crb: Vec<Ten>,
    /// (cos θ, sin θ) of the [`Need::Turn`] joints (the CRBA's scratch).
    cs: Vec<(f64, f64)>,
    /// Per-link quantities of [`id_derivatives_into`].
    dl: Vec<DerivLink>,
    /// Mass matrix / Cholesky factor of forward dynamics.
    fd_m: DMatrix<f64>,
    /// Right-hand side and scratch of forward dynamics.
    fd_rhs: Vec<f64>,
    fd_tmp: Vec<f64>,
    fd_zero: Vec<f64>,
    /// Stages of [`rk4_step`]: a1..a4, q2..q4, v2..v4.
    rk: [Vec<f64>; 10],
}

impl Workspace {
    /// Buffers sized for `robot`.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.dof();
        let p = robot.n_params();
        Workspace {
            kin: Kin::new(n),
            y: vec![0.0; n * p],
            tan: Tangents::new(robot),
            theta_inertials: robot.links.iter().map(|l| l.inertial).collect(),
            crb: vec![Ten::default(); n],
            cs: vec![(1.0, 0.0); n],
            dl: vec![DerivLink::default(); n],
            fd_m: DMatrix::zeros(n, n),
            fd_rhs: vec![0.0; n],
            fd_tmp: vec![0.0; n],
            fd_zero: vec![0.0; n],
            rk: std::array::from_fn(|_| vec![0.0; n]),
        }
    }
}

/// Which terms of the dynamics to include.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Terms {
    pub gravity: bool,
    pub drive: bool,
}

const ALL: Terms = Terms { gravity: true, drive: true };
