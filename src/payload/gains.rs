//! Drive gains identified with a known mass (Gautier & Briot, IROS 2011):
//! the design's `[gains]` table turns `idexp payload identify` into a
//! calibration of each joint's current → torque gain g_j = s_j·k_t,j·N_j.
//!
//! The robot file converts a logged current i_j to τ_file,j = g_file,j·i_j.
//! With ρ_j = g_j / g_file,j the true joint torque is ρ_j·τ_file,j, and every
//! row (run r, joint j, sample s) of every run gives
//!
//! ```text
//! Y_b(x) θ_b + A'(x) φ' + u_j − ρ_j τ_file,j(t_s) = −m A_M(x)     (loaded runs)
//! Y_b(x) θ_b             + u_j − ρ_j τ_file,j(t_s) = 0              (unloaded runs)
//! ```
//!
//! x = (q, q̇, q̈) at t_s − δ_r, δ_r the delay of run r's currents behind
//! its positions; Y_b the robot's base regressor (inertial and drive parameters θ_b),
//! A = Y_L T the payload's columns on the frame it is mounted to
//! ([`crate::robot::payload`]), split into the known mass's column A_M
//! (its coefficient m, known: the right-hand side) and the rest A' (φ': the
//! mass's first moments and inertia, unknown); u_j = ρ_j·o_j a constant per
//! joint (o_j the current offset as a torque, unless the friction model
//! already has an offset F0). Without the known mass the problem is homogeneous in
//! (θ_b, φ', u, ρ) — scaling a joint's gain and the torques it explains
//! leaves the equations unchanged —; the mass fixes the scale of every joint
//! its torques load. For given delays the problem is linear: weighted least
//! squares stacked over the runs with weights per run and joint
//! ([`crate::ident::study::stack`]). The delays minimise its weighted
//! residual; a trial δ_r moves the model, not the currents: every column of
//! run r is rebuilt from its kinematics at t_s − δ_r (`Columns::at`).
//!
//! A gain is determined when its profile σ (the σ of ρ_j with every other
//! unknown free: 1/‖P⊥ r_j‖ of its column of the weighted triangular factor
//! against the span of the others) is at most `max_std`·|ρ_j|; the others
//! keep the file's value (ρ_j = 1, moved to the right-hand side) and the
//! fit is repeated. A negative ρ_j says the file's current sign is wrong.

use super::chain;
use super::identify::structural;
use crate::error::{Error, Result};
use crate::ident::estimate::Dataset;
use crate::ident::study::stack::{self, Rows};
use crate::ident::study::{load_entry, Loaded};
use crate::optim::Control;
use crate::params::{BaseOptions, BaseParams};
use crate::robot::dynamics::{regressor_rows, Workspace};
use crate::robot::payload::Mount;
use crate::robot::ParamKind;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

fn max_std() -> f64 {
    0.01
}
fn yes() -> bool {
    true
}
fn max_delay() -> f64 {
    0.02
}

/// Another set of gains to compare with (`[[gains.compare]]`): given values,
/// a robot file's, or the controller's ratio in an RTDE recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainSet {
    /// Its name in the table (e.g. "controller", "published").
    pub name: String,
    /// One gain per joint, joint side (N·m/A): s·k_t·N.
    #[serde(default)]
    pub values: Option<Vec<f64>>,
    /// Or a robot file whose drives give them (relative to the design file).
    #[serde(default)]
    pub robot: Option<PathBuf>,
    /// Or an RTDE recording (relative to the design file) with
    /// `target_moment_j` and `target_current_j`: the controller's own ratio
    /// ([`rtde_gains`]).
    #[serde(default)]
    pub rtde: Option<PathBuf>,
}

/// The controller's gains in an RTDE recording (Universal Robots' `record.py`
/// CSV: `timestamp`, `actual_q_0…`, `target_moment_0…` in N·m and
/// `target_current_0…` in A, read by [`crate::data::logs::read_log`]): per
/// joint the least-squares ratio of target torque to target current through
/// the origin, g_j = Σ τ_j i_j / Σ i_j² over the rows (N·m/A, signed). An
/// error names the file and a joint whose target current is zero throughout.
pub fn rtde_gains(robot: &crate::robot::Robot, path: &Path) -> Result<Vec<f64>> {
    use crate::data::logs::{read_log, LogFormat, LogSpec};
    let read = |col: &str| -> Result<Vec<Vec<f64>>> {
        let mut spec = LogSpec::new(LogFormat::Csv);
        spec.t = Some("timestamp".into());
        spec.index_base = Some(0);
        spec.q = Some("actual_q_{j}".into());
        spec.tau = Some(format!("{col}_{{j}}"));
        Ok(read_log(path, robot, &spec)?.rep.tau)
    };
    let (tau, cur) = (read("target_moment")?, read("target_current")?);
    (0..robot.dof())
        .map(|j| {
            let (ti, ii) = tau.iter().zip(&cur).fold((0.0, 0.0), |(a, b), (t, i)| (a + t[j] * i[j], b + i[j] * i[j]));
            if ii > 0.0 {
                Ok(ti / ii)
            } else {
                Err(Error::invalid(
                    path.display().to_string(),
                    format!("target_current_{j}"),
                    format!(
                        "joint `{}`'s target current is zero in every row: no ratio of torque to current",
                        robot.joints[j].name
                    ),
                ))
            }
        })
        .collect()
}

/// The `[gains]` table of a payload design: calibrate the drive gains with a known mass.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsSpec {
    /// The known mass on the design's frame in the `[[loaded]]` runs (kg).
    pub mass: f64,
    /// Joints whose gain is calibrated (names; default: every joint).
    #[serde(default)]
    pub joints: Vec<String>,
    /// Largest relative σ of a gain that counts as determined by the motion.
    #[serde(default = "max_std")]
    pub max_std: f64,
    /// Estimate one delay of the currents behind the positions per run
    /// (default off: on the shipped rehearsal its σ is 0.65–0.75 ms per
    /// 50 s run, see docs/payload.md).
    #[serde(default)]
    pub delay: bool,
    /// The delays searched: −max_delay … max_delay (s).
    #[serde(default = "max_delay")]
    pub max_delay: f64,
    /// Estimate a constant current offset per joint (absorbed by F0 where the friction model has one).
    #[serde(default = "yes")]
    pub offsets: bool,
    /// Other gain sets shown beside the identified ones.
    #[serde(default)]
    pub compare: Vec<GainSet>,
}

impl GainsSpec {
    /// Checks the values; errors name `ctx` and the field.
    pub fn validate(&self, ctx: &str) -> Result<()> {
        let bad = |f: &str, m: String| Err(Error::invalid(ctx, format!("gains.{f}"), m));
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return bad("mass", format!("expected the known mass in kg (> 0), found {}", self.mass));
        }
        if !(self.max_std.is_finite() && self.max_std > 0.0 && self.max_std < 1.0) {
            return bad("max_std", format!("expected a relative σ in (0, 1), found {}", self.max_std));
        }
        if !(self.max_delay.is_finite() && self.max_delay > 0.0 && self.max_delay <= 1.0) {
            return bad("max_delay", format!("expected a delay in (0, 1] s, found {}", self.max_delay));
        }
        for (i, c) in self.compare.iter().enumerate() {
            if [c.values.is_some(), c.robot.is_some(), c.rtde.is_some()].iter().filter(|&&x| x).count() != 1 {
                return bad(
                    &format!("compare[{i}]"),
                    format!(
                        "`{}`: give one of values = [...] (N·m/A per joint), robot = \"file\" or rtde = \"recording.csv\"",
                        c.name
                    ),
                );
            }
            if let Some(v) = &c.values {
                if let Some(x) = v.iter().find(|x| !x.is_finite() || **x == 0.0) {
                    return bad(&format!("compare[{i}].values"), format!("expected non-zero finite gains, found {x}"));
                }
            }
        }
        Ok(())
    }
}

/// One joint's gain: the file's, the identified one and whether the motion determines it.
#[derive(Debug, Clone, Serialize)]
pub struct JointGain {
    /// Joint name.
    pub joint: String,
    /// The robot file's s·k_t·N (N·m/A).
    pub file: f64,
    /// The gain written (N·m/A, signed): identified when determined, else the file's.
    pub gain: f64,
    /// σ of the gain (N·m/A; ∞ when not determined).
    pub std: f64,
    /// ρ = gain / file as estimated (also when not determined), and its profile σ.
    pub ratio: f64,
    /// σ of ρ with every other unknown free.
    pub ratio_std: f64,
    /// True when calibrated and determined (σ(ρ) ≤ max_std·|ρ|).
    pub determined: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// True when the current's sign in the file is wrong (ρ < 0, determined).
    pub sign_flipped: bool,
    /// The current offset (A, logged minus true) and its σ, when estimated.
    pub offset: Option<(f64, f64)>,
    /// RMS of the known mass's torque on this joint over the loaded runs (N·m).
    pub mass_torque_rms: f64,
}

/// A run's part of the calibration.
#[derive(Debug, Clone, Serialize)]
pub struct GainsRun {
    /// Its name.
    pub name: String,
    /// With the known mass.
    pub loaded: bool,
    /// Files read.
    pub files: Vec<PathBuf>,
    /// Samples and rows used.
    pub samples: usize,
    /// Rows used.
    pub rows: usize,
    /// The currents' delay behind the positions (s) and its σ (None: not estimated).
    pub delay: Option<(f64, f64)>,
    /// The weights' σ per joint (N·m).
    pub sigma: Vec<f64>,
}

/// The calibration's result.
#[derive(Debug, Clone, Serialize)]
pub struct GainsEstimate {
    /// Robot file.
    pub robot: PathBuf,
    /// Frame of the known mass.
    pub frame: String,
    /// The known mass (kg).
    pub mass: f64,
    /// Per joint.
    pub joints: Vec<JointGain>,
    /// Other gain sets given (name, gains).
    pub compare: Vec<(String, Vec<f64>)>,
    /// The runs.
    pub runs: Vec<GainsRun>,
    /// Base parameters of the robot (names, estimate, profile σ; true torque units).
    pub base: Vec<(String, f64, f64)>,
    /// The known mass's other parameters (names, estimate, profile σ), about the frame's origin.
    pub payload: Vec<(String, f64, f64)>,
    /// Rank of the final problem and its number of unknowns.
    pub rank: usize,
    /// Unknowns.
    pub unknowns: usize,
    /// χ²/dof of the final fit.
    pub chi2_dof: f64,
    /// Notes for the report.
    pub notes: Vec<String>,
}

/// One run prepared: its rows, torques and kinematics; its columns at a
/// delay come from [`Columns::at`].
struct RunData {
    name: String,
    loaded: bool,
    files: Vec<PathBuf>,
    samples: usize,
    joint: Vec<usize>,
    sample: Vec<usize>,
    var: Option<DVector<f64>>,
    tau: Vec<Vec<f64>>,
    /// The processed run's times and kinematics (the model side of the delay).
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
    /// The positions' Fourier fit when q̇ and q̈ are its derivatives.
    fourier: Option<crate::trajectory::FourierTrajectory>,
    /// Sample step (s).
    h: f64,
    n_reps: usize,
}

/// q, q̇, q̈ per sample.
type Kinematics = (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<Vec<f64>>);

/// A run's columns at one delay: fixed columns F = base | payload' |
/// offsets (rows × pf) and y0 = −m·A_M (loaded) or 0.
type RunColumns = (DMatrix<f64>, DVector<f64>);

/// What the fixed columns are made of (shared by the runs).
struct Columns<'a> {
    robot: &'a crate::robot::Robot,
    base: &'a BaseParams,
    mount: &'a Mount,
    /// The payload's base-column map K (θ_pb = K φ) and the mass's column in it.
    k: &'a DMatrix<f64>,
    im: usize,
    mass: f64,
    off_joints: &'a [usize],
    dead_band: f64,
}

impl Columns<'_> {
    /// Run `r`'s columns with its currents `delay` behind its positions: the
    /// model is evaluated at t_s − δ (the logged current of sample s is the
    /// torque the dynamics needed δ earlier). The kinematics are smooth (the
    /// Fourier fit evaluated there, else the filtered q, q̇, q̈ phase-shifted,
    /// [`chain::shifted`]), so no interpolation touches the currents: these
    /// are sampled without an anti-alias filter and carry the Coulomb
    /// friction's steps, and shifting them by a fraction of a sample rings
    /// (measured: a 3.5 ms delay at 100 Hz came out 1.7–2.0 ms noise-free).
    fn at(&self, r: &RunData, delay: f64) -> RunColumns {
        let (q, qd, qdd) = r.kinematics(delay);
        let n = self.robot.dof();
        let p = self.robot.n_params();
        let m = q.len();
        let pb = self.base.names.len();
        let kb = self.k.nrows();
        let pf = pb + kb - 1 + self.off_joints.len();
        let c = crate::ident::estimate::base_design_dead_band(self.robot, self.base, &q, &qd, &qdd, self.dead_band);
        let rows = r.joint.len();
        let mut f = DMatrix::zeros(rows, pf);
        let mut y0 = DVector::zeros(rows);
        let mut ws = Workspace::new(self.robot);
        let mut yrow = vec![0.0; n * p];
        let mut cols = vec![0.0; n * 10];
        let mut last = usize::MAX;
        for i in 0..rows {
            let (j, s) = (r.joint[i], r.sample[i]);
            for b in 0..pb {
                f[(i, b)] = c[(j * m + s, b)];
            }
            if r.loaded {
                if s != last {
                    regressor_rows(self.robot, &mut ws, &q[s], &qd[s], &qdd[s], &mut yrow);
                    self.mount.columns(self.robot, &yrow, &mut cols);
                    last = s;
                }
                let mut col = pb;
                for bi in 0..kb {
                    // the payload's base column bi (θ_pb = K φ, K's row of M pure: checked)
                    let v: f64 = (0..10).map(|x| cols[j * 10 + x] * self.k[(bi, x)]).sum::<f64>();
                    if bi == self.im {
                        y0[i] = -self.mass * v;
                    } else {
                        f[(i, col)] = v;
                        col += 1;
                    }
                }
            }
            if let Some(o) = self.off_joints.iter().position(|&x| x == j) {
                f[(i, pb + kb - 1 + o)] = 1.0;
            }
        }
        (f, y0)
    }
}

impl RunData {
    /// q, q̇, q̈ at t_s − δ for every sample s.
    fn kinematics(&self, delay: f64) -> Kinematics {
        if delay == 0.0 {
            return (self.q.clone(), self.qd.clone(), self.qdd.clone());
        }
        if let Some(f) = &self.fourier {
            let times: Vec<f64> = self.t.iter().map(|t| t - delay).collect();
            let s = f.sample_at(&times);
            return (s.q, s.qd, s.qdd);
        }
        let shift = |x: &[Vec<f64>]| -> Vec<Vec<f64>> {
            let n = x.first().map_or(0, |v| v.len());
            let cols: Vec<Vec<f64>> = (0..n)
                .map(|j| chain::shifted(&x.iter().map(|v| v[j]).collect::<Vec<f64>>(), -delay / self.h))
                .collect();
            (0..x.len()).map(|s| cols.iter().map(|c| c[s]).collect()).collect()
        };
        (shift(&self.q), shift(&self.qd), shift(&self.qdd))
    }

    /// The run's rows of the Gauss–Newton step at `p` (see [`calibrate`]) with
    /// its columns `fc`: columns [γ_j F | F x − y0 on the free joints' rows],
    /// target t = τ + γ_j F x (free joints) or τ + y0 (fixed, γ = 1).
    fn linearised(&self, fc: &RunColumns, p: &Point, cal: &[Option<usize>], names: &[String]) -> Dataset {
        let (f, y0) = fc;
        let (rows, pf) = (f.nrows(), f.ncols());
        let nc = cal.iter().flatten().count();
        let mut c = DMatrix::zeros(rows, pf + nc);
        let mut y = DVector::zeros(rows);
        let x = DVector::from_column_slice(&p.x);
        let fx = f * &x;
        for i in 0..rows {
            let j = self.joint[i];
            let g = p.gamma[j];
            for k in 0..pf {
                c[(i, k)] = g * f[(i, k)];
            }
            let off = match cal[j] {
                Some(k) => {
                    c[(i, pf + k)] = fx[i] - y0[i];
                    g * fx[i]
                }
                None => y0[i],
            };
            y[i] = self.tau[self.sample[i]][j] + off;
        }
        Dataset {
            n: cal.len(),
            n_samples: self.samples,
            c,
            y,
            var: self.var.clone(),
            names: names.to_vec(),
            joint: self.joint.clone(),
            sample: self.sample.clone(),
        }
    }
}

/// Gauss–Newton iterations at most, and the largest change of a γ that ends them.
const GN_ITERATIONS: usize = 30;
const GN_TOL: f64 = 1e-10;

/// A point of the Gauss–Newton iteration: the linear unknowns x (base,
/// the mass's other parameters, offsets) and γ_j = 1/ρ_j per joint.
#[derive(Debug, Clone)]
struct Point {
    x: Vec<f64>,
    gamma: Vec<f64>,
}

/// Profile σ of unknown `col` from the weighted triangular factor `r`: the
/// inverse distance of its column from the span of the others (∞ if in it).
fn profile_std(r: &DMatrix<f64>, col: usize) -> f64 {
    let k = r.ncols();
    let norms: Vec<f64> = (0..k).map(|c| r.column(c).norm()).collect();
    if norms[col] == 0.0 {
        return f64::INFINITY;
    }
    let others: Vec<usize> = (0..k).filter(|&c| c != col && norms[c] > 0.0).collect();
    let mut o = DMatrix::zeros(r.nrows(), others.len());
    for (i, &c) in others.iter().enumerate() {
        o.set_column(i, &(r.column(c) / norms[c]));
    }
    let v = r.column(col) / norms[col];
    let mut res = v.clone_owned();
    if !others.is_empty() {
        let svd = o.svd(true, false);
        let u = svd.u.expect("u requested");
        let smax = svd.singular_values.max();
        for (i, s) in svd.singular_values.iter().enumerate() {
            if *s > 1e-9 * smax {
                let ui = u.column(i);
                res -= ui * ui.dot(&v);
            }
        }
    }
    let d = res.norm();
    if d < 1e-7 {
        f64::INFINITY
    } else {
        1.0 / (d * norms[col])
    }
}

/// Calibrates the drive gains of `design` (which has a `[gains]` table); its
/// relative paths are relative to `dir`.
pub fn calibrate(design: &super::PayloadDesign, dir: &Path, ctl: &Control) -> Result<GainsEstimate> {
    design.validate("payload")?;
    let spec = design
        .gains
        .as_ref()
        .ok_or_else(|| Error::invalid("payload", "gains", "a gain calibration needs a [gains] table (mass = the known mass in kg)"))?;
    let robot_path = dir.join(&design.robot);
    let robot = crate::robot::load(&robot_path)?;
    let n = robot.dof();
    let names: Vec<String> = robot.joints.iter().map(|j| j.name.clone()).collect();
    // the joints to calibrate, and every calibrated joint's file gain
    let mut selected = vec![spec.joints.is_empty(); n];
    for j in &spec.joints {
        match names.iter().position(|x| x == j) {
            Some(i) => selected[i] = true,
            None => {
                return Err(Error::invalid(
                    "payload",
                    "gains.joints",
                    format!("no joint `{j}` in {}: expected one of {}", robot_path.display(), names.join(", ")),
                ))
            }
        }
    }
    let file: Vec<f64> = robot.drives.iter().map(|d| d.torque_per_ampere().unwrap_or(f64::NAN)).collect();
    if let Some(j) = (0..n).find(|&j| !file[j].is_finite()) {
        return Err(Error::invalid(
            "payload",
            "robot",
            format!(
                "calibrating drive gains needs every drive's torque_constant (the runs log currents), but joint `{}` of {} has none: add torque_constant = k_t (N·m/A) and gear_ratio to its [[drive]] entry",
                names[j],
                robot_path.display()
            ),
        ));
    }
    let mut compare = Vec::new();
    for (i, c) in spec.compare.iter().enumerate() {
        let v = match (&c.values, &c.robot, &c.rtde) {
            (Some(v), _, _) => v.clone(),
            (None, Some(p), _) => {
                let r = crate::robot::load(&dir.join(p))?;
                r.drives.iter().map(|d| d.torque_per_ampere().unwrap_or(f64::NAN)).collect()
            }
            (None, None, Some(p)) => rtde_gains(&robot, &dir.join(p))?,
            _ => unreachable!("validated"),
        };
        if v.len() != n {
            return Err(Error::invalid(
                "payload",
                format!("gains.compare[{i}]"),
                format!("`{}`: {} gains for {n} joints", c.name, v.len()),
            ));
        }
        compare.push((c.name.clone(), v));
    }
    let mount = Mount::new(&robot, design.frame.as_deref(), "payload", "frame")?;
    let st = structural(&robot, &mount)?;
    let im = st.independent.iter().position(|&c| c == 9).ok_or_else(|| {
        Error::invalid(
            "payload",
            "frame",
            format!(
                "the mass on frame `{}` has no effect on the joint torques: it cannot calibrate gains",
                mount.frame
            ),
        )
    })?;
    if (0..10).any(|c| (st.k[(im, c)] - if c == 9 { 1.0 } else { 0.0 }).abs() > 1e-9) {
        return Err(Error::invalid(
            "payload",
            "frame",
            format!(
                "on frame `{}` the mass is sensed only together with other parameters ({}): it cannot calibrate gains",
                mount.frame, st.groupings[im]
            ),
        ));
    }
    let base = BaseParams::compute(&robot, &BaseOptions::default())?;
    let pb = base.names.len();
    let kb = st.independent.len();
    let has_f0: Vec<bool> = (0..n)
        .map(|j| robot.params().iter().any(|p| p.joint == j && matches!(p.kind, ParamKind::F0)))
        .collect();
    let off_joints: Vec<usize> = (0..n).filter(|&j| spec.offsets && !has_f0[j]).collect();
    let pf = pb + kb - 1 + off_joints.len();
    let mut col_names: Vec<String> = base.names.clone();
    col_names.extend((0..kb).filter(|&i| i != im).map(|i| format!("payload {}", st.names[i])));
    col_names.extend(off_joints.iter().map(|j| format!("offset {}", names[*j])));
    // read and prepare every run
    let obs = ctl.observer();
    obs.phase("gains read", Some((design.loaded.len() + design.unloaded.len()) as u64));
    let mut runs: Vec<RunData> = Vec::new();
    let maker = Columns {
        robot: &robot,
        base: &base,
        mount: &mount,
        k: &st.k,
        im,
        mass: spec.mass,
        off_joints: &off_joints,
        dead_band: if design.method == crate::ident::Method::Projection {
            0.0
        } else {
            crate::ident::DEAD_BAND
        },
    };
    // each run's columns at its current delay
    let mut cols: Vec<RunColumns> = Vec::new();
    for (loaded, list) in [(true, &design.loaded), (false, &design.unloaded)] {
        for spec_e in list {
            if ctl.interrupted() {
                return Err(Error::Interrupted);
            }
            let l: Loaded = load_entry(&robot, &base, spec_e, dir, design.method, design.sample_limit)?;
            let pr = &l.prep.pr;
            let m = pr.t.len();
            if m < 8 {
                return Err(Error::invalid("payload", format!("run `{}`", l.name), format!("{m} samples: too short")));
            }
            let h = (pr.t[m - 1] - pr.t[0]) / (m - 1) as f64;
            let edge = if spec.delay { (spec.max_delay / h).ceil() as usize + 2 } else { 0 };
            let full = &l.prep.full;
            let keep: Vec<usize> = (0..full.joint.len()).filter(|&r| full.sample[r] >= edge && full.sample[r] + edge < m).collect();
            let var = full.var.as_ref().map(|v| DVector::from_iterator(keep.len(), keep.iter().map(|&r| v[r])));
            let run = RunData {
                name: l.name.clone(),
                loaded,
                files: l.files.clone(),
                samples: m,
                joint: keep.iter().map(|&r| full.joint[r]).collect(),
                sample: keep.iter().map(|&r| full.sample[r]).collect(),
                var,
                tau: pr.tau.clone(),
                t: pr.t.clone(),
                q: pr.q.clone(),
                qd: pr.qd.clone(),
                qdd: pr.qdd.clone(),
                fourier: pr.fourier.clone().filter(|_| pr.velocity == crate::ident::VelocitySource::Positions),
                h,
                n_reps: l.n_reps,
            };
            cols.push(maker.at(&run, 0.0));
            runs.push(run);
            obs.progress(runs.len() as u64, &l.name);
        }
    }
    obs.phase_done();
    // the known mass's torque per joint (loaded runs)
    let mut mass_torque = vec![(0.0, 0usize); n];
    for (r, (_, y0)) in runs.iter().zip(&cols).filter(|(r, _)| r.loaded) {
        for (i, &j) in r.joint.iter().enumerate() {
            mass_torque[j].0 += y0[i] * y0[i];
            mass_torque[j].1 += 1;
        }
    }
    let mass_torque_rms: Vec<f64> = mass_torque.iter().map(|(s, c)| if *c > 0 { (s / *c as f64).sqrt() } else { 0.0 }).collect();
    let mut reason: Vec<Option<String>> = vec![None; n];
    for j in 0..n {
        if !selected[j] {
            reason[j] = Some("not in gains.joints: the file's value is kept".into());
        } else if mass_torque[j].1 == 0 {
            reason[j] =
                Some("no rows in the loaded runs (the joint stands still: the standstill rule leaves its rows out): the known mass does not load it".into());
        } else if !runs.iter().any(|r| !r.loaded && r.joint.contains(&j)) {
            reason[j] = Some("no rows in the unloaded runs (the joint stands still there)".into());
        }
    }
    let sopts = design.stack_options();
    let mut delays = vec![0.0; runs.len()];
    let mut delay_std = vec![f64::NAN; runs.len()];
    // every selected joint with rows keeps its gain as an unknown — also one
    // the motion does not determine, so that the file's (wrong) gain of its
    // rows does not bias the shared parameters —; which are determined is
    // decided on the final fit by their profile σ
    let cal: Vec<Option<usize>> = {
        let mut k = 0;
        (0..n)
            .map(|j| {
                (selected[j] && runs.iter().any(|r| r.joint.contains(&j))).then(|| {
                    k += 1;
                    k - 1
                })
            })
            .collect()
    };
    let mut names_all = col_names.clone();
    names_all.extend((0..n).filter(|&j| cal[j].is_some()).map(|j| format!("1/gain ratio {}", names[j])));
    let fit = |cols: &[RunColumns], p: &Point| -> Result<stack::Stacked> {
        let ds: Vec<Dataset> = runs.iter().zip(cols).map(|(r, fc)| r.linearised(fc, p, &cal, &names_all)).collect();
        let rows: Vec<Rows> = ds
            .iter()
            .zip(&runs)
            .map(|(d, r)| Rows {
                name: &r.name,
                data: d,
                n_reps: r.n_reps,
            })
            .collect();
        stack::estimate(&rows, &sopts)
    };
    // Gauss–Newton on the output-error form τ_file = γ_j (F x − y0), γ = 1/ρ,
    // from γ = 1, x = 0; each step a stacked weighted least squares
    let gauss_newton = |cols: &[RunColumns], start: Point| -> Result<(Point, stack::Stacked)> {
        let mut p = start;
        let mut last = None;
        for _ in 0..GN_ITERATIONS {
            if ctl.interrupted() {
                return Err(Error::Interrupted);
            }
            let stk = fit(cols, &p)?;
            let x: Vec<f64> = stk.theta.iter().take(pf).copied().collect();
            let mut gamma = p.gamma.clone();
            let mut change = 0.0_f64;
            for j in 0..n {
                if let Some(k) = cal[j] {
                    change = change.max((stk.theta[pf + k] - gamma[j]).abs());
                    gamma[j] = stk.theta[pf + k];
                }
            }
            p = Point { x, gamma };
            last = Some(stk);
            if change < GN_TOL {
                break;
            }
        }
        Ok((p, last.expect("at least one iteration")))
    };
    let start = Point {
        x: vec![0.0; pf],
        gamma: vec![1.0; n],
    };
    let (mut point, mut stk) = gauss_newton(&cols, start)?;
    if spec.delay {
        obs.phase("gains delay", Some(2 * runs.len() as u64));
        for sweep in 0..2 {
            let w: Vec<Vec<f64>> = (0..runs.len())
                .map(|e| {
                    (0..n)
                        .map(|j| {
                            stk.blocks
                                .iter()
                                .find(|b| b.experiment == e && b.joint == j)
                                .map_or(0.0, |b| 1.0 / (b.sigma * b.sigma).max(1e-300))
                        })
                        .collect()
                })
                .collect();
            let mut ne = Normal::new(&runs, &cols, &w, &point, &cal, &names_all);
            for e in 0..runs.len() {
                if ctl.interrupted() {
                    return Err(Error::Interrupted);
                }
                let mut at = |x: f64| {
                    ne.set(&runs[e], e, &maker.at(&runs[e], x), &point, &cal, &names_all);
                    ne.rss()
                };
                let (d, _) = chain::minimise(&mut at, -spec.max_delay, spec.max_delay, if sweep == 0 { 17 } else { 7 }, 1e-3 * runs[e].h);
                let hh = 0.05 * runs[e].h;
                let (a, b, c) = (at(d - hh), at(d), at(d + hh));
                delay_std[e] = chain::sigma_from_curvature(a, b, c, hh);
                delays[e] = d;
                cols[e] = maker.at(&runs[e], d);
                ne.set(&runs[e], e, &cols[e], &point, &cal, &names_all);
                obs.progress((sweep * runs.len() + e + 1) as u64, &runs[e].name);
            }
            (point, stk) = gauss_newton(&cols, point)?;
        }
        obs.phase_done();
    }
    let mut notes = Vec::new();
    let pstd: Vec<f64> = (0..stk.theta.len()).map(|c| profile_std(&stk.r, c)).collect();
    for j in 0..n {
        if let (Some(k), None) = (cal[j], &reason[j]) {
            let rel = pstd[pf + k] / stk.theta[pf + k].abs(); // σ(γ)/|γ| = σ(ρ)/|ρ| to first order
            if rel.is_nan() || rel > spec.max_std {
                reason[j] = Some(if rel.is_finite() {
                    format!(
                        "σ(g)/g = {:.1} % > max_std = {:.1} %: the motion does not determine it (the known mass's torque on it: {:.3} N·m RMS)",
                        100.0 * rel,
                        100.0 * spec.max_std,
                        mass_torque_rms[j]
                    )
                } else {
                    "its column is in the span of the others: the known mass's torques do not reach it".into()
                });
            }
        }
    }
    let joints: Vec<JointGain> = (0..n)
        .map(|j| {
            let (ratio, ratio_std) = match cal[j] {
                Some(k) => (1.0 / stk.theta[pf + k], pstd[pf + k] / (stk.theta[pf + k] * stk.theta[pf + k])),
                None => (1.0, f64::INFINITY),
            };
            let determined = cal[j].is_some() && reason[j].is_none();
            let offset = off_joints.iter().position(|&x| x == j).map(|o| {
                let c = pb + kb - 1 + o;
                // τ_file = g_file·i with i = i_true + i_off: γ·(… + u) = τ_file gives u = g·i_off
                let r = if cal[j].is_some() { ratio } else { 1.0 };
                (stk.theta[c] / (r * file[j]), pstd[c] / (r * file[j]).abs())
            });
            JointGain {
                joint: names[j].clone(),
                file: file[j],
                gain: if determined { ratio * file[j] } else { file[j] },
                std: if determined { ratio_std * file[j].abs() } else { f64::INFINITY },
                ratio,
                ratio_std,
                determined,
                reason: reason[j].clone(),
                sign_flipped: determined && ratio < 0.0,
                offset,
                mass_torque_rms: mass_torque_rms[j],
            }
        })
        .collect();
    for g in &joints {
        if g.sign_flipped {
            notes.push(format!(
                "joint `{}`: the current's sign in the robot file is wrong (ρ = {:.4}): robot.toml has current_sign flipped",
                g.joint, g.ratio
            ));
        }
        if !g.determined && selected[names.iter().position(|x| *x == g.joint).unwrap_or(0)] {
            notes.push(format!(
                "joint `{}`: gain not determined ({}); the file's value is kept",
                g.joint,
                g.reason.clone().unwrap_or_default()
            ));
        }
    }
    if off_joints.len() < n && spec.offsets {
        notes.push("joints whose friction model has an offset F0: their current offset is part of F0, not estimated apart".into());
    }
    let runs_out = runs
        .iter()
        .enumerate()
        .map(|(e, r)| GainsRun {
            name: r.name.clone(),
            loaded: r.loaded,
            files: r.files.clone(),
            samples: r.samples,
            rows: r.joint.len(),
            delay: spec.delay.then_some((delays[e], delay_std[e])),
            sigma: (0..n)
                .map(|j| stk.blocks.iter().find(|b| b.experiment == e && b.joint == j).map_or(f64::NAN, |b| b.sigma))
                .collect(),
        })
        .collect();
    Ok(GainsEstimate {
        robot: robot_path,
        frame: mount.frame.clone(),
        mass: spec.mass,
        joints,
        compare,
        runs: runs_out,
        base: (0..pb).map(|c| (base.names[c].clone(), stk.theta[c], pstd[c])).collect(),
        payload: (pb..pb + kb - 1)
            .map(|c| (col_names[c].trim_start_matches("payload ").to_string(), stk.theta[c], pstd[c]))
            .collect(),
        rank: stk.rank,
        unknowns: stk.theta.len(),
        chi2_dof: stk.chi2_dof,
        notes,
    })
}

/// The delay search's weighted least squares at a fixed linearisation point
/// (x, γ) and fixed weights: each run keeps its part of G = JᵀWJ, h = JᵀWt
/// and tᵀWt; a trial delay of one run rebuilds that run's columns
/// (`Columns::at`) and part, and the residual is tᵀWt − hᵀG⁺h.
struct Normal {
    /// Weights per run and joint.
    w: Vec<Vec<f64>>,
    /// Per run: G_e, h_e, (tᵀWt)_e.
    runs: Vec<(DMatrix<f64>, DVector<f64>, f64)>,
}

impl Normal {
    fn new(runs: &[RunData], cols: &[RunColumns], w: &[Vec<f64>], p: &Point, cal: &[Option<usize>], names: &[String]) -> Normal {
        let mut ne = Normal {
            w: w.to_vec(),
            runs: Vec::new(),
        };
        for (e, r) in runs.iter().enumerate() {
            ne.runs.push((DMatrix::zeros(0, 0), DVector::zeros(0), 0.0));
            ne.set(r, e, &cols[e], p, cal, names);
        }
        ne
    }

    /// Run `e`'s part with its columns `fc`.
    fn set(&mut self, r: &RunData, e: usize, fc: &RunColumns, p: &Point, cal: &[Option<usize>], names: &[String]) {
        let ds = r.linearised(fc, p, cal, names);
        let mut jw = ds.c;
        let mut t = ds.y;
        for i in 0..jw.nrows() {
            let sw = self.w[e][r.joint[i]].sqrt();
            jw.row_mut(i).scale_mut(sw);
            t[i] *= sw;
        }
        self.runs[e] = (jw.tr_mul(&jw), jw.tr_mul(&t), t.dot(&t));
    }

    /// The weighted residual sum of squares at the least-squares solution.
    fn rss(&self) -> f64 {
        let k = self.runs[0].1.len();
        let mut g = DMatrix::zeros(k, k);
        let mut h = DVector::zeros(k);
        let mut tt = 0.0;
        for (gp, hp, t) in &self.runs {
            g += gp;
            h += hp;
            tt += t;
        }
        let svd = g.svd(true, true);
        let tol = 1e-12 * svd.singular_values.max();
        match svd.solve(&h, tol) {
            Ok(x) => tt - h.dot(&x),
            Err(_) => f64::INFINITY,
        }
    }
}
