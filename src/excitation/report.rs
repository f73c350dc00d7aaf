//! Identifiability report of a trajectory and the output files of
//! `idexp excite` / `idexp assess`.
//!
//! For samples (q, q̇, q̈)_i, i = 1..N, of any trajectory, C is the stacked
//! base regressor (N·n × m, unweighted) and C_w = W½ C with W½ = diag(1/σ_j)
//! the torque-noise weights. The report gives
//!
//! * the singular values and the condition number of C_w with unit columns,
//!   and the numerical rank (σ_k > 10⁻⁸ σ_1);
//! * the sensitivity of each parameter, c̄_i = ‖c_i‖₁ / (n N) (paper 000 eq. 10);
//! * the covariance of the WLS estimate from the given data with noise
//!   σ_j on joint j, var(θ̂) = (C_wᵀ C_w)⁻¹ (paper 000 eq. 13 with N_f = 1),
//!   the standard deviations σ_i and the relative ones σ*_i = σ_i / |θ_i|
//!   (eq. 14) at the nominal base-parameter values; when C is rank
//!   deficient, those of the model without the non-excited parameters (which
//!   get ∞);
//! * the parameters that are not excited: zero columns, and those with a
//!   component above 0.1 in a right singular vector of the numerical null space.

use super::constraints::{ConstraintKind, Margin};
use super::{Criterion, ExciteResult, Problem, Scaling, Status};
use crate::error::{Error, Result};
use crate::io::plot::{write_svg, Panel, Series};
use crate::io::status::RunState;
use crate::io::States;
use crate::optim::Termination;
use crate::params::BaseParams;
use crate::robot::{regressor_rows, Robot, Workspace};
use crate::trajectory::lead::DeliveredSamples;
use crate::trajectory::seconds_text;
use nalgebra::DMatrix;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Relative rank tolerance on the singular values of the unit-column matrix.
pub const RANK_TOL: f64 = 1e-8;

/// Identifiability measures of a sampled trajectory.
#[derive(Debug, Clone, Serialize)]
pub struct Identifiability {
    /// Number of samples N.
    pub samples: usize,
    /// Rows N·n of C.
    pub rows: usize,
    /// Base-parameter names (columns of C).
    pub names: Vec<String>,
    /// Each base parameter as a combination of standard ones.
    pub groupings: Vec<String>,
    /// The robot's standard parameter whose regressor column is column j of C
    /// (`ZZ1` for the base parameter `ZZ1R`, `Fc1`, ...).
    pub parameters: Vec<String>,
    /// ‖column j of C_w‖ over the samples: the reference of the unit-column
    /// scaling (C_w's column j is divided by it).
    pub column_norms: Vec<f64>,
    /// Which samples the figures are computed from (`None`: not stated by the caller).
    pub source: Option<SampleSet>,
    /// Numerical rank of C.
    pub rank: usize,
    /// Condition number of C_w with unit columns (∞ when rank deficient).
    pub cond: f64,
    /// Singular values of C_w with unit columns, decreasing.
    pub singular_values: Vec<f64>,
    /// Condition number of the model without the non-excited parameters (= `cond` at full rank).
    pub cond_excited: f64,
    /// Sensitivities c̄_i (paper 000 eq. 10), in the units of torque per unit parameter.
    pub sensitivity: Vec<f64>,
    /// Nominal base-parameter values.
    pub nominal: Vec<f64>,
    /// Predicted standard deviations σ_i from one period (eq. 13).
    pub std_dev: Vec<f64>,
    /// Predicted relative standard deviations σ*_i = σ_i/|θ_i| (eq. 14; ∞ if θ_i = 0 or rank deficient).
    pub rel_std_dev: Vec<f64>,
    /// Torque noise standard deviation per joint used for W and σ_i.
    pub noise: Vec<f64>,
    /// Parameters not excited (zero column or in the numerical null space).
    pub unexcited: Vec<String>,
    /// Excited parameters whose predicted relative standard deviation exceeds 100 % (nominal ≠ 0) or is unbounded.
    pub poorly_identifiable: Vec<String>,
}

/// The robot's standard-parameter name of every base column (`ZZ1` for `ZZ1R`).
pub fn column_parameters(robot: &Robot, base: &BaseParams) -> Vec<String> {
    let names = robot.param_names();
    base.independent.iter().map(|&c| names[c].clone()).collect()
}

/// The samples one reported figure is computed from.
#[derive(Debug, Clone, Serialize)]
pub struct SampleSet {
    /// The CSV file holding them (`t`, q1..qn, qd1..qdn, qdd1..qddn), relative
    /// to the output folder when it is one of its files.
    pub file: String,
    /// Only the rows whose `segment` column holds this value (trajectory.csv:
    /// 0 lead-in, k period k, −1 lead-out); absent: every row.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segment: Option<i64>,
    /// Keep every `every`-th data row of the file (of the segment's rows when
    /// `segment` is given), starting with the first.
    pub every: usize,
    /// Number of samples N (rows of C: N·n).
    pub count: usize,
    /// Sample rate (Hz) of the rows used, when they are uniformly spaced.
    pub rate_hz: Option<f64>,
    /// Time of the first and of the last sample used (s), when the file has a `t` column.
    pub t_range: Option<[f64; 2]>,
    /// The same in words.
    pub description: String,
}

/// One base column of the stacked regressor C.
#[derive(Debug, Clone, Serialize)]
pub struct ColumnRecord {
    /// Base-parameter name (suffix `R`: other standard parameters are regrouped into it).
    pub name: String,
    /// The robot's standard parameter whose regressor column is this column.
    pub parameter: String,
    /// Its index in the robot's standard parameter vector.
    pub index: usize,
    /// The combination of standard parameters this column's coefficient
    /// estimates (θ_b,j = Σ k_i θ_i), as (parameter, k_i) pairs.
    pub combination: Vec<(String, f64)>,
    /// The same, readable.
    pub grouping: String,
    /// Nominal value of the combination.
    pub nominal: f64,
}

/// One reported condition number (or criterion) and what it is computed from.
#[derive(Debug, Clone, Serialize)]
pub struct Figure {
    /// Which figure of report.txt / report.json this is.
    pub label: String,
    /// Samples used.
    pub samples: SampleSet,
    /// Column scaling: `unit_column`, `nominal` or `none`.
    pub scaling: Scaling,
    /// ‖column j of W½C‖ over the samples (the reference of unit-column scaling).
    pub column_norms: Vec<f64>,
    /// Column factors D_jj: the matrix is W½ C D.
    pub scale: Vec<f64>,
    /// Criterion, for the design's criterion figure.
    pub criterion: Option<Criterion>,
    /// Criterion value, for the design's criterion figure.
    pub value: Option<f64>,
    /// σ_1/σ_m of W½ C D (capped at 10¹² for the design criterion, ∞ in the
    /// identifiability figures when rank deficient).
    pub cond: f64,
    /// Singular values of W½ C D, decreasing.
    pub singular_values: Vec<f64>,
}

/// criterion.json: everything needed to recompute every reported condition
/// number from the written files with any rigid-body regressor.
#[derive(Debug, Clone, Serialize)]
pub struct CriterionRecord {
    /// What this file is.
    pub about: String,
    /// The robot file.
    pub robot: String,
    /// Joint names, in the order of the columns q1..qn of the sample files.
    pub joints: Vec<String>,
    /// Gravity (m/s², base frame).
    pub gravity: [f64; 3],
    /// How the rows of C are formed, in words.
    pub regressor: String,
    /// |q̇_j| below this counts as 0 (the Coulomb column sign(q̇_j) is then 0).
    pub zero_velocity: f64,
    /// The columns of C, in order.
    pub columns: Vec<ColumnRecord>,
    /// Torque noise σ_j per joint (N·m or N); row r of joint j is weighted by 1/σ_j.
    pub noise: Vec<f64>,
    /// The reported figures.
    pub figures: Vec<Figure>,
}

impl CriterionRecord {
    /// The columns, weights and regressor description of `base` on `robot`
    /// (figures to be added).
    pub fn new(robot: &Robot, robot_file: &str, base: &BaseParams, noise: &[f64], about: String) -> CriterionRecord {
        let pn = robot.param_names();
        let theta = robot.nominal_params();
        let nominal = base.base_values(theta.as_slice());
        let columns = (0..base.n_base())
            .map(|j| ColumnRecord {
                name: base.names[j].clone(),
                parameter: pn[base.independent[j]].clone(),
                index: base.independent[j],
                combination: (0..base.n_std)
                    .filter(|&i| base.k[(j, i)] != 0.0)
                    .map(|i| (pn[i].clone(), base.k[(j, i)]))
                    .collect(),
                grouping: base.groupings[j].clone(),
                nominal: nominal[j],
            })
            .collect();
        let g = robot.gravity;
        CriterionRecord {
            about,
            robot: robot_file.to_string(),
            joints: robot.joints.iter().map(|j| j.name.clone()).collect(),
            gravity: [g.x, g.y, g.z],
            regressor: "one row per joint j and sample: the joint-side torque regressor τ = Y(q, q̇, q̈) θ; column `parameter` \
                        of Y for each column; inertial parameters per link about the link (joint) frame origin in the link frame, \
                        as the URDF's joint frames; Coulomb friction Fc_j: sign(q̇_j) on joint j's row, viscous Fv_j: q̇_j; \
                        samples stacked in time order, joints in order within a sample"
                .into(),
            zero_velocity: super::objective::ZERO_VELOCITY,
            columns,
            noise: noise.to_vec(),
            figures: Vec::new(),
        }
    }
}

impl SampleSet {
    /// Describes the samples taken every `every`-th row of `file` with times
    /// `t` (those used, if the file has them); `note` is added in words.
    pub fn new(file: &str, every: usize, t: Option<&[f64]>, note: &str) -> SampleSet {
        let mut times = TimeStats::default();
        t.unwrap_or_default().iter().for_each(|&v| times.add(v));
        SampleSet::from_parts(file, every, times.count, times.range(), times.rate(), note)
    }

    /// As [`SampleSet::new`] from the count, time range and rate.
    pub fn from_parts(file: &str, every: usize, count: usize, t_range: Option<[f64; 2]>, rate_hz: Option<f64>, note: &str) -> SampleSet {
        let mut description = format!(
            "{file}: {}{count} rows",
            if every > 1 {
                format!("every {} data row from the first, ", ordinal(every))
            } else {
                "all ".into()
            }
        );
        if let Some(r) = rate_hz {
            let _ = write!(description, " at {r} Hz");
        }
        if let Some([a, b]) = t_range {
            let _ = write!(description, ", t = {} … {} s", seconds_text(a), seconds_text(b));
        }
        if !note.is_empty() {
            let _ = write!(description, " ({note})");
        }
        SampleSet {
            file: file.to_string(),
            segment: None,
            every,
            count,
            rate_hz,
            t_range,
            description,
        }
    }
}

/// `2nd`, `3rd`, `7th`, `11th`, `21st`, ...
fn ordinal(k: usize) -> String {
    let suffix = match (k % 10, k % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{k}{suffix}")
}

/// Running statistics of sample times read block by block: first, last and
/// the extreme spacings (a uniform rate when they agree to 10⁻⁶).
#[derive(Debug, Clone, Default)]
struct TimeStats {
    count: usize,
    first: f64,
    last: f64,
    min_dt: f64,
    max_dt: f64,
}

impl TimeStats {
    fn add(&mut self, t: f64) {
        if self.count == 0 {
            self.first = t;
            self.min_dt = f64::INFINITY;
            self.max_dt = f64::NEG_INFINITY;
        } else {
            let dt = t - self.last;
            self.min_dt = self.min_dt.min(dt);
            self.max_dt = self.max_dt.max(dt);
        }
        self.last = t;
        self.count += 1;
    }

    fn range(&self) -> Option<[f64; 2]> {
        (self.count > 0).then_some([self.first, self.last])
    }

    fn rate(&self) -> Option<f64> {
        if self.count < 2 || self.min_dt.is_nan() || self.min_dt <= 0.0 || self.max_dt - self.min_dt > 1e-6 * self.min_dt {
            return None;
        }
        let dt = (self.last - self.first) / (self.count - 1) as f64;
        Some(((1.0 / dt) * 1e9).round() / 1e9)
    }
}

/// Stacks the base regressor of `states` and computes the report.
/// `noise`: σ_j per joint (N·m).
pub fn assess(robot: &Robot, base: &BaseParams, states: &States, noise: &[f64]) -> Result<Identifiability> {
    let mut acc = AssessAccumulator::new(robot, base, noise)?;
    for i in 0..states.len() {
        acc.add_sample(i, &states.q[i], &states.qd[i], &states.qdd[i], 1)?;
    }
    acc.finish()
}

/// [`assess`] of every row of a delivered trajectory's samples: a row that
/// repeats another bitwise ([`DeliveredSamples::source`]) is counted with
/// the row it repeats instead of being stacked again (the same CᵀC).
pub fn assess_delivered(robot: &Robot, base: &BaseParams, ds: &DeliveredSamples, noise: &[f64]) -> Result<Identifiability> {
    for (what, len) in [("q", ds.q.len()), ("qd", ds.qd.len()), ("qdd", ds.qdd.len()), ("source", ds.source.len())] {
        if len != ds.len() {
            return Err(Error::dim(format!("{what} rows of the delivered samples (one per time)"), ds.len(), len));
        }
    }
    let mut times = vec![0usize; ds.len()];
    for (k, &src) in ds.source.iter().enumerate() {
        if src > k || ds.source[src] != src {
            return Err(Error::invalid(
                "assess",
                "source",
                format!("sample {k} repeats sample {src}, which is not an earlier sample of its own"),
            ));
        }
        times[src] += 1;
    }
    let mut acc = AssessAccumulator::new(robot, base, noise)?;
    for (i, &w) in times.iter().enumerate() {
        acc.add_sample(i, &ds.q[i], &ds.qd[i], &ds.qdd[i], w)?;
    }
    acc.finish()
}

/// [`assess`] of a states CSV read block by block ([`read_states`]'s format
/// and checks, every `every`-th row): memory independent of the file length.
/// `segment`: only the rows whose `segment` column holds this value
/// (trajectory.csv of `idexp excite`: 0 lead-in, k period k, −1 lead-out).
pub fn assess_file(robot: &Robot, base: &BaseParams, path: &Path, segment: Option<i64>, every: usize, noise: &[f64]) -> Result<Identifiability> {
    let n = robot.dof();
    let mut rdr = crate::io::states::StatesReader::open(path, n)?;
    if let Some(k) = segment {
        rdr.only_segment(k)?;
    }
    let mut acc = AssessAccumulator::new(robot, base, noise)?;
    let mut block = crate::io::states::StateBlock::default();
    let mut times = TimeStats::default();
    while rdr.next_block(4096, every, &mut block)? > 0 {
        for &t in &block.t {
            times.add(t);
        }
        for i in 0..block.len(n) {
            let r = i * n..(i + 1) * n;
            acc.add(&block.q[r.clone()], &block.qd[r.clone()], &block.qdd[r]);
        }
    }
    if acc.samples == 0 {
        return Err(match segment {
            None => Error::Data {
                path: path.to_path_buf(),
                row: 0,
                column: "q1".into(),
                msg: "the file has no data rows".into(),
            },
            Some(k) => Error::Data {
                path: path.to_path_buf(),
                row: 0,
                column: "segment".into(),
                msg: format!("no row has segment {k} (trajectory.csv of idexp excite: 0 lead-in, 1 … P the periods, -1 lead-out)"),
            },
        });
    }
    let samples = acc.samples;
    let mut id = acc.finish()?;
    let note = segment.map_or(String::new(), |k| match k {
        0 => "segment 0 only: the lead-in".to_string(),
        -1 => "segment -1 only: the lead-out".to_string(),
        k => format!("segment {k} only: period {k}"),
    });
    let mut set = SampleSet::from_parts(&path.display().to_string(), every, samples, times.range(), times.rate(), &note);
    set.segment = segment;
    id.source = Some(set);
    Ok(id)
}

/// Rows of the weighted base regressor per QR update of the accumulator.
const ASSESS_BLOCK: usize = 1024;

/// Incremental [`assess`]: the weighted base regressor C_w (rows C/σ_j) is
/// never stored; its triangular QR factor R (C_w = Q R, m×m) is updated block
/// by block, and R has C_w's singular values, right singular vectors and
/// column norms.
struct AssessAccumulator<'a> {
    robot: &'a Robot,
    base: &'a BaseParams,
    noise: Vec<f64>,
    ws: Workspace,
    y: Vec<f64>,
    qd: Vec<f64>,
    /// Pending rows (row-major, m each) of C_w.
    rows: Vec<f64>,
    r: Option<DMatrix<f64>>,
    abs_sum: Vec<f64>,
    samples: usize,
}

impl<'a> AssessAccumulator<'a> {
    fn new(robot: &'a Robot, base: &'a BaseParams, noise: &[f64]) -> Result<Self> {
        let n = robot.dof();
        if noise.len() != n {
            return Err(Error::dim("noise levels (one per joint)", n, noise.len()));
        }
        let m = base.n_base();
        Ok(AssessAccumulator {
            robot,
            base,
            noise: noise.to_vec(),
            ws: Workspace::new(robot),
            y: vec![0.0; n * robot.n_params()],
            qd: vec![0.0; n],
            rows: Vec::with_capacity((ASSESS_BLOCK + n) * m),
            r: None,
            abs_sum: vec![0.0; m],
            samples: 0,
        })
    }

    fn add(&mut self, q: &[f64], qd: &[f64], qdd: &[f64]) {
        self.add_times(q, qd, qdd, 1);
    }

    /// [`Self::add_times`] of sample `i` of a caller's states, its lengths
    /// checked first (an error naming the sample, not a panic).
    fn add_sample(&mut self, i: usize, q: &[f64], qd: &[f64], qdd: &[f64], times: usize) -> Result<()> {
        let n = self.robot.dof();
        for (what, v) in [("q", q), ("qd", qd), ("qdd", qdd)] {
            if v.len() != n {
                return Err(Error::dim(format!("{what} of sample {i}"), n, v.len()));
            }
        }
        self.add_times(q, qd, qdd, times);
        Ok(())
    }

    /// [`Self::add`] of a sample that occurs `times` times: its rows scaled
    /// by √times, which adds to CᵀC (and so to R's singular values, right
    /// singular vectors and column norms) what `times` copies add.
    fn add_times(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], times: usize) {
        if times == 0 {
            return;
        }
        let (w, root) = (times as f64, (times as f64).sqrt());
        let n = self.robot.dof();
        let p = self.robot.n_params();
        self.qd.copy_from_slice(qd);
        for v in self.qd.iter_mut() {
            if v.abs() < super::objective::ZERO_VELOCITY {
                *v = 0.0;
            }
        }
        regressor_rows(self.robot, &mut self.ws, q, &self.qd, qdd, &mut self.y);
        for r in 0..n {
            for (j, &col) in self.base.independent.iter().enumerate() {
                let c = self.y[r * p + col];
                self.abs_sum[j] += w * c.abs();
                self.rows.push(root * (c / self.noise[r]));
            }
        }
        self.samples += times;
        if self.rows.len() >= ASSESS_BLOCK * self.base.n_base() {
            self.flush();
        }
    }

    /// R ← triangular factor of [R; pending rows].
    fn flush(&mut self) {
        let m = self.base.n_base();
        let nr = self.rows.len() / m;
        if nr == 0 {
            return;
        }
        let prev = self.r.as_ref().map(|r| r.nrows()).unwrap_or(0);
        let mut a = faer::Mat::<f64>::zeros(prev + nr, m);
        if let Some(r) = &self.r {
            a.submatrix_mut(0, 0, prev, m).copy_from(crate::linalg::to_faer(r));
        }
        for i in 0..nr {
            for j in 0..m {
                a[(prev + i, j)] = self.rows[i * m + j];
            }
        }
        self.rows.clear();
        let r = if prev + nr >= m {
            crate::linalg::qr_r(a)
        } else {
            DMatrix::from_fn(prev + nr, m, |i, j| a[(i, j)])
        };
        self.r = Some(r);
    }

    fn finish(mut self) -> Result<Identifiability> {
        let n = self.robot.dof();
        let m = self.base.n_base();
        let ns = self.samples;
        if ns * n < m {
            return Err(Error::invalid(
                "assess",
                "states",
                format!("{ns} samples × {n} joints cannot determine {m} base parameters"),
            ));
        }
        self.flush();
        let cw = self.r.take().unwrap_or_else(|| DMatrix::zeros(m, m));
        let sensitivity: Vec<f64> = self.abs_sum.iter().map(|s| s / (ns * n) as f64).collect();
        identifiability_from_factor(self.robot, self.base, &self.noise, cw, sensitivity, ns)
    }
}

/// The report from a matrix with the weighted base regressor's singular
/// values, right singular vectors and column norms (its QR factor R).
fn identifiability_from_factor(robot: &Robot, base: &BaseParams, noise: &[f64], cw: DMatrix<f64>, sensitivity: Vec<f64>, ns: usize) -> Result<Identifiability> {
    let n = robot.dof();
    let m = base.n_base();
    let norms: Vec<f64> = (0..m).map(|j| cw.column(j).norm()).collect();
    let maxn = norms.iter().cloned().fold(0.0, f64::max);
    let mut cn = cw.clone();
    for (j, f) in unit_scale(&norms).into_iter().enumerate() {
        cn.column_mut(j).scale_mut(f);
    }
    let (_, s, v) = crate::linalg::thin_svd(&cn)?;
    let s1 = s[0];
    let rank = s.iter().filter(|&&x| x > RANK_TOL * s1).count();
    let cond = if rank < m { f64::INFINITY } else { s1 / s[m - 1] };
    let theta = robot.nominal_params();
    let nominal: Vec<f64> = base.base_values(theta.as_slice()).iter().copied().collect();
    let mut unexcited_idx = Vec::new();
    for i in 0..m {
        let zero = norms[i] <= 1e-14 * maxn.max(1e-300);
        let null = (rank..m).any(|k| v[(i, k)].abs() > 0.1);
        if zero || null {
            unexcited_idx.push(i);
        }
    }
    let unexcited: Vec<String> = unexcited_idx.iter().map(|&i| base.names[i].clone()).collect();
    // standard deviations: of the full model when C has full rank, else of the
    // model with the non-excited parameters removed (they stay at ∞)
    let mut std_dev = vec![f64::INFINITY; m];
    let keep: Vec<usize> = (0..m).filter(|i| !unexcited_idx.contains(i)).collect();
    let mut cond_excited = cond;
    if rank == m {
        for i in 0..m {
            let d = 1.0 / norms[i];
            let var: f64 = (0..m).map(|k| (v[(i, k)] / s[k]).powi(2)).sum();
            std_dev[i] = d * var.sqrt();
        }
    } else if !keep.is_empty() {
        let sub = DMatrix::from_fn(cn.nrows(), keep.len(), |r, c| cn[(r, keep[c])]);
        let (_, s2, v2) = crate::linalg::thin_svd(&sub)?;
        let k = keep.len();
        cond_excited = if s2[k - 1] > RANK_TOL * s2[0] { s2[0] / s2[k - 1] } else { f64::INFINITY };
        if s2[k - 1] > RANK_TOL * s2[0] {
            for (a, &i) in keep.iter().enumerate() {
                let var: f64 = (0..k).map(|c| (v2[(a, c)] / s2[c]).powi(2)).sum();
                std_dev[i] = var.sqrt() / norms[i];
            }
        }
    }
    let rel_std_dev: Vec<f64> = (0..m)
        .map(|i| {
            if nominal[i].abs() > 0.0 {
                std_dev[i] / nominal[i].abs()
            } else {
                f64::INFINITY
            }
        })
        .collect();
    let poorly_identifiable = (0..m)
        .filter(|&i| !unexcited_idx.contains(&i) && (!std_dev[i].is_finite() || (nominal[i] != 0.0 && rel_std_dev[i] > 1.0)))
        .map(|i| base.names[i].clone())
        .collect();
    Ok(Identifiability {
        samples: ns,
        rows: ns * n,
        names: base.names.clone(),
        groupings: base.groupings.clone(),
        parameters: column_parameters(robot, base),
        column_norms: norms,
        source: None,
        rank,
        cond,
        singular_values: s.iter().copied().collect(),
        cond_excited,
        sensitivity,
        nominal,
        std_dev,
        rel_std_dev,
        noise: noise.to_vec(),
        unexcited,
        poorly_identifiable,
    })
}

impl Identifiability {
    /// A short text summary.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let m = self.names.len();
        if let Some(src) = &self.source {
            let _ = writeln!(s, "samples used: {}", src.description);
        }
        let _ = writeln!(s, "samples: {} ({} rows), base parameters: {m}, rank: {}", self.samples, self.rows, self.rank);
        let _ = writeln!(
            s,
            "base columns (the regressor column of each of these standard parameters; groupings in report.json): {}",
            self.parameters.join(" ")
        );
        let _ = writeln!(
            s,
            "matrix: C_w = rows of joint j divided by its torque noise σ_j, then every column divided by its norm over these \
             samples (norms: column_norms in report.json); |q̇_j| < {:e} counts as 0 (Coulomb column sign(q̇_j), viscous q̇_j)",
            super::objective::ZERO_VELOCITY
        );
        let _ = writeln!(s, "condition number (unit columns): {}", fmt_num(self.cond));
        let _ = writeln!(
            s,
            "singular values: {} … {}",
            fmt_num(self.singular_values[0]),
            fmt_num(*self.singular_values.last().unwrap_or(&0.0))
        );
        let _ = writeln!(s, "torque noise per joint (N·m): {:?}", self.noise);
        if self.unexcited.is_empty() {
            let _ = writeln!(s, "every base parameter is excited");
        } else {
            let _ = writeln!(s, "NOT excited ({}): {}", self.unexcited.len(), self.unexcited.join(" "));
            let _ = writeln!(s, "condition number without them: {}", fmt_num(self.cond_excited));
        }
        if !self.poorly_identifiable.is_empty() {
            let _ = writeln!(
                s,
                "relative std dev > 100 % ({}): {}",
                self.poorly_identifiable.len(),
                self.poorly_identifiable.join(" ")
            );
        }
        let _ = writeln!(s, "\n  #  parameter        nominal      sensitivity c̄   std dev σ     rel. σ*");
        for i in 0..m {
            let _ = writeln!(
                s,
                "{:>3}  {:<14} {:>12} {:>14} {:>13} {:>10}",
                i + 1,
                self.names[i],
                fmt_num(self.nominal[i]),
                fmt_num(self.sensitivity[i]),
                fmt_num(self.std_dev[i]),
                if self.rel_std_dev[i].is_finite() {
                    format!("{:.2} %", 100.0 * self.rel_std_dev[i])
                } else {
                    "∞".into()
                }
            );
        }
        s
    }

    /// Writes report.json, report.txt and singular_values.svg into `dir`.
    pub fn write(&self, dir: &Path, title: &str) -> Result<()> {
        crate::io::write_json(&dir.join("report.json"), self)?;
        crate::io::write_atomic(&dir.join("report.txt"), format!("{title}\n\n{}", self.text()).as_bytes())?;
        spectrum_svg(&dir.join("singular_values.svg"), &self.singular_values, title)
    }
}

fn fmt_list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}

fn fmt_num(v: f64) -> String {
    if !v.is_finite() {
        return if v > 0.0 { "∞".into() } else { format!("{v}") };
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        format!("{v:.4}")
    }
}

fn spectrum_svg(path: &Path, s: &[f64], title: &str) -> Result<()> {
    let x: Vec<f64> = (1..=s.len()).map(|i| i as f64).collect();
    let panel = Panel {
        title: "singular values of the unit-column regressor".into(),
        x_label: "index".into(),
        y_label: "σ".into(),
        series: vec![Series::bars("σ_i", x, s.to_vec())],
        log_y: true,
        ..Default::default()
    };
    write_svg(path, title, &[panel], 1)
}

/// Everything `idexp excite` writes, in one JSON document (report.json).
#[derive(Debug, Serialize)]
struct ExciteReport<'a> {
    design: &'a super::design::ExciteDesign,
    robot: &'a str,
    result: &'a ExciteResult,
    identifiability: &'a Identifiability,
    delivered_identifiability: &'a Identifiability,
    /// The criterion's samples read from trajectory.csv (segment 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    period_identifiability: Option<&'a Identifiability>,
    criterion_samples: &'a SampleSet,
    verification_rate: f64,
    applied_limits: &'a [super::limits::AppliedLimit],
}

/// What [`write_outputs`] computed for the reports.
#[derive(Debug, Clone)]
pub struct Written {
    /// Identifiability on the criterion's samples (criterion_samples.csv).
    pub identifiability: Identifiability,
    /// Identifiability of the delivered trajectory (every row of trajectory.csv).
    pub delivered: Identifiability,
    /// The contents of criterion.json.
    pub record: CriterionRecord,
}

/// The samples of the criterion: one period on the design's grid, as a [`SampleSet`].
pub fn criterion_sample_set(p: &Problem) -> SampleSet {
    let d = &p.design;
    let ratio = d.trajectory.controller_rate / d.objective.sample_rate;
    let k = ratio.round();
    let note = if (ratio - k).abs() < 1e-9 && k >= 1.0 {
        format!(
            "one period of the periodic trajectory, t_i = i/{} s; the times of rows 0, {k}, {}, … of periodic.csv",
            d.objective.sample_rate,
            2.0 * k
        )
    } else {
        format!("one period of the periodic trajectory, t_i = i/{} s", d.objective.sample_rate)
    };
    SampleSet::new("criterion_samples.csv", 1, Some(&p.objective.times), &note)
}

/// The samples of the delivered trajectory as written to trajectory.csv, as a [`SampleSet`].
fn delivered_sample_set(t: &[f64], periods: usize) -> SampleSet {
    SampleSet::new(
        "trajectory.csv",
        1,
        Some(t),
        &format!("the delivered trajectory: lead-in, {periods} period(s), lead-out, rest to rest"),
    )
}

/// Writes the outputs of a design run into `dir`: coefficients.json,
/// trajectory.csv (the delivered trajectory, rest to rest, with a `segment`
/// column: 0 lead-in, k period k, −1 lead-out), periodic.csv (one period,
/// `t, q, qd, qdd`), criterion_samples.csv (the samples of the criterion:
/// one period on its grid, exactly as evaluated), criterion.json (the base
/// columns by name with their combinations, the weights, the column norms
/// and scaling, every reported condition number with the samples it is
/// computed from), report.json, report.txt, design.json, status.json and the
/// SVG plots (joints.svg, singular_values.svg, ee_path.svg).
pub fn write_outputs(p: &Problem, r: &ExciteResult, dir: &Path) -> Result<Written> {
    write_outputs_with(p, r, dir, |_| Ok(()))
}

/// [`write_outputs`], with `extra` writing further files into `dir` after
/// every other file and before the final `status.json` (the command line's
/// `preview.html`), so the folder is complete only with them.
pub fn write_outputs_with(p: &Problem, r: &ExciteResult, dir: &Path, extra: impl FnOnce(&Path) -> Result<()>) -> Result<Written> {
    let d = &p.design;
    crate::io::folder::begin(dir, "excite", &crate::io::status::fingerprint_of(d)?)?;
    let noise = d.objective.noise.clone().unwrap_or_else(|| vec![1.0; p.robot.dof()]);
    // the criterion's own samples (not a re-evaluation at other times)
    let grid = p.objective.record(&r.trajectory)?;
    let grid_set = criterion_sample_set(p);
    let mut ident = assess(&p.robot, &p.base, &grid.samples, &noise)?;
    ident.source = Some(grid_set.clone());
    let coeff = serde_json::json!({
        "design": d.name,
        "robot": d.robot.display().to_string(),
        "status": r.status,
        "criterion": d.objective.criterion,
        "criterion_value": r.criterion,
        "cond": r.spectrum.cond,
        "frequency_hz": d.trajectory.frequency,
        "harmonics": d.trajectory.harmonics,
        "at_rest": d.trajectory.at_rest,
        "layout": p.layout,
        "x": r.x,
        "trajectory": r.trajectory,
        "joint_names": p.robot.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
        "revolute": p.robot.joints.iter().map(|j| j.kind == crate::robot::JointKind::Revolute).collect::<Vec<_>>(),
        "controller_rate": d.trajectory.controller_rate,
        "delivered": r.execution.delivered,
        "safety": r.execution.safety,
    });
    crate::io::write_json(&dir.join("coefficients.json"), &coeff)?;
    // trajectory.csv: the delivered trajectory (lead-in, periods, lead-out)
    // with its segment column; periodic.csv: one period, the former layout
    let delivered = match &r.execution.delivered {
        Some(dl) => dl.clone(),
        None => crate::trajectory::lead::Delivered {
            home: r.trajectory.q0.clone(),
            lead_in: None,
            periodic: r.trajectory.clone(),
            periods: 1,
            lead_out: None,
        },
    };
    let ds = delivered.sample(d.trajectory.controller_rate)?;
    // the delivered trajectory's identifiability (every row) while its CSV
    // is written: the two longest steps of the writing, side by side
    let (written_csv, delivered_ident) = rayon::join(
        || -> Result<()> {
            ds.write_csv(&dir.join("trajectory.csv"))?;
            r.trajectory.sample(d.trajectory.controller_rate)?.write(&dir.join("periodic.csv"))?;
            grid.samples.write(&dir.join("criterion_samples.csv"))
        },
        || assess_delivered(&p.robot, &p.base, &ds, &noise),
    );
    written_csv?;
    let mut delivered_ident = delivered_ident?;
    let delivered_set = delivered_sample_set(&ds.t, delivered.periods);
    // the criterion's samples as rows of trajectory.csv: period 1 (segment 1,
    // which starts after the lead-in, not at t = 0), every k-th row, when the
    // criterion's rate divides the controller's
    let ratio = d.trajectory.controller_rate / d.objective.sample_rate;
    let period_ident = match ratio.round() as usize {
        k if k >= 1 && (ratio - k as f64).abs() < 1e-9 => 'period: {
            let rows: Vec<usize> = (0..ds.t.len()).filter(|&i| ds.segment[i] == 1).step_by(k).collect();
            if rows.is_empty() {
                break 'period None;
            }
            let states = crate::io::States {
                t: None,
                q: rows.iter().map(|&i| ds.q[i].clone()).collect(),
                qd: rows.iter().map(|&i| ds.qd[i].clone()).collect(),
                qdd: rows.iter().map(|&i| ds.qdd[i].clone()).collect(),
            };
            let t: Vec<f64> = rows.iter().map(|&i| ds.t[i]).collect();
            let mut set = SampleSet::new(
                "trajectory.csv",
                k,
                Some(&t),
                "segment 1 only: period 1 of the delivered trajectory, which starts after the lead-in (trajectory.csv's t = 0 is the start of the lead-in, not of a period); the criterion's samples",
            );
            set.segment = Some(1);
            let mut id = assess(&p.robot, &p.base, &states, &noise)?;
            id.source = Some(set);
            Some(id)
        }
        _ => None,
    };
    delivered_ident.source = Some(delivered_set.clone());
    let mut record = CriterionRecord::new(
        &p.robot,
        &d.robot.display().to_string(),
        &p.base,
        &noise,
        format!(
            "what every condition number of `idexp excite {}` is computed from: the matrix W½·C·D, C the stacked base \
             regressor (rows: samples × joints; columns: `columns`), W½ = diag(1/noise_j) per joint row, D = diag(scale)",
            d.name
        ),
    );
    record.figures = vec![
        Figure {
            label: "criterion value and condition number (report.txt `criterion value`, `condition number`; \
                    report.json result.criterion, result.spectrum)"
                .into(),
            samples: grid_set.clone(),
            scaling: d.objective.scaling,
            column_norms: grid.column_norms.clone(),
            scale: grid.scale.clone(),
            criterion: Some(d.objective.criterion),
            value: Some(r.criterion),
            cond: r.spectrum.cond,
            singular_values: r.spectrum.singular_values.clone(),
        },
        ident_figure(
            "identifiability on the design grid (report.txt `identifiability`; report.json identifiability)",
            grid_set.clone(),
            &ident,
        ),
        ident_figure(
            "identifiability of the delivered trajectory (report.txt `delivered trajectory`; report.json delivered_identifiability)",
            delivered_set,
            &delivered_ident,
        ),
    ];
    if let Some((id, set)) = period_ident.as_ref().and_then(|id| id.source.as_ref().map(|s| (id, s))) {
        record.figures.push(ident_figure(
            "the criterion's samples read from trajectory.csv (report.txt `the same samples in trajectory.csv`; \
             report.json period_identifiability): segment 1 (period 1), every k-th row",
            set.clone(),
            id,
        ));
    }
    crate::io::write_json(&dir.join("criterion.json"), &record)?;
    crate::io::write_json(&dir.join("design.json"), d)?;
    let summary = serde_json::json!({
        "design_status": r.status,
        "stopped_by": r.stopped_by,
        "violated": r.violated.iter().map(|m| format!("{}: {} {} beyond the limit", m.name, fmt_num(-m.margin), m.unit)).collect::<Vec<_>>(),
        "cond": r.spectrum.cond,
        "seconds": r.seconds,
        "execution_problem": r.execution.problem,
        "delivered_seconds": r.execution.delivered.as_ref().map(|dl| dl.duration()),
        "safe_to_play": r.execution.safety.safe,
    });
    let interrupted = r
        .stopped_by
        .as_ref()
        .is_some_and(|b| b.ga == Some(Termination::Interrupted) || b.refine == Some(Termination::Interrupted));
    let (state, detail) = match (r.status, interrupted) {
        (super::Status::Infeasible, _) => (
            RunState::Infeasible,
            match (&r.execution.problem, r.violated.len()) {
                _ if r.unexcited().is_some() => format!("infeasible: {}", r.unexcited().unwrap_or_default()),
                (Some(e), 0) => format!("infeasible: not playable rest to rest: {e}"),
                (_, k) => format!("infeasible: {k} constraint(s) violated"),
            },
        ),
        (super::Status::Feasible, true) => (RunState::Interrupted, "interrupted; the best feasible design so far".to_string()),
        (super::Status::Feasible, false) => (
            RunState::Complete,
            format!(
                "feasible, condition number {:.4}{}",
                r.spectrum.cond,
                if r.execution.safety.safe == Some(false) {
                    "; NOT safe to play (collides: see report.txt)"
                } else {
                    ""
                }
            ),
        ),
    };
    let started = std::time::SystemTime::now().checked_sub(std::time::Duration::from_secs_f64(r.seconds.max(0.0)));
    let robot_path = d.robot.display().to_string();
    crate::io::write_json(
        &dir.join("report.json"),
        &ExciteReport {
            design: d,
            robot: &robot_path,
            result: r,
            identifiability: &ident,
            delivered_identifiability: &delivered_ident,
            period_identifiability: period_ident.as_ref(),
            criterion_samples: &grid_set,
            verification_rate: d.limits.check_rate,
            applied_limits: &p.applied_limits,
        },
    )?;
    crate::io::write_atomic(
        &dir.join("report.txt"),
        excite_report_text(p, r, &ident, Some(&delivered_ident), period_ident.as_ref()).as_bytes(),
    )?;
    spectrum_svg(
        &dir.join("singular_values.svg"),
        &r.spectrum.singular_values,
        &format!("{}: singular values", d.name),
    )?;
    joints_svg(p, r, &dir.join("joints.svg"))?;
    ee_svg(p, r, &dir.join("ee_path.svg"))?;
    extra(dir)?;
    // the final status last: a folder without it is marked `running`
    crate::io::status::write_status(dir, "excite", state, detail, started, crate::io::status::fingerprint_of(d)?, summary)?;
    Ok(Written {
        identifiability: ident,
        delivered: delivered_ident,
        record,
    })
}

/// The unit-column figure of an identifiability report.
pub fn ident_figure(label: &str, samples: SampleSet, id: &Identifiability) -> Figure {
    Figure {
        label: label.into(),
        samples,
        scaling: Scaling::UnitColumn,
        column_norms: id.column_norms.clone(),
        scale: unit_scale(&id.column_norms),
        criterion: None,
        value: None,
        cond: id.cond,
        singular_values: id.singular_values.clone(),
    }
}

/// The unit-column factors of the identifiability report: 1/‖c_j‖, 0 for a
/// column below 10⁻¹⁴ of the largest norm (a zero column).
pub fn unit_scale(norms: &[f64]) -> Vec<f64> {
    let maxn = norms.iter().cloned().fold(0.0, f64::max);
    norms.iter().map(|&v| if v > 1e-14 * maxn.max(1e-300) { 1.0 / v } else { 0.0 }).collect()
}

/// The text summary of a design run (report.txt) without the delivered
/// trajectory's identifiability ([`excite_report_text`]).
pub fn excite_text(p: &Problem, r: &ExciteResult, ident: &Identifiability) -> String {
    excite_report_text(p, r, ident, None, None)
}

/// The text summary of a design run (report.txt): `ident` on the criterion's
/// samples, `delivered` on every row of the delivered trajectory.
/// `period`: the criterion's samples read from trajectory.csv (segment 1).
pub fn excite_report_text(
    p: &Problem,
    r: &ExciteResult,
    ident: &Identifiability,
    delivered: Option<&Identifiability>,
    period: Option<&Identifiability>,
) -> String {
    let d = &p.design;
    let mut s = String::new();
    let _ = writeln!(s, "excitation design `{}` for robot `{}` ({})", d.name, p.robot.name, d.robot.display());
    let _ = writeln!(
        s,
        "trajectory: {} harmonics of {} Hz (period {} s), {} design variables{}{}",
        d.trajectory.harmonics,
        d.trajectory.frequency,
        seconds_text(1.0 / d.trajectory.frequency),
        p.layout.n_vars(),
        if d.trajectory.vary_q0 { ", q0 free" } else { "" },
        if d.trajectory.at_rest { ", starts and ends at rest" } else { "" }
    );
    let grid_set = criterion_sample_set(p);
    let noise = d.objective.noise.clone().unwrap_or_else(|| vec![1.0; p.robot.dof()]);
    let _ = writeln!(
        s,
        "criterion: {} of W½·C·D, C the stacked base regressor ({} columns × {} rows)",
        match d.objective.criterion {
            super::Criterion::Cond => "condition number σ_max/σ_min",
            super::Criterion::LogDet => "−log det((W½CD)ᵀ(W½CD)) (D-optimality)",
            super::Criterion::InvSigmaMin => "1/σ_min (E-optimality)",
        },
        p.objective.n_cols(),
        p.objective.n_rows(),
    );
    let _ = writeln!(s, "  samples: {}", grid_set.description);
    let _ = writeln!(
        s,
        "  W½ = diag(1/σ_j) per joint row, σ = {:?} N·m{}",
        noise,
        if d.objective.noise.is_none() { " (objective.noise not given)" } else { "" }
    );
    let _ = writeln!(
        s,
        "  D: {}",
        match d.objective.scaling {
            super::Scaling::UnitColumn => "every column of W½C divided by its norm over these samples (norms in criterion.json)",
            super::Scaling::Nominal => "every column times the nominal value of its base parameter (floored at 10⁻³ of the largest; criterion.json)",
            super::Scaling::None => "none (D = I)",
        }
    );
    let _ = writeln!(
        s,
        "  columns: the regressor column of each of these standard parameters (base parameters and their groupings in \
         criterion.json; Coulomb column sign(q̇_j), 0 for |q̇_j| < {:e}; viscous q̇_j): {}",
        super::objective::ZERO_VELOCITY,
        column_parameters(&p.robot, &p.base).join(" ")
    );
    let _ = writeln!(
        s,
        "  to recompute: criterion.json (columns, weights, column norms, every figure below with its samples) and the sample files it names"
    );
    let _ = writeln!(s);
    let status = match r.status {
        Status::Feasible => "FEASIBLE".to_string(),
        Status::Infeasible => "INFEASIBLE".to_string(),
    };
    let _ = writeln!(
        s,
        "status: {status}{}",
        r.stopped_by.as_ref().map(|b| format!(" (stopped early: {b})")).unwrap_or_default()
    );
    if r.execution.delivered.is_some() && r.status == Status::Feasible {
        let _ = writeln!(s, "safety: {}", r.execution.safety.statement);
    }
    let _ = writeln!(s, "criterion value: {}", fmt_num(r.criterion));
    let _ = writeln!(s, "condition number: {} (on the criterion's samples above)", fmt_num(r.spectrum.cond));
    if let Some(pi) = period {
        if let Some(src) = &pi.source {
            let _ = writeln!(
                s,
                "  the same samples in trajectory.csv: segment 1, every {} row, t = {} s: condition number {} (unit columns; \
                 `idexp assess {} trajectory.csv --segment 1 --every {}`). trajectory.csv starts with the lead-in at t = 0: \
                 its first {} s are not a period",
                ordinal(src.every),
                src.t_range
                    .map_or("?".to_string(), |[a, b]| format!("{} … {}", seconds_text(a), seconds_text(b))),
                fmt_num(pi.cond),
                p.design.robot.display(),
                src.every,
                r.trajectory.period_text()
            );
        }
    }
    if let Some(dl) = delivered {
        let _ = writeln!(
            s,
            "condition number of the delivered trajectory: {} (same columns and weights, unit columns over {}; rank {}/{})",
            fmt_num(dl.cond),
            dl.source.as_ref().map_or("", |s| s.description.as_str()),
            dl.rank,
            dl.names.len()
        );
    }
    if !r.violated.is_empty() {
        let _ = writeln!(s, "\nviolated constraints (on the {} Hz verification grid), worst first:", d.limits.check_rate);
        for m in &r.violated {
            if is_distance(m) {
                let _ = writeln!(s, "  {}", distance_violation(m));
                continue;
            }
            let _ = writeln!(
                s,
                "  {}: reaches {} {} at t = {:.3} s, {} {} beyond the limit",
                m.name,
                fmt_num(m.worst),
                m.unit,
                m.at,
                fmt_num(-m.margin),
                m.unit
            );
        }
        let _ = writeln!(s, "  (no trajectory found by the search meets these; relax them or move q0 / the workspace)");
    }
    s.push_str(&collision_text(p, &r.margins, d.limits.check_rate));
    let _ = writeln!(s, "\ndelivered trajectory (what trajectory.csv and the exports hold):");
    match (&r.execution.delivered, &r.execution.problem) {
        (Some(dl), problem) => {
            let _ = writeln!(
                s,
                "  from home {} at rest: lead-in {:.2} s, {} period(s) of {} s, lead-out {:.2} s back to home at rest; total {:.2} s",
                fmt_list(&dl.home),
                dl.lead_in_duration(),
                dl.periods,
                dl.periodic.period_text(),
                dl.lead_out_duration(),
                dl.duration()
            );
            match problem {
                None => {
                    let _ = writeln!(
                        s,
                        "  every sample within every joint limit{} on the {} Hz grid",
                        if d.workspace.is_empty() { "" } else { " and workspace constraint" },
                        r.execution.check_rate
                    );
                }
                Some(e) => {
                    let _ = writeln!(s, "  NOT playable: {e}");
                }
            }
        }
        (None, Some(e)) => {
            let _ = writeln!(s, "  NOT playable: {e}");
        }
        (None, None) => {}
    }
    let _ = writeln!(s, "\nlimits applied (value imposed; source):");
    for a in &p.applied_limits {
        let v = if a.class == "position" {
            format!("[{}, {}]", fmt_num(a.imposed[0]), fmt_num(a.imposed[1]))
        } else {
            format!("±{}", fmt_num(a.imposed[1]))
        };
        let _ = writeln!(s, "  {:<22} {:<13} {:>24} {:<7} {}", a.joint, a.class, v, a.unit, a.source);
    }
    let _ = writeln!(s, "\nworst margin per constraint ({} Hz grid; ≥ 0 holds):", d.limits.check_rate);
    for m in &r.margins {
        let _ = writeln!(s, "  {:<60} margin {:>12} {}", m.name, fmt_num(m.margin), m.unit);
    }
    let _ = writeln!(
        s,
        "\nsolver: GA {} generations, {} evaluations, {:.2} s ({:?}); best GA criterion {}",
        r.ga.generations,
        r.ga.evaluations,
        r.ga.seconds,
        r.ga.stop,
        fmt_num(r.ga.best)
    );
    for (k, rf) in r.refinements.iter().enumerate() {
        let _ = writeln!(
            s,
            "  refine #{}: {} → {} in {} evaluations, {:.2} s, {}{}",
            k + 1,
            fmt_num(rf.start),
            fmt_num(rf.end),
            rf.evaluations,
            rf.seconds,
            rf.status,
            if rf.violation > 0.0 {
                format!(", violation {:.2e}", rf.violation)
            } else {
                String::new()
            }
        );
    }
    let _ = writeln!(s, "chosen: {}; total {:.2} s on {} threads", r.chosen, r.seconds, r.threads);
    let _ = writeln!(
        s,
        "\nidentifiability (on the criterion's samples, unit columns whatever the criterion's scaling; predicted for the stated torque noise):"
    );
    s.push_str(&ident.text());
    s
}

/// The trajectory the plots show: the delivered one (lead-in, periods,
/// lead-out) when there is one, else one period. Samples at `rate` Hz with
/// their phase names; each phase as its own run of samples, the first sample
/// of the next phase repeated at its end so that the curve is continuous.
struct PlotPhases {
    names: Vec<String>,
    t: Vec<Vec<f64>>,
    q: Vec<Vec<Vec<f64>>>,
    qd: Vec<Vec<Vec<f64>>>,
}

fn plot_phases(r: &ExciteResult, rate: f64) -> Result<PlotPhases> {
    let mut out = PlotPhases {
        names: Vec::new(),
        t: Vec::new(),
        q: Vec::new(),
        qd: Vec::new(),
    };
    match &r.execution.delivered {
        Some(d) => {
            let s = d.sample(rate)?;
            let mut k = 0;
            while k < s.len() {
                let seg = s.segment[k];
                let mut e = k;
                while e < s.len() && s.segment[e] == seg {
                    e += 1;
                }
                let last = e.min(s.len() - 1);
                out.names.push(match seg {
                    0 => "lead-in".to_string(),
                    -1 => "lead-out".to_string(),
                    p => format!("period {p}"),
                });
                out.t.push(s.t[k..=last].to_vec());
                out.q.push(s.q[k..=last].to_vec());
                out.qd.push(s.qd[k..=last].to_vec());
                k = e;
            }
        }
        None => {
            let s = r.trajectory.sample(rate)?;
            out.names.push("one period (no delivered trajectory)".into());
            out.t.push(s.t.clone().unwrap_or_default());
            out.q.push(s.q.clone());
            out.qd.push(s.qd.clone());
        }
    }
    Ok(out)
}

fn joints_svg(p: &Problem, r: &ExciteResult, path: &Path) -> Result<()> {
    let n = p.robot.dof();
    let rate = (400.0 * p.design.trajectory.frequency).max(50.0 * p.design.trajectory.frequency * p.design.trajectory.harmonics as f64);
    let ph = plot_phases(r, rate)?;
    let unit = |j: usize, d: &str| -> String {
        let lin = p.robot.joints[j].kind == crate::robot::JointKind::Prismatic;
        format!("{}{d}", if lin { "m" } else { "rad" })
    };
    // one legend (first panel) names the phases; the colours repeat in every panel
    let series = |j: usize, first: bool, get: &dyn Fn(usize, usize) -> Vec<f64>| -> Vec<Series> {
        (0..ph.names.len())
            .map(|k| Series::line(if first { ph.names[k].clone() } else { String::new() }, ph.t[k].clone(), get(k, j)))
            .collect()
    };
    let mut panels = Vec::new();
    for j in 0..n {
        let name = &p.robot.joints[j].name;
        let mut hl = Vec::new();
        let [lo, hi] = p.limits.position[j];
        // one legend in all (first panel): the phases and the limit lines
        let lim = if j == 0 { "limit".to_string() } else { String::new() };
        if lo.is_finite() {
            hl.push((lo, lim.clone()));
        }
        if hi.is_finite() {
            hl.push((hi, if lo.is_finite() { String::new() } else { lim.clone() }));
        }
        panels.push(Panel {
            title: format!("q{} ({name})", j + 1),
            x_label: "t (s)".into(),
            y_label: unit(j, ""),
            series: series(j, j == 0, &|k, j| ph.q[k].iter().map(|v| v[j]).collect()),
            hlines: hl,
            ..Default::default()
        });
        let mut hv = Vec::new();
        let v = p.limits.velocity[j];
        if v.is_finite() {
            hv.push((v, String::new()));
            hv.push((-v, String::new()));
        }
        panels.push(Panel {
            title: format!("qd{} ({name})", j + 1),
            x_label: "t (s)".into(),
            y_label: unit(j, "/s"),
            series: series(j, false, &|k, j| ph.qd[k].iter().map(|v| v[j]).collect()),
            hlines: hv,
            ..Default::default()
        });
    }
    let what = if r.execution.delivered.is_some() {
        "delivered joint trajectory (lead-in, periods, lead-out), limits dashed red"
    } else {
        "joint trajectory (one period), limits dashed red"
    };
    write_svg(path, &format!("{}: {what}", p.design.name), &panels, 2)
}

fn ee_svg(p: &Problem, r: &ExciteResult, path: &Path) -> Result<()> {
    let frame = match p.design.workspace.first() {
        Some(c) => c.resolve(&p.robot, "design", "workspace[0]")?,
        None => p.robot.end_effector(),
    };
    let mut ph = plot_phases(r, (200.0 * p.design.trajectory.frequency).max(20.0))?;
    // the periods trace the same closed path: one series for all of them
    let periods: Vec<usize> = (0..ph.names.len()).filter(|&k| ph.names[k].starts_with("period ")).collect();
    if periods.len() > 1 {
        let (k0, n) = (periods[0], periods.len());
        ph.names[k0] = format!("periods 1–{n} (one closed path)");
        for &k in periods[1..].iter().rev() {
            ph.names.remove(k);
            ph.t.remove(k);
            ph.q.remove(k);
            ph.qd.remove(k);
        }
    }
    let mut ws = Workspace::new(&p.robot);
    let paths: Vec<Vec<[f64; 3]>> =
        ph.q.iter()
            .map(|qs| {
                qs.iter()
                    .map(|q| {
                        let v = super::constraints::frame_point(&p.robot, &mut ws, q, &frame);
                        [v.x, v.y, v.z]
                    })
                    .collect()
            })
            .collect();
    let all: Vec<[f64; 3]> = paths.iter().flatten().copied().collect();
    let ax = ["x", "y", "z"];
    let mut panels = Vec::new();
    for (pi, (a, b)) in [(0usize, 1usize), (0, 2), (1, 2)].into_iter().enumerate() {
        let mut series: Vec<Series> = paths
            .iter()
            .enumerate()
            .map(|(k, pts)| {
                Series::line(
                    if pi == 0 { ph.names[k].clone() } else { String::new() },
                    pts.iter().map(|v| v[a]).collect(),
                    pts.iter().map(|v| v[b]).collect(),
                )
            })
            .collect();
        let (lo, hi) = bounds(&all);
        for (ci, c) in p.design.workspace.iter().enumerate() {
            for (k, (xs, ys)) in outline(&c.shape, a, b, lo, hi).into_iter().enumerate() {
                series.push(Series::line(if k == 0 { format!("constraint {}", ci + 1) } else { String::new() }, xs, ys));
            }
        }
        panels.push(Panel {
            title: format!("{}–{} projection", ax[a], ax[b]),
            x_label: format!("{} (m)", ax[a]),
            y_label: format!("{} (m)", ax[b]),
            series,
            ..Default::default()
        });
    }
    write_svg(
        path,
        &format!(
            "{}: {} path (delivered trajectory by phase) and workspace constraints",
            p.design.name, frame.name
        ),
        &panels,
        3,
    )
}

fn bounds(pts: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pts {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    for i in 0..3 {
        let pad = 0.2 * (hi[i] - lo[i]).max(0.1);
        lo[i] -= pad;
        hi[i] += pad;
    }
    (lo, hi)
}

/// Outline(s) of a shape projected on axes (a, b), as polylines.
fn outline(shape: &crate::robot::cartesian::Shape, a: usize, b: usize, lo: [f64; 3], hi: [f64; 3]) -> Vec<(Vec<f64>, Vec<f64>)> {
    use crate::robot::cartesian::Shape;
    let rect = |mn: [f64; 3], mx: [f64; 3]| (vec![mn[a], mx[a], mx[a], mn[a], mn[a]], vec![mn[b], mn[b], mx[b], mx[b], mn[b]]);
    match shape {
        Shape::Box { min, max } => vec![rect(*min, *max)],
        Shape::OutsideBox { min, max, clearance } => {
            let mn = [min[0] - clearance, min[1] - clearance, min[2] - clearance];
            let mx = [max[0] + clearance, max[1] + clearance, max[2] + clearance];
            vec![rect(mn, mx)]
        }
        Shape::Sphere { center, radius } => {
            let k = 72;
            let th: Vec<f64> = (0..=k).map(|i| std::f64::consts::TAU * i as f64 / k as f64).collect();
            vec![(
                th.iter().map(|t| center[a] + radius * t.cos()).collect(),
                th.iter().map(|t| center[b] + radius * t.sin()).collect(),
            )]
        }
        Shape::HalfSpace { normal, offset } => {
            let nn = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
            let nv = [normal[0] / nn, normal[1] / nn, normal[2] / nn];
            let third = 3 - a - b;
            if nv[third].abs() > 1e-9 {
                return vec![];
            }
            // n_a x + n_b y = offset
            if nv[b].abs() > 1e-9 {
                let xs = vec![lo[a], hi[a]];
                let ys = xs.iter().map(|x| (offset - nv[a] * x) / nv[b]).collect();
                vec![(xs, ys)]
            } else {
                let x = offset / nv[a];
                vec![(vec![x, x], vec![lo[b], hi[b]])]
            }
        }
        Shape::Sector { center, azimuth, radius, z } => {
            if (a, b) == (0, 1) {
                let k = 48;
                let arc = |r: f64| -> (Vec<f64>, Vec<f64>) {
                    let ph: Vec<f64> = (0..=k).map(|i| azimuth[0] + (azimuth[1] - azimuth[0]) * i as f64 / k as f64).collect();
                    (
                        ph.iter().map(|p| center[0] + r * p.cos()).collect(),
                        ph.iter().map(|p| center[1] + r * p.sin()).collect(),
                    )
                };
                let ray = |p: f64| {
                    (
                        vec![center[0] + radius[0] * p.cos(), center[0] + radius[1] * p.cos()],
                        vec![center[1] + radius[0] * p.sin(), center[1] + radius[1] * p.sin()],
                    )
                };
                vec![arc(radius[0]), arc(radius[1]), ray(azimuth[0]), ray(azimuth[1])]
            } else {
                let zz = [center[2] + z[0], center[2] + z[1]];
                zz.iter().map(|&h| (vec![lo[a], hi[a]], vec![h, h])).collect()
            }
        }
    }
}

/// Reads a trajectory CSV (`t, q, qd, qdd`) for `idexp assess`, optionally
/// keeping every `every`-th row.
pub fn read_states(path: &Path, n: usize, every: usize) -> Result<States> {
    let s = States::read(path, n)?;
    if s.is_empty() {
        return Err(Error::Data {
            path: path.to_path_buf(),
            row: 0,
            column: "q1".into(),
            msg: "the file has no data rows".into(),
        });
    }
    if every <= 1 {
        return Ok(s);
    }
    let keep = |v: &Vec<Vec<f64>>| v.iter().step_by(every).cloned().collect::<Vec<_>>();
    Ok(States {
        t: s.t.as_ref().map(|t| t.iter().step_by(every).copied().collect()),
        q: keep(&s.q),
        qd: keep(&s.qd),
        qdd: keep(&s.qdd),
    })
}

/// The margins that are violated, as readable lines.
pub fn violation_lines(m: &[Margin]) -> Vec<String> {
    m.iter()
        .filter(|m| m.margin < 0.0)
        .map(|m| {
            if is_distance(m) {
                distance_violation(m)
            } else {
                format!("{}: {} {} beyond the limit", m.name, fmt_num(-m.margin), m.unit)
            }
        })
        .collect()
}

fn is_distance(m: &Margin) -> bool {
    matches!(m.kind, ConstraintKind::SelfCollision | ConstraintKind::WorldCollision)
}

/// `collision self: forearm_link – wrist_2_link at t = 3.141 s: distance −0.0130 m
/// (penetration 0.0130 m), 0.0330 m inside the 0.02 m margin`.
fn distance_violation(m: &Margin) -> String {
    let pair = m.name.trim_start_matches("distance ").split(" ≥ ").next().unwrap_or(&m.name);
    let pen = if m.worst < 0.0 {
        format!("penetration depth {:.4} m", -m.worst)
    } else {
        "no contact".to_string()
    };
    format!(
        "collision {pair} at t = {:.3} s: distance {:.4} m ({pen}), {:.4} m inside the {} m margin",
        m.at, m.worst, -m.margin, m.limit
    )
}

/// The collision lines of the report: geometry, checked and excluded pairs,
/// the worst distance per class on the verification grid.
pub fn collision_text(p: &Problem, margins: &[Margin], rate: f64) -> String {
    let mut s = String::new();
    let Some(sc) = p.constraints.scene() else {
        let why = if !p.design.collision.enabled {
            "off ([collision] enabled = false)"
        } else {
            "nothing to check (the robot file gives no collision geometry)"
        };
        let _ = writeln!(s, "\ncollision: {why}");
        return s;
    };
    let n_self = sc.pairs.iter().filter(|q| q.class == crate::robot::collision::PairClass::SelfCollision).count();
    let _ = writeln!(
        s,
        "\ncollision: margin {} m for {} pairs ({} self, {} world: {}); {} pairs not checked",
        sc.margin,
        sc.len(),
        n_self,
        sc.len() - n_self,
        {
            let mut w: Vec<&str> = sc
                .pairs
                .iter()
                .filter(|q| q.class == crate::robot::collision::PairClass::World)
                .map(|q| q.b.as_str())
                .collect();
            w.dedup();
            if w.is_empty() {
                "none".to_string()
            } else {
                w.join(", ")
            }
        },
        sc.excluded.len()
    );
    for e in &sc.excluded {
        let _ = writeln!(s, "  not checked: {} – {}: {}", e.a, e.b, e.reason);
    }
    let padded: Vec<String> = sc
        .bodies()
        .iter()
        .filter(|b| b.padding() > 0.0)
        .map(|b| format!("{} {:.1} mm", b.name, b.padding() * 1e3))
        .collect();
    if padded.is_empty() {
        let _ = writeln!(
            s,
            "  distances between convex parts (primitives, convex hulls of the meshes): a hull holds its mesh, so the \
             mesh distance is at least the one reported (replay on the full meshes: scripts/safety-replay.py)"
        );
    } else {
        let _ = writeln!(
            s,
            "  distances between convex parts (primitives, convex hulls of the collision meshes) grown by the robot \
             file's collision_padding ({}), which holds the vendor's full visual meshes: the distance of the full meshes \
             is at least the one reported (replay: scripts/safety-replay.py --meshes visual)",
            padded.join(", ")
        );
    }
    for (kind, label) in [(ConstraintKind::SelfCollision, "self"), (ConstraintKind::WorldCollision, "world")] {
        if let Some(w) = margins.iter().filter(|m| m.kind == kind).min_by(|a, b| a.worst.total_cmp(&b.worst)) {
            let pair = w.name.trim_start_matches("distance ").split(" ≥ ").next().unwrap_or(&w.name);
            let _ = writeln!(
                s,
                "  worst {label} distance on the {rate} Hz grid: {:.4} m ({pair}, t = {:.3} s){}",
                w.worst,
                w.at,
                if w.margin < 0.0 { " — VIOLATES the margin" } else { "" }
            );
        }
    }
    s
}
