//! Robot models: the immutable [`Robot`], loaders (URDF, DH tables in TOML),
//! kinematics, rigid-body dynamics (RNEA, CRBA, derivatives), the regressor,
//! Cartesian workspace constraints.
//!
//! Habit: model apart from data. [`Robot`] is built once and never mutated;
//! [`Workspace`] holds every buffer; algorithms are free functions
//! (`regressor(&robot, &mut ws, q, qd, qdd, &mut out)`).

pub mod cartesian;
pub mod collision;
pub mod dynamics;
pub mod export;
pub mod file;
pub mod kinematics;
pub mod mjcf;
pub mod model;
pub mod payload;
pub mod provenance;
pub mod resolve;
pub mod urdf;
pub mod validate;

pub use dynamics::{
    bias_forces, drive_params, forward_dynamics, forward_dynamics_into, friction_torque, gravity, id_derivative_rows, id_derivatives, inverse_dynamics,
    mass_matrix, mass_matrix_into, mass_matrix_with, mass_matrix_with_into, motor_inertia, regressor, regressor_derivatives, regressor_rows, rk4_step, rnea,
    Workspace,
};
pub use file::load;
pub use kinematics::{frame_jacobian, frame_pose, link_poses, Real};
pub use model::*;
