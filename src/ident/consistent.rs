//! Physically consistent identification by semidefinite programming
//! (`identify --consistent`).
//!
//! The weighted least-squares fit in base parameters, ‖W^{1/2}(Y_b θ_b − τ)‖²,
//! equals ‖R (θ_b − θ̂_b)‖² + SSR_WLS, with R the triangular factor of the QR
//! decomposition of W^{1/2} Y_b and θ̂_b the WLS estimate (the same weights as
//! WLS). The consistent estimate chooses standard parameters θ (θ_b = K θ) to
//!
//! min_θ ‖R (K θ − θ̂_b)‖² + λ ‖D^{1/2}(θ − θ_0)‖²
//! s.t. J_i(θ) ⪰ ε I₄ for every link i (Wensing, Kim & Slotine 2017),
//!      Ia_j ≥ 0, Fc_j ≥ 0, Fv_j ≥ 0, Fc⁺ ≥ 0, Fc⁻ ≤ 0, Fv± ≥ 0 for every drive,
//!
//! where J_i = [[½ tr(I_i) 1 − I_i, h_i], [h_iᵀ, m_i]] is the pseudo-inertia
//! of link i (I_i the inertia about the link origin, h_i = m_i c_i the first
//! moment, m_i the mass): J_i ⪰ 0 exactly when some non-negative mass
//! distribution has these moments (mass ≥ 0, inertia about the centre of mass
//! ⪰ 0 with the triangle inequalities). The λ-term picks, among the standard
//! parameters with the same base parameters, the one closest to the nominal
//! (CAD) values θ_0 ("closest to CAD"); D = diag(1/s_j²) with s_j = max(|θ_0,j|,
//! 10 % of the largest nominal value of its kind: inertias, first moments,
//! masses, drive parameters), and λ = `regularization` · σ²_min(R) (R scaled
//! to unit mean squared row norm), so `regularization` is the weight of a
//! 100 % deviation from CAD relative to the fit's smallest curvature: the
//! default 10⁻⁶ decides only what the data leave open. Where the WLS estimate is already consistent, the fit
//! term vanishes at a consistent θ and the estimate reproduces WLS (up to the
//! small λ-term and the solver tolerance).
//!
//! As one conic program for Clarabel, with variables x = (θ, t): minimise t
//! subject to (t, R(Kθ − θ̂_b), √λ D^{1/2}(θ − θ_0)) in the second-order cone,
//! svec(J_i(θ) − ε I) in the 4×4 PSD cone for every link, and the sign
//! constraints of the drive parameters in the non-negative cone.

use crate::error::{Error, Result};
use crate::optim::conic::{self as bridge, Cone, ConicStatus, Entries as Triplets, Program, Settings};
use crate::optim::Control;
use crate::robot::{ParamKind, ParamSign, Robot};
use nalgebra::{DMatrix, DVector, Matrix4, SymmetricEigen};
use serde::Serialize;

/// What a standard parameter is to the consistent fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// XX..ZZ, MX..MZ, M at offsets 0..9 of a link block.
    Inertial(usize),
    /// Must be ≥ 0 (Ia, Fc, Fv, Fc⁺, Fv⁺, Fv⁻).
    NonNegative,
    /// Must be ≤ 0 (Fc⁻ of the asymmetric model).
    NonPositive,
    /// Free (offsets F0).
    Free,
}

/// The role of every standard parameter of `robot`, and the index of each
/// link's first inertial parameter.
pub fn kinds_of(robot: &Robot) -> (Vec<Kind>, Vec<usize>) {
    let kinds = robot
        .params()
        .iter()
        .map(|p| match p.kind {
            k if k.is_inertial() => Kind::Inertial(ParamKind::INERTIAL.iter().position(|x| *x == k).unwrap_or(0)),
            k => match k.sign() {
                ParamSign::NonNegative => Kind::NonNegative,
                ParamSign::NonPositive => Kind::NonPositive,
                ParamSign::Free => Kind::Free,
            },
        })
        .collect();
    let links = (0..robot.dof()).map(|i| robot.link_param_offset(i)).collect();
    (kinds, links)
}

/// Options of the consistent fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ConsistentOptions {
    /// ε: J_i ⪰ ε I₄ (kg·m²; 0 allows point masses and thin rods).
    pub margin: f64,
    /// Weight of the closest-to-nominal term (see the module documentation).
    pub regularization: f64,
}

impl Default for ConsistentOptions {
    fn default() -> Self {
        ConsistentOptions {
            margin: 0.0,
            regularization: 1e-6,
        }
    }
}

/// The raw solution of [`solve`].
#[derive(Debug, Clone)]
pub struct Solution {
    /// Standard parameters θ.
    pub theta: DVector<f64>,
    /// Base parameters K θ.
    pub base: DVector<f64>,
    /// ‖R(Kθ − θ̂_b)‖²: the increase of the weighted residual sum of squares over WLS.
    pub extra_cost: f64,
    /// Smallest eigenvalue of each link's pseudo-inertia (kg·m²).
    pub min_eig: Vec<f64>,
    /// Clarabel's status.
    pub status: ConicStatus,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Solver time (s).
    pub solve_time: f64,
    /// λ used.
    pub lambda: f64,
}

/// The 4×4 pseudo-inertia of a link block θ[0..10] = (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M).
pub fn pseudo_inertia(p: &[f64]) -> Matrix4<f64> {
    let (xx, xy, xz, yy, yz, zz) = (p[0], p[1], p[2], p[3], p[4], p[5]);
    let tr = 0.5 * (xx + yy + zz);
    Matrix4::new(
        tr - xx,
        -xy,
        -xz,
        p[6], //
        -xy,
        tr - yy,
        -yz,
        p[7], //
        -xz,
        -yz,
        tr - zz,
        p[8], //
        p[6],
        p[7],
        p[8],
        p[9],
    )
}

/// Smallest eigenvalue of the pseudo-inertia of a link block.
pub fn min_pseudo_eigenvalue(p: &[f64]) -> f64 {
    SymmetricEigen::new(pseudo_inertia(p)).eigenvalues.min()
}

/// Linear map of a link block to J's entry (r, c): coefficients on the 10 parameters.
fn j_entry(r: usize, c: usize) -> [f64; 10] {
    let mut a = [0.0; 10];
    let (r, c) = if r <= c { (r, c) } else { (c, r) };
    match (r, c) {
        (0, 0) => {
            a[0] = -0.5;
            a[3] = 0.5;
            a[5] = 0.5
        }
        (1, 1) => {
            a[0] = 0.5;
            a[3] = -0.5;
            a[5] = 0.5
        }
        (2, 2) => {
            a[0] = 0.5;
            a[3] = 0.5;
            a[5] = -0.5
        }
        (0, 1) => a[1] = -1.0,
        (0, 2) => a[2] = -1.0,
        (1, 2) => a[4] = -1.0,
        (0, 3) => a[6] = 1.0,
        (1, 3) => a[7] = 1.0,
        (2, 3) => a[8] = 1.0,
        _ => a[9] = 1.0,
    }
    a
}

/// The problem data of [`solve`].
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// R (rows × n_base): the fit is ‖R(Kθ − θ̂_b)‖².
    pub r: &'a DMatrix<f64>,
    /// θ̂_b, the WLS estimate.
    pub theta_b: &'a DVector<f64>,
    /// K (n_base × p).
    pub k: &'a DMatrix<f64>,
    /// Index of each link's first inertial parameter.
    pub links: &'a [usize],
    /// Role of every standard parameter.
    pub kinds: &'a [Kind],
    /// θ_0 of the regularisation.
    pub nominal: &'a DVector<f64>,
    /// s_j of the regularisation (D = diag(1/s²)).
    pub scale: &'a DVector<f64>,
}

/// Runs a consistent-fit program through the Clarabel bridge under `ctl`
/// (500 iterations, the control's deadline as time limit, Ctrl-C through
/// the termination callback; with `progress`, each iteration reported to
/// the observer). A program Clarabel refuses to set up is an error; how a
/// run ended is the returned status.
pub(crate) fn run_clarabel(prog: Program, ctl: &Control, progress: bool) -> Result<bridge::Solved> {
    let settings = Settings {
        max_iter: Some(500),
        progress,
        ..Settings::default()
    };
    let sol = bridge::solve(prog, &settings, ctl);
    match &sol.status {
        ConicStatus::Settings(_) | ConicStatus::Setup(_) => Err(Error::Numerical(format!("Clarabel: {}", sol.status))),
        ConicStatus::Solver(_) => Ok(sol),
    }
}

/// Solves the consistent fit (see the module documentation); `ctl` stops
/// it (Ctrl-C: status `CallbackTerminated`; its deadline: `MaxTime`) and
/// receives its progress.
pub fn solve(pb: &Problem, o: &ConsistentOptions, ctl: &Control) -> Result<Solution> {
    let Problem {
        r,
        theta_b,
        k,
        links,
        kinds,
        nominal,
        scale,
    } = *pb;
    let nb = r.nrows();
    let p = k.ncols();
    if r.ncols() != k.nrows() || theta_b.len() != k.nrows() || kinds.len() != p || nominal.len() != p || scale.len() != p {
        return Err(Error::dim("consistent fit: parameters", p, kinds.len()));
    }
    if !(o.margin.is_finite() && o.margin >= 0.0) {
        return Err(Error::invalid(
            "consistent",
            "margin",
            format!("expected a margin ≥ 0 (kg·m²), found {}", o.margin),
        ));
    }
    if !(o.regularization.is_finite() && o.regularization > 0.0) {
        return Err(Error::invalid(
            "consistent",
            "regularization",
            format!(
                "expected a positive weight (it fixes the standard parameters the data cannot tell apart), found {}",
                o.regularization
            ),
        ));
    }
    let nx = p + 1;
    let it = p;
    // scale the fit so that its curvature is O(1): Clarabel's tolerances are absolute-ish
    let rn = (r.norm_squared() / nb.max(1) as f64).sqrt().max(1e-300);
    let rs = r / rn;
    let rk = &rs * k;
    let c = &rs * theta_b;
    // λ relative to the smallest curvature of the fit: the regularisation only
    // decides what the data leave open (the null space of K, and nearly so)
    let smin2 = rs.singular_values().iter().cloned().fold(f64::INFINITY, f64::min).powi(2);
    let lam = o.regularization * if smin2.is_finite() && smin2 > 0.0 { smin2 } else { 1.0 };
    let sl = lam.sqrt();
    let mut a = Triplets::new();
    let mut b: Vec<f64> = Vec::new();
    let mut cones = Vec::new();
    // SOC: (t, R(Kθ − θ̂_b), √λ D^{1/2}(θ − θ0)); s = b − A x
    let r0 = a.rows(1 + nb + p);
    a.push(r0, it, -1.0);
    b.push(0.0);
    for i in 0..nb {
        for j in 0..p {
            a.push(r0 + 1 + i, j, -rk[(i, j)]);
        }
        b.push(-c[i]);
    }
    for j in 0..p {
        let d = sl / scale[j];
        a.push(r0 + 1 + nb + j, j, -d);
        b.push(-d * nominal[j]);
    }
    cones.push(Cone::SecondOrder(1 + nb + p));
    // PSD cones: svec, upper triangle column by column, off-diagonals × √2
    let s2 = std::f64::consts::SQRT_2;
    for &l in links {
        for col in 0..4 {
            for row in 0..=col {
                let w = if row == col { 1.0 } else { s2 };
                let e = j_entry(row, col);
                let ri = a.rows(1);
                for (q, v) in e.iter().enumerate() {
                    a.push(ri, l + q, -w * v);
                }
                b.push(if row == col { -o.margin } else { 0.0 });
            }
        }
        cones.push(Cone::PsdTriangle(4));
    }
    let signed: Vec<(usize, f64)> = (0..p)
        .filter_map(|j| match kinds[j] {
            Kind::NonNegative => Some((j, 1.0)),
            Kind::NonPositive => Some((j, -1.0)),
            _ => None,
        })
        .collect();
    if !signed.is_empty() {
        for &(j, sg) in &signed {
            let ri = a.rows(1);
            a.push(ri, j, -sg);
            b.push(0.0);
        }
        cones.push(Cone::Nonnegative(signed.len()));
    }
    let mut q = vec![0.0; nx];
    q[it] = 1.0;
    let sol = run_clarabel(
        Program {
            n_var: nx,
            p: None,
            q,
            a,
            b,
            cones,
        },
        ctl,
        true,
    )?;
    let x = &sol.x;
    let theta = DVector::from_iterator(p, x[..p].iter().copied());
    let base = k * &theta;
    let extra = (r * (&base - theta_b)).norm_squared();
    let min_eig = links.iter().map(|&l| min_pseudo_eigenvalue(&theta.as_slice()[l..l + 10])).collect();
    Ok(Solution {
        theta,
        base,
        extra_cost: extra,
        min_eig,
        status: sol.status,
        iterations: sol.iterations,
        solve_time: sol.solve_time,
        lambda: lam,
    })
}

/// The scales s_j of the regularisation: |θ_0,j|, at least 10 % of the largest
/// nominal value of its kind (inertias, first moments, masses, drive parameters; 1 if all are 0).
pub fn regularization_scale(kinds: &[Kind], nominal: &DVector<f64>) -> DVector<f64> {
    let class = |k: Kind| match k {
        Kind::Inertial(q) if q < 6 => 0,
        Kind::Inertial(q) if q < 9 => 1,
        Kind::Inertial(_) => 2,
        _ => 3,
    };
    let mut big = [0.0f64; 4];
    for (j, &k) in kinds.iter().enumerate() {
        big[class(k)] = big[class(k)].max(nominal[j].abs());
    }
    DVector::from_iterator(
        kinds.len(),
        kinds.iter().enumerate().map(|(j, &k)| {
            let floor = if big[class(k)] > 0.0 { 0.1 * big[class(k)] } else { 1.0 };
            nominal[j].abs().max(floor)
        }),
    )
}

/// A constraint at its bound in the consistent estimate.
#[derive(Debug, Clone, Serialize)]
pub struct Active {
    /// `pseudo_inertia` (J_i ⪰ εI) or `sign` (a drive parameter at 0).
    pub constraint: String,
    /// Link (pseudo-inertia) or parameter name (sign).
    pub what: String,
    /// Smallest eigenvalue of J_i − εI, or the parameter's value.
    pub value: f64,
}

/// One body's standard parameters in Pinocchio's order and convention
/// (`Inertia::toDynamicParameters`): [m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy,
/// Ixz, Iyz, Izz], the inertia about the body (link) frame origin in link axes.
#[derive(Debug, Clone, Serialize)]
pub struct PinocchioBody {
    /// Link name.
    pub link: String,
    /// The 10 dynamic parameters.
    pub parameters: [f64; 10],
}

/// idexp's link block (XX, XY, XZ, YY, YZ, ZZ, MX, MY, MZ, M) in Pinocchio's order.
pub fn to_pinocchio(p: &[f64]) -> [f64; 10] {
    [p[9], p[6], p[7], p[8], p[0], p[1], p[3], p[2], p[4], p[5]]
}

/// How the consistent fit ended (`status` in estimate.json: `ok` or `failed: <Clarabel status>`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConsistentStatus {
    /// Clarabel solved the program (or almost: within its reduced tolerances).
    Ok,
    /// Clarabel ended with this status: the result is not a usable estimate.
    Failed(String),
}

impl ConsistentStatus {
    /// True for [`ConsistentStatus::Ok`].
    pub fn is_ok(&self) -> bool {
        matches!(self, ConsistentStatus::Ok)
    }

    /// From Clarabel's status.
    pub fn of(s: &ConicStatus) -> ConsistentStatus {
        if s.is_solved() {
            ConsistentStatus::Ok
        } else {
            ConsistentStatus::Failed(s.to_string())
        }
    }
}

impl std::fmt::Display for ConsistentStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConsistentStatus::Ok => f.write_str("ok"),
            ConsistentStatus::Failed(s) => write!(f, "failed: {s}"),
        }
    }
}

impl Serialize for ConsistentStatus {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// The constraints of a consistent solution at their bound: pseudo-inertias
/// whose smallest eigenvalue is within 1e-5 of their largest of `margin`,
/// drive parameters within 1e-6 of their scale of zero.
pub fn active_constraints(robot: &Robot, kinds: &[Kind], links: &[usize], sol: &Solution, margin: f64, scale: &DVector<f64>) -> Vec<Active> {
    let names = robot.param_names();
    let mut active = Vec::new();
    for (i, &l) in links.iter().enumerate() {
        let blk = &sol.theta.as_slice()[l..l + 10];
        let e = sol.min_eig[i] - margin;
        let big = SymmetricEigen::new(pseudo_inertia(blk)).eigenvalues.max().abs();
        if e <= 1e-5 * big + 1e-12 {
            active.push(Active {
                constraint: "pseudo_inertia".into(),
                what: robot.links[i].name.clone(),
                value: e,
            });
        }
    }
    for (j, &k) in kinds.iter().enumerate() {
        if matches!(k, Kind::NonNegative | Kind::NonPositive) && sol.theta[j].abs() <= 1e-6 * scale[j] {
            active.push(Active {
                constraint: "sign".into(),
                what: names[j].clone(),
                value: sol.theta[j],
            });
        }
    }
    active
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};
    use rand::{RngExt, SeedableRng};

    /// Three box-like links (consistent) with one Ia each.
    fn problem(rng: &mut rand_chacha::ChaCha8Rng) -> (Vec<f64>, Vec<usize>, Vec<Kind>) {
        let mut theta = vec![];
        let mut links = vec![];
        let mut kinds = vec![];
        for i in 0..3 {
            let m: f64 = rng.random_range(1.0..5.0);
            let c: Vector3<f64> = Vector3::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2));
            let (a, b, cc): (f64, f64, f64) = (rng.random_range(0.05..0.3), rng.random_range(0.05..0.3), rng.random_range(0.05..0.3));
            let ic = Matrix3::from_diagonal(&Vector3::new(
                m * (b * b + cc * cc) / 12.0,
                m * (a * a + cc * cc) / 12.0,
                m * (a * a + b * b) / 12.0,
            ));
            let io: Matrix3<f64> = ic + m * (c.dot(&c) * Matrix3::identity() - c * c.transpose());
            links.push(theta.len());
            theta.extend_from_slice(&[
                io[(0, 0)],
                io[(0, 1)],
                io[(0, 2)],
                io[(1, 1)],
                io[(1, 2)],
                io[(2, 2)],
                m * c.x,
                m * c.y,
                m * c.z,
                m,
            ]);
            for q in 0..10 {
                kinds.push(Kind::Inertial(q));
            }
            theta.push(0.1 * (i as f64 + 1.0));
            kinds.push(Kind::NonNegative);
        }
        (theta, links, kinds)
    }

    #[test]
    fn consistent_estimate_is_reproduced_and_inconsistent_one_is_projected() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (theta, links, kinds) = problem(&mut rng);
        let p = theta.len();
        let t = DVector::from_vec(theta);
        let r = DMatrix::from_fn(p, p, |i, j| {
            if j > i {
                rng.random_range(-1.0..1.0)
            } else if i == j {
                10.0
            } else {
                0.0
            }
        });
        let k = DMatrix::identity(p, p);
        let ones = DVector::from_element(p, 1.0);
        let o = ConsistentOptions::default();
        let pb = Problem {
            r: &r,
            theta_b: &t,
            k: &k,
            links: &links,
            kinds: &kinds,
            nominal: &t,
            scale: &ones,
        };
        let s = solve(&pb, &o, &Control::new()).unwrap();
        assert_eq!(s.status, ConicStatus::Solver(bridge::SolverStatus::Solved));
        assert!((&s.theta - &t).norm() < 1e-5 * t.norm(), "|θ−θ̂| = {:e}", (&s.theta - &t).norm());
        // inconsistent: negative mass on link 2 and a negative Ia; nominal far from it
        let mut bad = t.clone();
        bad[links[1] + 9] = -0.5;
        bad[10] = -0.05;
        let pb = Problem { theta_b: &bad, ..pb };
        let s = solve(&pb, &ConsistentOptions { margin: 1e-4, ..o }, &Control::new()).unwrap();
        let eig: Vec<f64> = links.iter().map(|&l| min_pseudo_eigenvalue(&s.theta.as_slice()[l..l + 10])).collect();
        assert!(eig.iter().all(|&e| e >= 1e-4 * (1.0 - 1e-6)), "{eig:?}");
        assert!(s.theta[10] >= -1e-9, "Ia = {}", s.theta[10]);
        // the fit is worse than the (infeasible) WLS point but no worse than the truth
        let cost = |x: &DVector<f64>| (&r * (x - &bad)).norm_squared();
        assert!(s.extra_cost > 0.0 && s.extra_cost <= cost(&t) * (1.0 + 1e-6));
    }

    #[test]
    fn pinocchio_order() {
        let p = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0];
        assert_eq!(to_pinocchio(&p), [10.0, 7.0, 8.0, 9.0, 1.0, 2.0, 4.0, 3.0, 5.0, 6.0]);
    }
}
