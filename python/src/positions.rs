//! `idexp.positions`: optimal measurement positions from a positions design.

use crate::arrays::{out1, out2, out_rows};
use crate::dicts::{base_dir, from_dict, source, to_dict, Source};
use crate::err::{value, IntoPy};
use crate::long::run_long;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Optimal measurement positions (`idexp.positions`): the relaxed design,
/// its Kiefer–Wolfowitz certificate, the rounded plan.
#[pyclass(module = "idexp", frozen)]
pub struct PositionsResult {
    inner: Arc<idexp::positions::PositionsRun>,
}

#[pymethods]
impl PositionsResult {
    /// Names of the identified parameters (p).
    #[getter]
    fn param_names(&self) -> Vec<String> {
        self.inner.names.clone()
    }
    /// Number of candidate configurations.
    #[getter]
    fn n_candidates(&self) -> usize {
        self.inner.relaxed.weights.len()
    }
    /// Rank of each candidate's information matrix.
    #[getter]
    fn ranks(&self) -> Vec<usize> {
        self.inner.ranks.clone()
    }
    /// Cost of each candidate (ones when the design gives none).
    #[getter]
    fn costs<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let n = self.inner.relaxed.weights.len();
        out1(py, self.inner.costs.clone().unwrap_or_else(|| vec![1.0; n]))
    }
    /// Candidate configurations (n_candidates, n); (n_candidates, 0) when the
    /// information comes from a file without joint values.
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let n = self.inner.q.first().map_or(0, Vec::len);
        if self.inner.q.iter().any(|r| r.len() != n) {
            return out2(py, self.inner.q.len(), 0, Vec::new());
        }
        out_rows(py, &self.inner.q, n)
    }
    /// Relaxed weights w (n_candidates,), Σ w = 1.
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.relaxed.weights.clone())
    }
    /// The plan: experiments per candidate (n_candidates,) after rounding.
    #[getter]
    fn plan(&self) -> Vec<usize> {
        self.inner.rounded.m.clone()
    }
    /// The rounded design (dict: m, total, cost, value, efficiency, …).
    #[getter]
    fn rounded<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.rounded)
    }
    /// The optimality certificate (dict: criterion, value, max_sensitivity,
    /// gap_bound, efficiency_bound, formula, …).
    #[getter]
    fn certificate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.relaxed.certificate)
    }
    /// The relaxed solution (weights, value, sensitivities, status, solver log).
    #[getter]
    fn relaxed<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.relaxed)
    }
    /// Solver status of the relaxation.
    #[getter]
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.relaxed.status)
    }
    /// The text report (`idexp positions` prints it).
    fn text(&self) -> String {
        idexp::positions::output::report_text(&self.inner)
    }
    /// The poses of the rounded plan (candidates with m_i > 0, in candidate
    /// order): dict with joint_names, q (k, n) and m (k,) measurements per
    /// pose. IdexpError when the candidates are not robot poses.
    #[getter]
    fn plan_poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (names, poses, m) = idexp::positions::output::plan_poses(&self.inner).py()?;
        let d = PyDict::new(py);
        d.set_item("q", out_rows(py, &poses, names.len()))?;
        d.set_item("joint_names", names)?;
        d.set_item("m", m)?;
        Ok(d)
    }
    /// export(folder, formats, dwell=2.0, move_speed=0.5, move_acceleration=1.0) -> list of paths
    ///
    /// The plan's poses for the controller, the files of `idexp positions
    /// --export`: "ur" (`<design>_poses.script`: one movej per pose at
    /// `move_speed` rad/s and `move_acceleration` rad/s², held m_i · `dwell`
    /// s) and "ros2" (`<design>_poses_ros2.yaml`: JointTrajectory waypoints,
    /// each pose reached at rest and held; the first reached 5 s after the
    /// start) and "csv" (`<design>_poses.csv`: the poses and their
    /// measurement counts). `formats`: a list or a comma-separated string.
    #[pyo3(signature = (folder, formats, dwell = 2.0, move_speed = 0.5, move_acceleration = 1.0))]
    fn export(
        &self,
        py: Python<'_>,
        folder: PathBuf,
        formats: &Bound<'_, PyAny>,
        dwell: f64,
        move_speed: f64,
        move_acceleration: f64,
    ) -> PyResult<Vec<PathBuf>> {
        let f = crate::exports::formats(formats)?;
        for (name, v) in [("move_speed", move_speed), ("move_acceleration", move_acceleration)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(value(format!("{name}: expected a positive value, got {v}")));
            }
        }
        if !(dwell.is_finite() && dwell >= 0.0) {
            return Err(value(format!("dwell: expected a time ≥ 0 s per measurement, got {dwell}")));
        }
        let motion = idexp::positions::output::PlanMotion {
            speed: move_speed,
            acceleration: move_acceleration,
            dwell,
            approach: 5.0,
        };
        py.detach(|| idexp::positions::output::write_plan_exports(&self.inner, &folder, &f, &motion))
            .py()
    }
    /// write(folder): the command line's output folder.
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| idexp::positions::output::write_outputs(&self.inner, &folder, None)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        format!(
            "PositionsResult({} candidates, {} experiments, efficiency bound {:.4})",
            self.inner.relaxed.weights.len(),
            self.inner.rounded.total,
            self.inner.relaxed.certificate.efficiency_bound
        )
    }
}

/// positions(design, seed=None, base_dir=None, time_limit=None, progress=None) -> PositionsResult
#[pyfunction]
#[pyo3(signature = (design, seed = None, base_dir = None, time_limit = None, progress = None))]
pub fn positions(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    seed: Option<u64>,
    base_dir: Option<PathBuf>,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<PositionsResult> {
    let (mut d, dir) = match source(design)? {
        Source::File(p) => (
            idexp::positions::PositionsDesign::read(&p).py()?,
            p.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(".")),
        ),
        Source::Dict(v) => {
            let d: idexp::positions::PositionsDesign = from_dict(v, "positions design")?;
            d.validate("positions design (dict)").py()?;
            (d, self::base_dir(base_dir))
        }
    };
    if let Some(s) = seed {
        d.seed = s;
    }
    let run = run_long(py, time_limit, progress.as_ref(), |ctl| idexp::positions::run_design(&d, &dir, ctl))?;
    Ok(PositionsResult { inner: Arc::new(run) })
}
