//! # idexp — identification experiments for industrial robots
//!
//! idexp designs, runs in simulation and evaluates identification experiments
//! for industrial robots. It is a library with a thin command-line tool
//! (`idexp`) on top. Units are SI, angles in rad.
//!
//! ## The model
//!
//! A serial (or tree) robot with n joints, standard inertial parameters per
//! link in the Khalil–Gautier order XX, XY, XZ, YY, YZ, ZZ (inertia about the
//! link origin), MX, MY, MZ (first moments), M (mass) — paper 002 eq. 3 — and
//! per drive the reflected rotor inertia Ia and friction (Fc·sign + Fv·q̇
//! [+ F0], paper 000 eq. 2, or the asymmetric model of paper 002 eq. 2). With a
//! coupling matrix C (motor positions θ = C q) the motor-side torque is
//!
//! τ = C⁻ᵀ τ_rb(q, q̇, q̈) + Ia ⊙ (C q̈) + f(C q̇) = Y(q, q̇, q̈) θ,
//!
//! linear in the standard parameters θ ([`robot::regressor`]). Only the base
//! parameters θ_b = K θ are identifiable ([`params::BaseParams`], computed
//! numerically by greedy QR over random states, Gautier 1991).
//!
//! ## The four problems
//!
//! 1. **Excitation design** ([`excitation`], [`trajectory`]): choose the
//!    Fourier coefficients δ of q_j(t) = q0_j + Σ_k a_kj/(kω) sin(kωt) −
//!    b_kj/(kω) cos(kωt) (paper 000 eq. 6, paper 002 eq. 17–19) to minimise an
//!    identifiability criterion of the stacked base regressor C(δ) — by default
//!    cond(C D), D normalising the columns — under joint position, velocity,
//!    acceleration, torque and Cartesian workspace limits (paper 002 eq. 20):
//!    genetic search, then SLSQP/MMA refinement with analytic gradients
//!    (dσ = uᵀ dC v).
//! 2. **Parameter identification** ([`ident`], [`sim`]): averaging of
//!    repetitions and Fourier filtering (paper 000 §III-C), WLS with
//!    sample-variance weights (eq. 5, 7–9), covariances and relative standard
//!    deviations (eq. 13–14), sensitivity-based model reduction (Algorithm 1),
//!    the projection method and maximum likelihood for closed-loop data
//!    (paper 002 eq. 10–16).
//! 3. **Position selection** ([`positions`]): the relaxed experiment
//!    allocation max_w log det Σ_i w_i F_i (and A-, E-optimal) over candidate
//!    configurations, solved with Clarabel, certified by the
//!    Kiefer–Wolfowitz equivalence theorem, rounded to whole experiments
//!    (paper 001 §5.2).
//! 4. **Gray-box FRF fitting** ([`elastic`], [`frf`]): an elastic robot
//!    linearised at chosen positions, fitted to multivariable FRF estimates
//!    G = Y U⁻¹ by NLS or log-LS (paper 001 eq. 4–8) from many perturbed
//!    starts θ·10^φ in parallel, with the asymptotic covariance (eq. 5).
//!
//! Papers: 000 Volkmann et al. (sensitivity-based model reduction), 001
//! Wernholt & Moberg (frequency-domain gray-box identification), 002 Bona &
//! Curatella (closed-loop rigid model identification).
//!
//! ## Layering
//!
//! The model is immutable ([`robot::Robot`]); every kernel takes a per-thread
//! [`robot::Workspace`] and does not allocate in its inner loop; convenience
//! functions and the CLI sit on top. Bad input is an [`Error`]; solver
//! outcomes are statuses inside the results.
#![warn(missing_docs)]

pub mod data;
pub mod elastic;
pub mod error;
pub mod excitation;
pub mod frf;
pub mod ident;
pub mod io;
pub mod linalg;
pub mod optim;
pub mod params;
pub mod payload;
pub mod plan;
pub mod positions;
pub mod preview;
pub mod rng;
pub mod robot;
pub mod sim;
pub mod trajectory;

pub use error::{Error, Result};

/// The README's Rust examples, compiled and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

/// The Rust examples of `docs/excitation.md`, compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../docs/excitation.md")]
pub struct ExcitationDocDoctests;

/// The Rust examples of `docs/elastic.md`, compiled as doctests.
#[cfg(doctest)]
#[doc = include_str!("../docs/elastic.md")]
pub struct ElasticDocDoctests;
