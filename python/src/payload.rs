//! `idexp.payload`: a payload's mass, centre of mass and inertia from loaded
//! (and unloaded) runs, as `idexp payload identify payload.toml`.

use crate::arrays::{out1, out_rows};
use crate::dicts::{design_and_dir, to_dict};
use crate::err::IntoPy;
use crate::long::run_long;
use idexp::payload::{export, PayloadDesign, PayloadResult};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// The result of a payload identification (`idexp.payload`).
#[pyclass(module = "idexp", frozen)]
pub struct PayloadFit {
    inner: Arc<PayloadResult>,
}

#[pymethods]
impl PayloadFit {
    /// What status.json says: `complete`, `failed` or `interrupted`.
    #[getter]
    fn state(&self) -> String {
        self.inner.estimate.state().to_string()
    }
    /// Mass (kg), or None without a usable payload.
    #[getter]
    fn mass(&self) -> Option<f64> {
        self.inner.estimate.payload.map(|p| p.mass)
    }
    /// Centre of mass in the payload's frame (m), or None.
    #[getter]
    fn com<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.estimate.payload.map(|p| out1(py, p.com.to_vec()))
    }
    /// Inertia about the centre of mass (3, 3) in the frame's axes (kg·m²), or None.
    #[getter]
    fn inertia<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.inner.estimate.payload.map(|p| {
            let m = p.inertia_matrix();
            let rows: Vec<Vec<f64>> = (0..3).map(|r| (0..3).map(|c| m[(r, c)]).collect()).collect();
            out_rows(py, &rows, 3)
        })
    }
    /// The ten standard parameters (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M) about the frame's origin, or None.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.estimate.payload.map(|p| out1(py, p.params().to_vec()))
    }
    /// payload.json's `payload_std` (σ of mass, com, inertia), or None.
    #[getter]
    fn std<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.payload_std)
    }
    /// The whole result as payload.json has it.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate)
    }
    /// The KUKA load data: dict with M, X, Y, Z (mm), A, B, C (deg), JX, JY, JZ; None without a payload.
    fn kuka<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(p) = self.inner.estimate.payload else { return Ok(None) };
        let pr = export::principal(&p);
        let v = serde_json::json!({
            "M": p.mass, "X": 1e3 * p.com[0], "Y": 1e3 * p.com[1], "Z": 1e3 * p.com[2],
            "A": pr.abc_deg[0], "B": pr.abc_deg[1], "C": pr.abc_deg[2],
            "JX": pr.moments[0], "JY": pr.moments[1], "JZ": pr.moments[2],
        });
        to_dict(py, &v).map(Some)
    }
    /// The text report.
    fn text(&self) -> String {
        self.inner.estimate.text()
    }
    /// write(folder): the command line's output folder (payload.json, report, exports, status.json).
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| self.inner.write(&folder, None)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        let e = &self.inner.estimate;
        match e.payload {
            Some(p) => format!(
                "PayloadFit({}, mass={:.4} kg, com=[{:.4}, {:.4}, {:.4}] m)",
                e.frame, p.mass, p.com[0], p.com[1], p.com[2]
            ),
            None => format!("PayloadFit({}, no usable payload)", e.frame),
        }
    }
}

/// payload(design, base_dir=None, time_limit=None, progress=None) -> PayloadFit
#[pyfunction]
#[pyo3(signature = (design, base_dir = None, time_limit = None, progress = None))]
pub fn payload(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<PayloadFit> {
    let (d, dir) = payload_design(design, base_dir, "payload")?;
    let res = run_long(py, time_limit, progress.as_ref(), |ctl| idexp::payload::run(&d, &dir, ctl))?;
    Ok(PayloadFit { inner: Arc::new(res) })
}

/// A payload design from a file or a dict (paths relative to the file's
/// folder or `base_dir`), named `default_name` when the dict has no name.
pub(crate) fn payload_design(design: &Bound<'_, PyAny>, base_dir: Option<PathBuf>, default_name: &str) -> PyResult<(PayloadDesign, PathBuf)> {
    design_and_dir(
        design,
        base_dir,
        "payload design",
        PayloadDesign::read,
        |d| {
            if d.name.is_empty() {
                d.name = default_name.into();
            }
        },
        PayloadDesign::validate,
    )
}

/// with_payload(robot, mass, com=(0, 0, 0), inertia=(0,)*6, frame=None) -> Robot
///
/// The robot carrying a payload (a rigid body) fixed to `frame` (a frame or
/// link of the robot file; default: the end effector): mass (kg), centre of
/// mass (m) and inertia about the centre of mass [Ixx, Ixy, Ixz, Iyy, Iyz,
/// Izz] (kg·m²), both in the frame's axes — the URDF meaning, the payload's
/// inertial placed by the frame's pose in its link (Pinocchio's
/// `frame.placement.act(Y)`), as `idexp simulate`'s `[payload]` and
/// `idexp payload identify` read them. Its `rnea`, `regressor`, … include
/// the payload; errors name the field (`idexp.IdexpError`).
#[pyfunction]
#[pyo3(signature = (robot, mass, com = [0.0; 3], inertia = [0.0; 6], frame = None))]
pub fn with_payload(
    py: Python<'_>,
    robot: &crate::robot::Robot,
    mass: f64,
    com: [f64; 3],
    inertia: [f64; 6],
    frame: Option<String>,
) -> PyResult<crate::robot::Robot> {
    let spec = idexp::robot::payload::PayloadSpec { frame, mass, com, inertia };
    let r = py
        .detach(|| {
            let (mount, p) = idexp::robot::payload::resolve(&robot.inner, &spec, "with_payload", "payload")?;
            mount.attach(&robot.inner, &p.params())
        })
        .py()?;
    Ok(crate::robot::Robot::new(r, robot.path.clone()))
}
