//! `idexp.study`: an identification study (many experiments, validation
//! runs, a prior) from a study file or a dict, as `idexp identify study.toml`.

use crate::arrays::{out1, out_rows};
use crate::dicts::{design_and_dir, to_dict};
use crate::err::{value, IdexpError, IntoPy};
use crate::long::run_long;
use crate::robot::Robot;
use idexp::ident::study::{run_dedicated, run_study, DedicatedResult, JointFit, StudyDesign, StudyResult};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// The result of an identification (`idexp.study`, and `idexp.identify`'s
/// [`crate::identify::Identification`], which extends it): estimates,
/// covariance, experiments, validation, the consistent fit and its model.
#[pyclass(module = "idexp", frozen, subclass)]
pub struct Study {
    pub(crate) inner: Arc<StudyResult>,
}

impl Study {
    /// The identified model (the robot with the consistent standard parameters).
    fn identified_model(&self) -> PyResult<idexp::robot::Robot> {
        match (&self.inner.estimate.consistent, self.inner.model().py()?) {
            (_, Some(m)) => Ok(m),
            (Some(c), None) => Err(IdexpError::new_err(format!(
                "the consistent fit ended with status `{}`: no identified model",
                c.status
            ))),
            (None, None) => Err(value(
                "no consistent estimate, so no identified model: identify with consistent=True (a study: a [consistent] table, dict key \"consistent\")",
            )),
        }
    }
}

#[pymethods]
impl Study {
    /// `ok`, `rank_deficient` (the least-squares estimate), or the solver's status (ML).
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
    /// Their combinations of standard parameters.
    #[getter]
    fn groupings(&self) -> Vec<String> {
        self.inner.estimate.groupings.clone()
    }
    /// The estimate θ̂ (n_base,).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.estimate.theta.clone())
    }
    /// Standard deviations σ_i.
    #[getter]
    fn std<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.estimate.std.clone())
    }
    /// Relative standard deviations σ*_i = σ_i/|θ̂_i| (paper 000 eq. 14).
    #[getter]
    fn rel_std<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.estimate.rel_std.clone())
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
    /// Comparison with the truth (list of dicts name, truth, estimate, z), or None.
    #[getter]
    fn truth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.truth)
    }
    /// The physically consistent estimate, as the `consistent` block of
    /// estimate.json: status, standard_names, standard (θ, p), base (K θ),
    /// the prior and its weight, extra_cost, chi2_dof, min_eigenvalue per
    /// link, active constraints, links beside the prior, prior-decided
    /// directions, pinocchio (per body, Pinocchio's order). None without one.
    #[getter]
    fn consistent<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.consistent)
    }
    /// The consistent standard parameters θ (p,) (`robot.param_names`
    /// order), or None (no consistent fit, or it failed).
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
    /// The identified model: the robot with the consistent standard
    /// parameters; ValueError without a consistent fit, IdexpError when it failed.
    fn model(&self) -> PyResult<Robot> {
        Ok(Robot::new(self.identified_model()?, self.inner.robot_path.clone()))
    }
    /// export(folder, formats=("urdf", "toml", "csv")) -> list of paths
    ///
    /// The model files of `idexp identify --export`: "csv" (`params.csv`:
    /// every base and standard parameter with std and σ*), "urdf"
    /// (`robot.urdf`: the robot's URDF with the consistent inertials; a DH
    /// robot has none: ValueError) and "toml" (`robot.toml`: the robot file
    /// with the consistent drive parameters and, for a DH table, inertials).
    /// urdf and toml need the consistent fit. `formats`: a list or a
    /// comma-separated string.
    #[pyo3(signature = (folder, formats = None))]
    fn export(&self, py: Python<'_>, folder: PathBuf, formats: Option<Bound<'_, PyAny>>) -> PyResult<Vec<PathBuf>> {
        let kinds = match &formats {
            Some(f) => crate::exports::model_kinds(f, &["urdf", "toml", "csv"])?,
            None => ["urdf", "toml", "csv"].map(String::from).to_vec(),
        };
        let model_kinds: Vec<String> = kinds.iter().filter(|k| *k != "csv").cloned().collect();
        let model = if model_kinds.is_empty() { None } else { Some(self.identified_model()?) };
        py.detach(|| -> PyResult<Vec<PathBuf>> {
            std::fs::create_dir_all(&folder).map_err(|e| crate::err::to_py(idexp::Error::io(&folder, e)))?;
            let mut files = Vec::new();
            if kinds.iter().any(|k| k == "csv") {
                let p = folder.join("params.csv");
                idexp::io::write_atomic(&p, idexp::ident::output::params_csv(&self.inner.estimate).as_bytes()).py()?;
                files.push(p);
            }
            if let Some(m) = &model {
                files.extend(crate::exports::write_model(&self.inner.robot_path, m, &folder, &model_kinds)?);
            }
            Ok(files)
        })
    }
    /// The text report (`idexp identify` prints it).
    fn text(&self) -> String {
        self.inner.estimate.text()
    }
    /// write(folder): the command line's output folder (study.json,
    /// estimate.json, report, CSVs, plots, exports, status.json).
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

/// The dedicated one-joint fits of a study whose every experiment names its
/// `joint` (paper 002 §3.2; `idexp.study` of such a design).
#[pyclass(module = "idexp", frozen)]
pub struct JointFits {
    inner: Arc<DedicatedResult>,
}

#[pymethods]
impl JointFits {
    /// Per entry name: its fit (gravity.json's or friction.json's keys) with
    /// `kind` ("gravity" | "friction"), and for a friction fit `min_speed`
    /// and `gravity_source`.
    #[getter]
    fn fits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut all = serde_json::Map::new();
        for e in &self.inner.entries {
            let mut v = e.json();
            if let Some(m) = v.as_object_mut() {
                m.insert("kind".into(), e.kind_name().into());
                if let JointFit::Friction { min_speed, gravity_source, .. } = &e.fit {
                    m.insert("min_speed".into(), (*min_speed).into());
                    m.insert("gravity_source".into(), gravity_source.clone().into());
                }
            }
            all.insert(e.name.clone(), v);
        }
        to_dict(py, &all)
    }
    /// The report (a line per entry, as report.txt).
    #[getter]
    fn report(&self) -> String {
        self.inner.text()
    }
    /// write(folder) -> folder: the folder `idexp identify` writes for this study.
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| self.inner.write(&folder, None)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        let what: Vec<String> = self.inner.entries.iter().map(|e| format!("{} joint {}", e.kind_name(), e.joint)).collect();
        format!("JointFits({}, {})", self.inner.design.name, what.join(", "))
    }
}

/// study(design, base_dir=None, time_limit=None, progress=None) -> Study,
/// or JointFits for a design of dedicated one-joint fits
#[pyfunction]
#[pyo3(signature = (design, base_dir = None, time_limit = None, progress = None))]
pub fn study(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<Py<PyAny>> {
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
    if d.is_dedicated() {
        let res = run_long(py, time_limit, progress.as_ref(), |ctl| run_dedicated(&d, &dir, &Default::default(), ctl))?;
        return Ok(Py::new(py, JointFits { inner: Arc::new(res) })?.into_any());
    }
    let res = run_long(py, time_limit, progress.as_ref(), |ctl| run_study(&d, &dir, ctl))?;
    Ok(Py::new(py, Study { inner: Arc::new(res) })?.into_any())
}
