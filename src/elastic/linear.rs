//! Linearisation of the elastic model at a static position, the parametric
//! FRF G(ω, θ) from motor torques to motor accelerations (or speeds or
//! positions), its analytic Jacobian ∂vec G/∂θ, and the information matrix of
//! paper 001 eq. 5.
//!
//! # Linear model
//!
//! With x = (q_m, q) (N = 2 n_a + n_e coordinates) the linearised equations at
//! a static equilibrium x* are M ẍ + D ẋ + K x = B τ_m with
//!
//! * M = blkdiag(diag(Ia), M_rb(q*)),
//! * K = Σ_j k_j b_j b_jᵀ + Σ_e k_e e_e e_eᵀ + blkdiag(0, ∂g/∂q(q*)) (gravity stiffness),
//! * D = Σ_j d_j b_j b_jᵀ + Σ_e d_e e_e e_eᵀ + diag(Fv, 0),
//! * b_j = e_{m,j} − Σ_a C_{ja} e_{q,a} (gearbox deflection direction), B = [I; 0].
//!
//! All three are symmetric, so A(s) = s²M + sD + K is complex symmetric and
//! G(s) = s^r Bᵀ A⁻¹ B (r = 2 accelerations, 1 speeds, 0 positions), with
//! W = A⁻¹B:
//!
//! ∂G/∂θ_i = −s^r Wᵀ (∂A/∂θ_i) W,
//!
//! a rank-one product for every spring, damper, rotor inertia and viscous
//! friction (∂A/∂k_j = b_j b_jᵀ, ∂A/∂d_j = s b_j b_jᵀ, ∂A/∂Ia_j = s² e_j e_jᵀ),
//! and s² ∂M + ∂K_g for a rigid inertial parameter (M_rb and ∂g/∂q are linear
//! in the inertial parameters).
//!
//! # Operating point
//!
//! A position is given by the actuated link coordinates q0. The elastic
//! joints take their static deflection under gravity, K_e q_e + g_e(q) = 0
//! (Newton iteration), computed with the parameter values passed to
//! [`ElasticModel::operating_point`] — the nominal ones in fitting — and held
//! fixed while θ varies. The deflections are of order g/k (≈10⁻³ rad), so the
//! linear model changes by that relative order if the true springs differ from
//! the nominal ones; [`ElasticModel::operating_point`] with the true values is
//! exact.

use super::model::{ElasticModel, ParamRole};
use crate::error::{Error, Result};
use crate::robot::{self, Workspace};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Complex scalar.
pub type C64 = num_complex::Complex<f64>;

/// Output of the FRF (motor side).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Output {
    /// Motor positions (rad per N·m).
    Position,
    /// Motor speeds.
    Velocity,
    /// Motor accelerations (paper 001 Fig. 9), the default.
    #[default]
    Acceleration,
}

impl Output {
    /// Power r of s = jω in G = s^r Bᵀ A⁻¹ B.
    pub fn power(self) -> i32 {
        match self {
            Output::Position => 0,
            Output::Velocity => 1,
            Output::Acceleration => 2,
        }
    }
}

/// A linearisation point: static equilibrium and the rigid-body matrices there.
#[derive(Debug, Clone)]
pub struct OperatingPoint {
    /// Actuated link coordinates (rad).
    pub q0: Vec<f64>,
    /// Extended coordinates at equilibrium (actuated + elastic deflections).
    pub q_ext: Vec<f64>,
    /// Extended standard parameters used for `m0`, `kg0`.
    pub pi0: Vec<f64>,
    /// Link-side mass matrix M_rb(q*) ((n_a+n_e)²).
    pub m0: DMatrix<f64>,
    /// Gravity stiffness ∂g/∂q(q*) ((n_a+n_e)², symmetrised).
    pub kg0: DMatrix<f64>,
    /// For every unknown rigid inertial parameter: (index in model params, ∂M_rb, ∂(∂g/∂q)).
    pub dlink: Vec<(usize, DMatrix<f64>, DMatrix<f64>)>,
    /// Static motor torques τ_m0 = C⁻ᵀ g_a (n_a).
    pub tau0: Vec<f64>,
    /// Static gearbox deflections δ0 = K_g⁻¹ τ_m0 (n_a).
    pub delta0: Vec<f64>,
}

/// The linear model M, D, K (N×N) at one operating point and parameter value.
#[derive(Debug, Clone)]
pub struct LinearModel {
    /// Mass matrix.
    pub m: DMatrix<f64>,
    /// Damping matrix.
    pub d: DMatrix<f64>,
    /// Stiffness matrix (springs + gravity).
    pub k: DMatrix<f64>,
    /// Number of motors n_a.
    pub n_motors: usize,
    /// Gearbox deflection directions b_j (N each).
    pub b: Vec<Vec<f64>>,
    /// Non-zero entries (index, value) of each b_j.
    pub b_nz: Vec<Vec<(usize, f64)>>,
    /// Full parameter values.
    pub vals: Vec<f64>,
}

fn sym(m: &mut DMatrix<f64>) {
    let n = m.nrows();
    for i in 0..n {
        for j in 0..i {
            let a = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = a;
            m[(j, i)] = a;
        }
    }
}

impl ElasticModel {
    /// Static equilibrium at actuated position `q0` for full parameter values
    /// `vals` ([`ElasticModel::full_values`]), with the rigid matrices there.
    pub fn operating_point(&self, q0: &[f64], vals: &[f64]) -> Result<OperatingPoint> {
        let na = self.n_motors();
        if q0.len() != na {
            return Err(Error::dim("position q0", na, q0.len()));
        }
        if q0.iter().any(|v| !v.is_finite()) {
            return Err(Error::Numerical("position q0 has non-finite entries".into()));
        }
        let nx = self.ext.dof();
        let pi = self.ext_params(vals);
        let mut ws = Workspace::new(&self.ext);
        let mut q = vec![0.0; nx];
        for j in 0..na {
            q[self.act_index[j]] = q0[j];
        }
        let zero = vec![0.0; nx];
        let mut tau = vec![0.0; nx];
        let ke: Vec<f64> = (0..self.n_elastic()).map(|e| self.value_of(vals, ParamRole::ArmSpring(e))).collect();
        // Newton on K_e q_e + g_e(q) = 0
        for _ in 0..50 {
            if self.n_elastic() == 0 {
                break;
            }
            robot::inverse_dynamics(&self.ext, &mut ws, &pi, &q, &zero, &zero, &mut tau);
            let (dg, _) = robot::id_derivatives(&self.ext, &mut ws, &pi, &q, &zero, &zero);
            let ne = self.n_elastic();
            let mut jac = DMatrix::zeros(ne, ne);
            let mut r = nalgebra::DVector::zeros(ne);
            for a in 0..ne {
                let ia = self.elastic_index[a];
                r[a] = ke[a] * q[ia] + tau[ia];
                for b in 0..ne {
                    jac[(a, b)] = dg[(ia, self.elastic_index[b])];
                }
                jac[(a, a)] += ke[a];
            }
            let step = jac.lu().solve(&r).ok_or_else(|| {
                Error::Numerical(format!(
                    "static equilibrium at q0 = {q0:?}: the elastic stiffness is singular (gravity exceeds the springs)"
                ))
            })?;
            let mut mx: f64 = 0.0;
            for a in 0..ne {
                q[self.elastic_index[a]] -= step[a];
                mx = mx.max(step[a].abs());
            }
            if mx < 1e-14 {
                break;
            }
        }
        robot::inverse_dynamics(&self.ext, &mut ws, &pi, &q, &zero, &zero, &mut tau);
        let m0 = robot::mass_matrix_with(&self.ext, &mut ws, &pi, &q);
        let (mut kg0, _) = robot::id_derivatives(&self.ext, &mut ws, &pi, &q, &zero, &zero);
        sym(&mut kg0);
        let mut dlink = Vec::new();
        for &u in &self.unknowns {
            if let ParamRole::Link(l) = self.params[u].role {
                let mut e = vec![0.0; pi.len()];
                e[l] = 1.0;
                let dm = robot::mass_matrix_with(&self.ext, &mut ws, &e, &q);
                let (mut dk, _) = robot::id_derivatives(&self.ext, &mut ws, &e, &q, &zero, &zero);
                sym(&mut dk);
                dlink.push((u, dm, dk));
            }
        }
        // static motor side: Cᵀ τ_m0 = g_a
        let ga = nalgebra::DVector::from_fn(na, |j, _| tau[self.act_index[j]]);
        let ct = self.coupling.transpose();
        let tau0 = ct.lu().solve(&ga).ok_or_else(|| Error::Numerical("coupling matrix is singular".into()))?;
        let delta0: Vec<f64> = (0..na).map(|j| tau0[j] / self.value_of(vals, ParamRole::GearSpring(j))).collect();
        Ok(OperatingPoint {
            q0: q0.to_vec(),
            q_ext: q,
            pi0: pi,
            m0,
            kg0,
            dlink,
            tau0: tau0.as_slice().to_vec(),
            delta0,
        })
    }

    /// The value of the parameter with `role` in full values `vals`.
    pub fn value_of(&self, vals: &[f64], role: ParamRole) -> f64 {
        self.params.iter().position(|p| p.role == role).map(|i| vals[i]).unwrap_or(0.0)
    }

    /// Assembles M, D, K at `op` for full parameter values `vals`.
    pub fn linear_model(&self, op: &OperatingPoint, vals: &[f64]) -> LinearModel {
        let na = self.n_motors();
        let nx = self.ext.dof();
        let n = na + nx;
        let mut m = DMatrix::zeros(n, n);
        let mut d = DMatrix::zeros(n, n);
        let mut k = DMatrix::zeros(n, n);
        let mut ml = op.m0.clone();
        let mut kl = op.kg0.clone();
        for (u, dm, dk) in &op.dlink {
            if let ParamRole::Link(l) = self.params[*u].role {
                let dv = vals[*u] - op.pi0[l];
                if dv != 0.0 {
                    ml += dm * dv;
                    kl += dk * dv;
                }
            }
        }
        m.view_mut((na, na), (nx, nx)).copy_from(&ml);
        k.view_mut((na, na), (nx, nx)).copy_from(&kl);
        let b: Vec<Vec<f64>> = (0..na)
            .map(|j| {
                let mut v = vec![0.0; n];
                v[j] = 1.0;
                for a in 0..na {
                    v[na + self.act_index[a]] -= self.coupling[(j, a)];
                }
                v
            })
            .collect();
        for (p, &v) in self.params.iter().zip(vals) {
            match p.role {
                ParamRole::GearSpring(j) | ParamRole::GearDamper(j) => {
                    let t = if matches!(p.role, ParamRole::GearSpring(_)) { &mut k } else { &mut d };
                    let bj = &b[j];
                    for r in 0..n {
                        if bj[r] != 0.0 {
                            for c in 0..n {
                                t[(r, c)] += v * bj[r] * bj[c];
                            }
                        }
                    }
                }
                ParamRole::ArmSpring(e) => {
                    let x = na + self.elastic_index[e];
                    k[(x, x)] += v;
                }
                ParamRole::ArmDamper(e) => {
                    let x = na + self.elastic_index[e];
                    d[(x, x)] += v;
                }
                ParamRole::RotorInertia(j) => m[(j, j)] += v,
                ParamRole::MotorViscous(j) => d[(j, j)] += v,
                ParamRole::Link(_) => {}
            }
        }
        let b_nz = b
            .iter()
            .map(|bj| bj.iter().enumerate().filter(|(_, v)| **v != 0.0).map(|(i, v)| (i, *v)).collect())
            .collect();
        LinearModel {
            m,
            d,
            k,
            n_motors: na,
            b,
            b_nz,
            vals: vals.to_vec(),
        }
    }
}

/// Per-thread buffers and cached structure for FRF evaluations of one model.
#[derive(Debug, Clone)]
pub struct FrfKernel {
    roles: Vec<ParamRole>,
    unknowns: Vec<usize>,
    elastic_index: Vec<usize>,
    n_motors: usize,
    /// Always solve the full N×N system (the reference path, for tests).
    full_solve: bool,
}

impl FrfKernel {
    /// A kernel for `model`.
    pub fn new(model: &ElasticModel) -> Self {
        FrfKernel {
            roles: model.params.iter().map(|p| p.role).collect(),
            unknowns: model.unknowns.clone(),
            elastic_index: model.elastic_index.clone(),
            n_motors: model.n_motors(),
            full_solve: false,
        }
    }

    /// The same kernel solving the full N×N system A W = B at every line by
    /// Gaussian elimination with partial pivoting (no motor-block
    /// elimination): the reference path the fast one is tested against.
    pub fn with_full_solve(mut self) -> Self {
        self.full_solve = true;
        self
    }

    /// G(jω) (n_a × n_a) and, if `jac`, ∂G/∂θ_i for every unknown i (in
    /// physical units of θ) into `dg` (resized to p).
    pub fn eval(&self, lin: &LinearModel, op: &OperatingPoint, omega: f64, output: Output, jac: bool, dg: &mut Vec<DMatrix<C64>>) -> Result<DMatrix<C64>> {
        let na = self.n_motors;
        let n = lin.m.nrows();
        let s = C64::new(0.0, omega);
        let s2 = s * s;
        let mut w = vec![C64::new(0.0, 0.0); n * na];
        if !solve_w(lin, s, &mut w, self.full_solve) {
            return Err(Error::Numerical(format!(
                "the linear model is singular at ω = {omega} rad/s (an undamped pole on the grid)"
            )));
        }
        let wv = |r: usize, j: usize| w[r * na + j];
        let sr = s.powi(output.power());
        let g = DMatrix::from_fn(na, na, |i, j| sr * wv(i, j));
        if !jac {
            return Ok(g);
        }
        dg.resize(self.unknowns.len(), DMatrix::zeros(na, na));
        let mut v = vec![C64::new(0.0, 0.0); na];
        // out = −s^r c vᵀ v with v = bᵀ W over the non-zero entries of b
        let mut rank1 = |entries: &mut dyn Iterator<Item = (usize, f64)>, c: C64, out: &mut DMatrix<C64>| {
            v.iter_mut().for_each(|x| *x = C64::new(0.0, 0.0));
            for (r, br) in entries {
                for j in 0..na {
                    v[j] += wv(r, j) * br;
                }
            }
            let f = -sr * c;
            for i in 0..na {
                let fi = f * v[i];
                for j in 0..na {
                    out[(i, j)] = fi * v[j];
                }
            }
        };
        let one = C64::new(1.0, 0.0);
        for (k, &u) in self.unknowns.iter().enumerate() {
            let out = &mut dg[k];
            if out.nrows() != na || out.ncols() != na {
                *out = DMatrix::zeros(na, na);
            }
            match self.roles[u] {
                ParamRole::GearSpring(j) | ParamRole::GearDamper(j) => {
                    let c = if matches!(self.roles[u], ParamRole::GearSpring(_)) { one } else { s };
                    rank1(&mut lin.b_nz[j].iter().copied(), c, out);
                }
                ParamRole::ArmSpring(e) | ParamRole::ArmDamper(e) => {
                    let x = na + self.elastic_index[e];
                    let c = if matches!(self.roles[u], ParamRole::ArmSpring(_)) { one } else { s };
                    rank1(&mut std::iter::once((x, 1.0)), c, out);
                }
                ParamRole::RotorInertia(j) => rank1(&mut std::iter::once((j, 1.0)), s2, out),
                ParamRole::MotorViscous(j) => rank1(&mut std::iter::once((j, 1.0)), s, out),
                ParamRole::Link(_) => {
                    let (_, dm, dk) = op
                        .dlink
                        .iter()
                        .find(|(uu, _, _)| *uu == u)
                        .ok_or_else(|| Error::Numerical("operating point was built for other unknowns".into()))?;
                    let nx = dm.nrows();
                    // T = (s² dM + dK) W_link (nx × na); out = −s^r W_linkᵀ T
                    let mut t = DMatrix::from_element(nx, na, C64::new(0.0, 0.0));
                    for r in 0..nx {
                        for c in 0..nx {
                            let coef = s2 * dm[(r, c)] + C64::new(dk[(r, c)], 0.0);
                            if coef.re == 0.0 && coef.im == 0.0 {
                                continue;
                            }
                            for j in 0..na {
                                t[(r, j)] += coef * wv(na + c, j);
                            }
                        }
                    }
                    for i in 0..na {
                        for j in 0..na {
                            let mut acc = C64::new(0.0, 0.0);
                            for r in 0..nx {
                                acc += wv(na + r, i) * t[(r, j)];
                            }
                            out[(i, j)] = -sr * acc;
                        }
                    }
                }
            }
        }
        Ok(g)
    }
}

/// W = A(s)⁻¹ B (N × n_a, row-major, into `w`, which must be zero) for
/// A(s) = s²M + sD + K and B = [I; 0].
///
/// The motor block A_mm of A is diagonal in this model (rotor inertia,
/// motor friction and the motor end of each gearbox spring–damper only act
/// on their own motor coordinate), so the motor coordinates are eliminated
/// first: with S = A_ll − A_lm A_mm⁻¹ A_ml (the n_x×n_x link-side Schur
/// complement),
///
/// W_l = −S⁻¹ A_lm A_mm⁻¹,  W_m = A_mm⁻¹ (I − A_ml W_l),
///
/// one (n_x)³/3 elimination instead of N³/3 (13 instead of 19 unknowns on
/// the shipped six-axis model, a third of the work). If the motor block is
/// not diagonal, or a diagonal entry is tiny relative to its terms (an
/// undamped motor resonance on the line, where elimination without pivoting
/// would lose digits), or `full` is set, the full system is solved with
/// partial pivoting instead. False if A is singular.
fn solve_w(lin: &LinearModel, s: C64, w: &mut [C64], full: bool) -> bool {
    let n = lin.m.nrows();
    let na = lin.n_motors;
    let nx = n - na;
    let s2 = s * s;
    let at = |i: usize, j: usize| s2 * lin.m[(i, j)] + s * lin.d[(i, j)] + C64::new(lin.k[(i, j)], 0.0);
    let mut schur = !full && na > 0 && nx > 0;
    let mut am = vec![C64::new(0.0, 0.0); na];
    if schur {
        'check: for i in 0..na {
            for j in 0..na {
                if i != j && (lin.m[(i, j)] != 0.0 || lin.d[(i, j)] != 0.0 || lin.k[(i, j)] != 0.0) {
                    schur = false;
                    break 'check;
                }
            }
            am[i] = at(i, i);
            let scale = (s2 * lin.m[(i, i)]).norm() + (s * lin.d[(i, i)]).norm() + lin.k[(i, i)].abs();
            let ok = am[i].norm() > 1e-6 * scale; // false for NaN too
            if !ok {
                schur = false;
                break;
            }
        }
    }
    if !schur {
        let mut a = vec![C64::new(0.0, 0.0); n * n];
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = at(i, j);
            }
        }
        for j in 0..na {
            w[j * na + j] = C64::new(1.0, 0.0);
        }
        return solve_in_place(&mut a, n, w, na);
    }
    let inv_am: Vec<C64> = am.iter().map(|a| C64::new(1.0, 0.0) / a).collect();
    // A_ml (na × nx) and A_lm (nx × na), non-zero entries only
    let mut aml: Vec<Vec<(usize, C64)>> = vec![Vec::new(); na];
    let mut alm: Vec<Vec<(usize, C64)>> = vec![Vec::new(); nx];
    for j in 0..na {
        for c in 0..nx {
            let (r, cc) = (j, na + c);
            if lin.m[(r, cc)] != 0.0 || lin.d[(r, cc)] != 0.0 || lin.k[(r, cc)] != 0.0 {
                aml[j].push((c, at(r, cc)));
            }
            if lin.m[(cc, r)] != 0.0 || lin.d[(cc, r)] != 0.0 || lin.k[(cc, r)] != 0.0 {
                alm[c].push((j, at(cc, r)));
            }
        }
    }
    // S = A_ll − A_lm A_mm⁻¹ A_ml, right-hand side R = −A_lm A_mm⁻¹
    let mut sm = vec![C64::new(0.0, 0.0); nx * nx];
    for r in 0..nx {
        for c in 0..nx {
            sm[r * nx + c] = at(na + r, na + c);
        }
    }
    let mut rhs = vec![C64::new(0.0, 0.0); nx * na];
    for r in 0..nx {
        for &(j, v) in &alm[r] {
            let f = v * inv_am[j];
            rhs[r * na + j] -= f;
            for &(c, u) in &aml[j] {
                sm[r * nx + c] -= f * u;
            }
        }
    }
    if !solve_in_place(&mut sm, nx, &mut rhs, na) {
        return false;
    }
    // W_l = rhs; W_m = A_mm⁻¹ (I − A_ml W_l)
    for j in 0..na {
        for i in 0..na {
            let mut acc = if i == j { C64::new(1.0, 0.0) } else { C64::new(0.0, 0.0) };
            for &(c, u) in &aml[j] {
                acc -= u * rhs[c * na + i];
            }
            w[j * na + i] = acc * inv_am[j];
        }
    }
    w[na * na..].copy_from_slice(&rhs);
    true
}

/// Solves A X = B in place by Gaussian elimination with partial pivoting
/// (A: n×n, B: n×m, both row-major); X overwrites B. False if A is singular.
pub(crate) fn solve_in_place(a: &mut [C64], n: usize, b: &mut [C64], m: usize) -> bool {
    for k in 0..n {
        let mut p = k;
        let mut best = a[k * n + k].norm_sqr();
        for i in k + 1..n {
            let v = a[i * n + k].norm_sqr();
            if v > best {
                best = v;
                p = i;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            for j in 0..m {
                b.swap(k * m + j, p * m + j);
            }
        }
        let inv = C64::new(1.0, 0.0) / a[k * n + k];
        let (top, rest) = a.split_at_mut((k + 1) * n);
        let pivot_row = &top[k * n + k + 1..(k + 1) * n];
        let (btop, brest) = b.split_at_mut((k + 1) * m);
        let pivot_b = &btop[k * m..(k + 1) * m];
        for i in 0..n - k - 1 {
            let row = &mut rest[i * n..(i + 1) * n];
            let f = row[k] * inv;
            if f.re == 0.0 && f.im == 0.0 {
                continue;
            }
            for (x, t) in row[k + 1..].iter_mut().zip(pivot_row) {
                *x -= f * t;
            }
            for (x, t) in brest[i * m..(i + 1) * m].iter_mut().zip(pivot_b) {
                *x -= f * t;
            }
        }
    }
    for k in (0..n).rev() {
        let inv = C64::new(1.0, 0.0) / a[k * n + k];
        for j in 0..m {
            let mut acc = b[k * m + j];
            for c in k + 1..n {
                acc -= a[k * n + c] * b[c * m + j];
            }
            b[k * m + j] = acc * inv;
        }
    }
    true
}

/// The parametric FRF G(ω_k, θ) at position `op` for unknowns `theta`, one
/// n_a×n_a matrix per angular frequency in `omegas` (rad/s).
pub fn frf(model: &ElasticModel, op: &OperatingPoint, theta: &[f64], omegas: &[f64], output: Output) -> Result<Vec<DMatrix<C64>>> {
    let vals = model.full_values(theta)?;
    let lin = model.linear_model(op, &vals);
    let ker = FrfKernel::new(model);
    let mut dg = Vec::new();
    omegas.iter().map(|&w| ker.eval(&lin, op, w, output, false, &mut dg)).collect()
}

/// FRFs per line and their Jacobians per line and parameter.
pub type FrfWithJacobian = (Vec<DMatrix<C64>>, Vec<Vec<DMatrix<C64>>>);

/// G(ω_k, θ) and its Jacobian: `(g[k], dg[k][i])` with `dg[k][i]` = ∂G(ω_k)/∂θ_i
/// (physical units of θ), i over the model's unknowns.
pub fn frf_jacobian(model: &ElasticModel, op: &OperatingPoint, theta: &[f64], omegas: &[f64], output: Output) -> Result<FrfWithJacobian> {
    let vals = model.full_values(theta)?;
    let lin = model.linear_model(op, &vals);
    let ker = FrfKernel::new(model);
    let mut gs = Vec::with_capacity(omegas.len());
    let mut dgs = Vec::with_capacity(omegas.len());
    for &w in omegas {
        let mut dg = Vec::new();
        gs.push(ker.eval(&lin, op, w, output, true, &mut dg)?);
        dgs.push(dg);
    }
    Ok((gs, dgs))
}

/// The estimator whose information is wanted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Estimator {
    /// Weighted nonlinear least squares, paper 001 eq. 4: E = vec Ĝ − vec G.
    Nls,
    /// Weighted logarithmic least squares, eq. 7: E = log(vec Ĝ / vec G).
    #[default]
    Lls,
    /// Magnitude-only LLS: E = log|Ĝ| − log|G| (real).
    LlsMagnitude,
}

impl Estimator {
    /// Short name used in file names and reports.
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Nls => "nls",
            Estimator::Lls => "lls",
            Estimator::LlsMagnitude => "lls_magnitude",
        }
    }
}

/// Noise on the FRF estimate vec Ĝ (circular complex, independent elements).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum NoiseModel {
    /// Every element has standard deviation `sigma` (units of G).
    Absolute {
        /// σ of each element.
        sigma: f64,
    },
    /// Element (i, j) has standard deviation `rel`·|G_ij|.
    Relative {
        /// Relative σ.
        rel: f64,
    },
}

impl NoiseModel {
    fn check(&self) -> Result<()> {
        let v = match *self {
            NoiseModel::Absolute { sigma } => sigma,
            NoiseModel::Relative { rel } => rel,
        };
        if !v.is_finite() || v <= 0.0 {
            return Err(Error::invalid("noise model", "sigma/rel", format!("expected a positive number, found {v}")));
        }
        Ok(())
    }
    /// Variance of element with value `g`.
    pub fn variance(&self, g: C64) -> f64 {
        match *self {
            NoiseModel::Absolute { sigma } => sigma * sigma,
            NoiseModel::Relative { rel } => rel * rel * g.norm_sqr(),
        }
    }
}

/// Adds Σ_elements w_e Re{conj(ψ_e) ψ_eᵀ} for one frequency to `f`, ψ_e the
/// row of ∂vec G/∂θ in the estimator's domain, w_e = 1/var_e (var in that domain).
pub fn accumulate_information(f: &mut DMatrix<f64>, g: &DMatrix<C64>, dg: &[DMatrix<C64>], weight: &dyn Fn(usize, usize) -> f64, estimator: Estimator) {
    let p = dg.len();
    let na = g.nrows();
    let mut psi = vec![C64::new(0.0, 0.0); p];
    for i in 0..na {
        for j in 0..na {
            let w = weight(i, j);
            if w == 0.0 {
                continue;
            }
            let gij = g[(i, j)];
            for (k, d) in dg.iter().enumerate() {
                psi[k] = match estimator {
                    Estimator::Nls => d[(i, j)],
                    Estimator::Lls => d[(i, j)] / gij,
                    Estimator::LlsMagnitude => C64::new((d[(i, j)] / gij).re, 0.0),
                };
            }
            for a in 0..p {
                for b in a..p {
                    let v = w * (psi[a].conj() * psi[b]).re;
                    f[(a, b)] += v;
                    if a != b {
                        f[(b, a)] += v;
                    }
                }
            }
        }
    }
}

/// The information matrix F = Σ_k Re{Ψ̄(k) Λ⁻¹ Ψ(k)ᵀ} (p×p, paper 001 eq. 5 with
/// optimal weights, eq. 6/8) of one experiment at actuated position `q0`,
/// angular frequencies `omegas` (rad/s), with the noise model `noise` on
/// vec Ĝ, for the nominal parameters and in the physical units of θ (order of
/// [`ElasticModel::unknown_names`]).
///
/// The asymptotic covariance is P_θ = ½ F⁻¹ (eq. 5; the ½ comes from the
/// circular complex noise). For [`Estimator::Nls`] Ψ = ∂vec G/∂θ and
/// Λ = diag(var Ĝ_ij); for [`Estimator::Lls`] Ψ = ∂vec log G/∂θ and
/// Λ = diag(var Ĝ_ij/|G_ij|²) — with optimal weights both give the same F;
/// for [`Estimator::LlsMagnitude`] only Re Ψ (the log-magnitude) enters.
/// Information matrices of independent experiments add.
pub fn information_matrix(model: &ElasticModel, q0: &[f64], omegas: &[f64], noise: &NoiseModel, estimator: Estimator) -> Result<DMatrix<f64>> {
    noise.check()?;
    let theta = model.nominal_unknowns();
    let vals = model.full_values(&theta)?;
    let op = model.operating_point(q0, &vals)?;
    information_matrix_at(model, &op, &theta, omegas, noise, estimator, Output::Acceleration)
}

/// [`information_matrix`] at a given operating point, parameter vector and output.
pub fn information_matrix_at(
    model: &ElasticModel,
    op: &OperatingPoint,
    theta: &[f64],
    omegas: &[f64],
    noise: &NoiseModel,
    estimator: Estimator,
    output: Output,
) -> Result<DMatrix<f64>> {
    noise.check()?;
    if omegas.iter().any(|w| !w.is_finite() || *w <= 0.0) {
        return Err(Error::invalid(
            "information matrix",
            "omegas",
            "expected positive finite angular frequencies (rad/s)",
        ));
    }
    let p = model.n_unknowns();
    let vals = model.full_values(theta)?;
    let lin = model.linear_model(op, &vals);
    let ker = FrfKernel::new(model);
    let mut f = DMatrix::zeros(p, p);
    let mut dg = Vec::new();
    for &w in omegas {
        let g = ker.eval(&lin, op, w, output, true, &mut dg)?;
        let wfun = |i: usize, j: usize| {
            let gij = g[(i, j)];
            let var = noise.variance(gij);
            let var_dom = match estimator {
                Estimator::Nls => var,
                Estimator::Lls | Estimator::LlsMagnitude => var / gij.norm_sqr().max(f64::MIN_POSITIVE),
            };
            if var_dom > 0.0 && var_dom.is_finite() {
                1.0 / var_dom
            } else {
                0.0
            }
        };
        accumulate_information(&mut f, &g, &dg, &wfun, estimator);
    }
    Ok(f)
}
