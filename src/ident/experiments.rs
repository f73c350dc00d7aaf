//! The dedicated experiments of paper 002 §3.2, one joint at a time with the
//! others at rest (the references come from [`crate::trajectory::reference`]:
//! `gravity_slopes` and `bang_bang`; `idexp simulate` writes them as
//! `reference.csv` for a real robot too).
//!
//! * **Gravity** (§3.2.1, eq. 23): on the constant-velocity parts of two slopes
//!   of opposite sign, τ_j = k sin(q_j + q_off) + c_± where c_± collects the
//!   velocity-dependent constant terms (friction, Coriolis, centripetal) of
//!   each direction. Linear least squares in (A, B, c₊, c₋) with
//!   τ = A sin q + B cos q + c_±, so k = √(A² + B²), q_off = atan2(B, A).
//!   For a rigid robot with the other joints at rest the gravity torque of a
//!   joint is exactly of this form (the distal centre of mass rotates about the axis).
//! * **Friction** (§3.2.2, eq. 2): bang-bang accelerations; with gravity from
//!   the gravity experiment (as in the paper), absent (vertical axis), or fitted alongside,
//!   τ_j = J q̈_j + A sin q_j + B cos q_j + [q̇ > 0](F_c⁺ + F_v⁺ q̇) + [q̇ < 0](F_c⁻ + F_v⁻ q̇),
//!   J the effective inertia (constant: M_jj does not depend on q_j), samples
//!   with |q̇_j| below `min_speed` left out (stiction region, not modelled).

use super::Processed;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Result of the gravity experiment.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct GravityFit {
    /// Joint (1-based).
    pub joint: usize,
    /// Amplitude k (N·m).
    pub k: f64,
    /// Offset q_off (rad).
    pub q_off: f64,
    /// Constant term of the positive slope c₊ (N·m).
    pub offset_pos: f64,
    /// Constant term of the negative slope c₋ (N·m).
    pub offset_neg: f64,
    /// Speed of the slopes (rad/s).
    pub speed: f64,
    /// Samples used.
    pub samples: usize,
    /// RMS residual (N·m).
    pub rms: f64,
}

impl GravityFit {
    /// τ_g(q) = k sin(q + q_off).
    pub fn torque(&self, q: f64) -> f64 {
        self.k * (q + self.q_off).sin()
    }
}

/// Result of the friction experiment.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FrictionFit {
    /// Joint (1-based).
    pub joint: usize,
    /// Effective inertia J (kg·m²).
    pub inertia: f64,
    /// Coulomb term for positive velocity F_c⁺ (N·m).
    pub fc_pos: f64,
    /// Coulomb term for negative velocity F_c⁻ (N·m, negative for the usual model).
    pub fc_neg: f64,
    /// Viscous coefficient for positive velocity (N·m·s/rad).
    pub fv_pos: f64,
    /// Viscous coefficient for negative velocity (N·m·s/rad).
    pub fv_neg: f64,
    /// Gravity amplitude and offset used (fitted here or taken from the gravity experiment).
    pub gravity_k: f64,
    /// Gravity offset (rad).
    pub gravity_q_off: f64,
    /// Whether gravity came from a gravity experiment.
    pub gravity_given: bool,
    /// Standard deviations of (J, F_c⁺, F_v⁺, F_c⁻, F_v⁻) from the residual variance.
    pub std: Vec<f64>,
    /// Samples used.
    pub samples: usize,
    /// RMS residual (N·m).
    pub rms: f64,
}

fn lstsq(a: &DMatrix<f64>, b: &DVector<f64>) -> Result<(DVector<f64>, DMatrix<f64>, f64)> {
    if a.nrows() <= a.ncols() {
        return Err(Error::Numerical(format!(
            "{} samples for {} unknowns: the experiment is too short",
            a.nrows(),
            a.ncols()
        )));
    }
    let (u, s, v) = crate::linalg::thin_svd(a)?;
    if s[s.len() - 1] <= 1e-10 * s[0] {
        return Err(Error::Numerical(
            "the experiment does not determine all unknowns (both directions and enough motion are needed)".into(),
        ));
    }
    let mut vs = v.clone();
    for (j, mut c) in vs.column_iter_mut().enumerate() {
        c /= s[j];
    }
    let x = &vs * (u.transpose() * b);
    let r = b - a * &x;
    let s2 = r.norm_squared() / (a.nrows() - a.ncols()) as f64;
    let cov = &vs * vs.transpose() * s2;
    Ok((x, cov, (r.norm_squared() / a.nrows() as f64).sqrt()))
}

fn check_joint(pr: &Processed, joint: usize) -> Result<usize> {
    let n = pr.n_joints();
    if joint == 0 || joint > n {
        return Err(Error::invalid("experiment", "joint", format!("expected a joint number 1..{n}, got {joint}")));
    }
    Ok(joint - 1)
}

/// Largest speed of another joint, as a fraction of the experiment joint's
/// largest speed, for the others to count as at rest.
pub const GRAVITY_OTHERS_AT_REST: f64 = 0.05;
/// Least share of the moving samples (|q̇_j| above 10 % of its largest value)
/// at constant speed (within 2 % of the largest) for a slopes run.
pub const GRAVITY_CONSTANT_SPEED_SHARE: f64 = 0.5;

/// Refuses a run that is not a gravity-slopes run of joint `j` (0-based):
/// another joint moving, or joint `j` mostly accelerating (e.g. a Fourier
/// run), where eq. 23 does not hold and k would absorb inertia and coupling.
fn check_slopes_run(pr: &Processed, j: usize, vmax: f64) -> Result<()> {
    let what = "gravity experiment";
    let joint = j + 1;
    let (other, other_max) = (0..pr.n_joints())
        .filter(|&i| i != j)
        .map(|i| (i, pr.qd.iter().map(|v| v[i].abs()).fold(0.0, f64::max)))
        .fold((j, 0.0), |b, c| if c.1 > b.1 { c } else { b });
    if other_max > GRAVITY_OTHERS_AT_REST * vmax {
        return Err(Error::invalid(
            what,
            "run",
            format!(
                "not a gravity-slopes run of joint {joint}: joint {} moves too (up to {other_max:.4} rad/s, \
                 more than {:.0} % of joint {joint}'s {vmax:.4} rad/s); the experiment needs the other joints at rest \
                 (a `gravity_slopes` reference)",
                other + 1,
                100.0 * GRAVITY_OTHERS_AT_REST
            ),
        ));
    }
    let moving = pr.qd.iter().filter(|v| v[j].abs() > 0.1 * vmax).count();
    let constant = pr.qd.iter().filter(|v| (v[j].abs() - vmax).abs() < 0.02 * vmax).count();
    let share = constant as f64 / moving.max(1) as f64;
    if share < GRAVITY_CONSTANT_SPEED_SHARE {
        return Err(Error::invalid(
            what,
            "run",
            format!(
                "not a gravity-slopes run of joint {joint}: only {:.0} % of its moving samples are at constant speed \
                 ({vmax:.4} rad/s within 2 %), at least {:.0} % expected (slow slopes of constant velocity, \
                 a `gravity_slopes` reference)",
                100.0 * share,
                100.0 * GRAVITY_CONSTANT_SPEED_SHARE
            ),
        ));
    }
    Ok(())
}

/// Fits the gravity model of eq. 23 on the constant-velocity samples of a
/// slopes run (|q̇_j| within 2 % of its largest value and |q̈_j| below 2 % of max |q̈_j|·).
pub fn gravity_experiment(pr: &Processed, joint: usize) -> Result<GravityFit> {
    let j = check_joint(pr, joint)?;
    let vmax = pr.qd.iter().map(|v| v[j].abs()).fold(0.0, f64::max);
    if vmax <= 0.0 {
        return Err(Error::invalid(
            "gravity experiment",
            "joint",
            format!("joint {joint} does not move in this run"),
        ));
    }
    let amax = pr.qdd.iter().map(|v| v[j].abs()).fold(0.0, f64::max);
    check_slopes_run(pr, j, vmax)?;
    let idx: Vec<usize> = (0..pr.len())
        .filter(|&p| (pr.qd[p][j].abs() - vmax).abs() < 0.02 * vmax && pr.qdd[p][j].abs() <= 0.02 * amax.max(1e-9) + 1e-3)
        .collect();
    let a = DMatrix::from_fn(idx.len(), 4, |r, c| {
        let p = idx[r];
        let q = pr.q[p][j];
        match c {
            0 => q.sin(),
            1 => q.cos(),
            2 => f64::from(pr.qd[p][j] > 0.0),
            _ => f64::from(pr.qd[p][j] < 0.0),
        }
    });
    let b = DVector::from_iterator(idx.len(), idx.iter().map(|&p| pr.tau[p][j]));
    let (x, _, rms) = lstsq(&a, &b)?;
    Ok(GravityFit {
        joint,
        k: x[0].hypot(x[1]),
        q_off: x[1].atan2(x[0]),
        offset_pos: x[2],
        offset_neg: x[3],
        speed: vmax,
        samples: idx.len(),
        rms,
    })
}

/// The gravity term of the friction experiment.
#[derive(Debug, Clone, PartialEq)]
pub enum GravityTerm<'a> {
    /// Fitted alongside (A sin q + B cos q): well posed only when the joint
    /// sweeps a wide range; over a small excursion cos q is nearly constant and
    /// collinear with the Coulomb terms (the standard deviations show it).
    Fit,
    /// From a gravity experiment on the same joint (paper 002 §3.2.2).
    Given(&'a GravityFit),
    /// None: the joint axis is vertical (or gravity is compensated).
    Zero,
}

/// Fits the asymmetric Coulomb + viscous model (eq. 2) and the effective
/// inertia on a bang-bang run, with the given gravity term.
pub fn friction_experiment(pr: &Processed, joint: usize, gravity: GravityTerm<'_>, min_speed: f64) -> Result<FrictionFit> {
    let j = check_joint(pr, joint)?;
    if let GravityTerm::Given(g) = gravity {
        if g.joint != joint {
            return Err(Error::invalid(
                "friction experiment",
                "gravity",
                format!("the gravity fit is for joint {}, not {joint}", g.joint),
            ));
        }
    }
    let given = match gravity {
        GravityTerm::Given(g) => Some(g),
        _ => None,
    };
    let idx: Vec<usize> = (0..pr.len()).filter(|&p| pr.qd[p][j].abs() > min_speed).collect();
    let ncol = if matches!(gravity, GravityTerm::Fit) { 7 } else { 5 };
    let a = DMatrix::from_fn(idx.len(), ncol, |r, c| {
        let p = idx[r];
        let (q, v, acc) = (pr.q[p][j], pr.qd[p][j], pr.qdd[p][j]);
        let (pos, neg) = (f64::from(v > 0.0), f64::from(v < 0.0));
        match c {
            0 => acc,
            1 => pos,
            2 => pos * v,
            3 => neg,
            4 => neg * v,
            5 => q.sin(),
            _ => q.cos(),
        }
    });
    let b = DVector::from_iterator(idx.len(), idx.iter().map(|&p| pr.tau[p][j] - given.map_or(0.0, |g| g.torque(pr.q[p][j]))));
    let (x, cov, rms) = lstsq(&a, &b)?;
    let (gk, goff) = match gravity {
        GravityTerm::Given(g) => (g.k, g.q_off),
        GravityTerm::Fit => (x[5].hypot(x[6]), x[6].atan2(x[5])),
        GravityTerm::Zero => (0.0, 0.0),
    };
    Ok(FrictionFit {
        joint,
        inertia: x[0],
        fc_pos: x[1],
        fv_pos: x[2],
        fc_neg: x[3],
        fv_neg: x[4],
        gravity_k: gk,
        gravity_q_off: goff,
        gravity_given: given.is_some(),
        std: (0..5).map(|i| cov[(i, i)].max(0.0).sqrt()).collect(),
        samples: idx.len(),
        rms,
    })
}
