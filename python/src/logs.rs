//! Robot logs (`idexp.read_log`, `idexp.log_info`): the library's readers of
//! RTDE recorder CSVs, CSVs with a column map, headerless CSVs and ROS 2 bags
//! ([`idexp::data::logs`]), the samples returned as numpy arrays.

use crate::arrays::{out1, out_rows};
use crate::dicts::to_dict;
use crate::err::{value, IntoPy};
use crate::robot::Robot;
use idexp::data::logs::{bag_info, LogFormat, LogSpec};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::path::PathBuf;

/// The spec from `spec` (a map file path or a dict) and the keyword overrides.
fn spec_of(spec: Option<&Bound<'_, PyAny>>, format: Option<&str>, topic: Option<String>) -> PyResult<LogSpec> {
    let map = match spec {
        Some(obj) if obj.is_instance_of::<PyDict>() => {
            let v: serde_json::Value =
                pythonize::depythonize(obj).map_err(|e| value(format!("spec: the dict is not plain data (str, numbers, lists, dicts): {e}")))?;
            Some(serde_json::from_value::<LogSpec>(v).map_err(|e| value(format!("spec: {e}")))?)
        }
        Some(obj) if obj.is_instance_of::<PyString>() || obj.extract::<PathBuf>().is_ok() => Some(LogSpec::read(&obj.extract::<PathBuf>()?).py()?),
        Some(obj) => return Err(value(format!("spec: expected a map file path or a dict, got {}", obj.get_type().name()?))),
        None => None,
    };
    let format = format.map(|f| f.parse::<LogFormat>()).transpose().py()?;
    LogSpec::resolve(map, "spec", format, topic, None).py()
}

/// read_log(log, robot, format=None, spec=None, topic=None) -> dict
///
/// Reads a robot log (an RTDE recorder CSV, a CSV with a column map, a
/// headerless CSV, a ROS 2 bag folder or .mcap/.db3 file) for `robot`:
/// `t` (N,) in s from the first sample (possibly irregular), `q`, `tau`
/// (N, n), `qd`, `qdd` (N, n) or None, and `report` (source, columns used,
/// time span, step statistics). `spec` is a map file or a dict with the
/// fields of a map file; `format` and `topic` override it.
#[pyfunction]
#[pyo3(signature = (log, robot, format = None, spec = None, topic = None))]
pub fn read_log<'py>(
    py: Python<'py>,
    log: PathBuf,
    robot: &Robot,
    format: Option<&str>,
    spec: Option<Bound<'py, PyAny>>,
    topic: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let s = spec_of(spec.as_ref(), format, topic)?;
    let r = py.detach(|| idexp::data::logs::read_log(&log, &robot.inner, &s)).py()?;
    let n = robot.inner.dof();
    let d = PyDict::new(py);
    d.set_item("t", out1(py, r.rep.t))?;
    d.set_item("q", out_rows(py, &r.rep.q, n))?;
    d.set_item("tau", out_rows(py, &r.rep.tau, n))?;
    d.set_item("qd", r.rep.qd.as_ref().map(|v| out_rows(py, v, n)))?;
    d.set_item("qdd", r.rep.qdd.as_ref().map(|v| out_rows(py, v, n)))?;
    d.set_item("report", to_dict(py, &r.report)?)?;
    Ok(d)
}

/// log_info(bag) -> dict: the topics of a ROS 2 bag with their types,
/// message counts, joint names, header-stamp span and step statistics
/// (`idexp log info`).
#[pyfunction]
pub fn log_info<'py>(py: Python<'py>, bag: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    let i = py.detach(|| bag_info(&bag)).py()?;
    to_dict(py, &i)
}
