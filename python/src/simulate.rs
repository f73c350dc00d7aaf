//! `idexp.simulate`: a simulated run from a simulation design.

use crate::arrays::{out1, out_rows};
use crate::dicts::{base_dir, from_dict, source, to_dict, Source};
use crate::err::IntoPy;
use crate::long::run_long;
use idexp::data::Repetition;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A simulated run (`idexp.simulate`): repetitions, the true parameters.
#[pyclass(module = "idexp", frozen)]
pub struct SimRun {
    pub(crate) result: Arc<idexp::sim::SimResult>,
    design: idexp::sim::SimDesign,
    pub(crate) truth: idexp::data::Truth,
}

fn rep_dict<'py>(py: Python<'py>, r: &Repetition) -> PyResult<Bound<'py, PyDict>> {
    let n = r.n_joints();
    let d = PyDict::new(py);
    d.set_item("t", out1(py, r.t.clone()))?;
    d.set_item("q", out_rows(py, &r.q, n))?;
    d.set_item("tau", out_rows(py, &r.tau, n))?;
    for (k, v) in [("r", &r.r), ("qd", &r.qd), ("qdd", &r.qdd)] {
        if let Some(v) = v {
            d.set_item(k, out_rows(py, v, n))?;
        }
    }
    Ok(d)
}

#[pymethods]
impl SimRun {
    /// Repetitions: list of dicts with t (N,), q, tau (N, n) and, when
    /// recorded, r (reference), qd, qdd.
    #[getter]
    fn repetitions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let l = PyList::empty(py);
        for r in &self.result.reps {
            l.append(rep_dict(py, r)?)?;
        }
        Ok(l)
    }
    /// True base parameters (dict: names, values) of the simulated robot.
    #[getter]
    fn truth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.truth)
    }
    /// Simulation status (tracking errors, repetitions).
    #[getter]
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.result.status)
    }
    /// write(folder): the run folder (rep_001.csv…, reference.csv,
    /// trajectory.json, truth.json, design.json, status.json).
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| self.result.write(&folder, &self.design)).py()?;
        Ok(folder)
    }
    fn __len__(&self) -> usize {
        self.result.reps.len()
    }
    fn __repr__(&self) -> String {
        format!(
            "SimRun({} repetitions of {} samples)",
            self.result.reps.len(),
            self.result.reps.first().map_or(0, |r| r.len())
        )
    }
}

/// simulate(design, seed=None, base_dir=None, progress=None) -> SimRun
#[pyfunction]
#[pyo3(signature = (design, seed = None, base_dir = None, progress = None))]
pub fn simulate(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    seed: Option<u64>,
    base_dir: Option<PathBuf>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<SimRun> {
    let (mut d, dir, ctx) = match source(design)? {
        Source::File(p) => {
            let d = idexp::sim::SimDesign::read(&p).py()?;
            (d, p.parent().map(Path::to_path_buf).unwrap_or_default(), p.display().to_string())
        }
        Source::Dict(v) => {
            let d: idexp::sim::SimDesign = from_dict(v, "simulate design")?;
            d.validate("simulate design (dict)").py()?;
            (d, self::base_dir(base_dir), "simulate design (dict)".to_string())
        }
    };
    if let Some(s) = seed {
        d.seed = s;
    }
    let setup = idexp::sim::SimSetup::from_design(&d, &dir, &ctx).py()?;
    let res = run_long(py, None, progress.as_ref(), |ctl| setup.run(ctl))?;
    let truth = res.truth().py()?;
    Ok(SimRun {
        result: Arc::new(res),
        design: d,
        truth,
    })
}
