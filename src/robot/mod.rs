//! Robot models: the immutable [`Robot`], loaders (URDF, DH tables in TOML),
//! kinematics, rigid-body dynamics (RNEA, CRBA, derivatives), the regressor.

pub mod model;

pub use model::*;
