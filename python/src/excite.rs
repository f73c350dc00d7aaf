//! `idexp.excite` (an excitation trajectory from a design) and
//! `idexp.export_trajectory` (the controller exports of a design written
//! earlier).

use crate::arrays::{out1, out2, out_rows};
use crate::dicts::{base_dir, from_dict, resolve, source, to_dict, Source};
use crate::err::{value, IdexpError, IntoPy};
use crate::long::run_long;
use idexp::excitation::design::ExciteDesign;
use idexp::excitation::report as xr;
use idexp::io::states::States;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The result of `idexp.excite`: the designed Fourier trajectory, its
/// identifiability and constraint margins.
#[pyclass(module = "idexp", frozen)]
pub struct ExciteResult {
    problem: Arc<idexp::excitation::Problem>,
    pub(crate) result: Arc<idexp::excitation::ExciteResult>,
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
    /// The names of the criterion's columns: the base parameters, or with
    /// `objective.columns = "gains"` one gain per joint ("gain <joint>") and
    /// the known mass's nine unknown parameters ("payload XX", …).
    #[getter]
    fn column_names(&self) -> Vec<String> {
        self.problem.objective.column_names.clone()
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
