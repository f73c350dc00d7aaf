//! `idexp.identify`: the one-run identification of a robot from a run
//! (folders or CSV files, a `SimRun`, or dicts of arrays).

use crate::arrays::{self, out1, out2, Arg};
use crate::dicts::to_dict;
use crate::err::{value, IntoPy};
use crate::excite::ExciteResult;
use crate::long::run_long;
use crate::robot::Robot;
use crate::simulate::SimRun;
use crate::study::Study;
use idexp::data::{Repetition, Run, TorqueFrom, TorqueSource};
use idexp::ident::study::{run_study_with, ConsistentSpec, ExperimentSpec, FilterName, Given, Inputs, StudyDesign};
use idexp::ident::{self, Method, Weights};
use idexp::trajectory::FourierTrajectory;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use std::sync::Arc;

/// An identification (`idexp.identify`): a one-experiment [`Study`] with
/// the one-run views: the errors of the run and of the validation run, and
/// the measured and predicted torques behind them.
#[pyclass(module = "idexp", frozen, extends = Study)]
pub struct Identification;

#[pymethods]
impl Identification {
    /// Errors on the rows of the identification run used for the estimate:
    /// dict with e, e_rel, rms (n,) and noise_floor (eq. 11–12).
    #[getter]
    fn errors<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(slf.py(), &slf.as_super().get().inner.estimate.experiments.first().map(|e| &e.errors))
    }
    /// Errors on the validation run's rows selected like the estimate's, or None.
    #[getter]
    fn validation_errors<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(slf.py(), &slf.as_super().get().inner.estimate.validation.first().map(|v| &v.errors))
    }
    /// Measured and predicted torques of the identification data, per joint:
    /// dict with t (N,) (processed sample times), measured and predicted
    /// (N, n) (N·m; NaN where a row was left out as too slow).
    #[getter]
    fn torques<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let py = slf.py();
        let inner = &slf.as_super().get().inner;
        let e = &inner.experiments[0];
        let ds = &e.prep.full;
        let (n, ns) = (ds.n, ds.n_samples);
        let theta = nalgebra::DVector::from_column_slice(&inner.estimate.theta);
        let pred = &ds.c * theta;
        let mut m = vec![f64::NAN; ns * n];
        let mut p = vec![f64::NAN; ns * n];
        for i in 0..ds.y.len() {
            let k = ds.sample[i] * n + ds.joint[i];
            m[k] = ds.y[i];
            p[k] = pred[i];
        }
        let d = PyDict::new(py);
        let t = &e.prep.pr.t;
        d.set_item("t", out1(py, t.iter().take(ns).copied().collect()))?;
        d.set_item("measured", out2(py, ns, n, m))?;
        d.set_item("predicted", out2(py, ns, n, p))?;
        Ok(d)
    }
    fn __repr__(slf: &Bound<'_, Self>) -> String {
        let e = &slf.as_super().get().inner.estimate;
        format!(
            "Identification({}, {}, {} base parameters, cond={:.4})",
            e.method.name(),
            e.status,
            e.names.len(),
            e.cond
        )
    }
}

/// A run argument: path(s), a SimRun, or dict(s) of arrays.
/// How a run given by paths takes its joint torques (`torque_from`,
/// `current_tolerance`: `idexp identify --torque-from --current-tolerance`).
struct Drives<'a> {
    robot: &'a idexp::robot::Robot,
    from: TorqueFrom,
    tolerance: f64,
}

fn read_run(py: Python<'_>, obj: &Bound<'_, PyAny>, drives: &Drives<'_>, what: &str) -> PyResult<(Run, Option<FourierTrajectory>, TorqueSource)> {
    let n = drives.robot.dof();
    if let Ok(s) = obj.cast::<SimRun>() {
        let s = s.get();
        let run = Run::new(Vec::new(), s.result.reps.clone()).py()?;
        return Ok((run, s.result.setup.reference.fourier().cloned(), TorqueSource::logged_torques()));
    }
    let dicts: Option<Vec<Bound<'_, PyDict>>> = if let Ok(d) = obj.cast::<PyDict>() {
        Some(vec![d.clone()])
    } else if let Ok(l) = obj.cast::<PyList>() {
        if !l.is_empty() && l.iter().all(|x| x.is_instance_of::<PyDict>()) {
            Some(l.iter().map(|x| x.cast_into::<PyDict>().expect("checked")).collect())
        } else {
            None
        }
    } else {
        None
    };
    if let Some(ds) = dicts {
        let mut reps = Vec::new();
        for (i, d) in ds.iter().enumerate() {
            let ctx = format!("{what}[{i}]");
            let get = |k: &str| -> PyResult<Option<Arg>> { d.get_item(k)?.map(|v| v.extract::<Arg>()).transpose() };
            let need = |k: &str| -> PyResult<Arg> { get(k)?.ok_or_else(|| value(format!("{ctx}: missing key `{k}` (t, q and tau are required)"))) };
            let t = arrays::any_vector(&format!("{ctx}['t']"), &need("t")?)?;
            let rows = t.len();
            let m = |k: &str, a: &Arg| arrays::matrix_rows(&format!("{ctx}['{k}']"), a, Some(rows), n);
            let q = m("q", &need("q")?)?;
            let tau = m("tau", &need("tau")?)?;
            let opt = |k: &str| -> PyResult<Option<Vec<Vec<f64>>>> { get(k)?.map(|a| m(k, &a)).transpose() };
            reps.push(Repetition {
                t,
                q,
                tau,
                r: opt("r")?,
                qd: opt("qd")?,
                qdd: opt("qdd")?,
            });
        }
        return Ok((Run::new(Vec::new(), reps).py()?, None, TorqueSource::logged_torques()));
    }
    let paths: Vec<PathBuf> = if let Ok(p) = obj.extract::<PathBuf>() {
        vec![p]
    } else if let Ok(v) = obj.extract::<Vec<PathBuf>>() {
        v
    } else {
        return Err(value(format!(
            "{what}: expected a run folder or CSV path, a list of paths, a SimRun, or a dict (list of dicts) with arrays t, q, tau"
        )));
    };
    let (run, src) = py.detach(|| Run::read_drives(&paths, drives.robot, None, drives.from, drives.tolerance)).py()?;
    let traj = ident::run_trajectory(&run).py()?;
    Ok((run, traj, src))
}

fn read_trajectory(obj: &Bound<'_, PyAny>) -> PyResult<FourierTrajectory> {
    if let Ok(e) = obj.cast::<ExciteResult>() {
        return match &e.get().result.trajectory {
            idexp::trajectory::ShapeMotion::Fourier(t) => Ok(t.clone()),
            _ => Err(value(
                "trajectory: a B-spline excitation has no Fourier series to filter with; pass no trajectory (the measured samples are used as they are)",
            )),
        };
    }
    let p: PathBuf = obj
        .extract()
        .map_err(|_| value("trajectory: expected an ExciteResult or the path of a coefficients.json / trajectory.json"))?;
    FourierTrajectory::load(&p).py()
}

/// identify(robot, run, method="wls", ...) -> Identification
#[pyfunction]
#[pyo3(signature = (robot, run, method = "wls", weights = "sample", filter = "auto", cutoff = 10.0, trajectory = None,
                    harmonics = None, decimate = 1, validate = None, truth = None, consistent = false, margin = 0.0,
                    regularization = 1e-6, standstill = "auto", torque_from = "auto", current_tolerance = 0.05,
                    velocity_from = "auto", dead_band = ident::DEAD_BAND, time_limit = None, progress = None))]
#[allow(clippy::too_many_arguments)] // the Python signature mirrors `idexp identify`'s options
pub fn identify(
    py: Python<'_>,
    robot: &Robot,
    run: &Bound<'_, PyAny>,
    method: &str,
    weights: &str,
    filter: &str,
    cutoff: f64,
    trajectory: Option<Bound<'_, PyAny>>,
    harmonics: Option<usize>,
    decimate: usize,
    validate: Option<Bound<'_, PyAny>>,
    truth: Option<Bound<'_, PyAny>>,
    consistent: bool,
    margin: f64,
    regularization: f64,
    standstill: &str,
    torque_from: &str,
    current_tolerance: f64,
    velocity_from: &str,
    dead_band: f64,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<Py<Identification>> {
    let r = &robot.inner;
    let method: Method = method.parse().py()?;
    let weights: Weights = weights.parse().py()?;
    let filter: FilterName = filter.parse().py()?;
    let drives = Drives {
        robot: r,
        from: torque_from.parse().py()?,
        tolerance: current_tolerance,
    };
    let mut inputs = Inputs {
        robot: Some((**r).clone()),
        ..Default::default()
    };
    let (run, run_traj, src) = read_run(py, run, &drives, "run")?;
    let trajectory = match &trajectory {
        Some(t) => Some(read_trajectory(t)?),
        None => run_traj,
    };
    let mut e = ExperimentSpec::new(Vec::new());
    e.name = "run".into();
    e.filter = filter;
    e.cutoff = cutoff;
    e.harmonics = harmonics;
    e.decimate = decimate;
    e.standstill = Some(standstill.parse().py()?);
    e.velocity_from = velocity_from.parse().py()?;
    inputs.entries.insert(
        e.name.clone(),
        Given {
            run,
            trajectory,
            torque_source: src,
        },
    );
    let mut design = StudyDesign::one_experiment("identify", robot.path.clone(), e.clone()).repetition_weighted(weights);
    design.method = method;
    design.dead_band = dead_band;
    if consistent {
        design.consistent = Some(ConsistentSpec::closest_to_nominal(margin, regularization));
    }
    if let Some(v) = &validate {
        let (run, trajectory, src) = read_run(py, v, &drives, "validate")?;
        let mut ve = e.validation_like(Vec::new(), None);
        ve.name = "validate".into();
        inputs.entries.insert(
            ve.name.clone(),
            Given {
                run,
                trajectory,
                torque_source: src,
            },
        );
        design.validation.push(ve);
    }
    inputs.truth = match &truth {
        None => None,
        Some(t) => Some(if let Ok(s) = t.cast::<SimRun>() {
            s.get().truth.clone()
        } else {
            let p: PathBuf = t.extract().map_err(|_| value("truth: expected a SimRun or the path of a truth.json"))?;
            idexp::data::Truth::read(&p).py()?
        }),
    };
    let res = run_long(py, time_limit, progress.as_ref(), |ctl| {
        run_study_with(&design, std::path::Path::new(""), &inputs, ctl)
    })?;
    Py::new(py, PyClassInitializer::from(Study { inner: Arc::new(res) }).add_subclass(Identification))
}
