//! Standard ⇄ base parameters, computed numerically (Gautier 1991).
//!
//! The regressor Y (n × p) is stacked over random states (q within the joint
//! limits, random q̇ and q̈) into W (N·n × p), its columns are normalised to
//! unit norm, and columns are taken greedily in a preferred order — every
//! parameter kind except YY, MZ, M first, then YY, MZ, M, each link in
//! increasing order — keeping a column when its residual after projection on
//! the columns already kept exceeds `tol` (relative to its norm). This is the
//! numerical counterpart of Khalil's regrouping rules: YY_j, MZ_j, M_j are the
//! ones that get regrouped, so the base parameters read like the hand-derived
//! sets (`XX2 - YY2`, `ZZ1 + YY2 + ...`). The rank found is cross-checked
//! against column-pivoted QR (faer).
//!
//! With W_b the kept columns and W_d the others, W_d = W_b β, so
//! W θ = W_b (θ_b + β θ_d): the base parameters are θ_base = K θ with
//! K = [I β] (in the original column positions), and the base regressor is
//! Y_base = Y[:, kept].
//!
//! [`info`]: the robot summary and the torque/regressor tables of `idexp robot`.

pub mod info;
pub mod stream;

use crate::error::{Error, Result};
use crate::robot::{regressor_rows, ParamKind, Robot, Workspace};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use serde::Serialize;

/// Options of the base-parameter computation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseOptions {
    /// Number of random states stacked.
    pub samples: usize,
    /// Seed of the random states.
    pub seed: u64,
    /// Rank tolerance: a column is independent when the norm of its residual,
    /// after projection on the columns kept before it, exceeds `tol` times its
    /// own norm. Default 1e-6.
    pub tol: f64,
    /// Consider only the rigid-body inertial columns (drive columns left out).
    pub inertial_only: bool,
}

impl Default for BaseOptions {
    fn default() -> Self {
        BaseOptions {
            samples: 200,
            seed: 1,
            tol: 1e-6,
            inertial_only: false,
        }
    }
}

/// The base parameters of a robot.
#[derive(Debug, Clone, Serialize)]
pub struct BaseParams {
    /// Number of standard parameters p.
    pub n_std: usize,
    /// Standard-parameter indices of the base parameters (kept columns), in layout order.
    pub independent: Vec<usize>,
    /// Indices of the standard parameters regrouped into others (non-zero column in β).
    pub regrouped: Vec<usize>,
    /// Indices of standard parameters with no effect on the torques (zero columns).
    pub unidentifiable: Vec<usize>,
    /// K (n_base × p): θ_base = K θ.
    #[serde(skip)]
    pub k: DMatrix<f64>,
    /// Names of the base parameters (the kept standard parameter, with suffix `R` when regrouped).
    pub names: Vec<String>,
    /// Each base parameter as a readable linear combination of standard ones.
    pub groupings: Vec<String>,
    /// Tolerance used.
    pub tol: f64,
    /// Smallest relative residual among the kept columns (margin above `tol`).
    pub smallest_kept: f64,
    /// Largest relative residual among the discarded columns (margin below `tol`).
    pub largest_dropped: f64,
    /// Rank from column-pivoted QR with the same tolerance (equals `independent.len()`).
    pub rank_qr: usize,
    /// Number of stacked states.
    pub samples: usize,
    /// Whether only inertial columns were considered.
    pub inertial_only: bool,
}

fn priority(kind: ParamKind) -> u8 {
    match kind {
        ParamKind::YY | ParamKind::MZ | ParamKind::M => 1,
        _ => 0,
    }
}

/// Stacks the regressor over `samples` random states into W (samples·n × p).
pub fn random_stack(robot: &Robot, samples: usize, seed: u64) -> DMatrix<f64> {
    let n = robot.dof();
    let p = robot.n_params();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut ws = Workspace::new(robot);
    let mut w = DMatrix::zeros(samples * n, p);
    let mut row = vec![0.0; n * p];
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for s in 0..samples {
        for j in 0..n {
            let l = &robot.joints[j].limits;
            let lo = if l.lower.is_finite() { l.lower } else { -std::f64::consts::PI };
            let hi = if l.upper.is_finite() { l.upper } else { std::f64::consts::PI };
            q[j] = rng.random_range(lo..=hi);
            qd[j] = rng.random_range(-2.0..2.0);
            qdd[j] = rng.random_range(-5.0..5.0);
        }
        regressor_rows(robot, &mut ws, &q, &qd, &qdd, &mut row);
        for r in 0..n {
            for c in 0..p {
                w[(s * n + r, c)] = row[r * p + c];
            }
        }
    }
    w
}

/// The regressor stack of `opts.samples` random states, after checking that
/// there are enough states for the robot's parameters.
fn checked_stack(robot: &Robot, opts: &BaseOptions) -> Result<DMatrix<f64>> {
    let p = robot.n_params();
    let min_samples = p.div_ceil(robot.dof()) + 1;
    if opts.samples < min_samples {
        return Err(Error::invalid(
            "base parameters",
            "samples",
            format!("expected at least {min_samples} states for {p} parameters"),
        ));
    }
    Ok(random_stack(robot, opts.samples, opts.seed))
}

impl BaseParams {
    /// Computes the base parameters of `robot`.
    pub fn compute(robot: &Robot, opts: &BaseOptions) -> Result<BaseParams> {
        if !(opts.tol > 0.0 && opts.tol < 1.0) {
            return Err(Error::invalid("base parameters", "tol", format!("expected 0 < tol < 1, found {}", opts.tol)));
        }
        let w = checked_stack(robot, opts)?;
        Self::from_stack(robot, &w, opts)
    }

    /// Base parameters whose independent columns are exactly the standard
    /// parameters `names` (e.g. a paper's or another tool's base set,
    /// `["ZZ1", "XX2", ...]`): each name must be a parameter of the robot,
    /// none may be a combination of the others (the error names the
    /// dependent ones), and together they must span the regressor (the error
    /// says how many are missing and which columns would complete the set).
    /// The other columns regroup onto them as in [`BaseParams::compute`].
    pub fn with_columns(robot: &Robot, names: &[String], opts: &BaseOptions) -> Result<BaseParams> {
        let info = robot.params();
        let ctx = "base_columns";
        let mut forced = Vec::with_capacity(names.len());
        for (i, nm) in names.iter().enumerate() {
            let c = info.iter().position(|pi| pi.name == *nm).ok_or_else(|| {
                let all: Vec<&str> = info.iter().map(|pi| pi.name.as_str()).collect();
                Error::invalid(
                    ctx,
                    format!("[{i}]"),
                    format!("`{nm}` is not a parameter of robot `{}`; allowed: {}", robot.name, all.join(", ")),
                )
            })?;
            if forced.contains(&c) {
                return Err(Error::invalid(ctx, format!("[{i}]"), format!("`{nm}` is named twice")));
            }
            if opts.inertial_only && !info[c].kind.is_inertial() {
                return Err(Error::invalid(
                    ctx,
                    format!("[{i}]"),
                    format!("`{nm}` is a drive parameter, but the columns are inertial only"),
                ));
            }
            forced.push(c);
        }
        let w = checked_stack(robot, opts)?;
        let b = Self::from_stack_ordered(robot, &w, opts, &forced)?;
        let no_effect: Vec<String> = forced.iter().filter(|c| b.unidentifiable.contains(c)).map(|&c| info[c].name.clone()).collect();
        if !no_effect.is_empty() {
            return Err(Error::invalid(
                ctx,
                "names",
                format!(
                    "{} {} no effect on the torques and cannot be a base column",
                    no_effect.join(", "),
                    if no_effect.len() == 1 { "has" } else { "have" }
                ),
            ));
        }
        let dependent: Vec<String> = forced.iter().filter(|c| !b.independent.contains(c)).map(|&c| info[c].name.clone()).collect();
        if !dependent.is_empty() {
            return Err(Error::invalid(
                ctx,
                "names",
                format!(
                    "the named columns are not independent: {} {} a combination of the names before {} in the list (remove {} or name other columns)",
                    dependent.join(", "),
                    if dependent.len() == 1 { "is" } else { "are" },
                    if dependent.len() == 1 { "it" } else { "them" },
                    if dependent.len() == 1 { "it" } else { "them" }
                ),
            ));
        }
        if b.n_base() > forced.len() {
            let extra: Vec<String> = b.independent.iter().filter(|c| !forced.contains(c)).map(|&c| info[c].name.clone()).collect();
            return Err(Error::invalid(
                ctx,
                "names",
                format!(
                    "the {} named columns do not span the regressor (rank {}): {} more needed, e.g. {}",
                    forced.len(),
                    b.n_base(),
                    extra.len(),
                    extra.join(", ")
                ),
            ));
        }
        Ok(b)
    }

    /// The parameters of the standard columns `cols` alone, every other
    /// standard parameter taken as known (e.g. a payload's link columns on a
    /// robot whose model is known): the independent ones among `cols` (in the
    /// given order) are kept, the dependent ones regroup onto them, those with
    /// no effect on the torques are listed as unidentifiable; the other
    /// parameters have zero columns in K.
    pub fn of_columns(robot: &Robot, cols: &[usize], opts: &BaseOptions) -> Result<BaseParams> {
        let w = checked_stack(robot, opts)?;
        Self::of_stack_columns(robot, w, cols, opts)
    }

    /// [`BaseParams::of_columns`] on a given stacked regressor W (rows × p),
    /// e.g. one whose columns `cols` were mapped to a payload's own frame.
    pub fn of_stack_columns(robot: &Robot, mut w: DMatrix<f64>, cols: &[usize], opts: &BaseOptions) -> Result<BaseParams> {
        let p = robot.n_params();
        if cols.is_empty() || cols.iter().any(|&c| c >= p) {
            return Err(Error::invalid(
                "base parameters",
                "columns",
                format!("expected column indices below {p}, found {cols:?}"),
            ));
        }
        for c in 0..p {
            if !cols.contains(&c) {
                w.column_mut(c).fill(0.0);
            }
        }
        let mut b = Self::from_stack_ordered(robot, &w, opts, cols)?;
        b.unidentifiable.retain(|c| cols.contains(c));
        Ok(b)
    }

    /// Computes the base parameters from a given stacked regressor W (rows × p),
    /// e.g. the regressor of a particular trajectory.
    pub fn from_stack(robot: &Robot, w: &DMatrix<f64>, opts: &BaseOptions) -> Result<BaseParams> {
        Self::from_stack_ordered(robot, w, opts, &[])
    }

    /// [`BaseParams::from_stack`] trying the columns `first` before the
    /// preferred order.
    fn from_stack_ordered(robot: &Robot, w: &DMatrix<f64>, opts: &BaseOptions, first: &[usize]) -> Result<BaseParams> {
        let p = robot.n_params();
        if w.ncols() != p {
            return Err(Error::dim("stacked regressor columns", p, w.ncols()));
        }
        let info = robot.params();
        let considered: Vec<usize> = (0..p).filter(|&c| !opts.inertial_only || info[c].kind.is_inertial()).collect();
        let norms: Vec<f64> = (0..p).map(|c| w.column(c).norm()).collect();
        let scale = norms.iter().cloned().fold(0.0, f64::max);
        let mut order: Vec<usize> = considered.clone();
        order.sort_by_key(|&c| (priority(info[c].kind), c));
        if !first.is_empty() {
            order.retain(|c| !first.contains(c));
            order.splice(0..0, first.iter().copied());
        }
        // greedy modified Gram–Schmidt with re-orthogonalisation
        let rows = w.nrows();
        let mut basis: Vec<DVector<f64>> = Vec::new();
        let mut kept: Vec<usize> = Vec::new();
        let mut smallest_kept = f64::INFINITY;
        let mut largest_dropped: f64 = 0.0;
        let mut unidentifiable = Vec::new();
        for &c in &order {
            if norms[c] <= 1e-12 * scale.max(1e-300) {
                unidentifiable.push(c);
                continue;
            }
            let mut v = w.column(c) / norms[c];
            crate::linalg::orthogonalize(&basis, &mut v);
            let res = v.norm();
            if res > opts.tol {
                smallest_kept = smallest_kept.min(res);
                basis.push(v / res);
                kept.push(c);
            } else {
                largest_dropped = largest_dropped.max(res);
            }
        }
        let _ = rows;
        if kept.is_empty() {
            return Err(Error::Numerical("the regressor is zero: no parameter affects the torques".into()));
        }
        // rank cross-check with column-pivoted QR on the normalised columns
        let wn = DMatrix::from_fn(w.nrows(), considered.len(), |i, j| {
            let c = considered[j];
            if norms[c] > 1e-12 * scale.max(1e-300) {
                w[(i, c)] / norms[c]
            } else {
                0.0
            }
        });
        let (diag, _) = crate::linalg::col_piv_qr_diag(&wn);
        let rank_qr = diag.iter().filter(|&&d| d > opts.tol * diag[0].max(1e-300)).count();
        kept.sort_unstable();
        let dependent: Vec<usize> = considered
            .iter()
            .copied()
            .filter(|c| !kept.contains(c) && !unidentifiable.contains(c))
            .collect();
        // β from least squares W_b β = W_d
        let wb = DMatrix::from_fn(w.nrows(), kept.len(), |i, j| w[(i, kept[j])]);
        let wd = DMatrix::from_fn(w.nrows(), dependent.len(), |i, j| w[(i, dependent[j])]);
        let beta = if dependent.is_empty() {
            DMatrix::zeros(kept.len(), 0)
        } else {
            let qr = wb.clone().qr();
            let qtb = qr.q().transpose() * &wd;
            qr.r()
                .solve_upper_triangular(&qtb)
                .ok_or_else(|| Error::Numerical("base-parameter regrouping: singular triangular factor".into()))?
        };
        let mut k = DMatrix::zeros(kept.len(), p);
        let mut regrouped = Vec::new();
        for (i, &c) in kept.iter().enumerate() {
            k[(i, c)] = 1.0;
        }
        for (j, &d) in dependent.iter().enumerate() {
            let col = beta.column(j);
            let mx = col.amax();
            let mut any = false;
            for i in 0..kept.len() {
                let b = beta[(i, j)];
                if b.abs() > 1e-9 * mx.max(1.0) && b.abs() > 1e-12 {
                    k[(i, d)] = clean(b);
                    any = true;
                }
            }
            if any {
                regrouped.push(d);
            } else {
                unidentifiable.push(d);
            }
        }
        unidentifiable.sort_unstable();
        let names: Vec<String> = kept
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let grouped = (0..p).any(|d| d != c && k[(i, d)] != 0.0);
                format!("{}{}", info[c].name, if grouped { "R" } else { "" })
            })
            .collect();
        let groupings = (0..kept.len()).map(|i| grouping_string(&k, i, kept[i], robot)).collect();
        Ok(BaseParams {
            n_std: p,
            independent: kept,
            regrouped,
            unidentifiable,
            k,
            names,
            groupings,
            tol: opts.tol,
            smallest_kept,
            largest_dropped,
            rank_qr,
            samples: w.nrows() / robot.dof(),
            inertial_only: opts.inertial_only,
        })
    }

    /// Number of base parameters.
    pub fn n_base(&self) -> usize {
        self.independent.len()
    }

    /// Base parameter values θ_base = K θ.
    pub fn base_values(&self, theta: &[f64]) -> DVector<f64> {
        &self.k * DVector::from_column_slice(theta)
    }

    /// The base regressor rows: Y_base = Y[:, independent] for a row-major
    /// n×p regressor `y`, into row-major n×n_base `out`.
    pub fn select_rows(&self, y: &[f64], n: usize, out: &mut [f64]) {
        let nb = self.n_base();
        for r in 0..n {
            for (j, &c) in self.independent.iter().enumerate() {
                out[r * nb + j] = y[r * self.n_std + c];
            }
        }
    }

    /// Base regressor of a stacked standard regressor W: W[:, independent].
    pub fn select(&self, w: &DMatrix<f64>) -> DMatrix<f64> {
        DMatrix::from_fn(w.nrows(), self.n_base(), |i, j| w[(i, self.independent[j])])
    }

    /// The SI unit of base parameter `k`: its kept standard parameter's
    /// ([`unit()`]; a grouping adds only terms of the same unit).
    pub fn unit(&self, robot: &Robot, k: usize) -> &'static str {
        unit(robot, self.independent[k])
    }

    /// One standard parameter vector that has the given base values (the
    /// minimum-norm one on the dependent parameters: they are set to zero).
    pub fn standard_from_base(&self, base: &[f64]) -> DVector<f64> {
        let mut th = DVector::zeros(self.n_std);
        for (j, &c) in self.independent.iter().enumerate() {
            th[c] = base[j];
        }
        th
    }
}

/// Rounds values that are integers or simple decimals up to round-off.
fn clean(b: f64) -> f64 {
    let r = (b * 1e9).round() / 1e9;
    if (r - b).abs() < 1e-10 * b.abs().max(1.0) {
        r
    } else {
        b
    }
}

fn grouping_string(k: &DMatrix<f64>, i: usize, kept: usize, robot: &Robot) -> String {
    let names = robot.params();
    let mut s = names[kept].name.clone();
    for d in 0..k.ncols() {
        if d == kept {
            continue;
        }
        let b = k[(i, d)];
        if b == 0.0 {
            continue;
        }
        let (sign, a) = if b < 0.0 { ("-", -b) } else { ("+", b) };
        if (a - 1.0).abs() < 1e-12 {
            s.push_str(&format!(" {sign} {}", names[d].name));
        } else {
            s.push_str(&format!(" {sign} {}*{}", fmt_coef(a), names[d].name));
        }
    }
    s
}

fn fmt_coef(a: f64) -> String {
    let s = format!("{:.6}", a);
    let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    if s == "0" {
        format!("{a:.3e}")
    } else {
        s
    }
}

/// The SI unit of a parameter of kind `kind` on a joint of kind `joint`:
/// kg·m² (inertias), kg·m (first moments), kg (mass); the drive's rotor
/// inertia, friction and offsets in kg·m², N·m, N·m·s/rad on a revolute joint
/// and kg, N, N·s/m on a prismatic one.
pub fn unit_of(kind: ParamKind, joint: crate::robot::JointKind) -> &'static str {
    use ParamKind::*;
    let prismatic = joint == crate::robot::JointKind::Prismatic;
    match kind {
        XX | XY | XZ | YY | YZ | ZZ => "kg·m²",
        MX | MY | MZ => "kg·m",
        M => "kg",
        Ia if prismatic => "kg",
        Ia => "kg·m²",
        Fv | FvPos | FvNeg if prismatic => "N·s/m",
        Fv | FvPos | FvNeg => "N·m·s/rad",
        Fc | F0 | FcPos | FcNeg | Fs | FsPos | FsNeg if prismatic => "N",
        Fc | F0 | FcPos | FcNeg | Fs | FsPos | FsNeg => "N·m",
    }
}

/// The SI unit of standard parameter `j` of `robot` ([`unit_of`]; a drive
/// parameter takes its joint's kind).
pub fn unit(robot: &Robot, j: usize) -> &'static str {
    let p = &robot.params()[j];
    let joint = if p.kind.is_inertial() {
        crate::robot::JointKind::Revolute
    } else {
        robot.joints[p.joint].kind
    };
    unit_of(p.kind, joint)
}
