//! The estimators of one experiment: the projection method and maximum
//! likelihood for closed-loop data (paper 002 eq. 10–16) and the
//! sensitivity-based model reduction (paper 000 Algorithm 1). The
//! least-squares methods stack every experiment ([`super::stack`]); these
//! need one experiment's repetitions, references or error growth, so the
//! design allows them with one `[[experiment]]` only
//! ([`super::StudyDesign::validate`]).

use super::{BlockWeight, ExperimentReport, Loaded, StudyDesign};
use crate::error::{Error, Result};
use crate::ident::closed_loop::{self, MlInfo, ProjectionInfo, ProjectionOptions};
use crate::ident::estimate::{self, errors, LsFit, Weights};
use crate::ident::reduce::{self, ReduceOptions, Reduction};
use crate::ident::Method;
use crate::optim::Control;
use crate::params::BaseParams;
use crate::robot::Robot;

/// What a one-experiment estimator gives beside its fit.
pub(super) struct Single {
    /// The base columns estimated (all of them but after a reduction).
    pub cols: Vec<usize>,
    /// The fit.
    pub fit: LsFit,
    /// How its rows were weighted (per joint, for the report).
    pub weight: BlockWeight,
    /// Projection-method details.
    pub projection: Option<ProjectionInfo>,
    /// Maximum-likelihood details.
    pub ml: Option<MlInfo>,
    /// The model reduction.
    pub reduction: Option<Reduction>,
}

/// The repetition weights of a one-experiment WLS (the design's, else per sample).
fn sample_weights(design: &StudyDesign) -> Weights {
    design.repetition_weights.unwrap_or(Weights::Sample)
}

/// Runs the design's one-experiment estimator on `e`; None when the method
/// stacks experiments (WLS/OLS without a reduction).
pub(super) fn estimate(design: &StudyDesign, robot: &Robot, base: &BaseParams, e: &Loaded, ctl: &Control) -> Result<Option<Single>> {
    let all: Vec<usize> = (0..base.n_base()).collect();
    let full = &e.prep.full;
    let needs_variances = |what: &str| -> Result<()> {
        if full.var.is_none() && sample_weights(design) == Weights::Sample {
            return Err(Error::invalid(
                format!("experiment `{}`", e.name),
                "repetition_weights",
                format!(
                    "{what} weighs every sample by its variance over the repetitions, but the experiment has {} repetition and no variance columns: record N_r ≥ 2 repetitions (or an averaged run with var_tau columns and `repetitions`), or set repetition_weights = \"joint\"",
                    e.n_reps
                ),
            ));
        }
        Ok(())
    };
    Ok(match (design.method, &design.reduce) {
        (Method::Wls, Some(r)) => {
            needs_variances("model reduction with sample weights")?;
            let ro = ReduceOptions {
                tol: r.tol,
                rank_tol: r.rank_tol,
                essential: r.essential.essential(),
                moving_speed: r.moving_speed,
                weights: sample_weights(design),
            };
            let moving: Vec<bool> = (0..robot.dof())
                .map(|j| e.prep.pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max) > r.moving_speed)
                .collect();
            let red = reduce::reduce(robot, base, full, &moving, &ro, ctl)?;
            Some(Single {
                cols: red.kept.clone(),
                fit: red.reduced.clone(),
                weight: block_weight(sample_weights(design)),
                projection: None,
                ml: None,
                reduction: Some(red),
            })
        }
        (Method::Projection, _) => {
            let run = e
                .run
                .as_ref()
                .ok_or_else(|| Error::Numerical("the projection method needs the experiment's run".into()))?;
            let po = ProjectionOptions {
                lags: design.projection.lags.map(|[a, b]| (a, b)),
                ..Default::default()
            };
            let (fit, info) = closed_loop::projection(full, &e.prep.pr, run, e.spec.decimate, &po)?;
            Some(Single {
                cols: all,
                fit,
                weight: block_weight(po.weights),
                projection: Some(info),
                ml: None,
                reduction: None,
            })
        }
        (Method::Ml, _) => {
            needs_variances("maximum likelihood starts from a WLS fit that")?;
            let start = estimate::wls(full, sample_weights(design))?;
            let (fit, info) = closed_loop::ml(
                robot,
                base,
                &e.prep.pr,
                closed_loop::MlStart {
                    cols: &all,
                    theta: &start.theta,
                    scale: &start.std,
                },
                &design.ml.options(),
                ctl,
            )?;
            Some(Single {
                cols: all,
                fit,
                weight: block_weight(sample_weights(design)),
                projection: None,
                ml: Some(info),
                reduction: None,
            })
        }
        (Method::Wls | Method::Ols, _) => None,
    })
}

fn block_weight(w: Weights) -> BlockWeight {
    match w {
        Weights::Sample => BlockWeight::Sample,
        Weights::Joint => BlockWeight::Joint,
    }
}

/// The report of the one experiment behind a [`Single`] fit: the whole
/// information is its own; σ per joint is the RMS residual of its rows.
pub(super) fn experiment_report(e: &Loaded, s: &Single) -> ExperimentReport {
    let n = e.prep.full.n;
    let stats = super::RowStats {
        weights: (0..n)
            .map(|j| if e.prep.full.joint.contains(&j) { s.weight } else { BlockWeight::NoRows })
            .collect(),
        sigma: errors(&e.prep.full, &s.fit.theta).rms,
        chi2_per_row: s.fit.chi2_dof,
        share: vec![1.0; s.cols.len()],
        alone: (s.fit.rank, s.fit.cond),
    };
    super::experiment_report_of(e, &s.fit.theta, stats)
}
