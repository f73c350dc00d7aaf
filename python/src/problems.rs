//! The four problems (and the simulation between them) as Python functions:
//! `excite`, `assess`, `simulate`, `identify`, `positions`, `fit`.
//!
//! Every function takes a design as a path (the file the command line takes)
//! or, where the design type is plain data, a dict with the file's fields;
//! relative paths inside a dict are resolved against `base_dir` (default:
//! the current directory), inside a file against the file's folder, as on the
//! command line.

use crate::arrays::{self, out1, out2, out_rows, Arg};
use crate::err::{value, IdexpError, IntoPy};
use crate::long::run_long;
use crate::robot::Robot;
use idexp::data::{Repetition, Run, TorqueFrom};
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::report as xr;
use idexp::ident::{self, FilterChoice, IdentOptions, Method, Weights};
use idexp::io::states::States;
use idexp::params::{BaseOptions, BaseParams};
use idexp::trajectory::FourierTrajectory;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A serde value as Python objects (dicts, lists, floats, strings).
pub fn to_dict<'py, T: serde::Serialize + ?Sized>(py: Python<'py>, v: &T) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, v).map_err(|e| IdexpError::new_err(format!("idexp: could not convert a result to Python: {e}")))
}

/// A design given as a file or as a dict.
pub(crate) enum Source {
    File(PathBuf),
    Dict(serde_json::Value),
}

pub(crate) fn source(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
    if obj.is_instance_of::<PyDict>() {
        let v: serde_json::Value =
            pythonize::depythonize(obj).map_err(|e| value(format!("design: the dict is not plain data (str, numbers, lists, dicts): {e}")))?;
        return Ok(Source::Dict(v));
    }
    match obj.extract::<PathBuf>() {
        Ok(p) => Ok(Source::File(p)),
        Err(_) => Err(value(format!(
            "design: expected a path (str or os.PathLike) or a dict, got {}",
            obj.get_type().name()?
        ))),
    }
}

/// Deserialises a design dict; errors name the field like the file readers do.
/// A dict input as T; an error names the field it fails on (`field
/// `refine.stall`: invalid value: integer `-1`, expected usize`).
pub(crate) fn from_dict<T: serde::de::DeserializeOwned>(v: serde_json::Value, what: &str) -> PyResult<T> {
    serde_path_to_error::deserialize(v).map_err(|e| {
        let path = e.path().to_string();
        if path == "." {
            IdexpError::new_err(format!("{what} (dict): {}", e.inner()))
        } else {
            IdexpError::new_err(format!("{what} (dict): field `{path}`: {}", e.inner()))
        }
    })
}

pub(crate) fn base_dir(b: Option<PathBuf>) -> PathBuf {
    b.unwrap_or_else(|| PathBuf::from("."))
}

/// A design and the folder its relative paths start from: a file is read by
/// `read` (its folder); a dict is deserialised (`what` names it in errors),
/// given its default name by `name` and checked by `validate` (`base_dir`).
pub(crate) fn design_and_dir<T: serde::de::DeserializeOwned>(
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    what: &str,
    read: impl FnOnce(&Path) -> idexp::Result<T>,
    name: impl FnOnce(&mut T),
    validate: impl FnOnce(&T, &str) -> idexp::Result<()>,
) -> PyResult<(T, PathBuf)> {
    Ok(match source(design)? {
        Source::File(p) => (read(&p).py()?, p.parent().map(Path::to_path_buf).unwrap_or_default()),
        Source::Dict(v) => {
            let mut d: T = from_dict(v, what)?;
            name(&mut d);
            validate(&d, &format!("{what} (dict)")).py()?;
            (d, self::base_dir(base_dir))
        }
    })
}

fn resolve(dir: &Path, p: &Path) -> PathBuf {
    if p.is_relative() {
        dir.join(p)
    } else {
        p.to_path_buf()
    }
}

// ───────────────────────────── excite ─────────────────────────────

/// The result of `idexp.excite`: the designed Fourier trajectory, its
/// identifiability and constraint margins.
#[pyclass(module = "idexp", frozen)]
pub struct ExciteResult {
    problem: Arc<idexp::excitation::Problem>,
    result: Arc<idexp::excitation::ExciteResult>,
    robot_path: PathBuf,
}

fn states_dict<'py>(py: Python<'py>, s: &States, n: usize) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    if let Some(t) = &s.t {
        d.set_item("t", out1(py, t.clone()))?;
    }
    d.set_item("q", out_rows(py, &s.q, n))?;
    d.set_item("qd", out_rows(py, &s.qd, n))?;
    d.set_item("qdd", out_rows(py, &s.qdd, n))?;
    Ok(d)
}

#[pymethods]
impl ExciteResult {
    /// "feasible" or "infeasible" (on the verification grid).
    #[getter]
    fn status(&self) -> &'static str {
        match self.result.status {
            idexp::excitation::Status::Feasible => "feasible",
            idexp::excitation::Status::Infeasible => "infeasible",
        }
    }
    /// Whether every constraint holds on the verification grid.
    #[getter]
    fn feasible(&self) -> bool {
        self.result.status == idexp::excitation::Status::Feasible
    }
    /// Whether the delivered trajectory may be played: dict with
    /// collisions ("imposed", "checked_afterwards", "not_checked"), safe
    /// (True, False, or None when nothing could be checked), closest (pair,
    /// distance in m, cap, t in s, segment; for "checked_afterwards") and
    /// statement.
    #[getter]
    fn safety<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.result.execution.safety)
    }
    /// What cut the run short (time limit, evaluation budget), or None.
    #[getter]
    fn stopped_by(&self) -> Option<String> {
        self.result.stopped_by.as_ref().map(|s| s.to_string())
    }
    /// Fourier coefficients: dict with omega (rad/s), period (s), q0 (n,),
    /// a (n, n_h) and b (n, n_h) (rad/s) of q_j(t) = q0_j + Σ_k a_kj/(kω)
    /// sin(kωt) − b_kj/(kω) cos(kωt). For a B-spline design
    /// (`shape = "bspline"`): shape ("bspline"), degree, duration (s), knots
    /// and control (n, s + p) (rad or m).
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = match &self.result.trajectory {
            idexp::trajectory::ShapeMotion::Fourier(t) => t,
            idexp::trajectory::ShapeMotion::BSpline(m) => {
                let d = PyDict::new(py);
                d.set_item("shape", "bspline")?;
                d.set_item("degree", m.degree)?;
                d.set_item("duration", idexp::trajectory::Motion::duration(m))?;
                d.set_item("knots", out1(py, m.knots.clone()))?;
                let (n, c) = (m.control.len(), m.control[0].len());
                d.set_item("control", out2(py, n, c, m.control.iter().flatten().copied().collect()))?;
                return Ok(d);
            }
        };
        let (n, nh) = (t.n_joints(), t.n_harmonics());
        let d = PyDict::new(py);
        d.set_item("omega", t.omega)?;
        d.set_item("period", t.period())?;
        d.set_item("q0", out1(py, t.q0.clone()))?;
        d.set_item("a", out2(py, n, nh, t.a.iter().flatten().copied().collect()))?;
        d.set_item("b", out2(py, n, nh, t.b.iter().flatten().copied().collect()))?;
        Ok(d)
    }
    /// The design vector x (the optimiser's variables).
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.result.x.clone())
    }
    /// Criterion value.
    #[getter]
    fn criterion(&self) -> f64 {
        self.result.criterion
    }
    /// Condition number of the scaled base regressor.
    #[getter]
    fn cond(&self) -> f64 {
        self.result.spectrum.cond
    }
    /// Singular values of the scaled base regressor, decreasing.
    #[getter]
    fn singular_values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        out1(py, self.result.spectrum.singular_values.clone())
    }
    /// Worst margin of every constraint (list of dicts: name, kind, limit,
    /// worst, margin (≥ 0 feasible), at (s), unit).
    #[getter]
    fn margins<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.result.margins)
    }
    /// The violated constraints, worst first (empty when feasible).
    #[getter]
    fn violated<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.result.violated)
    }
    /// Wall time of the search (s).
    #[getter]
    fn seconds(&self) -> f64 {
        self.result.seconds
    }
    /// Base parameter names (the columns of the criterion's regressor).
    #[getter]
    fn base_names(&self) -> Vec<String> {
        self.problem.base.names.clone()
    }
    /// The robot file of the design.
    #[getter]
    fn robot(&self) -> PathBuf {
        self.robot_path.clone()
    }
    /// The trajectory sampled at the design's controller rate (the rows of
    /// periodic.csv; trajectory.csv holds the delivered lead-in, periods and lead-out): dict with t (N,), q, qd, qdd (N, n).
    #[getter]
    fn trajectory<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        self.sample(py, self.problem.design.trajectory.controller_rate)
    }
    /// result.sample(rate) -> dict: one period sampled at `rate` Hz.
    fn sample<'py>(&self, py: Python<'py>, rate: f64) -> PyResult<Bound<'py, PyDict>> {
        let s = self.result.trajectory.sample(rate).py()?;
        states_dict(py, &s, self.problem.robot.dof())
    }
    /// The delivered trajectory, what trajectory.csv and the controller
    /// exports hold: from the home pose at rest through the lead-in, the
    /// `periods` periods and the lead-out back to home at rest, sampled at
    /// the design's controller rate. A dict with t (N,), q, qd, qdd (N, n),
    /// segment (N,) int64 (0 lead-in, k period k, −1 lead-out, trajectory.csv's
    /// column), labels ({code: "lead_in" | "period k" | "lead_out"}), phases
    /// (list of (label, start s, end s)), home (n,), periods, period,
    /// lead_in_duration, lead_out_duration, duration (s) and rate (Hz).
    /// None when the design is not playable rest to rest (see `report`).
    #[getter]
    fn delivered<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        match &self.result.execution.delivered {
            Some(d) => Ok(Some(crate::exports::delivered_dict(
                py,
                d,
                self.problem.design.trajectory.controller_rate,
                self.problem.robot.dof(),
            )?)),
            None => Ok(None),
        }
    }
    /// result.delivered_sample(rate) -> dict | None: the delivered trajectory
    /// sampled at `rate` Hz (keys as `delivered`).
    fn delivered_sample<'py>(&self, py: Python<'py>, rate: f64) -> PyResult<Option<Bound<'py, PyDict>>> {
        match &self.result.execution.delivered {
            Some(d) => Ok(Some(crate::exports::delivered_dict(py, d, rate, self.problem.robot.dof())?)),
            None => Ok(None),
        }
    }
    /// result.export(folder, formats, rate=None, ur="e-series", csv_units="rad",
    /// csv_derivatives=False, approach_speed=0.5, approach_acceleration=1.0) -> list of paths
    ///
    /// The delivered trajectory in controller formats, the files of `idexp
    /// excite --export`: "ur" (`<design>.script`, URScript servoj at the
    /// controller's rate: 500 Hz e-series, 125 Hz CB3, after a movej to the
    /// start with `approach_speed` rad/s and `approach_acceleration` rad/s²),
    /// "ros2" (`<design>_ros2.yaml`, a JointTrajectory, and
    /// `<design>_ros2_goal.yaml`, its FollowJointTrajectory goal), "csv"
    /// (`<design>_export.csv`, positions in `csv_units`, with velocities and
    /// accelerations if `csv_derivatives`). ROS 2 and CSV are sampled at
    /// `rate` Hz (default: the design's controller rate). `formats`: a list or
    /// a comma-separated string. An infeasible design has nothing safe to
    /// play: IdexpError.
    #[pyo3(signature = (folder, formats, rate = None, ur = "e-series", csv_units = "rad", csv_derivatives = false,
                        approach_speed = 0.5, approach_acceleration = 1.0))]
    #[allow(clippy::too_many_arguments)] // the Python signature mirrors `idexp excite --export`'s options
    fn export(
        &self,
        py: Python<'_>,
        folder: PathBuf,
        formats: &Bound<'_, PyAny>,
        rate: Option<f64>,
        ur: &str,
        csv_units: &str,
        csv_derivatives: bool,
        approach_speed: f64,
        approach_acceleration: f64,
    ) -> PyResult<Vec<PathBuf>> {
        let f = crate::exports::formats(formats)?;
        let a = crate::exports::TrajectoryArgs {
            rate,
            ur,
            csv_units,
            csv_derivatives,
            approach_speed,
            approach_acceleration,
        };
        let p = &self.problem;
        let o = a.options(f, p.design.trajectory.controller_rate, &p.design.name)?;
        let d = self.result.playable().map_err(|why| {
            IdexpError::new_err(format!(
                "export: design `{}`: {why} (see result.safety, result.violated and result.report)",
                p.design.name
            ))
        })?;
        let names: Vec<String> = p.robot.joints.iter().map(|j| j.name.clone()).collect();
        let revolute: Vec<bool> = p.robot.joints.iter().map(|j| j.kind == idexp::robot::JointKind::Revolute).collect();
        py.detach(|| idexp::trajectory::export::write_exports(&folder, &names, &revolute, d, &o)).py()
    }
    /// The whole result as the library serialises it (report.json's "result").
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &*self.result)
    }
    /// result.write(folder): the command line's output folder
    /// (coefficients.json, trajectory.csv, report.json, report.txt,
    /// design.json, status.json, SVG plots). Returns the folder.
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| xr::write_outputs(&self.problem, &self.result, &folder)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        format!(
            "ExciteResult({}, cond={:.4}, criterion={:.6}, {:.1} s)",
            self.status(),
            self.result.spectrum.cond,
            self.result.criterion,
            self.result.seconds
        )
    }
}

/// excite(design, time_limit=None, seed=None, base_dir=None, progress=None) -> ExciteResult
#[pyfunction]
#[pyo3(signature = (design, time_limit = None, seed = None, base_dir = None, progress = None))]
pub fn excite(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    time_limit: Option<f64>,
    seed: Option<u64>,
    base_dir: Option<PathBuf>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<ExciteResult> {
    let (mut d, ctx) = match source(design)? {
        Source::File(p) => (ExciteDesign::load(&p).py()?, p.display().to_string()),
        Source::Dict(v) => {
            let mut d: ExciteDesign = from_dict(v, "excite design")?;
            if d.name.is_empty() {
                d.name = "excite".into();
            }
            d.robot = resolve(&self::base_dir(base_dir), &d.robot);
            (d, "excite design (dict)".to_string())
        }
    };
    if let Some(s) = seed {
        d.seed = s;
    }
    if let Some(t) = time_limit {
        if !(t.is_finite() && t > 0.0) {
            return Err(value(format!("time_limit: expected a positive number of seconds, got {t}")));
        }
        d.time_limit = Some(t);
    }
    let robot_path = d.robot.clone();
    let robot = idexp::robot::load(&d.robot).py()?;
    let p = idexp::excitation::Problem::new(d, robot, &ctx).py()?;
    let r = run_long(py, None, progress.as_ref(), |ctl| idexp::excitation::run(&p, ctl))?;
    Ok(ExciteResult {
        problem: Arc::new(p),
        result: Arc::new(r),
        robot_path,
    })
}

// ───────────────────────────── assess ─────────────────────────────

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

// ───────────────────────────── simulate ─────────────────────────────

/// A simulated run (`idexp.simulate`): repetitions, the true parameters.
#[pyclass(module = "idexp", frozen)]
pub struct SimRun {
    result: Arc<idexp::sim::SimResult>,
    design: idexp::sim::SimDesign,
    truth: idexp::data::Truth,
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

// ───────────────────────────── identify ─────────────────────────────

/// An identification (`idexp.identify`): estimates, covariance, σ*, errors,
/// and the measured and predicted torques behind them.
#[pyclass(module = "idexp", frozen)]
pub struct Identification {
    inner: Arc<ident::Identification>,
    options: serde_json::Value,
    robot: Arc<idexp::robot::Robot>,
    robot_path: PathBuf,
}

impl Identification {
    fn identified_model(&self) -> PyResult<idexp::robot::Robot> {
        match &self.inner.estimate.consistent {
            Some(c) if c.status.is_ok() => self.robot.with_params(&c.standard).py(),
            Some(c) => Err(IdexpError::new_err(format!(
                "export: the consistent fit ended with status `{}`: no identified model to write",
                c.status
            ))),
            None => Err(value(
                "formats: \"urdf\" and \"toml\" write the physically consistent model: identify with consistent=True",
            )),
        }
    }
}

#[pymethods]
impl Identification {
    /// `ok`, `rank_deficient`, or the solver's status (ML).
    #[getter]
    fn status(&self) -> String {
        self.inner.estimate.status.to_string()
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
    /// Estimates θ̂ (n_base,).
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
    /// Covariance of θ̂ (n_base, n_base).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let c = &self.inner.estimate.covariance;
        out_rows(py, c, c.len())
    }
    /// Errors on the identification run: dict with e, e_rel, rms (n,) and
    /// noise_floor (eq. 11–12).
    #[getter]
    fn errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.errors)
    }
    /// Errors on the validation run, or None.
    #[getter]
    fn validation_errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.validation)
    }
    /// Comparison with the truth (list of dicts name, truth, estimate, z), or None.
    #[getter]
    fn truth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate.truth)
    }
    /// The estimate as estimate.json has it.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.estimate)
    }
    /// Measured and predicted torques of the identification data, per joint:
    /// dict with t (N,) (processed sample times), measured and predicted
    /// (N, n) (N·m; NaN where a row was left out as too slow).
    #[getter]
    fn torques<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let ds = &self.inner.dataset;
        let (n, ns) = (ds.n, ds.n_samples);
        let theta = nalgebra::DVector::from_column_slice(&self.inner.estimate.theta);
        let pred = &ds.c * theta;
        let mut m = vec![f64::NAN; ns * n];
        let mut p = vec![f64::NAN; ns * n];
        for i in 0..ds.y.len() {
            let k = ds.sample[i] * n + ds.joint[i];
            m[k] = ds.y[i];
            p[k] = pred[i];
        }
        let d = PyDict::new(py);
        let t = &self.inner.processed.t;
        d.set_item("t", out1(py, t.iter().take(ns).copied().collect()))?;
        d.set_item("measured", out2(py, ns, n, m))?;
        d.set_item("predicted", out2(py, ns, n, p))?;
        Ok(d)
    }
    /// The physically consistent estimate (`consistent=True`), as the
    /// `consistent` block of estimate.json: status, standard_names, standard
    /// (θ, p), base (K θ), extra_cost, extra_cost_rel, chi2_dof,
    /// min_eigenvalue per link, active constraints, errors, pinocchio
    /// (per body, Pinocchio's order), lambda, iterations. None without
    /// `consistent=True`.
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
    /// The identified model: the robot with the consistent standard
    /// parameters (`consistent=True`); IdexpError otherwise.
    fn model(&self) -> PyResult<Robot> {
        Ok(Robot::new(self.identified_model()?, self.robot_path.clone()))
    }
    /// export(folder, formats=("urdf", "toml", "csv")) -> list of paths
    ///
    /// The files of `idexp identify --export`: "csv" (`params.csv`: every
    /// base and standard parameter with std and σ*), "urdf" (`robot.urdf`:
    /// the robot's URDF with the consistent inertials; a DH robot has none:
    /// ValueError) and "toml" (`robot.toml`: the robot file with the
    /// consistent drive parameters and, for a DH table, inertials). urdf and
    /// toml need `identify(..., consistent=True)`. `formats`: a list or a
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
                files.extend(crate::exports::write_model(&self.robot_path, m, &folder, &model_kinds)?);
            }
            Ok(files)
        })
    }
    /// The text report (`idexp identify` prints it).
    fn text(&self) -> String {
        self.inner.estimate.text()
    }
    /// write(folder): the command line's output folder (estimate.json,
    /// report, plots, options.json, status.json).
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| -> idexp::Result<()> {
            self.inner.write(&folder)?;
            idexp::io::write_json(&folder.join("options.json"), &self.options)?;
            self.inner.write_status(&folder, None, &self.options, false).map(|_| ())
        })
        .py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        let e = &self.inner.estimate;
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

fn read_run(py: Python<'_>, obj: &Bound<'_, PyAny>, drives: &Drives<'_>, what: &str) -> PyResult<(Run, Option<FourierTrajectory>)> {
    let n = drives.robot.dof();
    if let Ok(s) = obj.cast::<SimRun>() {
        let s = s.get();
        let run = Run::new(Vec::new(), s.result.reps.clone()).py()?;
        return Ok((run, s.result.setup.reference.fourier().cloned()));
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
        return Ok((Run::new(Vec::new(), reps).py()?, None));
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
    let run = py
        .detach(|| Run::read_drives(&paths, drives.robot, None, drives.from, drives.tolerance))
        .py()?
        .0;
    let traj = ident::run_trajectory(&run).py()?;
    Ok((run, traj))
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
) -> PyResult<Identification> {
    let r = &robot.inner;
    let method: Method = method.parse().py()?;
    let weights: Weights = weights.parse().py()?;
    if !(cutoff.is_finite() && cutoff > 0.0) {
        return Err(value(format!("cutoff: expected a positive frequency in Hz, got {cutoff}")));
    }
    let standstill: ident::Standstill = standstill.parse().py()?;
    let velocity_from: ident::VelocityFrom = velocity_from.parse().py()?;
    let drives = Drives {
        robot: r,
        from: torque_from.parse().py()?,
        tolerance: current_tolerance,
    };
    let (run, run_traj) = read_run(py, run, &drives, "run")?;
    let traj = match &trajectory {
        Some(t) => Some(read_trajectory(t)?),
        None => run_traj,
    };
    let filter = match filter {
        "auto" if traj.is_none() => FilterChoice::Given(ident::Filter::LowPass { cutoff }),
        "auto" => FilterChoice::Auto,
        "fourier" => match &traj {
            Some(t) => FilterChoice::Given(ident::Filter::Fourier {
                omega: t.omega,
                n_h: t.n_harmonics(),
            }),
            None => return Err(value("filter: \"fourier\" needs the run's Fourier trajectory: pass trajectory=")),
        },
        "lowpass" => FilterChoice::Given(ident::Filter::LowPass { cutoff }),
        "none" => FilterChoice::Given(ident::Filter::None),
        f => return Err(value(format!("filter: expected \"auto\", \"fourier\", \"lowpass\" or \"none\", got {f:?}"))),
    };
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(value(format!("margin: expected ε ≥ 0 (kg·m²; every pseudo-inertia ⪰ ε I), got {margin}")));
    }
    if !(regularization.is_finite() && regularization >= 0.0) {
        return Err(value(format!(
            "regularization: expected a weight ≥ 0 of the closest-to-nominal term, got {regularization}"
        )));
    }
    let opts = IdentOptions {
        method,
        weights,
        filter,
        harmonics,
        decimate,
        consistent: consistent.then_some(idexp::ident::consistent::ConsistentOptions { margin, regularization }),
        standstill,
        velocity_from,
        dead_band,
        ..Default::default()
    };
    let val = validate.as_ref().map(|v| read_run(py, v, &drives, "validate")).transpose()?;
    let truth = match &truth {
        None => None,
        Some(t) => Some(if let Ok(s) = t.cast::<SimRun>() {
            s.get().truth.clone()
        } else {
            let p: PathBuf = t.extract().map_err(|_| value("truth: expected a SimRun or the path of a truth.json"))?;
            idexp::data::Truth::read(&p).py()?
        }),
    };
    let base = robot.default_base()?;
    let mut id = run_long(py, time_limit, progress.as_ref(), |ctl| {
        ident::identify(r, &base, &run, traj.as_ref(), val.as_ref().map(|(v, t)| (v, t.as_ref())), &opts, ctl)
    })?;
    if let Some(t) = &truth {
        id.estimate.compare_truth(&t.base_names, &t.base).py()?;
    }
    let options = serde_json::json!({ "robot": robot.path.display().to_string(), "options": opts, "source": "python" });
    Ok(Identification {
        inner: Arc::new(id),
        options,
        robot: robot.inner.clone(),
        robot_path: robot.path.clone(),
    })
}

// ───────────────────────────── positions ─────────────────────────────

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

// ───────────────────────────── fit ─────────────────────────────

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

/// export_trajectory(coefficients, formats, out=None, rate=None, ur="e-series", csv_units="rad",
/// csv_derivatives=False, approach_speed=0.5, approach_acceleration=1.0) -> list of paths
///
/// `idexp export`: the delivered trajectory of a design written earlier
/// (its `coefficients.json`) in controller formats, into `out` (default: the
/// folder of coefficients.json); options as `ExciteResult.export`.
#[pyfunction]
#[pyo3(signature = (coefficients, formats, out = None, rate = None, ur = "e-series", csv_units = "rad",
                    csv_derivatives = false, approach_speed = 0.5, approach_acceleration = 1.0))]
#[allow(clippy::too_many_arguments)] // the Python signature mirrors `idexp export`'s options
pub fn export_trajectory(
    py: Python<'_>,
    coefficients: PathBuf,
    formats: &Bound<'_, PyAny>,
    out: Option<PathBuf>,
    rate: Option<f64>,
    ur: &str,
    csv_units: &str,
    csv_derivatives: bool,
    approach_speed: f64,
    approach_acceleration: f64,
) -> PyResult<Vec<PathBuf>> {
    let f = crate::exports::formats(formats)?;
    let a = crate::exports::TrajectoryArgs {
        rate,
        ur,
        csv_units,
        csv_derivatives,
        approach_speed,
        approach_acceleration,
    };
    let des = idexp::trajectory::export::Designed::load(&coefficients).py()?;
    let o = a.options(f, des.controller_rate, &des.design)?;
    let dir = out.unwrap_or_else(|| coefficients.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(".")));
    py.detach(|| idexp::trajectory::export::write_exports(&dir, &des.names, &des.revolute, &des.delivered, &o))
        .py()
}
