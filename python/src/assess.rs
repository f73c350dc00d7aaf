//! `idexp.assess`: the identifiability of a sampled trajectory.

use crate::arrays::{self, out1, Arg};
use crate::dicts::to_dict;
use crate::err::{value, IntoPy};
use crate::robot::Robot;
use idexp::excitation::report as xr;
use idexp::io::states::States;
use idexp::params::{BaseOptions, BaseParams};
use numpy::PyArray1;
use pyo3::prelude::*;
use std::path::PathBuf;

/// Identifiability of a sampled trajectory (`idexp.assess`).
#[pyclass(module = "idexp", frozen)]
pub struct Identifiability {
    inner: xr::Identifiability,
}

#[pymethods]
impl Identifiability {
    /// Base parameter names.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.names.clone()
    }
    /// Numerical rank of the stacked base regressor.
    #[getter]
    fn rank(&self) -> usize {
        self.inner.rank
    }
    /// Condition number with unit columns (inf when rank deficient).
    #[getter]
    fn cond(&self) -> f64 {
        self.inner.cond
    }
    /// Singular values with unit columns, decreasing.
    #[getter]
    fn singular_values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.singular_values.clone())
    }
    /// Predicted standard deviations σ_i from one period (paper 000 eq. 13).
    #[getter]
    fn std_dev<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.std_dev.clone())
    }
    /// Predicted relative standard deviations σ*_i (eq. 14).
    #[getter]
    fn rel_std_dev<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.rel_std_dev.clone())
    }
    /// Sensitivities c̄_i (paper 000 eq. 10).
    #[getter]
    fn sensitivity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.inner.sensitivity.clone())
    }
    /// Parameters not excited.
    #[getter]
    fn unexcited(&self) -> Vec<String> {
        self.inner.unexcited.clone()
    }
    /// Everything, as `idexp assess --json` prints it.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner)
    }
    /// The text report (`idexp assess` prints it).
    fn text(&self) -> String {
        self.inner.text()
    }
    /// write(folder, title="identifiability"): report.json, report.txt,
    /// singular_values.svg.
    #[pyo3(signature = (folder, title = "identifiability".to_string()))]
    fn write(&self, folder: PathBuf, title: String) -> PyResult<PathBuf> {
        self.inner.write(&folder, &title).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        format!(
            "Identifiability(rank={}/{}, cond={:.4})",
            self.inner.rank,
            self.inner.names.len(),
            self.inner.cond
        )
    }
}

/// assess(robot, t, q, qd, qdd, noise=1.0, inertial=False) -> Identifiability
#[pyfunction]
#[pyo3(signature = (robot, t, q, qd, qdd, noise = None, inertial = false))]
#[allow(clippy::too_many_arguments)] // the Python signature: robot, the sampled states, options
pub fn assess(py: Python<'_>, robot: &Robot, t: Option<Arg>, q: Arg, qd: Arg, qdd: Arg, noise: Option<Arg>, inertial: bool) -> PyResult<Identifiability> {
    let r = &robot.inner;
    let n = r.dof();
    let q = arrays::matrix_rows("q", &q, None, n)?;
    let rows = q.len();
    let qd = arrays::matrix_rows("qd", &qd, Some(rows), n)?;
    let qdd = arrays::matrix_rows("qdd", &qdd, Some(rows), n)?;
    let t = t.map(|t| arrays::vector("t", &t, rows, "one time per row of q")).transpose()?;
    let noise = match noise {
        None => vec![1.0; n],
        Some(a) => {
            let v = a.as_array();
            let vals: Vec<f64> = v.iter().copied().collect();
            let vals = match (v.ndim(), vals.len()) {
                (0, 1) => vec![vals[0]; n],
                (1, k) if k == n => vals,
                _ => return Err(value(format!("noise: expected a number or shape ({n},) (N·m per joint)"))),
            };
            if let Some(j) = vals.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
                return Err(value(format!("noise: value {} is {}: expected a positive standard deviation", j, vals[j])));
            }
            vals
        }
    };
    let states = States { t, q, qd, qdd };
    let id = py
        .detach(|| {
            let base = BaseParams::compute(
                r,
                &BaseOptions {
                    inertial_only: inertial,
                    ..BaseOptions::default()
                },
            )?;
            xr::assess(r, &base, &states, &noise)
        })
        .py()?;
    Ok(Identifiability { inner: id })
}
