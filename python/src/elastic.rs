//! The elastic (FRF) problem: `idexp.multisine` (the references),
//! `idexp.frf` (FRF estimates) and `idexp.fit` (the multistart gray-box fit).

use crate::dicts::to_dict;
use crate::err::{value, IntoPy};
use crate::long::run_long;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// A multistart gray-box FRF fit (`idexp.fit`).
#[pyclass(module = "idexp", frozen)]
pub struct FitResult {
    inner: Arc<idexp::frf::pipeline::FitRun>,
}

#[pymethods]
impl FitResult {
    /// The output folder (written by the fit, resumable).
    #[getter]
    fn folder(&self) -> PathBuf {
        self.inner.dir.clone()
    }
    /// The log of the starts (starts.jsonl or the shard's).
    #[getter]
    fn log(&self) -> PathBuf {
        self.inner.log.clone()
    }
    /// One dict per start of this run (index, status, cost, θ, …).
    #[getter]
    fn records<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.records)
    }
    /// The multistart report (best start, costs, parameter statistics), or
    /// None for a shard (merge the shards with the command line's `idexp merge`).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.report)
    }
    /// Index of the best start, or None (shard, or no start converged).
    #[getter]
    fn best_index(&self) -> Option<usize> {
        self.inner.report.as_ref().and_then(|r| r.best_index)
    }
    /// The text report, or None for a shard.
    fn text(&self) -> Option<String> {
        self.inner.report.as_ref().map(|r| r.text())
    }
    fn __repr__(&self) -> String {
        format!(
            "FitResult({} starts, folder={:?})",
            self.inner.records.len(),
            self.inner.dir.display().to_string()
        )
    }
}

/// fit(design, starts=None, shard=None, ...) -> FitResult
#[pyfunction]
#[pyo3(signature = (design, starts = None, shard = None, data = None, method = None, weights = None, seed = None, out = None,
                    time_limit = None, progress = None))]
#[allow(clippy::too_many_arguments)] // the Python signature mirrors `idexp fit`'s options
pub fn fit(
    py: Python<'_>,
    design: PathBuf,
    starts: Option<usize>,
    shard: Option<&str>,
    data: Option<PathBuf>,
    method: Option<&str>,
    weights: Option<&str>,
    seed: Option<u64>,
    out: Option<PathBuf>,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<FitResult> {
    if starts == Some(0) {
        return Err(value("starts: expected at least 1 start"));
    }
    let o = idexp::frf::pipeline::FitOptions {
        data,
        estimator: method.map(str::parse).transpose().py()?,
        weights: weights.map(str::parse).transpose().py()?,
        starts,
        seed,
        shard: shard.map(idexp::frf::multistart::Shard::parse).transpose().py()?,
        out,
    };
    let r = run_long(py, time_limit, progress.as_ref(), |ctl| idexp::frf::pipeline::fit(&design, &o, ctl))?;
    Ok(FitResult { inner: Arc::new(r) })
}

/// multisine(design, out=None) -> dict: the multisine references of an
/// elastic design (`idexp multisine`); the summary, with the output folder
/// under "folder".
#[pyfunction]
#[pyo3(signature = (design, out = None))]
pub fn multisine<'py>(py: Python<'py>, design: PathBuf, out: Option<PathBuf>) -> PyResult<Bound<'py, PyAny>> {
    let (s, dir) = py.detach(|| idexp::frf::pipeline::multisine(&design, out.as_deref())).py()?;
    let d = to_dict(py, &s)?;
    d.set_item("folder", dir)?;
    Ok(d)
}

/// frf(input, out=None, progress=None) -> str: FRF estimates (`idexp frf`)
/// from an elastic design (simulated measurements) or a runs.json; returns
/// the frf.json written (the `data` of `fit`).
#[pyfunction]
#[pyo3(signature = (input, out = None, progress = None))]
pub fn frf(py: Python<'_>, input: PathBuf, out: Option<PathBuf>, progress: Option<Bound<'_, PyAny>>) -> PyResult<PathBuf> {
    let (_, dir) = run_long(py, None, progress.as_ref(), |ctl| idexp::frf::pipeline::frf(&input, out.as_deref(), ctl))?;
    Ok(dir.join("frf.json"))
}
