//! Conic formulations of the relaxed allocation problem, solved by Clarabel.
//!
//! Clarabel solves min ½xᵀPx + qᵀx s.t. Ax + s = b, s ∈ K. The PSD cone
//! `PSDTriangleConeT(n)` holds svec(X): the upper triangle stacked column by
//! column, off-diagonal entries scaled by √2 (so ⟨svec X, svec Y⟩ = tr XY).
//!
//! ## D-optimal, second-order-cone form (default)
//!
//! After Sagnol (2011) and Sagnol & Harman (2015, eq. 8): with F_i = H_i H_iᵀ
//! (H_i p×r_i) and F_0 = H_0 H_0ᵀ (weight fixed to 1),
//!
//! det M(w) = max { Π_j J_jj : Σ_i H_i Z_i = J lower triangular,
//!                   ‖Z_i e_j‖² ≤ t_ij w_i, Σ_i t_ij ≤ J_jj },
//!
//! (Cauchy–Schwarz gives JᵀM⁻¹J ⪯ ZᵀW⁻¹Z, Hadamard's inequality gives
//! Π J_jj ≤ det M; equality for J = L·diag(L_jj), M = LLᵀ). log det is then
//! Σ u_j with (u_j, 1, J_jj) ∈ K_exp. Rotated cones ‖z‖² ≤ t w are
//! (t + w, t − w, 2z) ∈ SOC. No semidefinite cone is needed: the KKT system is
//! sparse, instead of the dense (2p)(2p+1)/2-square block of the lifted
//! log-det cone that grows like p⁶.
//!
//! ## D-optimal, semidefinite form (cross-check)
//!
//! log det M ≥ Σ u_j ⇔ ∃ lower-triangular Z: [[M, Z],[Zᵀ, Diag Z]] ⪰ 0 and
//! (u_j, 1, Z_jj) ∈ K_exp (MOSEK modelling cookbook §6.2.3).
//!
//! ## A-optimal
//!
//! tr(Kᵀ M⁻¹ K) = min { Σ_i s_i : Σ_i H_i Y_i = K, ‖Y_i‖_F² ≤ s_i w_i }
//! (Sagnol 2011; the same Cauchy–Schwarz argument), K = I or the inverse of a
//! congruence scaling. Equivalent to the Schur-complement constraint
//! [[M, K],[Kᵀ, Y]] ⪰ 0, min tr Y, without the 2p×2p cone.
//!
//! ## E-optimal
//!
//! max t s.t. M(w) − t I ⪰ 0 (one p×p PSD cone). The dual of that cone, Z ⪰ 0
//! with tr Z = 1, certifies: λ_min(M(w')) ≤ tr(Z F_0) + max_i tr(Z F_i) for
//! every design w'.

use super::problem::Problem;
use super::relax::SolverOptions;
use crate::optim::conic::{self as bridge, svec_index, svec_scale, Cone, Entries as Triplets, Program, Settings};
use crate::optim::Control;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Which conic formulation of the D-optimal problem to give Clarabel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Formulation {
    /// Second-order and exponential cones (Sagnol 2011): sparse, fast.
    #[default]
    Socp,
    /// The lifted 2p×2p log-det semidefinite cone plus exponential cones.
    Sdp,
}

pub use crate::optim::conic::ConicStatus;

/// What Clarabel returned.
#[derive(Debug, Clone)]
pub struct ConicResult {
    /// Weights on the sub-problem's candidates (cleaned: ≥ 0, unit sum).
    pub w: Vec<f64>,
    /// Clarabel's status (`Solved`, `AlmostSolved`, `MaxIterations`, ...).
    pub status: ConicStatus,
    /// True for Solved / AlmostSolved.
    pub ok: bool,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Clarabel's solve time (s).
    pub solve_time: f64,
    /// Number of variables and constraint rows.
    pub size: (usize, usize),
    /// For E: the dual matrix of the PSD constraint (p×p, not normalised).
    pub dual: Option<DMatrix<f64>>,
}

/// Appends the simplex on the weights w (columns `w0..w0 + k`): Σ w = 1 (zero
/// cone), then w ≥ 0 (nonnegative cone).
fn push_simplex(a: &mut Triplets, b: &mut Vec<f64>, cones: &mut Vec<Cone>, w0: usize, k: usize) {
    let r = a.rows(1);
    for i in 0..k {
        a.push(r, w0 + i, 1.0);
    }
    b.push(1.0);
    cones.push(Cone::Zero(1));
    let r = a.rows(k);
    for i in 0..k {
        a.push(r + i, w0 + i, -1.0);
        b.push(0.0);
    }
    cones.push(Cone::Nonnegative(k));
}

/// Fills the leading p×p block of a PSD slack s = b − A x whose svec rows start
/// at `r` with F_0 + Σ_i w_i F_i: the prior goes into `bb` (the block's part of
/// b), −F_i into the weight columns `w0 + i`.
fn push_weighted_information(a: &mut Triplets, bb: &mut [f64], r: usize, pb: &Problem, w0: usize) {
    let p = pb.p();
    if let Some(f0) = pb.prior() {
        for j in 0..p {
            for i in 0..=j {
                bb[svec_index(i, j)] = f0[(i, j)] * svec_scale(i, j);
            }
        }
    }
    for i in 0..pb.n() {
        let f = pb.matrix(i);
        for jj in 0..p {
            for ii in 0..=jj {
                a.push(r + svec_index(ii, jj), w0 + i, -f[(ii, jj)] * svec_scale(ii, jj));
            }
        }
    }
}

/// Appends u_j ≤ ln x_j for j in 0..p (u_j in the columns `u0 + j`, x_j in
/// the column `x(j)`): one exponential cone (u_j, 1, x_j) each.
fn push_log_epigraphs(a: &mut Triplets, b: &mut Vec<f64>, cones: &mut Vec<Cone>, u0: usize, p: usize, x: impl Fn(usize) -> usize) {
    for j in 0..p {
        let r = a.rows(3);
        a.push(r, u0 + j, -1.0);
        a.push(r + 2, x(j), -1.0);
        b.extend_from_slice(&[0.0, 1.0, 0.0]);
        cones.push(Cone::Exponential);
    }
}

/// The program min qᵀx s.t. b − Ax ∈ cones (no quadratic term).
fn linear(n_var: usize, q: Vec<f64>, a: Triplets, b: Vec<f64>, cones: Vec<Cone>) -> Program {
    Program {
        n_var,
        p: None,
        q,
        a,
        b,
        cones,
    }
}

/// Solves `prog` with Clarabel (the bridge [`crate::optim::conic`]) at
/// tolerance `tol`; the first `n_w` variables are the weights. Returns
/// Clarabel's dual solution beside the result (empty when not set up).
fn solve(prog: Program, set: &SolverOptions, tol: f64, n_w: usize, ctl: &Control) -> (Vec<f64>, ConicResult) {
    let settings = Settings {
        verbose: set.verbose,
        max_iter: Some(set.max_iter),
        time_limit: set.time_limit,
        tol: Some(tol),
        progress: false,
    };
    let sol = bridge::solve(prog, &settings, ctl);
    let ok = sol.status.is_solved();
    let mut w: Vec<f64> = if sol.x.len() >= n_w {
        sol.x[..n_w].to_vec()
    } else {
        vec![1.0 / n_w as f64; n_w]
    };
    if !sol.x.is_empty() {
        super::firstorder::normalise(&mut w);
        if w.iter().sum::<f64>() <= 0.0 || w.iter().any(|v| !v.is_finite()) {
            w = vec![1.0 / n_w as f64; n_w];
        }
    }
    let res = ConicResult {
        w,
        status: sol.status,
        ok,
        iterations: sol.iterations,
        solve_time: sol.solve_time,
        size: sol.size,
        dual: None,
    };
    (sol.z, res)
}

/// D-optimal design on `pb` with the chosen formulation.
pub fn solve_d(pb: &Problem, set: &SolverOptions, ctl: &Control) -> ConicResult {
    match set.formulation {
        Formulation::Socp => solve_d_socp(pb, set, ctl),
        Formulation::Sdp => solve_d_sdp(pb, set, ctl),
    }
}

/// D-optimal design, second-order-cone form (see the module docs).
pub fn solve_d_socp(pb: &Problem, set: &SolverOptions, ctl: &Control) -> ConicResult {
    let (p, k) = (pb.p(), pb.n());
    // blocks: index 0..k candidates, k = prior (weight 1) if present
    let mut factors: Vec<nalgebra::DMatrixView<'_, f64>> = (0..k).map(|i| pb.factor(i)).collect();
    if let Some(h0) = pb.prior_factor() {
        factors.push(h0.columns(0, h0.ncols()));
    }
    let nb = factors.len();
    // variable layout
    let w0 = 0;
    let t0 = k; // t[b][j] at t0 + b*p + j
    let mut z_off = Vec::with_capacity(nb); // Z_b[c][j] at z_off[b] + c*p + j
    let mut cur = t0 + nb * p;
    for h in &factors {
        z_off.push(cur);
        cur += h.ncols() * p;
    }
    let j0 = cur; // J[a][j], a ≥ j, at j0 + svec-like lower index
    let jidx = |a: usize, j: usize| j0 + a * (a + 1) / 2 + j;
    cur += p * (p + 1) / 2;
    let u0 = cur;
    cur += p;
    let n_var = cur;
    let mut q = vec![0.0; n_var];
    for j in 0..p {
        q[u0 + j] = -1.0;
    }
    let mut a = Triplets::new();
    let mut b = Vec::new();
    let mut cones = Vec::new();
    // equalities: Σ w = 1; Σ_b H_b Z_b − J = 0
    let r = a.rows(1 + p * p);
    for i in 0..k {
        a.push(r, w0 + i, 1.0);
    }
    b.push(1.0);
    for aa in 0..p {
        for j in 0..p {
            let row = r + 1 + aa * p + j;
            for (bi, h) in factors.iter().enumerate() {
                for c in 0..h.ncols() {
                    a.push(row, z_off[bi] + c * p + j, h[(aa, c)]);
                }
            }
            if aa >= j {
                a.push(row, jidx(aa, j), -1.0);
            }
            b.push(0.0);
        }
    }
    cones.push(Cone::Zero(1 + p * p));
    // nonnegative: w ≥ 0, J_jj − Σ_b t_bj ≥ 0  (s = b − A x)
    let r = a.rows(k + p);
    for i in 0..k {
        a.push(r + i, w0 + i, -1.0);
        b.push(0.0);
    }
    for j in 0..p {
        a.push(r + k + j, jidx(j, j), -1.0);
        for bi in 0..nb {
            a.push(r + k + j, t0 + bi * p + j, 1.0);
        }
        b.push(0.0);
    }
    cones.push(Cone::Nonnegative(k + p));
    // rotated cones (t + w, t − w, 2 Z_b e_j)
    for (bi, h) in factors.iter().enumerate() {
        let l = h.ncols();
        for j in 0..p {
            let r = a.rows(l + 2);
            let t = t0 + bi * p + j;
            a.push(r, t, -1.0);
            a.push(r + 1, t, -1.0);
            if bi < k {
                a.push(r, w0 + bi, -1.0);
                a.push(r + 1, w0 + bi, 1.0);
                b.push(0.0);
                b.push(0.0);
            } else {
                b.push(1.0);
                b.push(-1.0);
            }
            for c in 0..l {
                a.push(r + 2 + c, z_off[bi] + c * p + j, -2.0);
                b.push(0.0);
            }
            cones.push(Cone::SecondOrder(l + 2));
        }
    }
    // exponential cones (u_j, 1, J_jj)
    push_log_epigraphs(&mut a, &mut b, &mut cones, u0, p, |j| jidx(j, j));
    solve(linear(n_var, q, a, b, cones), set, set.clarabel_tol, k, ctl).1
}

/// D-optimal design, lifted semidefinite form (see the module docs).
pub fn solve_d_sdp(pb: &Problem, set: &SolverOptions, ctl: &Control) -> ConicResult {
    let (p, k) = (pb.p(), pb.n());
    let n2 = 2 * p;
    let w0 = 0;
    let z0 = k; // Z[a][j], a ≥ j
    let zidx = |a: usize, j: usize| z0 + a * (a + 1) / 2 + j;
    let u0 = k + p * (p + 1) / 2;
    let n_var = u0 + p;
    let mut q = vec![0.0; n_var];
    for j in 0..p {
        q[u0 + j] = -1.0;
    }
    let mut a = Triplets::new();
    let mut b = Vec::new();
    let mut cones = Vec::new();
    push_simplex(&mut a, &mut b, &mut cones, w0, k);
    // PSD block: s = svec(X), X = [[F0 + Σ w F, Z],[Zᵀ, Diag Z]]
    let nsv = n2 * (n2 + 1) / 2;
    let r = a.rows(nsv);
    let s2 = std::f64::consts::SQRT_2;
    let mut bb = vec![0.0; nsv];
    push_weighted_information(&mut a, &mut bb, r, pb, w0);
    for aa in 0..p {
        for j in 0..=aa {
            // Z[aa][j] sits at X[aa][p + j]
            a.push(r + svec_index(aa, p + j), zidx(aa, j), -s2);
            if aa == j {
                a.push(r + svec_index(p + j, p + j), zidx(aa, j), -1.0);
            }
        }
    }
    b.extend_from_slice(&bb);
    cones.push(Cone::PsdTriangle(n2));
    push_log_epigraphs(&mut a, &mut b, &mut cones, u0, p, |j| zidx(j, j));
    solve(linear(n_var, q, a, b, cones), set, set.clarabel_tol, k, ctl).1
}

/// A-optimal design: min tr(Kᵀ M(w)⁻¹ K) (K p×p, e.g. the identity).
pub fn solve_a(pb: &Problem, kmat: &DMatrix<f64>, set: &SolverOptions, ctl: &Control) -> ConicResult {
    let (p, k) = (pb.p(), pb.n());
    let mut factors: Vec<nalgebra::DMatrixView<'_, f64>> = (0..k).map(|i| pb.factor(i)).collect();
    if let Some(h0) = pb.prior_factor() {
        factors.push(h0.columns(0, h0.ncols()));
    }
    let nb = factors.len();
    let w0 = 0;
    let s0 = k; // s_b
    let mut y_off = Vec::with_capacity(nb); // Y_b[c][j] at y_off[b] + c*p + j
    let mut cur = s0 + nb;
    for h in &factors {
        y_off.push(cur);
        cur += h.ncols() * p;
    }
    let n_var = cur;
    let mut q = vec![0.0; n_var];
    for bi in 0..nb {
        q[s0 + bi] = 1.0;
    }
    let mut a = Triplets::new();
    let mut b = Vec::new();
    let mut cones = Vec::new();
    let r = a.rows(1 + p * p);
    for i in 0..k {
        a.push(r, w0 + i, 1.0);
    }
    b.push(1.0);
    for aa in 0..p {
        for j in 0..p {
            let row = r + 1 + aa * p + j;
            for (bi, h) in factors.iter().enumerate() {
                for c in 0..h.ncols() {
                    a.push(row, y_off[bi] + c * p + j, h[(aa, c)]);
                }
            }
            b.push(kmat[(aa, j)]);
        }
    }
    cones.push(Cone::Zero(1 + p * p));
    let r = a.rows(k);
    for i in 0..k {
        a.push(r + i, w0 + i, -1.0);
        b.push(0.0);
    }
    cones.push(Cone::Nonnegative(k));
    for (bi, h) in factors.iter().enumerate() {
        let l = h.ncols();
        let r = a.rows(l * p + 2);
        a.push(r, s0 + bi, -1.0);
        a.push(r + 1, s0 + bi, -1.0);
        if bi < k {
            a.push(r, w0 + bi, -1.0);
            a.push(r + 1, w0 + bi, 1.0);
            b.push(0.0);
            b.push(0.0);
        } else {
            b.push(1.0);
            b.push(-1.0);
        }
        for c in 0..l {
            for j in 0..p {
                a.push(r + 2 + c * p + j, y_off[bi] + c * p + j, -2.0);
                b.push(0.0);
            }
        }
        cones.push(Cone::SecondOrder(l * p + 2));
    }
    solve(linear(n_var, q, a, b, cones), set, 1e-2 * set.clarabel_tol, k, ctl).1
}

/// E-optimal design: max t s.t. M(w) − tI ⪰ 0. Returns the PSD dual matrix in `dual`.
pub fn solve_e(pb: &Problem, set: &SolverOptions, ctl: &Control) -> ConicResult {
    let (p, k) = (pb.p(), pb.n());
    let w0 = 0;
    let t = k;
    let n_var = k + 1;
    let mut q = vec![0.0; n_var];
    q[t] = -1.0;
    let mut a = Triplets::new();
    let mut b = Vec::new();
    let mut cones = Vec::new();
    push_simplex(&mut a, &mut b, &mut cones, w0, k);
    let nsv = p * (p + 1) / 2;
    let r_psd = a.rows(nsv);
    let mut bb = vec![0.0; nsv];
    push_weighted_information(&mut a, &mut bb, r_psd, pb, w0);
    for j in 0..p {
        a.push(r_psd + svec_index(j, j), t, 1.0);
    }
    b.extend_from_slice(&bb);
    cones.push(Cone::PsdTriangle(p));
    let (z, mut res) = solve(linear(n_var, q, a, b, cones), set, 1e-2 * set.clarabel_tol, k, ctl);
    {
        // the dual rows of the PSD block follow the 1 + k rows before it
        let base = 1 + k;
        if z.len() >= base + nsv {
            let mut zm = DMatrix::zeros(p, p);
            for j in 0..p {
                for i in 0..=j {
                    let v = z[base + svec_index(i, j)] / svec_scale(i, j);
                    zm[(i, j)] = v;
                    zm[(j, i)] = v;
                }
            }
            res.dual = Some(zm);
        }
    }
    res
}
