//! `idexp.plan`: the cheapest repetitions of candidate experiments that meet
//! every accuracy target, as `idexp plan plan.toml [--rehearse N]`.

use crate::dicts::{design_and_dir, to_dict};
use crate::err::IntoPy;
use crate::long::run_long;
use idexp::plan::{rehearse, run_design, PlanDesign, PlanRun, PlanStatus};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Arc;

/// A plan (`idexp.plan`): repetitions per candidate, their cost against the
/// relaxed bound, every target's predicted value, refusals, the rehearsal.
#[pyclass(module = "idexp", frozen)]
pub struct Plan {
    inner: Arc<PlanRun>,
}

#[pymethods]
impl Plan {
    /// `planned`, `unreachable`, `over_budget`, `interrupted` or `failed`.
    #[getter]
    fn status(&self) -> &'static str {
        self.inner.solution.status.name()
    }
    /// Candidate names, in the design's order.
    #[getter]
    fn candidates(&self) -> Vec<String> {
        self.inner.model.candidates.iter().map(|c| c.name.clone()).collect()
    }
    /// Repetitions per candidate (the integer plan).
    #[getter]
    fn repetitions(&self) -> Vec<usize> {
        self.inner.solution.repetitions.clone()
    }
    /// The plan's robot time (s).
    #[getter]
    fn cost(&self) -> f64 {
        self.inner.solution.cost
    }
    /// The relaxation's lower bound on every plan's cost (s).
    #[getter]
    fn relaxed_cost(&self) -> f64 {
        self.inner.solution.relaxed_cost
    }
    /// Every target's predicted value for the plan (σ or RMS, the target's unit).
    #[getter]
    fn values(&self) -> Vec<f64> {
        self.inner.solution.values.clone()
    }
    /// σ per joint of one repetition of each candidate (N·m), and where it comes from.
    #[getter]
    fn sigma(&self) -> Vec<(Vec<f64>, String)> {
        self.inner.model.candidates.iter().map(|c| (c.sigma.clone(), c.noise_source.clone())).collect()
    }
    /// The total robot time available (s), or None.
    #[getter]
    fn budget(&self) -> Option<f64> {
        self.inner.solution.budget
    }
    /// `over_budget`: the best plan within the budget (repetitions, cost,
    /// values, worst_ratio, lower_bound, missed targets), else None.
    #[getter]
    fn within_budget<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.solution.within_budget)
    }
    /// The unreachable targets (label, reason, best reachable value, bound).
    #[getter]
    fn refused<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.solution.refused)
    }
    /// The whole solution as plan.json has it.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.solution)
    }
    /// The rehearsal (seeds, targets met, achieved σ beside the prediction), or None.
    #[getter]
    fn rehearsal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.inner.rehearsal)
    }
    /// The text report (`idexp plan` prints it).
    fn text(&self) -> String {
        idexp::plan::output::report_text(&self.inner)
    }
    /// write(folder): the command line's output folder (plan.json, report,
    /// CSVs, σ-vs-repetitions plots, status.json).
    fn write(&self, py: Python<'_>, folder: PathBuf) -> PyResult<PathBuf> {
        py.detach(|| idexp::plan::output::write_outputs(&self.inner, &folder, None)).py()?;
        Ok(folder)
    }
    fn __repr__(&self) -> String {
        let s = &self.inner.solution;
        format!(
            "Plan({}, repetitions={:?}, cost={:.1} s, relaxed bound {:.1} s)",
            self.status(),
            s.repetitions,
            s.cost,
            s.relaxed_cost
        )
    }
}

/// plan(design, base_dir=None, rehearse=0, time_limit=None, progress=None) -> Plan
#[pyfunction]
#[pyo3(signature = (design, base_dir = None, rehearse = 0, time_limit = None, progress = None))]
pub fn plan(
    py: Python<'_>,
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    rehearse: usize,
    time_limit: Option<f64>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<Plan> {
    let (d, dir) = design_and_dir(
        design,
        base_dir,
        "plan design",
        PlanDesign::read,
        |d| {
            if d.name.is_empty() {
                d.name = "plan".into();
            }
        },
        PlanDesign::validate,
    )?;
    let run = run_long(py, time_limit, progress.as_ref(), |ctl| {
        let mut run = run_design(&d, &dir, ctl)?;
        if rehearse > 0 && run.solution.status == PlanStatus::Planned {
            run.rehearsal = Some(self::rehearse(&run, None, rehearse, &dir, ctl)?);
        }
        Ok(run)
    })?;
    Ok(Plan { inner: Arc::new(run) })
}
