//! Planning an identification campaign (`idexp plan`): how many repetitions
//! of which candidate experiments, at the least robot time, meet every
//! accuracy target — a parameter's σ (base or standard, absolute or
//! relative) or the RMS torque-prediction error on a task trajectory.
//!
//! 1. [`model`]: each candidate's information per repetition F_e (the rows
//!    the study will keep, each an independent torque sample of σ²_j), the
//!    study's prior Λ, the task's Gram matrix and the targets as vectors;
//! 2. [`solve`]: the convex relaxation (a Schur-complement LMI, solved by
//!    supporting hyperplanes as LPs on Clarabel), its rounding by
//!    enumeration, the refusal of unreachable targets with the reason and
//!    the best value; with setup costs over the subsets of used experiments, and the best
//!    plan within a total-time budget ([`budget`]);
//! 3. [`rehearse`](mod@rehearse): the plan simulated with many noise seeds and identified
//!    by the study engine, the achieved σ and errors beside the prediction;
//! 4. [`output`]: the folder (plan.json, report.txt, plan.csv, params.csv,
//!    targets.csv, σ-vs-repetitions plots, status.json).
//!
//! The formulas and a worked example: docs/plan.md.

pub mod budget;
pub mod design;
pub mod model;
pub mod output;
pub mod rehearse;
pub mod solve;

pub use budget::{Miss, WithinBudget};
pub use design::{CandidateNoise, CandidateSpec, NoiseFrom, PlanDesign, TargetSpec};
pub use model::{build, Candidate, Model, Space, Target, TargetKind, Task};
pub use rehearse::{rehearse, Rehearsal};
pub use solve::{plan, PlanStatus, Prepared, Refusal, Solution};

use crate::error::Result;
use crate::optim::Control;
use std::path::Path;

/// Half-width of the enumeration around the relaxed solution.
pub const WINDOW: usize = 2;

/// A finished plan: the design, the model and the solution.
#[derive(Debug, Clone)]
pub struct PlanRun {
    /// The design.
    pub design: PlanDesign,
    /// The model.
    pub model: Model,
    /// The solution.
    pub solution: Solution,
    /// The rehearsal, if one was run.
    pub rehearsal: Option<Rehearsal>,
}

/// Builds the model of `design` (paths relative to `dir`) and plans it.
pub fn run_design(design: &PlanDesign, dir: &Path, ctl: &Control) -> Result<PlanRun> {
    design.validate("plan")?;
    let model = build(design, dir, ctl)?;
    let solution = plan(&model, WINDOW, ctl)?;
    Ok(PlanRun {
        design: design.clone(),
        model,
        solution,
        rehearsal: None,
    })
}
