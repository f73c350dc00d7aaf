//! Payload identification: the ten inertial parameters of a payload from runs
//! with it (and, optionally, the same runs without it), the robot's model known.
//!
//! With the payload's parameters φ_F (its frame F's origin and axes), the
//! joint torques are τ = τ_robot(x) + Y_L(x) T φ_F (see
//! [`crate::robot::payload`]): the payload's torques are linear in φ_F with
//! the columns A(x) = Y_L(x) T. Each row of a loaded run gives
//!
//! * without unloaded runs: b = τ_measured − τ_model(x) — the robot model's
//!   error (inertias, friction) stays in b;
//! * with the unloaded run of the same trajectory (paired sample by sample):
//!   b = (τ_L − τ_U) − (τ_model(x_L) − τ_model(x_U)) — the robot's own torques
//!   cancel, and the model is used only for the small difference of the two
//!   tracked motions, so its error enters to second order.
//!
//! The combinations of φ_F the robot's joints can sense at all are the base
//! parameters of the payload's columns on random states (structural; all ten
//! for a six-axis arm, fewer for a planar one); they are estimated by weighted
//! least squares stacked over the loaded runs (weights per run and joint from
//! the repetitions or the residuals, iterated: [`crate::ident::study::stack`]),
//! and the physically consistent payload is the closest one in that metric
//! with a positive semidefinite pseudo-inertia ([`crate::ident::consistent`],
//! one link), the directions the data leave open taken from the guess.

use super::align::{self, Alignment};
use super::design::PayloadDesign;
use crate::error::{Error, Result};
use crate::ident::consistent::{self, ConsistentStatus, Kind};
use crate::ident::estimate::Dataset;
use crate::ident::prior::{self, PriorMetric, PriorProblem};
use crate::ident::study::stack::Rows;
use crate::ident::study::{load_entry, BlockWeight, Loaded};
use crate::ident::EstimateStatus;
use crate::optim::Control;
use crate::params::{random_stack, BaseOptions, BaseParams};
use crate::robot::dynamics::{regressor_rows, rnea, Workspace};
use crate::robot::payload::{Mount, Payload, PARAM_NAMES};
use crate::robot::Robot;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Relative size (of tr J) under which the consistent payload's smallest
/// pseudo-inertia eigenvalue counts as on the boundary.
pub const BOUNDARY_REL: f64 = 1e-6;

/// Which combinations of the payload's parameters the robot's joints sense at all.
#[derive(Debug, Clone, Serialize)]
pub struct Structural {
    /// Base parameters (names of φ_F with `R` when others regroup onto them).
    pub names: Vec<String>,
    /// Each as a combination of φ_F.
    pub groupings: Vec<String>,
    /// Indices (0..10) of φ_F kept as base parameters.
    pub independent: Vec<usize>,
    /// φ_F with no effect on the joint torques.
    pub unidentifiable: Vec<String>,
    /// K (k × 10): θ_b = K φ_F.
    #[serde(skip)]
    pub k: DMatrix<f64>,
}

/// One loaded run (with its unloaded twin).
#[derive(Debug, Clone, Serialize)]
pub struct PayloadRun {
    /// Name.
    pub name: String,
    /// Files read.
    pub files: Vec<PathBuf>,
    /// Repetitions averaged.
    pub repetitions: usize,
    /// The unloaded run subtracted, if any.
    pub unloaded: Option<String>,
    /// Its files.
    pub unloaded_files: Vec<PathBuf>,
    /// Per joint: largest |q_L − q_U| between the paired samples (rad or m), after alignment.
    pub tracking_difference: Option<Vec<f64>>,
    /// How the unloaded twin was aligned (time shift, overlap, remaining difference).
    pub alignment: Option<Alignment>,
    /// Processed samples.
    pub samples: usize,
    /// Rows used.
    pub rows: usize,
    /// Per joint: how the rows were weighted.
    pub weights: Vec<BlockWeight>,
    /// Per joint: the noise σ of the weights (N·m).
    pub sigma: Vec<f64>,
    /// Per joint: RMS of the payload's torque b (N·m).
    pub rms_payload: Vec<f64>,
    /// Per joint: RMS of the residual b − A φ̂ at the consistent estimate (N·m).
    pub rms_residual: Vec<f64>,
    /// Its share of the information (mean over the base parameters).
    pub information_share: f64,
}

/// Mass, centre of mass and inertia with their standard deviations.
#[derive(Debug, Clone, Serialize)]
pub struct PayloadStd {
    /// σ of the mass (kg).
    pub mass: f64,
    /// σ of the centre of mass (m).
    pub com: [f64; 3],
    /// σ of the inertia about the centre of mass, [Ixx, Ixy, Ixz, Iyy, Iyz, Izz] (kg·m²).
    pub inertia: [f64; 6],
}

/// The consistent payload.
#[derive(Debug, Clone, Serialize)]
pub struct ConsistentPayload {
    /// How the conic program ended.
    pub status: ConsistentStatus,
    /// φ_F (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M) about the frame's origin.
    pub params: Vec<f64>,
    /// Smallest eigenvalue of the pseudo-inertia (kg·m²).
    pub min_eig: f64,
    /// Increase of the weighted residual sum of squares over least squares.
    pub extra_cost: f64,
    /// The fit lies on the consistency boundary: smallest pseudo-inertia
    /// eigenvalue ≤ margin + 1e-6·tr(J) (a flat body, or a line or a point:
    /// what the data allow, not a physical tool).
    pub on_boundary: bool,
}

/// The result of a payload identification.
#[derive(Debug, Clone, Serialize)]
pub struct PayloadEstimate {
    /// Robot file.
    pub robot: PathBuf,
    /// Frame of the payload.
    pub frame: String,
    /// Link carrying it.
    pub link: String,
    /// Whether unloaded runs were subtracted.
    pub differencing: bool,
    /// What the joints sense at all.
    pub structural: Structural,
    /// The runs.
    pub runs: Vec<PayloadRun>,
    /// Least squares: status.
    pub status: EstimateStatus,
    /// Base parameters θ̂_b.
    pub theta: Vec<f64>,
    /// Their standard deviations.
    pub std: Vec<f64>,
    /// σ relative to |θ̂| (or to the payload's mass·(0.1 m)ⁱ scale, when θ̂ is near 0).
    pub rel_std: Vec<f64>,
    /// Covariance of θ̂_b.
    pub cov: Vec<Vec<f64>>,
    /// Rank and condition number of the weighted design (unit columns).
    pub rank: usize,
    /// cond(√W A) with unit-norm columns.
    pub cond: f64,
    /// Weighted residual sum of squares per degree of freedom.
    pub chi2_dof: f64,
    /// Base parameters the motion determines poorly (σ > 25 % of the scale), by name.
    pub poorly_determined: Vec<String>,
    /// The consistent payload (None: interrupted).
    pub consistent: Option<ConsistentPayload>,
    /// The identified payload (from the consistent parameters).
    pub payload: Option<Payload>,
    /// Its standard deviations (when every φ_F is identifiable).
    pub payload_std: Option<PayloadStd>,
    /// The guess, if given.
    pub guess: Option<Payload>,
    /// The true payload of a simulated run, if given.
    pub truth: Option<Payload>,
    /// Notes for the user (model use, tracking, what is not identifiable).
    pub notes: Vec<String>,
    /// Stopped by the user before the consistent fit.
    pub interrupted: bool,
    /// The first run's payload torques per joint (for `residuals.svg`).
    #[serde(skip)]
    pub plot: Vec<JointTorques>,
}

/// One joint's payload torques over a run: b (measured, after subtracting the
/// robot's) and A φ̂ (the identified payload's).
#[derive(Debug, Clone, Default)]
pub struct JointTorques {
    /// Times of the rows used (s).
    pub t: Vec<f64>,
    /// b (N·m).
    pub measured: Vec<f64>,
    /// A φ̂ (N·m).
    pub predicted: Vec<f64>,
}

fn grouping(k: &DMatrix<f64>, i: usize) -> String {
    let mut s = String::new();
    for c in 0..10 {
        let v = k[(i, c)];
        if v == 0.0 {
            continue;
        }
        if !s.is_empty() {
            s.push_str(if v < 0.0 { " - " } else { " + " });
        } else if v < 0.0 {
            s.push('-');
        }
        if (v.abs() - 1.0).abs() > 1e-12 {
            s.push_str(&format!("{:.6}·", v.abs()));
        }
        s.push_str(PARAM_NAMES[c]);
    }
    s
}

/// The base parameters of the payload's columns in its own frame on random
/// states of `robot` (the link's columns mapped by T, every other column known).
pub fn structural(robot: &Robot, mount: &Mount) -> Result<Structural> {
    let opts = BaseOptions {
        inertial_only: true,
        ..BaseOptions::default()
    };
    let o = robot.link_param_offset(mount.link);
    let w = random_stack(robot, opts.samples, opts.seed);
    let a = w.columns(o, 10) * mount.t;
    let mut wf = DMatrix::zeros(w.nrows(), w.ncols());
    wf.columns_mut(o, 10).copy_from(&a);
    let cols: Vec<usize> = (o..o + 10).collect();
    let b = BaseParams::of_stack_columns(robot, wf, &cols, &opts)?;
    let k = b.k.columns(o, 10).into_owned();
    let independent: Vec<usize> = b.independent.iter().map(|c| c - o).collect();
    let names = independent
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let grouped = (0..10).any(|d| d != c && k[(i, d)] != 0.0);
            format!("{}{}", PARAM_NAMES[c], if grouped { "R" } else { "" })
        })
        .collect();
    let groupings = (0..independent.len()).map(|i| grouping(&k, i)).collect();
    Ok(Structural {
        names,
        groupings,
        independent,
        unidentifiable: b.unidentifiable.iter().map(|c| PARAM_NAMES[c - o].to_string()).collect(),
        k,
    })
}

/// The rows of one loaded run (minus its unloaded twin, aligned in time by
/// [`super::align`]): A (payload base columns) and b, in a joint-major
/// [`Dataset`]; the alignment; the rows' times.
fn payload_rows(robot: &Robot, mount: &Mount, st: &Structural, l: &Loaded, u: Option<&Loaded>) -> Result<(Dataset, Option<Alignment>, Vec<f64>)> {
    let n = robot.dof();
    let p = robot.n_params();
    let pr = &l.prep.pr;
    let m = pr.t.len();
    let ctx = format!("loaded run `{}`", l.name);
    let (al, twin) = match u {
        Some(u) => {
            let al = align::align(pr, &u.prep.pr, &ctx, &u.name)?;
            let tw = align::resample(&u.prep.pr, u.prep.every.var.as_ref().map(|v| v.as_slice()), &al);
            (Some(al), Some(tw))
        }
        None => (None, None),
    };
    let [first, end] = al.as_ref().map_or([0, m], |a| a.overlap);
    let kb = st.independent.len();
    let mut ws = Workspace::new(robot);
    let mut y = vec![0.0; n * p];
    let mut cols = vec![0.0; n * 10];
    let mut tau_l = vec![0.0; n];
    let mut tau_u = vec![0.0; n];
    // per sample of the overlap: A (n × kb) and the model torque difference
    let mut a_s = vec![0.0; m * n * kb];
    let mut model = vec![0.0; m * n];
    for s in first..end {
        regressor_rows(robot, &mut ws, &pr.q[s], &pr.qd[s], &pr.qdd[s], &mut y);
        mount.columns(robot, &y, &mut cols);
        for j in 0..n {
            for (bi, &c) in st.independent.iter().enumerate() {
                a_s[(s * n + j) * kb + bi] = cols[j * 10 + c];
            }
        }
        rnea(robot, &mut ws, &pr.q[s], &pr.qd[s], &pr.qdd[s], &mut tau_l);
        match &twin {
            Some(tw) => {
                let k = s - first;
                rnea(robot, &mut ws, &tw.q[k], &tw.qd[k], &tw.qdd[k], &mut tau_u);
                for j in 0..n {
                    model[s * n + j] = tw.tau[k][j] + tau_l[j] - tau_u[j];
                }
            }
            None => model[s * n..(s + 1) * n].copy_from_slice(&tau_l),
        }
    }
    let full = &l.prep.full;
    let keep: Vec<usize> = (0..full.joint.len()).filter(|&r| (first..end).contains(&full.sample[r])).collect();
    let rows = keep.len();
    let mut c = DMatrix::zeros(rows, kb);
    let mut b = DVector::zeros(rows);
    // variances of the averaged torques (every_row's, joint-major: row j·m + s)
    let var_l = l.prep.every.var.as_ref();
    let var_u = twin.as_ref().and_then(|t| t.var.as_ref());
    let has_var = var_l.is_some() && (u.is_none() || var_u.is_some());
    let mut var = DVector::zeros(if has_var { rows } else { 0 });
    let len = end - first;
    for (i, &r) in keep.iter().enumerate() {
        let (j, s) = (full.joint[r], full.sample[r]);
        for bi in 0..kb {
            c[(i, bi)] = a_s[(s * n + j) * kb + bi];
        }
        b[i] = pr.tau[s][j] - model[s * n + j];
        if has_var {
            var[i] = var_l.map_or(0.0, |v| v[j * m + s]) + var_u.map_or(0.0, |v| v[j * len + s - first]);
        }
    }
    let times = keep.iter().map(|&r| pr.t[full.sample[r]]).collect();
    Ok((
        Dataset {
            n,
            n_samples: m,
            c,
            y: b,
            var: has_var.then_some(var),
            names: st.names.clone(),
            joint: keep.iter().map(|&r| full.joint[r]).collect(),
            sample: keep.iter().map(|&r| full.sample[r]).collect(),
        },
        al,
        times,
    ))
}

/// The map φ_F → (m, c, I_c) and its Jacobian (central differences), for the
/// delta-method standard deviations.
fn payload_std(phi: &[f64], cov: &DMatrix<f64>) -> Option<PayloadStd> {
    let g = |p: &[f64]| -> Option<[f64; 10]> {
        let x = Payload::from_params(p).ok()?;
        let mut out = [0.0; 10];
        out[0] = x.mass;
        out[1..4].copy_from_slice(&x.com);
        out[4..10].copy_from_slice(&x.inertia);
        Some(out)
    };
    g(phi)?;
    let mut jac = DMatrix::zeros(10, 10);
    for k in 0..10 {
        let h = 1e-6 * phi[k].abs().max(1e-4);
        let mut a = phi.to_vec();
        let mut b = phi.to_vec();
        a[k] += h;
        b[k] -= h;
        let (ga, gb) = (g(&a)?, g(&b)?);
        for r in 0..10 {
            jac[(r, k)] = (ga[r] - gb[r]) / (2.0 * h);
        }
    }
    let c = &jac * cov * jac.transpose();
    let s = |i: usize| c[(i, i)].max(0.0).sqrt();
    Some(PayloadStd {
        mass: s(0),
        com: [s(1), s(2), s(3)],
        inertia: [s(4), s(5), s(6), s(7), s(8), s(9)],
    })
}

/// Reads the true payload of a simulated run (its design.json's `payload`).
fn read_truth(dir: &Path) -> Result<Payload> {
    let path = dir.join("design.json");
    let text = crate::io::read_to_string(&path)?;
    let d: crate::sim::SimDesign = serde_json::from_str(&text).map_err(|e| Error::parse(&path, e.to_string()))?;
    let spec = d.payload.ok_or_else(|| {
        Error::invalid(
            path.display().to_string(),
            "payload",
            "the simulated run carries no payload: `truth` names a run simulated with a [payload]",
        )
    })?;
    Payload::from_spec(&spec, &path.display().to_string(), "payload")
}

/// Identifies the payload of `design`, whose relative paths are relative to
/// `dir`; `ctl` stops it between runs and in the consistent fit.
pub fn identify(design: &PayloadDesign, dir: &Path, ctl: &Control) -> Result<PayloadEstimate> {
    design.validate("payload")?;
    let robot_path = dir.join(&design.robot);
    let robot = crate::robot::load(&robot_path)?;
    let mount = Mount::new(&robot, design.frame.as_deref(), "payload", "frame")?;
    let st = structural(&robot, &mount)?;
    let guess = match &design.guess {
        Some(g) => Some(g.check("payload", "guess")?),
        None => None,
    };
    let truth = match &design.truth {
        Some(t) => Some(read_truth(&dir.join(t))?),
        None => None,
    };
    // the payload link's base columns only: prepare's own stack stays small
    let o = robot.link_param_offset(mount.link);
    let link_cols: Vec<usize> = (o..o + 10).collect();
    let base = BaseParams::of_columns(
        &robot,
        &link_cols,
        &BaseOptions {
            inertial_only: true,
            ..BaseOptions::default()
        },
    )?;
    let obs = ctl.observer();
    let total = design.loaded.len() + design.unloaded.len();
    obs.phase("payload read", Some(total as u64));
    let mut data = Vec::with_capacity(design.loaded.len());
    let mut runs = Vec::with_capacity(design.loaded.len());
    let mut row_times = Vec::with_capacity(design.loaded.len());
    for (i, spec) in design.loaded.iter().enumerate() {
        if ctl.interrupted() {
            return Err(Error::Interrupted);
        }
        let l = load_entry(&robot, &base, spec, dir, design.method, design.sample_limit)?;
        let u = match design.unloaded.get(i) {
            Some(us) => Some(load_entry(&robot, &base, us, dir, design.method, design.sample_limit)?),
            None => None,
        };
        obs.progress((i + 1 + usize::from(u.is_some()) * (i + 1)) as u64, &l.name);
        let (ds, alignment, times) = payload_rows(&robot, &mount, &st, &l, u.as_ref())?;
        row_times.push(times);
        runs.push(PayloadRun {
            name: l.name.clone(),
            files: l.files.clone(),
            repetitions: l.n_reps,
            unloaded: u.as_ref().map(|u| u.name.clone()),
            unloaded_files: u.as_ref().map(|u| u.files.clone()).unwrap_or_default(),
            tracking_difference: alignment.as_ref().map(|a| a.max_difference.clone()),
            alignment,
            samples: ds.n_samples,
            rows: ds.y.len(),
            weights: Vec::new(),
            sigma: Vec::new(),
            rms_payload: rms_per_joint(&ds, &ds.y, robot.dof()),
            rms_residual: Vec::new(),
            information_share: 0.0,
        });
        data.push(ds);
    }
    obs.phase_done();
    let rows: Vec<Rows> = data
        .iter()
        .zip(&runs)
        .map(|(d, r)| Rows {
            name: &r.name,
            data: d,
            n_reps: r.repetitions,
        })
        .collect();
    let sopts = design.stack_options();
    let stk = crate::ident::study::stack::estimate(&rows, &sopts)?;
    let kb = st.independent.len();
    let n = robot.dof();
    for (e, r) in runs.iter_mut().enumerate() {
        let blocks: Vec<_> = stk.blocks.iter().filter(|b| b.experiment == e).collect();
        r.weights = blocks.iter().map(|b| b.weight).collect();
        r.sigma = blocks.iter().map(|b| b.sigma).collect();
        r.information_share = stk.share[e].iter().sum::<f64>() / kb as f64;
    }
    let status = if stk.rank < kb { EstimateStatus::RankDeficient } else { EstimateStatus::Ok };
    let std: Vec<f64> = (0..kb).map(|i| stk.cov[(i, i)].max(0.0).sqrt()).collect();
    // scale of each base parameter: |θ̂|, at least its kind's natural size for this payload
    let m_scale = stk.theta.iter().zip(&st.independent).find(|(_, &c)| c == 9).map(|(v, _)| v.abs());
    let m_ref = guess.map(|g| g.mass).or(m_scale).unwrap_or(1.0).max(1e-3);
    let kind_scale = |c: usize| match c {
        9 => m_ref,
        6..=8 => m_ref * 0.1,
        _ => m_ref * 0.01,
    };
    let rel_std: Vec<f64> = (0..kb).map(|i| std[i] / stk.theta[i].abs().max(kind_scale(st.independent[i]))).collect();
    let poorly_determined = (0..kb)
        .filter(|&i| std[i] > 0.25 * stk.theta[i].abs().max(kind_scale(st.independent[i])))
        .map(|i| st.names[i].clone())
        .collect();
    let mut notes = Vec::new();
    if !st.unidentifiable.is_empty() || kb < 10 {
        notes.push(format!(
            "the robot's joints sense {kb} of the payload's 10 parameters (combinations: {}); {} the guess decides the rest",
            st.names.join(", "),
            if st.unidentifiable.is_empty() {
                String::new()
            } else {
                format!("{} have no effect on the joint torques; ", st.unidentifiable.join(", "))
            }
        ));
    }
    if stk.chi2_dof > 2.0 && !stk.blocks.iter().all(|b| b.weight == BlockWeight::Residual) {
        notes.push(format!(
            "χ²/dof = {:.2}: the residuals are larger than the repetitions' noise, so something the payload's ten parameters cannot explain is in the torques{}",
            stk.chi2_dof,
            if design.unloaded.is_empty() { " — most likely the robot model's error: add unloaded runs of the same trajectories" } else { " (tracking differences, a load that moves)" }
        ));
    }
    if design.unloaded.is_empty() {
        notes.push("no unloaded runs: the robot model's torques are subtracted, so its error (inertia, friction) biases the payload; unloaded runs of the same trajectories remove it".into());
    }
    // consistent fit: one pseudo-inertia, the guess (or nothing) for what the data leave open
    let kinds: Vec<Kind> = (0..10).map(Kind::Inertial).collect();
    // the prior: the guess's inertia about its centre of mass (per unit mass),
    // placed at a centre of mass and with a mass that agree with what the data
    // see — the guess's φ corrected by the least change (in the scales s) that
    // reproduces θ̂_b, then rebuilt as a rigid body — so that what the data
    // leave open (e.g. the height of the centre of mass on a planar arm) is
    // the guess's, and the prior itself is physically consistent
    let nominal = DVector::from_vec(match guess {
        Some(g) => prior_from_guess(&g, &st.k, &stk.theta, &kinds),
        None => vec![0.0; 10],
    });
    let scale = consistent::regularization_scale(&kinds, &nominal);
    let (consistent, interrupted) = if ctl.interrupted() {
        (None, true)
    } else {
        // closest to the prior in the scales s, with the weight relative to
        // the fit's smallest curvature: it decides only what the data leave open
        let sol = prior::solve(
            &PriorProblem {
                r: &stk.r,
                theta_b: &stk.theta,
                k: &st.k,
                links: &[0],
                link_names: &["payload".to_string()],
                kinds: &kinds,
                prior: &nominal,
                scale: &scale,
            },
            PriorMetric::Euclidean,
            prior::relative_weight(&stk.r, design.regularization),
            design.margin,
            ctl,
        )?;
        let status = ConsistentStatus::of(&sol.status);
        let interrupted = ctl.interrupted();
        let phi: Vec<f64> = sol.theta.iter().copied().collect();
        // tr J = tr Σ + m = ½ (XX + YY + ZZ) + M about the frame's origin
        let tr_j = 0.5 * (phi[0] + phi[3] + phi[5]) + phi[9];
        let on_boundary = sol.min_eig[0] <= design.margin + BOUNDARY_REL * tr_j.abs();
        (
            Some(ConsistentPayload {
                status,
                params: phi,
                min_eig: sol.min_eig[0],
                extra_cost: sol.extra_cost,
                on_boundary,
            }),
            interrupted,
        )
    };
    let payload = match &consistent {
        Some(c) if c.status.is_ok() => Payload::from_params(&c.params).ok(),
        _ => None,
    };
    if let (Some(c), Some(_)) = (&consistent, &payload) {
        if c.on_boundary {
            notes.push(format!(
                "the consistent payload lies on the consistency boundary (smallest pseudo-inertia eigenvalue {:.2e} kg·m² ≤ margin + {BOUNDARY_REL:e}·tr J): its mass is concentrated on a plane, a line or a point — what these data allow, not a physical tool; the inertia is the least-determined part (more excitation of the payload's rotation, or a guess, decides it)",
                c.min_eig
            ));
        }
    }
    if let (Some(c), None) = (&consistent, &payload) {
        if c.status.is_ok() {
            notes.push("the consistent fit gives a zero mass: no payload is seen in the torques".into());
        }
    }
    // residuals at the consistent estimate; the first run's torques for the picture
    let mut plot = Vec::new();
    if let Some(c) = &consistent {
        let tb = &st.k * DVector::from_column_slice(&c.params);
        for (e, (d, r)) in data.iter().zip(runs.iter_mut()).enumerate() {
            let pred = &d.c * &tb;
            let res = &d.y - &pred;
            r.rms_residual = rms_per_joint(d, &res, n);
            if e == 0 {
                plot = (0..n)
                    .map(|j| {
                        let rows: Vec<usize> = (0..d.joint.len()).filter(|&i| d.joint[i] == j).collect();
                        JointTorques {
                            t: rows.iter().map(|&i| row_times[0][i]).collect(),
                            measured: rows.iter().map(|&i| d.y[i]).collect(),
                            predicted: rows.iter().map(|&i| pred[i]).collect(),
                        }
                    })
                    .collect();
            }
        }
    }
    let payload_std = if kb == 10 && st.independent == (0..10).collect::<Vec<_>>() && stk.rank == 10 {
        // K = I: θ_b = φ_F, the covariance is φ_F's
        let phi = match &consistent {
            Some(c) => c.params.clone(),
            None => stk.theta.iter().copied().collect(),
        };
        payload_std(&phi, &stk.cov)
    } else {
        None
    };
    Ok(PayloadEstimate {
        robot: robot_path,
        frame: mount.frame.clone(),
        link: robot.links[mount.link].name.clone(),
        differencing: !design.unloaded.is_empty(),
        structural: st,
        runs,
        status,
        theta: stk.theta.iter().copied().collect(),
        std,
        rel_std,
        cov: (0..kb).map(|i| (0..kb).map(|j| stk.cov[(i, j)]).collect()).collect(),
        rank: stk.rank,
        cond: stk.cond_normalized,
        chi2_dof: stk.chi2_dof,
        poorly_determined,
        consistent,
        payload,
        payload_std,
        guess,
        truth,
        notes,
        interrupted,
        plot,
    })
}

/// The consistent prior of a guess given the base estimate θ̂_b = K φ (see [`identify`]).
fn prior_from_guess(g: &Payload, k: &DMatrix<f64>, theta_b: &DVector<f64>, kinds: &[Kind]) -> Vec<f64> {
    let guess = DVector::from_column_slice(&g.params());
    let s = consistent::regularization_scale(kinds, &guess);
    let s2 = DMatrix::from_diagonal(&s.map(|v| v * v));
    let Some(chol) = (k * &s2 * k.transpose()).cholesky() else {
        return guess.iter().copied().collect();
    };
    // the guess scaled to a mass, corrected to reproduce θ̂_b; twice: first to
    // find the mass the data see, then with the guess scaled to it (the
    // unseen first moments are then the guess's centre times that mass)
    let mut mass = g.mass;
    let mut mix = guess.clone();
    for _ in 0..2 {
        let phi = &guess * (mass / g.mass);
        mix = &phi + &s2 * k.transpose() * chol.solve(&(theta_b - k * &phi));
        if !(mix[9].is_finite() && mix[9] > 0.0) {
            return guess.iter().copied().collect();
        }
        mass = mix[9];
    }
    let f = mass / g.mass;
    Payload {
        mass,
        com: [mix[6] / mass, mix[7] / mass, mix[8] / mass],
        inertia: g.inertia.map(|v| v * f),
    }
    .params()
    .to_vec()
}

fn rms_per_joint(d: &Dataset, v: &DVector<f64>, n: usize) -> Vec<f64> {
    let mut s = vec![0.0; n];
    let mut c = vec![0usize; n];
    for (r, &j) in d.joint.iter().enumerate() {
        s[j] += v[r] * v[r];
        c[j] += 1;
    }
    (0..n).map(|j| if c[j] > 0 { (s[j] / c[j] as f64).sqrt() } else { 0.0 }).collect()
}
