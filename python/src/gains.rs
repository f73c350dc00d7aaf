//! `idexp.calibrate_gains`: each joint's drive gain (current → joint torque)
//! calibrated with a known mass, as `idexp payload identify` does for a
//! payload design with a `[gains]` table; `idexp.rtde_gains`: the
//! controller's target torque / target current ratio of an RTDE recording.

use crate::arrays::out1;
use crate::dicts::to_dict;
use crate::err::IntoPy;
use crate::long::run_long;
use idexp::payload::gains::{calibrate, GainsEstimate};
use idexp::payload::PayloadDesign;
use numpy::PyArray1;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// A gain calibration (`idexp.calibrate_gains`): per joint the gain written
/// (identified where the motion determines it, else the file's), its σ,
/// whether it is determined and why not, the current's sign and offset.
#[pyclass(module = "idexp", frozen)]
pub struct GainsFit {
    inner: Arc<GainsEstimate>,
    design: Arc<PayloadDesign>,
}

#[pymethods]
impl GainsFit {
    /// Joint names.
    #[getter]
    fn joints(&self) -> Vec<String> {
        self.inner.joints.iter().map(|g| g.joint.clone()).collect()
    }
    /// The gains written (N·m/A, joint side, signed): identified where determined, else the file's.
    #[getter]
    fn gains<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.joints.iter().map(|g| g.gain).collect())
    }
    /// σ of each gain (N·m/A; inf where not determined).
    #[getter]
    fn std<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.joints.iter().map(|g| g.std).collect())
    }
    /// The robot file's gains s·k_t·N (N·m/A).
    #[getter]
    fn file_gains<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.joints.iter().map(|g| g.file).collect())
    }
    /// Per joint: True when the motion determines its gain (σ/g ≤ max_std).
    #[getter]
    fn determined(&self) -> Vec<bool> {
        self.inner.joints.iter().map(|g| g.determined).collect()
    }
    /// The whole calibration as gains.json has it (joints with ratio, σ,
    /// reason, sign, offset; runs with their delays; compared sets; notes).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &*self.inner)
    }
    /// The text report.
    fn text(&self) -> String {
        self.inner.text()
    }
    /// write(folder): the command line's output folder (gains.json, gains.csv,
    /// report.txt, robot.toml with the calibrated gains, design.json, status.json).
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| self.inner.write(&self.design, &folder, None)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        let n = self.inner.joints.iter().filter(|g| g.determined).count();
        format!(
            "GainsFit({} kg on {}, {n} of {} gains determined)",
            self.inner.mass,
            self.inner.frame,
            self.inner.joints.len()
        )
    }
}

/// calibrate_gains(design, base_dir=None, time_limit=None, progress=None) -> GainsFit
#[pyfunction]
#[pyo3(signature = (design, base_dir = None, time_limit = None, progress = None))]
pub fn calibrate_gains(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<GainsFit> {
    let (d, dir) = crate::payload::payload_design(design, base_dir, "gains")?;
    if d.gains.is_none() {
        return Err(crate::err::value(
            "calibrate_gains: the design has no [gains] table (the known mass): idexp.payload identifies a payload",
        ));
    }
    let g = run_long(py, time_limit, progress.as_ref(), |ctl| calibrate(&d, &dir, ctl))?;
    Ok(GainsFit {
        inner: Arc::new(g),
        design: Arc::new(d),
    })
}

/// rtde_gains(robot, path) -> numpy array (n,): per joint the controller's
/// ratio of target torque to target current in an RTDE recording
/// (`target_moment_j` / `target_current_j`, least squares through the
/// origin; N·m/A), as `[[gains.compare]] rtde = "…"` compares it.
#[pyfunction]
pub fn rtde_gains<'py>(py: Python<'py>, robot: &crate::robot::Robot, path: PathBuf) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let g = idexp::payload::gains::rtde_gains(&robot.inner, &path).py()?;
    Ok(out1(py, g))
}
