//! The physics of the physically consistent estimate: the pseudo-inertia
//! J_i = [[½ tr(I_i) 1 − I_i, h_i], [h_iᵀ, m_i]] of a link block (I_i the
//! inertia about the link origin, h_i = m_i c_i the first moment, m_i the
//! mass; J_i ⪰ 0 exactly when some non-negative mass distribution has these
//! moments, Wensing, Kim & Slotine 2017), the role of every standard
//! parameter in the fit ([`Kind`]: a link block's entry, or a drive parameter
//! with its sign), the scales s_j of the prior (|θ_0,j|, at least 10 % of the
//! largest nominal value of its kind), the constraints a solution holds at
//! their bound, Pinocchio's parameter order and how a fit ended. The fit
//! itself, min ‖R(Kθ − θ̂_b)‖² + w·P(θ − θ₀) subject to J_i(θ) ⪰ εI₄ and the
//! drives' signs, is one conic program in [`super::prior`].

use crate::optim::conic::ConicStatus;
use crate::robot::{ParamKind, ParamSign, Robot};
use nalgebra::{DVector, Matrix4, SymmetricEigen};
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

/// The solution of a consistent fit ([`super::prior::solve`]).
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
    /// The prior weight w.
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

    #[test]
    fn pinocchio_order() {
        let p = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0];
        assert_eq!(to_pinocchio(&p), [10.0, 7.0, 8.0, 9.0, 1.0, 2.0, 4.0, 3.0, 5.0, 6.0]);
    }
}
