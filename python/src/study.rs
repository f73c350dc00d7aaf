//! `idexp.study`: an identification study (many experiments, validation
//! runs, a prior) from a study file or a dict, as `idexp identify study.toml`.

use crate::arrays::{out1, out_rows};
use crate::dicts::{design_and_dir, to_dict};
use crate::err::IntoPy;
use crate::long::run_long;
use crate::robot::Robot;
use idexp::ident::study::{run_study, StudyDesign, StudyResult};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// The result of an identification study (`idexp.study`).
#[pyclass(module = "idexp", frozen)]
pub struct Study {
    inner: Arc<StudyResult>,
}

#[pymethods]
impl Study {
    /// `ok` or `rank_deficient` (of the stacked least-squares estimate).
    #[getter]
    fn status(&self) -> String {
        self.inner.estimate.status.to_string()
    }
    /// What status.json says: `complete`, `failed` or `interrupted`.
    #[getter]
    fn state(&self) -> String {
        self.inner.estimate.state(self.inner.interrupted).to_string()
    }
    /// Base parameter names.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.estimate.names.clone()
    }
    /// The stacked estimate θ̂ (n_base,).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.estimate.theta.clone())
    }
    /// Standard deviations σ_i.
    #[getter]
    fn std<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.estimate.std.clone())
    }
    /// Covariance (n_base, n_base).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let c = &self.inner.estimate.covariance;
        out_rows(py, c, c.len())
    }
    /// Per experiment: estimate.json's `experiments` entries (weights, σ, errors, information share, ...).
    #[getter]
    fn experiments<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.experiments)
    }
    /// Per validation run: estimate.json's `validation` entries.
    #[getter]
    fn validation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.validation)
    }
    /// The consistent estimate with its prior (estimate.json's `consistent`), or None.
    #[getter]
    fn consistent<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.consistent)
    }
    /// The consistent standard parameters θ (p,), or None.
    #[getter]
    fn consistent_theta<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner
            .estimate
            .consistent
            .as_ref()
            .filter(|c| c.status.is_ok())
            .map(|c| out1(py, c.standard.clone()))
    }
    /// The whole estimate as estimate.json has it.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate)
    }
    /// The identified model (the robot with the consistent standard parameters); IdexpError without one.
    fn model(&self) -> PyResult<Robot> {
        match self.inner.model().py()? {
            Some(m) => Ok(Robot::new(m, self.inner.robot_path.clone())),
            None => Err(crate::err::IdexpError::new_err(
                "the study has no usable consistent estimate: add a [consistent] table (dict key \"consistent\")",
            )),
        }
    }
    /// The text report.
    fn text(&self) -> String {
        self.inner.estimate.text()
    }
    /// write(folder): the command line's output folder (estimate.json, report,
    /// CSVs, plots, exports, status.json).
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| self.inner.write(&folder, None)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        let e = &self.inner.estimate;
        format!(
            "Study({}, {} experiments, {} validation runs, {}, cond={:.4})",
            e.name,
            e.experiments.len(),
            e.validation.len(),
            e.status,
            e.cond
        )
    }
}

/// study(design, base_dir=None, time_limit=None, progress=None) -> Study
#[pyfunction]
#[pyo3(signature = (design, base_dir = None, time_limit = None, progress = None))]
pub fn study(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<Study> {
    let (d, dir) = design_and_dir(
        design,
        base_dir,
        "study design",
        StudyDesign::read,
        |d| {
            if d.name.is_empty() {
                d.name = "study".into();
            }
        },
        StudyDesign::validate,
    )?;
    let res = run_long(py, time_limit, progress.as_ref(), |ctl| run_study(&d, &dir, ctl))?;
    Ok(Study { inner: Arc::new(res) })
}
