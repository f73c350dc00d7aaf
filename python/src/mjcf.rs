//! `idexp.mjcf` and `idexp.write_mjcf`: a robot model (nominal, or an
//! identified one from `Identification.model()` / `Robot.with_params`) as
//! MJCF for MuJoCo, written by the library's [`idexp::robot::export::mjcf_string`].

use crate::err::IntoPy;
use crate::robot::Robot;
use pyo3::prelude::*;
use std::path::PathBuf;

/// mjcf(robot) -> str
///
/// The MJCF text of `robot` (as `idexp robot mjcf` writes it): one body per
/// link with its inertial, hinge/slide joints with range, armature = Ia,
/// damping = Fv, frictionloss = Fc, a motor per joint, gravity; what MJCF
/// cannot express (coupling, asymmetric friction, offsets, tanh/Stribeck
/// shapes) stated in XML comments. Load it with
/// `mujoco.MjModel.from_xml_string`.
#[pyfunction]
pub fn mjcf(robot: &Robot) -> String {
    idexp::robot::export::mjcf_string(&robot.inner)
}

/// write_mjcf(robot, folder) -> str
///
/// Writes `robot.xml` (the text of `mjcf(robot)`) into `folder` (created if
/// missing) and returns its path.
#[pyfunction]
pub fn write_mjcf(py: Python<'_>, robot: &Robot, folder: PathBuf) -> PyResult<PathBuf> {
    py.detach(|| idexp::robot::export::write_mjcf(&robot.inner, &folder)).py()
}
