//! The physically consistent estimate with a prior (the identification
//! study's `[consistent]` block).
//!
//! [`super::consistent`] keeps the estimate physically possible; with few or
//! poorly exciting data a possible estimate can still be implausible (a 12.9 kg
//! link fitted at 0.56 kg, a rotor inertia at exactly 0). A prior θ₀ (the
//! robot file's nominal parameters or another robot file) decides what the
//! data leave open. With θ = θ₀ + S x, S = diag(s) the prior's scales
//! (s_j = `scale` · max(|θ₀,j|, 10 % of the largest nominal value of its
//! kind), [`super::consistent::regularization_scale`]):
//!
//! min_x ‖R(K(θ₀ + S x) − θ̂_b)‖² + w · P(x)
//! s.t. J_i(θ) ⪰ ε I₄ for every link, the drives' sign constraints,
//!
//! with R and θ̂_b the weighted least-squares factor and estimate (the first
//! term is the increase of the weighted residual sum of squares over WLS, in
//! χ² units when the weights are inverse variances) and the prior term P:
//!
//! * **Euclidean**: P = ‖x‖² = Σ_j ((θ_j − θ₀,j)/s_j)²: a Gaussian prior of
//!   standard deviation s_j on every standard parameter when w = 1.
//! * **Entropic** (Lee & Park 2019; FloBaRoID's geometric prior): for each
//!   link the Bregman divergence of −log det between pseudo-inertias,
//!   D(J, J₀) = log det J₀ − log det J + tr(J₀⁻¹ J) − 4 (≥ 0, zero only at
//!   J = J₀, invariant to the choice of frame and units; ≈ ½‖J₀^{-½}(J − J₀)J₀^{-½}‖²_F
//!   near J₀), plus ‖x_j‖² on the drive parameters. It needs a positive
//!   definite prior pseudo-inertia for every link.
//!
//! Both are one conic program for Clarabel, with the 4×4 PSD cones of the
//! pseudo-inertias and the non-negative cone of the signs. The Euclidean
//! metric minimises t ≥ ‖((A x − c)/ρ, √w x/ρ)‖ in a second-order cone (A =
//! R K S, c = R(θ̂_b − K θ₀), ρ the rms row norm of A) at a gap tolerance of
//! 10⁻¹²: with the weight of `{ relative = 10⁻⁶ }` the directions only the
//! prior sees (the standard parameters K does not see, a payload's height on
//! a planar arm) are resolved to the solver's tolerance on the norm, where a
//! quadratic objective leaves them loose. The entropic metric has a quadratic
//! objective and t ≤ log det J_i written as [[J_i, L_i], [L_iᵀ, diag(L_i)]] ⪰ 0
//! with L_i lower triangular and t_k ≤ log (L_i)_kk in exponential cones
//! (MOSEK Modeling Cookbook §6.2.3). A sign-constrained drive parameter is
//! returned on its side of 0 (the solver's rounding clamped).
//!
//! The same program serves the payload's consistent fit (one link, the
//! guess as prior, `src/payload/identify.rs`).

use super::consistent::{kinds_of, min_pseudo_eigenvalue, pseudo_inertia, regularization_scale, Kind, Solution};
use crate::error::{Error, Result};
use crate::optim::conic::{self as bridge, Cone, ConicStatus, Entries as Triplets, Program, Settings};
use crate::optim::Control;
use crate::robot::Robot;
use nalgebra::{DMatrix, DVector, Matrix4, SymmetricEigen};
use serde::{Deserialize, Serialize};

/// The prior's metric.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum PriorMetric {
    /// Σ ((θ − θ₀)/s)² on every standard parameter.
    Euclidean,
    /// The log-det (Bregman) divergence between pseudo-inertias, Euclidean on drive parameters.
    #[default]
    Entropic,
}

impl PriorMetric {
    /// The name in files.
    pub fn name(self) -> &'static str {
        match self {
            PriorMetric::Euclidean => "euclidean",
            PriorMetric::Entropic => "entropic",
        }
    }
}

/// The data of [`solve`].
#[derive(Debug, Clone, Copy)]
pub struct PriorProblem<'a> {
    /// R (rows × n_base): the fit is ‖R(Kθ − θ̂_b)‖².
    pub r: &'a DMatrix<f64>,
    /// θ̂_b, the least-squares estimate.
    pub theta_b: &'a DVector<f64>,
    /// K (n_base × p).
    pub k: &'a DMatrix<f64>,
    /// Index of each link's first inertial parameter.
    pub links: &'a [usize],
    /// Link names (for messages).
    pub link_names: &'a [String],
    /// Role of every standard parameter.
    pub kinds: &'a [Kind],
    /// The prior θ₀.
    pub prior: &'a DVector<f64>,
    /// The scales s.
    pub scale: &'a DVector<f64>,
}

/// The 4×4 coefficient matrix of link parameter `q` (0..10) in the pseudo-inertia.
fn coefficient(q: usize) -> Matrix4<f64> {
    let mut p = [0.0; 10];
    p[q] = 1.0;
    pseudo_inertia(&p)
}

/// Solves the consistent fit with a prior of weight `weight` (see the module
/// documentation); ε = `margin`. `ctl` stops the solver (Ctrl-C, its
/// deadline); the caller reports the progress (one solve of a weight scan).
pub fn solve(pb: &PriorProblem, metric: PriorMetric, weight: f64, margin: f64, ctl: &Control) -> Result<Solution> {
    solve_with_unknown(pb, &vec![false; pb.prior.len()], metric, weight, margin, ctl)
}

/// The prior weight `relative` · σ²_min, σ_min the smallest singular value
/// of the fit's factor `r` (`[consistent] weight = { relative = r }`): a
/// pull that decides only what the data leave open (`relative` alone when
/// `r` has no positive singular value).
pub fn relative_weight(r: &DMatrix<f64>, relative: f64) -> f64 {
    let smin = r.singular_values().iter().copied().fold(f64::INFINITY, f64::min);
    relative * if smin.is_finite() && smin > 0.0 { smin * smin } else { 1.0 }
}

/// Relative pull of the prior on a parameter without a known value
/// ([`solve_with_unknown`]): 10⁻⁶ of the known parameters' weight, so the data
/// decide it wherever they see it and a direction no data see stays at the
/// prior's value (0) instead of leaving the problem unbounded.
pub const UNKNOWN_PULL: f64 = 1e-6;

/// [`solve`] with the drive parameters `unknown[j]` not pulled toward the
/// prior (their prior term is weighted by [`UNKNOWN_PULL`]): a robot file's
/// 0 for a reflected rotor inertia or a friction coefficient is "unknown",
/// and pulling it to 0 pushes a geared arm's large rotor inertias into the
/// link inertias they are grouped with. Their sign constraints stay.
pub fn solve_with_unknown(pb: &PriorProblem, unknown: &[bool], metric: PriorMetric, weight: f64, margin: f64, ctl: &Control) -> Result<Solution> {
    let PriorProblem {
        r,
        theta_b,
        k,
        links,
        link_names,
        kinds,
        prior,
        scale,
    } = *pb;
    let p = k.ncols();
    if r.ncols() != k.nrows() || theta_b.len() != k.nrows() || kinds.len() != p || prior.len() != p || scale.len() != p {
        return Err(Error::dim("consistent fit with a prior: parameters", p, prior.len()));
    }
    if !(weight.is_finite() && weight > 0.0) {
        return Err(Error::invalid(
            "consistent",
            "weight",
            format!("expected a positive prior weight, found {weight}"),
        ));
    }
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(Error::invalid("consistent", "margin", format!("expected a margin ≥ 0 (kg·m²), found {margin}")));
    }
    if unknown.len() != p || unknown.iter().zip(kinds).any(|(&u, k)| u && matches!(k, Kind::Inertial(_))) {
        return Err(Error::invalid(
            "consistent",
            "unknown",
            "expected one flag per standard parameter, set only on drive parameters",
        ));
    }
    let coef: Vec<Matrix4<f64>> = (0..10).map(coefficient).collect();
    let entropic = metric == PriorMetric::Entropic;
    let mut j0inv = Vec::new();
    if entropic {
        for (i, &l) in links.iter().enumerate() {
            let j0 = pseudo_inertia(&prior.as_slice()[l..l + 10]);
            let e = SymmetricEigen::new(j0).eigenvalues.min();
            let inv = j0.try_inverse().filter(|_| e > 0.0).ok_or_else(|| {
                Error::invalid(
                    "consistent",
                    "metric",
                    format!(
                        "the entropic prior needs a positive definite prior pseudo-inertia, but link `{}`'s smallest eigenvalue is {e:.3e} kg·m² (a point mass, a rod or a massless link): use metric = \"euclidean\" or a prior with a solid body for that link",
                        link_names.get(i).map_or("?", String::as_str)
                    ),
                )
            })?;
            j0inv.push(inv);
        }
    }
    // fit in x: ‖A x − c‖², A = R K S, c = R(θ̂_b − K θ₀)
    let s = DMatrix::from_diagonal(scale);
    let a = r * k * &s;
    let c = r * (theta_b - k * prior);
    // Euclidean: minimise t with (t, (A x − c)/ρ, √w u ∘ x/ρ) in a second-order
    // cone (ρ the rms row norm of A, u = 1 or √UNKNOWN_PULL): a direction only
    // the prior sees is then resolved to the solver's tolerance on t, not on
    // t² (a weight of 10⁻⁶ σ²_min leaves it loose in the quadratic form).
    // Entropic: the quadratic form and the log-det terms below.
    let lvar = |i: usize, row: usize, col: usize| p + 14 * i + row * (row + 1) / 2 + col; // row ≥ col
    let vvar = |i: usize, kk: usize| p + 14 * i + 10 + kk;
    let (nx, pm, q) = if entropic {
        let ata = a.transpose() * &a;
        let atc = a.transpose() * &c;
        // scale the objective to O(1) (the argmin is unchanged)
        let kappa = (ata.trace() / p as f64).max(weight).max(1e-300);
        let inertial: Vec<bool> = kinds.iter().map(|k| matches!(k, Kind::Inertial(_))).collect();
        let nx = p + 14 * links.len();
        let mut pm = Triplets::new();
        let pr0 = pm.rows(p);
        for col in 0..p {
            for row in 0..=col {
                let mut v = 2.0 * ata[(row, col)];
                if row == col && !inertial[col] {
                    v += 2.0 * weight * if unknown[col] { UNKNOWN_PULL } else { 1.0 };
                }
                pm.push(pr0 + row, col, v / kappa);
            }
        }
        let _ = pm.rows(nx - p);
        let mut q = vec![0.0; nx];
        for j in 0..p {
            q[j] = -2.0 * atc[j] / kappa;
        }
        for (i, &l) in links.iter().enumerate() {
            for (qq, cm) in coef.iter().enumerate() {
                // ∂ tr(J₀⁻¹ J)/∂x = tr(J₀⁻¹ E_q) s
                q[l + qq] += weight * (j0inv[i] * cm).trace() * scale[l + qq] / kappa;
            }
            for kk in 0..4 {
                q[vvar(i, kk)] = -weight / kappa;
            }
        }
        (nx, Some(pm), q)
    } else {
        let mut q = vec![0.0; p + 1];
        q[p] = 1.0;
        (p + 1, None, q)
    };
    let mut am = Triplets::new();
    let mut b: Vec<f64> = Vec::new();
    let mut cones = Vec::new();
    if !entropic {
        let rows = a.nrows();
        let rho = (a.norm_squared() / rows.max(1) as f64).sqrt().max(1e-300);
        let r0 = am.rows(1 + rows + p);
        am.push(r0, p, -1.0);
        b.push(0.0);
        for i in 0..rows {
            for j in 0..p {
                am.push(r0 + 1 + i, j, -a[(i, j)] / rho);
            }
            b.push(-c[i] / rho);
        }
        for j in 0..p {
            let pull = if unknown[j] { UNKNOWN_PULL } else { 1.0 };
            am.push(r0 + 1 + rows + j, j, -(weight * pull).sqrt() / rho);
            b.push(0.0);
        }
        cones.push(Cone::SecondOrder(1 + rows + p));
    }
    let s2 = std::f64::consts::SQRT_2;
    // J_i(θ₀ + S x) − ε I ⪰ 0 (svec: upper triangle column by column, off-diagonals × √2)
    let push_j = |am: &mut Triplets, b: &mut Vec<f64>, l: usize, row: usize, col: usize, w: f64, eps: f64| {
        let ri = am.rows(1);
        let mut b0 = 0.0;
        for (qq, cm) in coef.iter().enumerate() {
            let v = cm[(row, col)];
            if v != 0.0 {
                am.push(ri, l + qq, -w * v * scale[l + qq]);
                b0 += v * prior[l + qq];
            }
        }
        b.push(w * (b0 - if row == col { eps } else { 0.0 }));
    };
    for &l in links {
        for col in 0..4 {
            for row in 0..=col {
                push_j(&mut am, &mut b, l, row, col, if row == col { 1.0 } else { s2 }, margin);
            }
        }
        cones.push(Cone::PsdTriangle(4));
    }
    if entropic {
        for (i, &l) in links.iter().enumerate() {
            // [[J, L], [Lᵀ, diag(L)]] ⪰ 0, 8×8
            for col in 0..8 {
                for row in 0..=col {
                    let w = if row == col { 1.0 } else { s2 };
                    if col < 4 {
                        push_j(&mut am, &mut b, l, row, col, w, 0.0);
                        continue;
                    }
                    let ri = am.rows(1);
                    let lc = col - 4;
                    if row < 4 {
                        // upper-right block entry (row, 4 + lc) = L[row][lc], zero above L's diagonal
                        if row >= lc {
                            am.push(ri, lvar(i, row, lc), -w);
                        }
                    } else if row - 4 == lc {
                        am.push(ri, lvar(i, lc, lc), -w);
                    }
                    b.push(0.0);
                }
            }
            cones.push(Cone::PsdTriangle(8));
            for kk in 0..4 {
                // (v, 1, L_kk) ∈ K_exp: v ≤ log L_kk
                let ri = am.rows(3);
                am.push(ri, vvar(i, kk), -1.0);
                am.push(ri + 2, lvar(i, kk, kk), -1.0);
                b.extend_from_slice(&[0.0, 1.0, 0.0]);
                cones.push(Cone::Exponential);
            }
        }
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
            let ri = am.rows(1);
            am.push(ri, j, -sg * scale[j]);
            b.push(sg * prior[j]);
        }
        cones.push(Cone::Nonnegative(signed.len()));
    }
    let sol = run_clarabel(
        Program {
            n_var: nx,
            p: pm,
            q,
            a: am,
            b,
            cones,
        },
        ctl,
        // the cone form's t is a norm: a tighter gap resolves what only the prior sees
        (!entropic).then_some(1e-12),
    )?;
    let x = &sol.x;
    let mut theta = prior + &s * DVector::from_iterator(p, x[..p].iter().copied());
    // a sign-constrained drive parameter the solver left a rounding error on
    // the wrong side of 0 (within its feasibility tolerance) is at its bound:
    // 0, so that a robot file written from it reads back
    for (j, kind) in kinds.iter().enumerate() {
        match kind {
            Kind::NonNegative => theta[j] = theta[j].max(0.0),
            Kind::NonPositive => theta[j] = theta[j].min(0.0),
            _ => {}
        }
    }
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
        lambda: weight,
    })
}

/// Runs a consistent-fit program through the Clarabel bridge under `ctl`
/// (500 iterations, the control's deadline as time limit, Ctrl-C through
/// the termination callback; `tol` the gap tolerance, None for Clarabel's).
/// A program Clarabel refuses to set up is an error; how a run ended is the
/// returned status.
fn run_clarabel(prog: Program, ctl: &Control, tol: Option<f64>) -> Result<bridge::Solved> {
    let settings = Settings {
        max_iter: Some(500),
        tol,
        ..Settings::default()
    };
    let sol = bridge::solve(prog, &settings, ctl);
    match &sol.status {
        ConicStatus::Settings(_) | ConicStatus::Setup(_) => Err(Error::Numerical(format!("Clarabel: {}", sol.status))),
        ConicStatus::Solver(_) => Ok(sol),
    }
}

/// The entropic divergence D(J, J₀) of a link block θ from its prior block θ₀
/// (∞ when J is not positive definite; NaN when J₀ is not).
pub fn divergence(theta: &[f64], prior: &[f64]) -> f64 {
    let (j, j0) = (pseudo_inertia(theta), pseudo_inertia(prior));
    let (Some(cj), Some(c0)) = (j.cholesky(), j0.cholesky()) else {
        return if j0.cholesky().is_none() { f64::NAN } else { f64::INFINITY };
    };
    let ld = |c: &nalgebra::Cholesky<f64, nalgebra::Const<4>>| 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
    ld(&c0) - ld(&cj) + (c0.inverse() * j).trace() - 4.0
}

/// The prior's parameters and scales for `robot`: θ₀ from `prior` (a robot
/// with the same parameter layout, or the robot itself) and
/// s = `scale` · the consistent fit's regularisation scales.
pub fn prior_of(robot: &Robot, prior: Option<&Robot>, scale: f64) -> Result<(DVector<f64>, DVector<f64>)> {
    let theta0 = match prior {
        None => robot.nominal_params(),
        Some(pr) => {
            let (a, b) = (robot.param_names(), pr.param_names());
            if a != b {
                let first = a.iter().zip(&b).position(|(x, y)| x != y).unwrap_or(a.len().min(b.len()));
                return Err(Error::invalid(
                    pr.source.clone(),
                    "prior",
                    format!(
                        "the prior robot has {} standard parameters, the identified robot {} (first difference at parameter {}: `{}` vs `{}`): the prior must describe the same robot (same links, joints and drive models)",
                        b.len(),
                        a.len(),
                        first + 1,
                        b.get(first).map_or("-", String::as_str),
                        a.get(first).map_or("-", String::as_str)
                    ),
                ));
            }
            pr.nominal_params()
        }
    };
    let (kinds, _) = kinds_of(robot);
    Ok((theta0.clone(), regularization_scale(&kinds, &theta0) * scale))
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
        let names: Vec<String> = (1..=3).map(|i| format!("l{i}")).collect();
        // the closest-to-nominal weight of `{ relative = 1e-6 }`
        let w = relative_weight(&r, 1e-6);
        let pb = PriorProblem {
            r: &r,
            theta_b: &t,
            k: &k,
            links: &links,
            link_names: &names,
            kinds: &kinds,
            prior: &t,
            scale: &ones,
        };
        let s = solve(&pb, PriorMetric::Euclidean, w, 0.0, &Control::new()).unwrap();
        assert!(s.status.is_solved(), "{}", s.status);
        assert!((&s.theta - &t).norm() < 1e-5 * t.norm(), "|θ−θ̂| = {:e}", (&s.theta - &t).norm());
        // inconsistent: negative mass on link 2 and a negative Ia; nominal far from it
        let mut bad = t.clone();
        bad[links[1] + 9] = -0.5;
        bad[10] = -0.05;
        let pb = PriorProblem { theta_b: &bad, ..pb };
        let s = solve(&pb, PriorMetric::Euclidean, w, 1e-4, &Control::new()).unwrap();
        let eig: Vec<f64> = links.iter().map(|&l| min_pseudo_eigenvalue(&s.theta.as_slice()[l..l + 10])).collect();
        assert!(eig.iter().all(|&e| e >= 1e-4 * (1.0 - 1e-6)), "{eig:?}");
        assert!(s.theta[10] >= -1e-9, "Ia = {}", s.theta[10]);
        // the fit is worse than the (infeasible) WLS point but no worse than the truth
        let cost = |x: &DVector<f64>| (&r * (x - &bad)).norm_squared();
        assert!(s.extra_cost > 0.0 && s.extra_cost <= cost(&t) * (1.0 + 1e-6));
    }

    fn block(m: f64, c: [f64; 3], d: [f64; 3]) -> Vec<f64> {
        // a box of principal moments d about its COM c, inertia about the origin
        let io = [
            d[0] + m * (c[1] * c[1] + c[2] * c[2]),
            -m * c[0] * c[1],
            -m * c[0] * c[2],
            d[1] + m * (c[0] * c[0] + c[2] * c[2]),
            -m * c[1] * c[2],
            d[2] + m * (c[0] * c[0] + c[1] * c[1]),
        ];
        let mut v = io.to_vec();
        v.extend_from_slice(&[m * c[0], m * c[1], m * c[2], m]);
        v
    }

    #[test]
    fn divergence_is_zero_at_the_prior_and_matches_its_second_order_expansion() {
        let b0 = block(2.0, [0.1, -0.05, 0.2], [0.02, 0.03, 0.025]);
        assert!(divergence(&b0, &b0).abs() < 1e-12);
        let mut b1 = b0.clone();
        b1[9] *= 1.0001;
        let d = divergence(&b1, &b0);
        // ½‖J₀^{-½} ΔJ J₀^{-½}‖²: for a mass change only, ΔJ = Δm e₄e₄ᵀ
        let j0 = pseudo_inertia(&b0);
        let inv = j0.try_inverse().unwrap();
        let dm = b1[9] - b0[9];
        let expect = 0.5 * (dm * inv[(3, 3)]).powi(2);
        assert!((d - expect).abs() < 1e-3 * expect, "{d} vs {expect}");
    }

    #[test]
    fn without_data_the_estimate_is_the_prior_and_with_exact_data_the_data() {
        // one link and one drive parameter, K = I
        let mut prior = block(2.0, [0.1, -0.05, 0.2], [0.02, 0.03, 0.025]);
        prior.push(0.3);
        let truth = {
            let mut t = block(2.4, [0.12, -0.04, 0.18], [0.025, 0.028, 0.03]);
            t.push(0.2);
            t
        };
        let p = prior.len();
        let kinds: Vec<Kind> = (0..10).map(Kind::Inertial).chain([Kind::NonNegative]).collect();
        let prior = DVector::from_vec(prior);
        let kmat = DMatrix::identity(p, p);
        let scale = regularization_scale(&kinds, &prior) * 0.5;
        let names = vec!["l1".to_string()];
        for metric in [PriorMetric::Euclidean, PriorMetric::Entropic] {
            // data that see only the mass: the rest is the prior's
            let mut r = DMatrix::zeros(1, p);
            r[(0, 9)] = 1e3;
            let tb = DVector::from_vec(truth.clone());
            let pb = PriorProblem {
                r: &r,
                theta_b: &tb,
                k: &kmat,
                links: &[0],
                link_names: &names,
                kinds: &kinds,
                prior: &prior,
                scale: &scale,
            };
            let s = solve(&pb, metric, 1.0, 0.0, &Control::new()).unwrap();
            assert!((s.theta[9] - truth[9]).abs() < 1e-3, "{metric:?}: mass {}", s.theta[9]);
            assert!((s.theta[10] - prior[10]).abs() < 1e-6, "{metric:?}: drive parameter {}", s.theta[10]);
            // rich data: every parameter seen 10⁴ × more precisely than the prior
            let r = DMatrix::from_diagonal(&scale.map(|v| 1e4 / v));
            let pb = PriorProblem { r: &r, ..pb };
            let s = solve(&pb, metric, 1.0, 0.0, &Control::new()).unwrap();
            for j in 0..p {
                assert!(
                    (s.theta[j] - truth[j]).abs() < 1e-3 * scale[j],
                    "{metric:?}: parameter {j}: {} vs {}",
                    s.theta[j],
                    truth[j]
                );
            }
        }
    }
}
