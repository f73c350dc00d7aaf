//! Several experiments in one weighted least-squares problem.
//!
//! Each experiment e contributes the rows of its base regressor (joint-major:
//! the rows of joint j are one block b = (e, j)). The rows are weighted by the
//! inverse variance of their torque:
//!
//! * **from repetitions** (an experiment of N_r ≥ 2 repetitions, or an
//!   averaged run with variance columns): the sample variances of eq. 7
//!   divided by N_r (`sample`), or their per-joint means (`joint`), as the
//!   one-run WLS of paper 000; by default per sample from
//!   [`SAMPLE_WEIGHTS_FROM`] repetitions on, per joint below;
//! * **from the residuals** (every other experiment, or all of them with
//!   `weights = "residuals"`): one variance σ²_b per experiment and joint,
//!   estimated iteratively — start from unit variances, estimate θ, set
//!   σ²_b = ‖y_b − C_b θ‖² / (n_b − k n_b / N) (the block's share of the
//!   degrees of freedom), re-estimate, until the variances change by less than
//!   `tol` (relative) — Gautier's per-joint weighting extended to
//!   experiments: a quiet experiment is not drowned by a noisy one, and the
//!   joints of one experiment are weighed by their own noise.
//!
//! Because a residual weight is constant over a block, every block is reduced
//! once to the triangular factor R_b of its (sample-weighted) rows [C_b | y_b]
//! ([`r_factor`]); an iteration then works on the stacked, reweighted k + 1
//! column factors only (‖y_b − C_b θ‖² = ‖R_b [θ; −1]‖²), never on the rows.
//!
//! The estimate's covariance is (CᵀWC)⁻¹ with the final weights (paper 000
//! eq. 13). Each experiment's share of the information is
//! tr((CᵀWC)⁻¹ F_e)/k with F_e = C_eᵀW_eC_e: the shares sum to one over the
//! experiments (and per parameter, the diagonal of (CᵀWC)⁻¹F_e does).

use crate::error::{Error, Result};
use crate::ident::estimate::{r_factor, row_variances, solve_factor, Dataset, Weights};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where the rows' weights come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum WeightSource {
    /// Repetitions where an experiment has them, residuals elsewhere.
    #[default]
    Auto,
    /// Repetitions for every experiment (an error names an experiment without).
    Repetitions,
    /// Residuals (per experiment and joint) for every experiment.
    Residuals,
}

/// Options of [`estimate`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StackOptions {
    /// Where the weights come from.
    pub weights: WeightSource,
    /// Per-sample or per-joint variances for experiments with repetitions;
    /// None: per sample from [`SAMPLE_WEIGHTS_FROM`] repetitions on, per joint below.
    pub repetition_weights: Option<Weights>,
    /// Ordinary least squares (unit weights, no iteration) instead.
    pub ols: bool,
    /// Largest number of reweighting iterations.
    pub max_iterations: usize,
    /// Relative change of every block variance below which the iteration stops.
    pub tol: f64,
}

impl Default for StackOptions {
    fn default() -> Self {
        StackOptions {
            weights: WeightSource::Auto,
            repetition_weights: None,
            ols: false,
            max_iterations: 50,
            tol: 1e-6,
        }
    }
}

/// One experiment's rows for [`estimate`].
#[derive(Debug, Clone, Copy)]
pub struct Rows<'a> {
    /// Name (for messages).
    pub name: &'a str,
    /// The rows used for the estimate (every base column).
    pub data: &'a Dataset,
    /// Repetitions N_r behind the rows.
    pub n_reps: usize,
}

/// Repetitions from which `repetition_weights` = auto weighs every sample by
/// its own variance: below, the sample variance of one time step is too noisy
/// to weigh its row (for N_r ≤ 3 the inverse of a sample variance has no
/// finite mean), so the joint's mean variance is used.
pub const SAMPLE_WEIGHTS_FROM: usize = 10;

/// How the rows of one block were weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockWeight {
    /// Per-sample variances from the repetitions (eq. 7).
    Sample,
    /// The joint's mean sample variance from the repetitions.
    Joint,
    /// The block's residual variance (iterated).
    Residual,
    /// Unit weight (ordinary least squares).
    Unit,
    /// The joint has no rows in the experiment (every row left out by the standstill rule).
    NoRows,
}

/// One block (experiment e, joint j) of the stacked problem.
#[derive(Debug, Clone, Serialize)]
pub struct Block {
    /// Experiment index.
    pub experiment: usize,
    /// Joint (0-based).
    pub joint: usize,
    /// Rows.
    pub rows: usize,
    /// How its rows are weighted.
    pub weight: BlockWeight,
    /// The torque noise σ the weights stand for (N·m): the residual σ_b, or
    /// the RMS of the rows' σ for repetition weights.
    pub sigma: f64,
    /// Weighted residual sum of squares of the block at the estimate.
    pub chi2: f64,
}

/// The stacked estimate.
#[derive(Debug, Clone)]
pub struct Stacked {
    /// θ̂ (every base column).
    pub theta: DVector<f64>,
    /// Covariance (CᵀWC)⁻¹.
    pub cov: DMatrix<f64>,
    /// Rank of the weighted design.
    pub rank: usize,
    /// Condition number of the weighted design √W C.
    pub cond: f64,
    /// The same with unit-norm columns.
    pub cond_normalized: f64,
    /// Weighted residual sum of squares per degree of freedom.
    pub chi2_dof: f64,
    /// The blocks, experiment by experiment, joint by joint.
    pub blocks: Vec<Block>,
    /// Reweighting iterations done (0 without residual weights).
    pub iterations: usize,
    /// True when the reweighting converged within `tol` (or had nothing to iterate).
    pub converged: bool,
    /// Per experiment, the information share per parameter (diagonal of (CᵀWC)⁻¹F_e).
    pub share: Vec<Vec<f64>>,
    /// Per experiment, (rank, condition number) of its own weighted design.
    pub alone: Vec<(usize, f64)>,
    /// The triangular factor R (k × k) of the weighted design √W C.
    pub r: DMatrix<f64>,
    /// Per row of every experiment (in order), 1/σ of the row at the final weights.
    pub row_weights: Vec<DVector<f64>>,
}

/// A block's rows: contiguous in a joint-major dataset.
fn block_ranges(ds: &Dataset) -> Vec<(usize, usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=ds.joint.len() {
        if i == ds.joint.len() || ds.joint[i] != ds.joint[start] {
            out.push((ds.joint[start], start, i));
            start = i;
        }
    }
    out
}

/// Singular values (decreasing) of a small matrix.
fn singular(m: &DMatrix<f64>) -> Vec<f64> {
    let mut s: Vec<f64> = m.singular_values().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    s
}

/// (condition number, with unit-norm columns) of the design whose triangular factor is `r`.
fn conds(r: &DMatrix<f64>, k: usize) -> (f64, f64) {
    let c = |m: &DMatrix<f64>| {
        let s = singular(m);
        if s.len() < k || s[s.len() - 1] <= 0.0 {
            f64::INFINITY
        } else {
            s[0] / s[s.len() - 1]
        }
    };
    let mut rn = r.clone();
    for mut col in rn.column_iter_mut() {
        let nrm = col.norm();
        if nrm > 0.0 {
            col /= nrm;
        }
    }
    (c(r), c(&rn))
}

/// Stacks blocks' factors scaled by `omega` and re-factorises.
fn stack(factors: &[DMatrix<f64>], omega: &[f64], cols: usize) -> DMatrix<f64> {
    let rows: usize = factors.iter().map(|f| f.nrows()).sum();
    let mut st = DMatrix::zeros(rows, cols);
    let mut r0 = 0;
    for (f, w) in factors.iter().zip(omega) {
        st.rows_mut(r0, f.nrows()).copy_from(&(f * *w));
        r0 += f.nrows();
    }
    r_factor(&st)
}

/// Estimates the base parameters from several experiments' rows (see the
/// module documentation).
pub fn estimate(exps: &[Rows<'_>], o: &StackOptions) -> Result<Stacked> {
    let Some(first) = exps.first() else {
        return Err(Error::invalid("study", "experiment", "expected at least one experiment"));
    };
    let k = first.data.c.ncols();
    if let Some(e) = exps.iter().find(|e| e.data.c.ncols() != k) {
        return Err(Error::dim(format!("base columns of experiment `{}`", e.name), k, e.data.c.ncols()));
    }
    if !(o.tol.is_finite() && o.tol > 0.0) {
        return Err(Error::invalid("study", "irls_tol", format!("expected a positive tolerance, found {}", o.tol)));
    }
    let total: usize = exps.iter().map(|e| e.data.y.len()).sum();
    if total <= k {
        return Err(Error::Numerical(format!(
            "{total} equations for {k} parameters over every experiment: the study is too short"
        )));
    }
    // per experiment: the rows' sample weights (1/σ from repetitions) or none (residual weights)
    let mut sample_sw: Vec<Option<(Weights, DVector<f64>)>> = Vec::with_capacity(exps.len());
    for e in exps {
        let from_reps = !o.ols && e.data.var.is_some() && o.weights != WeightSource::Residuals;
        if o.weights == WeightSource::Repetitions && e.data.var.is_none() && !o.ols {
            return Err(Error::invalid(
                "study",
                "weights",
                format!(
                    "weights = \"repetitions\", but experiment `{}` has one repetition and no variance columns: give it repetitions, or use weights = \"auto\" (its weights from its residuals)",
                    e.name
                ),
            ));
        }
        let rw = o
            .repetition_weights
            .unwrap_or(if e.n_reps >= SAMPLE_WEIGHTS_FROM { Weights::Sample } else { Weights::Joint });
        sample_sw.push(if from_reps {
            Some((rw, row_variances(e.data, rw)?.map(|v| 1.0 / v.sqrt())))
        } else {
            None
        });
    }
    // blocks and their factors of [C_b | y_b] (rows sample-weighted where repetitions give weights)
    let mut blocks = Vec::new();
    let mut ranges = Vec::new();
    for (ei, e) in exps.iter().enumerate() {
        for (j, r0, r1) in block_ranges(e.data) {
            let weight = match (&sample_sw[ei], o.ols) {
                (_, true) => BlockWeight::Unit,
                (Some((Weights::Sample, _)), _) => BlockWeight::Sample,
                (Some(_), _) => BlockWeight::Joint,
                (None, _) => BlockWeight::Residual,
            };
            let sigma = match &sample_sw[ei] {
                Some((_, sw)) => ((r0..r1).map(|i| 1.0 / (sw[i] * sw[i])).sum::<f64>() / (r1 - r0) as f64).sqrt(),
                None => 1.0,
            };
            blocks.push(Block {
                experiment: ei,
                joint: j,
                rows: r1 - r0,
                weight,
                sigma,
                chi2: 0.0,
            });
            ranges.push((ei, r0, r1));
        }
    }
    let factors: Vec<DMatrix<f64>> = ranges
        .par_iter()
        .map(|&(ei, r0, r1)| {
            let d = exps[ei].data;
            let mut a = DMatrix::zeros(r1 - r0, k + 1);
            a.columns_mut(0, k).copy_from(&d.c.rows(r0, r1 - r0));
            for i in r0..r1 {
                a[(i - r0, k)] = d.y[i];
            }
            if let Some((_, sw)) = &sample_sw[ei] {
                for i in r0..r1 {
                    a.row_mut(i - r0).scale_mut(sw[i]);
                }
            }
            r_factor(&a)
        })
        .collect();
    if factors.iter().any(|f| f.iter().any(|v| !v.is_finite())) {
        return Err(Error::Numerical("the weighted design matrix has non-finite entries".into()));
    }
    let ssr = |f: &DMatrix<f64>, th: &DVector<f64>| -> f64 {
        let mut x = DVector::from_element(k + 1, -1.0);
        x.rows_mut(0, k).copy_from(th);
        (f * x).norm_squared()
    };
    let mut omega: Vec<f64> = vec![1.0; blocks.len()];
    let iterate = blocks.iter().any(|b| b.weight == BlockWeight::Residual);
    let mut iterations = 0;
    let mut converged = true;
    let mut sol = solve_factor(&stack(&factors, &omega, k + 1), k)?;
    if iterate {
        converged = false;
        let floor_of = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max) * 1e-12 + 1e-300;
        let mut var: Vec<f64> = blocks.iter().map(|b| b.sigma * b.sigma).collect();
        while iterations < o.max_iterations {
            iterations += 1;
            let mut next = var.clone();
            for (bi, b) in blocks.iter().enumerate() {
                if b.weight == BlockWeight::Residual {
                    let dof = b.rows as f64 * (1.0 - k as f64 / total as f64);
                    next[bi] = ssr(&factors[bi], &sol.0) / dof.max(1.0);
                }
            }
            let fl = floor_of(&next);
            for v in &mut next {
                *v = v.max(fl);
            }
            let change = next.iter().zip(&var).map(|(a, b)| ((a - b) / b).abs()).fold(0.0, f64::max);
            var = next;
            for (bi, b) in blocks.iter().enumerate() {
                if b.weight == BlockWeight::Residual {
                    omega[bi] = 1.0 / var[bi].sqrt();
                }
            }
            sol = solve_factor(&stack(&factors, &omega, k + 1), k)?;
            if change < o.tol {
                converged = true;
                break;
            }
        }
        for (bi, b) in blocks.iter_mut().enumerate() {
            if b.weight == BlockWeight::Residual {
                b.sigma = var[bi].sqrt();
            }
        }
    }
    let (theta, cov, rank) = sol;
    let mut chi2 = 0.0;
    for (bi, b) in blocks.iter_mut().enumerate() {
        b.chi2 = ssr(&factors[bi], &theta) * omega[bi] * omega[bi];
        chi2 += b.chi2;
    }
    // R of √W C alone (drop the y column)
    let cfactors: Vec<DMatrix<f64>> = factors.iter().map(|f| f.columns(0, k).into_owned()).collect();
    let r = stack(&cfactors, &omega, k);
    let (cond, cond_normalized) = conds(&r, k);
    let mut share = Vec::with_capacity(exps.len());
    let mut alone = Vec::with_capacity(exps.len());
    for ei in 0..exps.len() {
        let idx: Vec<usize> = (0..blocks.len()).filter(|&b| blocks[b].experiment == ei).collect();
        let fs: Vec<DMatrix<f64>> = idx.iter().map(|&b| cfactors[b].clone()).collect();
        let ws: Vec<f64> = idx.iter().map(|&b| omega[b]).collect();
        let re = stack(&fs, &ws, k);
        let fe = re.transpose() * &re;
        let d = &cov * fe;
        share.push((0..k).map(|i| d[(i, i)]).collect());
        let s = singular(&re);
        let smax = s.first().copied().unwrap_or(0.0);
        let rk = s.iter().filter(|&&x| x > 1e-10 * smax).count();
        alone.push((rk, if rk < k { f64::INFINITY } else { smax / s[s.len() - 1] }));
    }
    let mut row_weights = Vec::with_capacity(exps.len());
    for (ei, e) in exps.iter().enumerate() {
        let mut w = match &sample_sw[ei] {
            Some((_, sw)) => sw.clone(),
            None => DVector::from_element(e.data.y.len(), 1.0),
        };
        for (bi, b) in blocks.iter().enumerate().filter(|(_, b)| b.experiment == ei) {
            let (_, r0, r1) = ranges[bi];
            debug_assert_eq!(r1 - r0, b.rows);
            for i in r0..r1 {
                w[i] *= omega[bi];
            }
        }
        row_weights.push(w);
    }
    Ok(Stacked {
        theta,
        cov,
        rank,
        cond,
        cond_normalized,
        chi2_dof: chi2 / (total - rank).max(1) as f64,
        blocks,
        iterations,
        converged,
        share,
        alone,
        r,
        row_weights,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn dataset(c: DMatrix<f64>, y: DVector<f64>, n: usize, var: Option<DVector<f64>>) -> Dataset {
        let m = c.nrows() / n;
        Dataset {
            n,
            n_samples: m,
            names: (0..c.ncols()).map(|i| format!("p{i}")).collect(),
            joint: (0..c.nrows()).map(|r| r / m).collect(),
            sample: (0..c.nrows()).map(|r| r % m).collect(),
            c,
            y,
            var,
        }
    }

    #[test]
    fn residual_weights_equal_the_true_noise_and_the_estimate_equals_explicit_wls() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let nrm = Normal::new(0.0, 1.0).unwrap();
        let theta = DVector::from_vec(vec![1.0, -2.0, 0.5]);
        // two experiments, two joints each, noise σ = 0.1, 1.0 | 0.01, 0.3
        let sig = [[0.1, 1.0], [0.01, 0.3]];
        let mut sets = Vec::new();
        for (e, s) in sig.iter().enumerate() {
            let m = 4000 + 1000 * e;
            let c = DMatrix::from_fn(2 * m, 3, |_, _| nrm.sample(&mut rng));
            let y = DVector::from_fn(2 * m, |r, _| (c.row(r) * &theta)[0] + s[r / m] * nrm.sample(&mut rng));
            sets.push(dataset(c, y, 2, None));
        }
        let rows: Vec<Rows> = sets
            .iter()
            .enumerate()
            .map(|(i, d)| Rows {
                name: if i == 0 { "a" } else { "b" },
                data: d,
                n_reps: 1,
            })
            .collect();
        let st = estimate(&rows, &StackOptions::default()).unwrap();
        assert!(st.converged && st.iterations > 1);
        for b in &st.blocks {
            let s = sig[b.experiment][b.joint];
            assert!((b.sigma - s).abs() < 0.05 * s, "block {b:?}: σ {} vs {s}", b.sigma);
        }
        // explicit WLS with the estimated σ_b on the raw rows gives the same θ and covariance
        let total: usize = sets.iter().map(|d| d.y.len()).sum();
        let mut a = DMatrix::zeros(total, 3);
        let mut yy = Vec::with_capacity(total);
        for (e, d) in sets.iter().enumerate() {
            for r in 0..d.y.len() {
                let b = st.blocks.iter().find(|b| b.experiment == e && b.joint == d.joint[r]).unwrap();
                a.row_mut(yy.len()).copy_from(&(d.c.row(r) / b.sigma));
                yy.push(d.y[r] / b.sigma);
            }
        }
        let yv = DVector::from_vec(yy);
        let ata = a.transpose() * &a;
        let th = ata.clone().lu().solve(&(a.transpose() * yv)).unwrap();
        let cov = ata.try_inverse().unwrap();
        assert!((&th - &st.theta).norm() < 1e-9 * th.norm(), "{th} vs {}", st.theta);
        assert!((&cov - &st.cov).norm() < 1e-8 * cov.norm());
        // shares sum to one per parameter
        for i in 0..3 {
            let s: f64 = st.share.iter().map(|v| v[i]).sum();
            assert!((s - 1.0).abs() < 1e-9, "{s}");
        }
        assert!((st.chi2_dof - 1.0).abs() < 0.05, "χ²/dof {}", st.chi2_dof);
    }

    #[test]
    fn repetitions_required_names_the_experiment() {
        let c = DMatrix::from_fn(20, 2, |r, c| (r * 3 + c) as f64 % 7.0);
        let y = DVector::from_element(20, 1.0);
        let d = dataset(c, y, 1, None);
        let o = StackOptions {
            weights: WeightSource::Repetitions,
            ..Default::default()
        };
        let e = estimate(
            &[Rows {
                name: "gravity",
                data: &d,
                n_reps: 1,
            }],
            &o,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("`gravity`") && e.contains("weights"), "{e}");
    }
}
