//! The study's physically consistent estimate with a prior (`[consistent]`):
//! the weight (given, or chosen on the validation runs), the estimate per
//! link beside the prior, implausible values flagged, and the directions the
//! prior decided.

use super::{ConsistentReport, ConsistentSpec, Direction, Flag, LinkPrior, Loaded, Stacked, UnknownParam, UnknownRule, UnknownSpec, WeightRule, WeightSpec};
use crate::error::{Error, Result};
use crate::ident::consistent::{kinds_of, ConsistentStatus, Kind};
use crate::ident::estimate::{errors, Dataset};
use crate::ident::prior::PriorProblem;
use crate::optim::Control;
use crate::params::BaseParams;
use crate::robot::Robot;
use nalgebra::{DMatrix, DVector, SymmetricEigen};

/// The consistent estimate with a prior; None when interrupted.
#[allow(clippy::too_many_arguments)] // the study's parts, each needed once
pub(super) fn consistent_with_prior(
    robot: &Robot,
    base: &BaseParams,
    prior_robot: Option<&Robot>,
    cs: &ConsistentSpec,
    st: &Stacked,
    experiments: &[Loaded],
    validations: &[Loaded],
    ctl: &Control,
) -> Result<Option<ConsistentReport>> {
    let (kinds, links) = kinds_of(robot);
    let (theta0, scale) = crate::ident::prior::prior_of(robot, prior_robot, cs.scale)?;
    let link_names: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
    let pb = PriorProblem {
        r: &st.r,
        theta_b: &st.theta,
        k: &base.k,
        links: &links,
        link_names: &link_names,
        kinds: &kinds,
        prior: &theta0,
        scale: &scale,
    };
    let unknown = unknown_of(robot, &kinds, &theta0, &cs.unknown)?;
    let every_val: Vec<&Dataset> = validations.iter().map(|v| &v.prep.every).collect();
    let mut tolerance = None;
    let (weight, curve, sol) = match cs.weight {
        WeightSpec::Value(w) => (
            w,
            Vec::new(),
            crate::ident::prior::solve_with_unknown(&pb, &unknown, cs.metric, w, cs.margin, ctl)?,
        ),
        WeightSpec::Relative { relative } => {
            let w = crate::ident::prior::relative_weight(&st.r, relative);
            (
                w,
                Vec::new(),
                crate::ident::prior::solve_with_unknown(&pb, &unknown, cs.metric, w, cs.margin, ctl)?,
            )
        }
        WeightSpec::Rule(WeightRule::Validation) => {
            let obs = ctl.observer();
            obs.phase("identify prior weight", Some(cs.weight_grid.len() as u64));
            let range = torque_ranges(&every_val);
            let mut scored: Vec<(f64, f64, f64, crate::ident::consistent::Solution)> = Vec::new();
            let mut curve = Vec::new();
            for (i, &w) in cs.weight_grid.iter().enumerate() {
                if ctl.interrupted() {
                    obs.phase_done();
                    return Ok(None);
                }
                let sol = crate::ident::prior::solve_with_unknown(&pb, &unknown, cs.metric, w, cs.margin, ctl)?;
                let ok = ConsistentStatus::of(&sol.status).is_ok();
                let (score, se) = if ok {
                    range_scaled_error(&every_val, sol.base.as_slice(), &range)
                } else {
                    (f64::INFINITY, f64::INFINITY)
                };
                curve.push((w, score, sol.extra_cost));
                obs.progress(i as u64 + 1, &format!("weight {w:e}: validation {score:.4e}"));
                scored.push((w, score, se, sol));
            }
            obs.phase_done();
            let best = scored
                .iter()
                .filter(|x| x.1.is_finite())
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|x| (x.1, x.2))
                .ok_or_else(|| Error::invalid("consistent", "weight_grid", "no candidate weight gave a consistent estimate"))?;
            // one-standard-error rule: the strongest prior within one standard error of the best
            // (a tolerance that is not a number, from non-finite error terms: none, the best alone)
            let tol = if best.1.is_finite() { best.1 } else { 0.0 };
            let pick = scored
                .into_iter()
                .filter(|x| x.1 <= best.0 + tol)
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .expect("the best is within its own tolerance");
            tolerance = Some(tol);
            (pick.0, curve, pick.3)
        }
    };
    let status = ConsistentStatus::of(&sol.status);
    let names = robot.param_names();
    let th = sol.theta.as_slice();
    let active = crate::ident::consistent::active_constraints(robot, &kinds, &links, &sol, cs.margin, &scale);
    let mut flags = Vec::new();
    let [lo, hi] = cs.plausible;
    let ratio_flag = |flags: &mut Vec<Flag>, what: String, v: f64, p: f64, unit: &str| {
        if p > 0.0 && (v < lo * p || v > hi * p) {
            flags.push(Flag {
                what,
                value: v,
                prior: p,
                reason: format!("{:.3}× the prior's {p:.4e} {unit} (plausible: {lo}–{hi}×)", v / p),
            });
        }
    };
    let mut link_rows = Vec::new();
    for (i, &l) in links.iter().enumerate() {
        let (b, b0) = (&th[l..l + 10], &theta0.as_slice()[l..l + 10]);
        let com = |b: &[f64]| if b[9] > 0.0 { [b[6] / b[9], b[7] / b[9], b[8] / b[9]] } else { [0.0; 3] };
        // tr(I_c) = tr(I_o) − 2 m |c|²
        let trc = |b: &[f64]| {
            let c = com(b);
            b[0] + b[3] + b[5] - 2.0 * b[9] * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
        };
        let name = &link_names[i];
        ratio_flag(&mut flags, format!("{name} mass"), b[9], b0[9], "kg");
        ratio_flag(&mut flags, format!("{name} inertia about the COM (trace)"), trc(b), trc(b0), "kg·m²");
        link_rows.push(LinkPrior {
            link: name.clone(),
            mass: [b[9], b0[9]],
            com: [com(b), com(b0)],
            inertia_trace: [trc(b), trc(b0)],
            divergence: crate::ident::prior::divergence(b, b0),
        });
    }
    for (j, kd) in kinds.iter().enumerate() {
        if matches!(kd, Kind::NonNegative | Kind::NonPositive) {
            ratio_flag(&mut flags, names[j].clone(), th[j].abs(), theta0[j].abs(), "");
        }
    }
    let (unidentifiable, prior_decided, n_prior_decided) = directions(&st.r, &base.k, &scale, &sol.theta, &theta0, weight, &names);
    let rk = &st.r * &base.k;
    let unknown_rows = (0..names.len())
        .filter(|&j| unknown[j])
        .map(|j| {
            let h = rk.column(j).norm();
            UnknownParam {
                name: names[j].clone(),
                value: th[j],
                std_data: if h > 1e-12 * rk.norm() { 1.0 / h } else { f64::INFINITY },
            }
        })
        .collect();
    let consistent_experiments = experiments.iter().map(|e| errors(&e.prep.every, sol.base.as_slice())).collect();
    let total: usize = experiments.iter().map(|e| e.prep.full.y.len()).sum();
    let ssr_wls: f64 = st.blocks.iter().map(|b| b.chi2).sum();
    Ok(Some(ConsistentReport {
        status,
        prior: cs.prior.to_string(),
        metric: cs.metric,
        weight,
        weight_curve: curve,
        weight_tolerance: tolerance,
        scale: cs.scale,
        margin: cs.margin,
        standard_names: names,
        standard: th.to_vec(),
        prior_standard: theta0.as_slice().to_vec(),
        prior_scale: scale.as_slice().to_vec(),
        base: sol.base.as_slice().to_vec(),
        extra_cost: sol.extra_cost,
        chi2_dof: (ssr_wls + sol.extra_cost) / total.saturating_sub(st.rank).max(1) as f64,
        min_eigenvalue: sol.min_eig.clone(),
        active,
        links: link_rows,
        flags,
        unidentifiable,
        prior_decided,
        n_prior_decided,
        unknown: unknown_rows,
        experiments: consistent_experiments,
        pinocchio: links
            .iter()
            .zip(&link_names)
            .map(|(&l, name)| crate::ident::consistent::PinocchioBody {
                link: name.clone(),
                parameters: crate::ident::consistent::to_pinocchio(&th[l..l + 10]),
            })
            .collect(),
        iterations: sol.iterations,
        solve_time: sol.solve_time,
    }))
}

/// The directions of the standard parameters (in prior scales) that the fit
/// does not see (curvature ≤ 1e-10 of the largest) and those it sees less
/// than the prior (curvature below `weight`): (count unseen, weakest listed, count weak).
fn directions(
    r: &DMatrix<f64>,
    k: &DMatrix<f64>,
    scale: &DVector<f64>,
    theta: &DVector<f64>,
    theta0: &DVector<f64>,
    weight: f64,
    names: &[String],
) -> (usize, Vec<Direction>, usize) {
    let a = r * k * DMatrix::from_diagonal(scale);
    let h = a.transpose() * &a;
    let eig = SymmetricEigen::new(h);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let x = (theta - theta0).component_div(scale);
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let unseen = order.iter().filter(|&&i| eig.eigenvalues[i] <= 1e-10 * lmax).count();
    let weak: Vec<usize> = order.iter().copied().filter(|&i| eig.eigenvalues[i] < weight).collect();
    let listed = weak
        .iter()
        .take(12)
        .map(|&i| {
            let v = eig.eigenvectors.column(i);
            let mut comp: Vec<(usize, f64)> = v.iter().copied().enumerate().collect();
            comp.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            Direction {
                curvature: eig.eigenvalues[i].max(0.0),
                components: comp.iter().take(3).map(|&(j, c)| (names[j].clone(), c)).collect(),
                offset: v.dot(&x),
            }
        })
        .collect();
    (unseen, listed, weak.len())
}

/// Per standard parameter: a drive parameter without a known value (`unknown`).
fn unknown_of(robot: &Robot, kinds: &[Kind], theta0: &DVector<f64>, spec: &UnknownSpec) -> Result<Vec<bool>> {
    let drive = |j: usize| !matches!(kinds[j], Kind::Inertial(_));
    let names = robot.param_names();
    match spec {
        UnknownSpec::Rule(UnknownRule::None) => Ok(vec![false; names.len()]),
        UnknownSpec::Rule(UnknownRule::Zeros) => Ok((0..names.len()).map(|j| drive(j) && theta0[j] == 0.0).collect()),
        UnknownSpec::Names(list) => {
            let mut out = vec![false; names.len()];
            for n in list {
                match names.iter().position(|x| x == n) {
                    Some(j) if drive(j) => out[j] = true,
                    Some(_) => {
                        return Err(Error::invalid(
                            "study: [consistent]",
                            "unknown",
                            format!(
                            "`{n}` is a link inertial parameter: only drive parameters (Ia, Fc, Fv, …) can be unknown; a link's inertial values are its prior"
                        ),
                        ))
                    }
                    None => {
                        let drives: Vec<&String> = (0..names.len()).filter(|&j| drive(j)).map(|j| &names[j]).collect();
                        return Err(Error::invalid(
                            "study: [consistent]",
                            "unknown",
                            format!(
                                "`{n}` is not a parameter of robot {}: expected \"zeros\", \"none\" or drive parameter names among {drives:?}",
                                robot.name
                            ),
                        ));
                    }
                }
            }
            Ok(out)
        }
    }
}

/// Per joint, the range (max − min) of the measured torques over every row of every validation run.
fn torque_ranges(sets: &[&Dataset]) -> Vec<f64> {
    let n = sets.first().map_or(0, |d| d.n);
    let (mut lo, mut hi) = (vec![f64::INFINITY; n], vec![f64::NEG_INFINITY; n]);
    for d in sets {
        for (i, &j) in d.joint.iter().enumerate() {
            lo[j] = lo[j].min(d.y[i]);
            hi[j] = hi[j].max(d.y[i]);
        }
    }
    (0..n).map(|j| if hi[j] > lo[j] { hi[j] - lo[j] } else { 0.0 }).collect()
}

/// The criterion by which `weight = "validation"` chooses: the mean over the
/// (run, joint) terms t_{r,j} = RMS_{r,j}(τ − Cθ) / range_j, with range_j the
/// joint's torque range over every validation run (a joint carrying no
/// torque anywhere is left out, so a static pose with a vertical first axis
/// does not dominate as a relative error would), and its standard error
/// sd(t)/√K over the K terms (K = 1: the term's own sampling error, t·√(1/(2N))).
pub(super) fn range_scaled_error(sets: &[&Dataset], theta: &[f64], range: &[f64]) -> (f64, f64) {
    let th = DVector::from_column_slice(theta);
    let mut terms = Vec::new();
    let mut rows = 0usize;
    for d in sets {
        let pred = &d.c * &th;
        let (mut sq, mut cnt) = (vec![0.0; d.n], vec![0usize; d.n]);
        for (i, &j) in d.joint.iter().enumerate() {
            sq[j] += (d.y[i] - pred[i]).powi(2);
            cnt[j] += 1;
        }
        for j in 0..d.n {
            if cnt[j] > 0 && range.get(j).is_some_and(|&r| r > 0.0) {
                terms.push((sq[j] / cnt[j] as f64).sqrt() / range[j]);
                rows += cnt[j];
            }
        }
    }
    let k = terms.len();
    if k == 0 {
        return (f64::INFINITY, f64::INFINITY);
    }
    let mean = terms.iter().sum::<f64>() / k as f64;
    let se = if k >= 2 {
        (terms.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / (k - 1) as f64 / k as f64).sqrt()
    } else {
        mean * (0.5 / rows.max(1) as f64).sqrt()
    };
    (mean, se)
}
