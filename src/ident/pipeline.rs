//! The one-run pipeline ([`identify`]): one identification run (and an
//! optional validation run) to an estimate with its errors, plausibility
//! flags and, as asked, the model reduction or the consistent fit.

use super::{closed_loop, consistent, estimate, reduce};
use super::{
    filter_warnings, in_joint_coordinates, prepare, process_with, resolve_filter, Dataset, Estimate, EstimateStatus, Filter, FilterChoice, IdentOptions,
    Identification, Implausible, LsFit, Method, Prepared, Run, Weights,
};
use crate::error::{Error, Result};
use crate::params::BaseParams;
use crate::robot::Robot;
use crate::trajectory::FourierTrajectory;
use nalgebra::DVector;

/// Identifies the base parameters of `robot` from `run` (validated on
/// `validation`, each with its Fourier trajectory if known). `ctl` stops the
/// model reduction and the maximum-likelihood stage (they return what they
/// have, marked as interrupted).
pub fn identify(
    robot: &Robot,
    base: &BaseParams,
    run: &Run,
    trajectory: Option<&FourierTrajectory>,
    validation: Option<(&Run, Option<&FourierTrajectory>)>,
    opts: &IdentOptions,
    ctl: &crate::optim::Control,
) -> Result<Identification> {
    if run.n_joints() != robot.dof() {
        return Err(Error::dim("joints in the run", robot.dof(), run.n_joints()));
    }
    if opts.decimate == 0 {
        return Err(Error::invalid("identify", "decimate", "expected ≥ 1"));
    }
    if opts.consistent.is_some() && (opts.reduce.is_some() || !matches!(opts.method, Method::Wls | Method::Ols)) {
        return Err(Error::invalid(
            "identify",
            "--consistent",
            "the physically consistent fit uses the least-squares fit of every base parameter: run it with method wls or ols and without --reduce",
        ));
    }
    let run = &*in_joint_coordinates(robot, run, opts.coordinates)?;
    if opts.reduce.is_some() && !matches!(opts.method, Method::Wls) {
        return Err(Error::invalid(
            "identify",
            "reduce",
            "model reduction (paper 000 Algorithm 1) uses WLS: run it with method wls",
        ));
    }
    let uses_sample_weights = matches!(opts.method, Method::Wls | Method::Ml) && opts.weights == Weights::Sample;
    let Prepared {
        pr,
        filter,
        every,
        full,
        drop,
        rows_used,
        slow,
        vmin,
    } = prepare(robot, base, run, trajectory, opts, uses_sample_weights)?;
    let moving: Vec<bool> = (0..robot.dof())
        .map(|j| pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max) > opts.reduce.as_ref().map_or(0.05, |r| r.moving_speed))
        .collect();
    let mut projection = None;
    let mut ml = None;
    let mut reduction = None;
    let (cols, fit): (Vec<usize>, LsFit) = match opts.method {
        Method::Ols => ((0..base.n_base()).collect(), estimate::ols(&full)?),
        Method::Wls => match &opts.reduce {
            None => ((0..base.n_base()).collect(), estimate::wls(&full, opts.weights)?),
            Some(ro) => {
                let red = reduce::reduce(robot, base, &full, &moving, ro, ctl)?;
                let out = (red.kept.clone(), red.reduced.clone());
                reduction = Some(red);
                out
            }
        },
        Method::Projection => {
            let (f, info) = closed_loop::projection(&full, &pr, run, opts.decimate, &opts.projection)?;
            projection = Some(info);
            ((0..base.n_base()).collect(), f)
        }
        Method::Ml => {
            let start = estimate::wls(&full, opts.weights)?;
            let cols: Vec<usize> = (0..base.n_base()).collect();
            let (f, info) = closed_loop::ml(
                robot,
                base,
                &pr,
                closed_loop::MlStart {
                    cols: &cols,
                    theta: &start.theta,
                    scale: &start.std,
                },
                &opts.ml,
                ctl,
            )?;
            ml = Some(info);
            (cols, f)
        }
    };
    let ds = full.columns(&cols);
    let errors = estimate::errors(&ds, &fit.theta);
    let every_ds = every.columns(&cols);
    let errors_all = estimate::errors(&every_ds, &fit.theta);
    let mut val_every = None;
    let val_ds = match validation {
        Some((vrun, vtraj)) => {
            if vrun.n_joints() != robot.dof() {
                return Err(Error::dim("joints in the validation run", robot.dof(), vrun.n_joints()));
            }
            let vrun = &*in_joint_coordinates(robot, vrun, opts.coordinates)?;
            let vf = match (&opts.filter, vtraj) {
                (FilterChoice::Given(f), _) if !matches!(f, Filter::Fourier { .. }) => f.clone(),
                (_, Some(t)) => resolve_filter(&FilterChoice::Auto, Some(t), opts.harmonics),
                (_, None) => resolve_filter(&FilterChoice::Auto, None, None),
            };
            let vp = process_with(vrun, &vf, opts.velocity_from)?.decimated(opts.decimate);
            let ve = Dataset::every_row_dead_band(robot, base, &vp, super::prepare::dead_band(opts)).columns(&cols);
            let vd = ve.moving_rows_of(&vp, slow, vmin, &drop);
            val_every = Some(ve);
            Some(vd)
        }
        None => None,
    };
    let val_errors = val_ds.as_ref().map(|d| estimate::errors(d, &fit.theta));
    let val_errors_all = val_every.as_ref().map(|d| estimate::errors(d, &fit.theta));
    let consistent = match &opts.consistent {
        None => None,
        Some(co) => {
            let sw = match opts.method {
                Method::Wls => estimate::row_variances(&full, opts.weights)?.map(|v| 1.0 / v.sqrt()),
                _ => DVector::from_element(full.y.len(), 1.0),
            };
            let (mut c, sol) = consistent::fit(robot, base, &full, &sw, &fit.theta, co, ctl)?;
            let th = sol.base.as_slice();
            c.errors = estimate::errors(&ds, th);
            c.errors_all = estimate::errors(&every_ds, th);
            c.validation = val_ds.as_ref().map(|d| estimate::errors(d, th));
            c.validation_all = val_every.as_ref().map(|d| estimate::errors(d, th));
            Some(c)
        }
    };
    let positive = estimate::must_be_positive(robot, base);
    let implausible = cols
        .iter()
        .enumerate()
        .filter(|(i, &c)| positive[c] && fit.theta[*i] < 0.0)
        .map(|(i, &c)| Implausible {
            name: base.names[c].clone(),
            grouping: base.groupings[c].clone(),
            value: fit.theta[i],
            std: fit.std[i],
        })
        .collect();
    let status = if let Some(m) = &ml {
        EstimateStatus::Ml(m.status)
    } else if fit.rank < cols.len() {
        EstimateStatus::RankDeficient
    } else {
        EstimateStatus::Ok
    };
    let estimate = Estimate {
        status,
        method: opts.method,
        names: cols.iter().map(|&c| base.names[c].clone()).collect(),
        groupings: cols.iter().map(|&c| base.groupings[c].clone()).collect(),
        covariance: fit.cov.row_iter().map(|r| r.iter().copied().collect()).collect(),
        theta: fit.theta.clone(),
        std: fit.std.clone(),
        rel_std: fit.rel_std.clone(),
        rank: fit.rank,
        cond: fit.cond,
        cond_normalized: fit.cond_normalized,
        chi2_dof: fit.chi2_dof,
        errors,
        validation: val_errors,
        errors_all,
        rows_used,
        torque_source: None,
        validation_all: val_errors_all,
        standard_names: robot.param_names(),
        base_k: cols.iter().map(|&c| base.k.row(c).iter().copied().collect()).collect(),
        coordinates: opts.coordinates,
        averaged: run.averaged.is_some(),
        consistent,
        implausible,
        n_reps: pr.n_reps,
        n_samples: pr.len(),
        warnings: filter_warnings(&pr, false)
            .into_iter()
            .chain(
                crate::robot::export::inertial_warnings(robot)
                    .into_iter()
                    .map(|w| format!("nominal model: {w}")),
            )
            .collect(),
        filter_residual: pr.filter_residual.clone(),
        velocity: pr.velocity,
        filter,
        projection,
        ml,
        reduction,
        truth: None,
    };
    Ok(Identification {
        estimate,
        processed: pr,
        dataset: ds,
        validation: val_ds,
    })
}
