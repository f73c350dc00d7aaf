//! One run made ready for estimation as its study entry says: its
//! coordinates, the processed samples and the rows the standstill rule keeps.

use super::study::ExperimentSpec;
use super::{process_with, Coordinates, Dataset, Filter, Method, Processed, RowsUsed, Run, Standstill};
use crate::error::{Error, Result};
use crate::params::BaseParams;
use crate::robot::Robot;
use crate::trajectory::FourierTrajectory;

/// Fourier filtering at the trajectory's ω, with `harmonics` (default: its
/// n_h, the excited ones as in paper 000 §III-C; more keep the part of the
/// closed-loop response above the excitation band that n_h would remove from q̈).
pub fn fourier_filter(trajectory: &FourierTrajectory, harmonics: Option<usize>) -> Filter {
    Filter::Fourier {
        omega: trajectory.omega,
        n_h: harmonics.unwrap_or(trajectory.n_harmonics()),
    }
}

/// The Fourier trajectory stored next to a run (`trajectory.json` in its folder), if any.
pub fn run_trajectory(run: &Run) -> Result<Option<FourierTrajectory>> {
    match run.folder().map(|d| d.join("trajectory.json")) {
        Some(p) if p.exists() => Ok(Some(FourierTrajectory::load(&p)?)),
        _ => Ok(None),
    }
}

/// A run in joint coordinates (runs logged motor-side mapped through the coupling).
pub fn in_joint_coordinates<'a>(robot: &Robot, run: &'a Run, coordinates: Coordinates) -> Result<std::borrow::Cow<'a, Run>> {
    Ok(match coordinates {
        Coordinates::Joint => std::borrow::Cow::Borrowed(run),
        Coordinates::Motor => {
            let mut r = run.clone();
            r.to_joint_coordinates(&robot.coupling_matrix())?;
            std::borrow::Cow::Owned(r)
        }
    })
}

/// A run ready for estimation ([`prepare`]).
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The processed (averaged, filtered, decimated) run.
    pub pr: Processed,
    /// The filter used.
    pub filter: Filter,
    /// Every sample's rows (every base column).
    pub every: Dataset,
    /// The rows the standstill rule keeps.
    pub full: Dataset,
    /// Per joint: the standstill rule drops its slow rows.
    pub drop: Vec<bool>,
    /// Per joint: the rows used and why.
    pub rows_used: Vec<RowsUsed>,
    /// Slow-row fraction applied.
    pub slow: f64,
    /// Slow-row speed applied.
    pub vmin: f64,
}

/// Processes a run (in joint coordinates) as its entry `spec` says —
/// decimation, velocities, standstill rule — with `filter`, for `method`
/// (the projection method keeps every row and uses no dead band), and
/// stacks its base regressor. The entry's fields are validated by the design.
pub fn prepare(robot: &Robot, base: &BaseParams, run: &Run, filter: Filter, spec: &ExperimentSpec, method: Method, dead_band: f64) -> Result<Prepared> {
    let pr = process_with(run, &filter, spec.velocity_from)?.decimated(spec.decimate);
    let projection = method == Method::Projection;
    let (slow, vmin) = if projection { (0.0, 0.0) } else { (spec.slow_ratio, spec.min_speed) };
    let dead_band = if projection { 0.0 } else { dead_band };
    let standstill = spec.standstill.unwrap_or(spec.kind.default_standstill());
    let drop: Vec<bool> = robot
        .drives
        .iter()
        .map(|d| match standstill {
            Standstill::Auto => d.discontinuous_at_rest(),
            Standstill::Drop => true,
            Standstill::Keep => false,
        })
        .collect();
    let every = Dataset::every_row_dead_band(robot, base, &pr, dead_band);
    let full = every.moving_rows_of(&pr, slow, vmin, &drop);
    if full.c.nrows() <= full.c.ncols() && every.c.nrows() > every.c.ncols() {
        let vmax: Vec<String> = (0..robot.dof())
            .map(|j| format!("{:.3e}", pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max)))
            .collect();
        return Err(Error::invalid(run.files.first().map_or_else(|| "identify".to_string(), |f| f.display().to_string()), "min_speed", format!("no row is fast enough: {} of {} rows left after the speed rule |q̇_j| ≥ max({slow} · max |q̇_j|, {vmin} rad/s) (`slow_ratio`, `min_speed`; `kind = \"static\"` for poses held at rest has no speed rule), more than {} needed; largest |q̇_j| of the run: [{}] rad/s", full.c.nrows(), every.c.nrows(), full.c.ncols(), vmax.join(", "))));
    }
    let rows_used = rows_used(robot, &full, pr.len(), &drop, (slow, vmin, dead_band), method, standstill);
    Ok(Prepared {
        pr,
        filter,
        every,
        full,
        drop,
        rows_used,
        slow,
        vmin,
    })
}

/// The rows of each joint in `full` and the standstill rule that chose them.
fn rows_used(
    robot: &Robot,
    full: &Dataset,
    total: usize,
    drop: &[bool],
    (slow, vmin, dead_band): (f64, f64, f64),
    method: Method,
    standstill: Standstill,
) -> Vec<RowsUsed> {
    (0..robot.dof())
        .map(|j| {
            let used = full.joint.iter().filter(|&&k| k == j).count();
            let d = &robot.drives[j];
            let shape = if matches!(d.friction, crate::robot::Friction::None) {
                "no friction".to_string()
            } else {
                format!("Coulomb {}", d.coulomb.describe())
            };
            let reason = if method == Method::Projection {
                "every row kept: the projection method needs every sample".to_string()
            } else if slow <= 0.0 && vmin <= 0.0 {
                "every row kept: slow_ratio = 0 and min_speed = 0".to_string()
            } else if drop[j] {
                let why = match standstill {
                    Standstill::Drop => "standstill drop".to_string(),
                    _ => format!("{shape} is discontinuous at rest"),
                };
                format!("rows with |q̇| < max({slow}·max|q̇|, {vmin}) left out: {why}")
            } else {
                let why = match standstill {
                    Standstill::Keep if d.discontinuous_at_rest() && dead_band > 0.0 => {
                        format!("standstill keep; the Coulomb term is 0 within the dead band |q̇| < {dead_band} (dead_band)")
                    }
                    Standstill::Keep => "standstill keep".to_string(),
                    _ => format!("{shape} is continuous at rest"),
                };
                format!("every row kept, standstill included: {why}")
            };
            RowsUsed {
                joint: robot.joints[j].name.clone(),
                used,
                total,
                slow_dropped: used < total,
                reason,
            }
        })
        .collect()
}

/// Joints whose filter residual exceeds 3× the noise of the averaged
/// positions, with the advice in the study's words (`harmonics = …`).
pub(crate) fn filter_warnings(pr: &Processed) -> Vec<String> {
    let mut w = Vec::new();
    for (j, (res, noise)) in pr.filter_residual.iter().enumerate() {
        if let Some(nz) = noise {
            if *res > 3.0 * nz && *res > 0.0 {
                let hint = match pr.filter {
                    Filter::Fourier { n_h, .. } => format!(
                        "the closed-loop response has harmonics above the {n_h} kept (tracking errors of a nonlinear plant); dropping them biases q̈: consider {}{}",
                        "harmonics = ",
                        4 * n_h
                    ),
                    Filter::LowPass { cutoff } => format!(
                        "the low-pass at {cutoff} Hz removes motion: consider a higher {}",
                        "`cutoff = …`"
                    ),
                    Filter::None => String::new(),
                };
                w.push(format!(
                    "joint {}: the filter removes {res:.3e} rad RMS from the averaged positions, {:.1}× their noise ({nz:.3e}); {hint}",
                    j + 1,
                    res / nz
                ));
            }
        }
    }
    w
}
