//! Elastic gray-box robot models (paper 001 §3): a rigid robot whose actuated
//! joints drive their links through gearbox spring–dampers, with extra
//! non-actuated torsional spring–damper joints inside the chain; the
//! linearisation at a static position (gravity stiffness included), the
//! parametric FRF G(ω, θ) from motor torques to motor accelerations with its
//! analytic Jacobian ∂vec G/∂θ, the information matrix of paper 001 eq. 5, and
//! a time-domain closed-loop simulation of the nonlinear model around a
//! position ([`sim`]).
//!
//! ```no_run
//! use idexp::elastic::{self, ElasticModel, Estimator, NoiseModel};
//! let m = ElasticModel::load(std::path::Path::new("designs/elastic_industrial6.toml"))?;
//! let omegas: Vec<f64> = (1..=40).map(|k| 2.0 * std::f64::consts::PI * (2 * k - 1) as f64).collect();
//! let q0 = vec![0.0, -0.6, 0.4, 0.0, 0.9, 0.0];
//! let f = elastic::information_matrix(&m, &q0, &omegas, &NoiseModel::Relative { rel: 0.02 }, Estimator::Lls)?;
//! assert_eq!(f.nrows(), m.n_unknowns());
//! # Ok::<(), idexp::Error>(())
//! ```

pub mod linear;
pub mod model;
pub mod sim;

pub use linear::{
    accumulate_information, frf, frf_jacobian, information_matrix, information_matrix_at, Estimator, FrfKernel, LinearModel, NoiseModel, OperatingPoint,
    Output, C64,
};
pub use model::{ElasticJointSpec, ElasticModel, ElasticSpec, GearboxSpec, ModelParam, ParamRole, PayloadSpec};

/// A mode of the linear model: natural frequency and damping ratio.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Mode {
    /// Natural frequency |λ|/(2π) (Hz).
    pub freq_hz: f64,
    /// Damping ratio −Re λ/|λ|.
    pub zeta: f64,
}

/// Modes of M ẍ + D ẋ + K x = 0 (eigenvalues λ of [[0, I], [−M⁻¹K, −M⁻¹D]]
/// with Im λ > 0, sorted by frequency). Real eigenvalues (rigid-body and
/// gravity-unstable motions of the open loop) are left out.
pub fn modes(lin: &LinearModel) -> crate::Result<Vec<Mode>> {
    let n = lin.m.nrows();
    let minv = lin
        .m
        .clone()
        .try_inverse()
        .ok_or_else(|| crate::Error::Numerical("the mass matrix of the linear model is singular".into()))?;
    let mut a = nalgebra::DMatrix::zeros(2 * n, 2 * n);
    for i in 0..n {
        a[(i, n + i)] = 1.0;
    }
    let mk = -&minv * &lin.k;
    let md = -&minv * &lin.d;
    a.view_mut((n, 0), (n, n)).copy_from(&mk);
    a.view_mut((n, n), (n, n)).copy_from(&md);
    let ev = a.complex_eigenvalues();
    let mut out: Vec<Mode> = ev
        .iter()
        .filter(|l| l.im > 1e-9 * l.norm().max(1.0))
        .map(|l| Mode {
            freq_hz: l.norm() / (2.0 * std::f64::consts::PI),
            zeta: -l.re / l.norm(),
        })
        .collect();
    out.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    Ok(out)
}
