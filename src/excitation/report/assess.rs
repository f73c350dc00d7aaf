//! The identifiability computation: the weighted base regressor of a sample
//! set accumulated as its QR factor, its spectrum, rank, sensitivities and
//! predicted standard deviations; the states readers of `idexp assess`.

use super::outputs::{unit_scale, SampleSet};
use crate::error::{Error, Result};
use crate::io::States;
use crate::params::BaseParams;
use crate::robot::{regressor_rows, Robot, Workspace};
use crate::trajectory::lead::DeliveredSamples;
use nalgebra::DMatrix;
use serde::Serialize;
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

/// Running statistics of sample times read block by block: first, last and
/// the extreme spacings (a uniform rate when they agree to 10⁻⁶).
#[derive(Debug, Clone, Default)]
pub(super) struct TimeStats {
    pub(super) count: usize,
    first: f64,
    last: f64,
    min_dt: f64,
    max_dt: f64,
}

impl TimeStats {
    pub(super) fn add(&mut self, t: f64) {
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

    pub(super) fn range(&self) -> Option<[f64; 2]> {
        (self.count > 0).then_some([self.first, self.last])
    }

    pub(super) fn rate(&self) -> Option<f64> {
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
            if v.abs() < crate::excitation::objective::ZERO_VELOCITY {
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
