//! The elastic gray-box model as an information source (paper 001 §5.2, eq. 5).
//!
//! One experiment at the static configuration q0 (the rigid joints of the
//! linearisation) measures the FRF matrix Ĝ(ω_k) (n_a × n_a, motor torques to
//! motor accelerations by default) at the excited lines ω_k. With the
//! estimator's residual ψ_e(k) = ∂E_e/∂θ for every element e = (i, j)
//! (NLS: ∂G_ij/∂θ; LLS: ∂log G_ij/∂θ; LLS on the magnitude: Re ∂log G_ij/∂θ)
//! and the assumed noise variance λ_e(k) of Ĝ_ij in that domain (NLS:
//! var Ĝ_ij; LLS: var Ĝ_ij / |G_ij|²), the information is
//!
//! F(q0) = Σ_k Re{Ψ̄(k) Λ(k)⁻¹ Ψ(k)ᵀ} = Σ_k Σ_e λ_e⁻¹ (Re ψ_e Re ψ_eᵀ + Im ψ_e Im ψ_eᵀ)
//!
//! (p×p, P_θ = ½ F⁻¹; [`crate::elastic::information_matrix`] is the same sum).
//! It is the Gram matrix of the thin real factor
//!
//! G(q0) = [ λ_e^{-1/2} Re ψ_e(k), λ_e^{-1/2} Im ψ_e(k) ]_{k, e}   (p × 2 n_a² K),
//!
//! F = G Gᵀ ([`ElasticSource::jacobian_factor`]). The designer works with a
//! compressed factor H (p × r, r ≤ p, F = H Hᵀ, from the eigendecomposition
//! of the parameter-scaled F, eigenvalues below 10⁻¹³·λ_max dropped).
//!
//! ## Parameter scaling
//!
//! The unknowns mix spring stiffnesses (~10⁵ N·m/rad) and dampers (~1 N·m·s/rad),
//! so the diagonal of F in physical units spans about 10¹¹, and the relative
//! eigenvalue cut of the compressed factor would act on units rather than on
//! information. With `scale = nominal` (the default) the source reports the
//! information about θ_k / θ_k,nom, F_s = S F S with S = diag(θ_nom): D-optimal
//! weights do not change under this congruence (the designer's own scaling
//! copes with physical units too; the tests check both give the same plan);
//! A and E then measure relative variances, the meaningful choice for
//! parameters in different units. `scale = physical` keeps θ in its units (S = I).

use super::information::InformationSource;
use super::problem::psd_factor;
use crate::elastic::{ElasticModel, Estimator, FrfKernel, NoiseModel, OperatingPoint, Output};
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DMatrixView};
use serde::{Deserialize, Serialize};

/// Units of the parameters the elastic source reports information about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ElasticScale {
    /// θ_k / θ_k,nom (dimensionless; D-optimal weights unchanged).
    #[default]
    Nominal,
    /// θ in physical units.
    Physical,
}

/// Elastic FRF information per configuration (see the module docs).
#[derive(Debug, Clone)]
pub struct ElasticSource {
    /// The elastic model (unknowns θ, nominal values used for linearisation).
    pub model: ElasticModel,
    /// Angular frequencies of the excited lines (rad/s).
    pub omegas: Vec<f64>,
    /// Assumed noise on the FRF elements.
    pub noise: NoiseModel,
    /// Estimator whose information is wanted.
    pub estimator: Estimator,
    /// FRF output (motor position, speed or acceleration).
    pub output: Output,
    /// S: the information is about θ_k / s_k (p values: 1 or θ_nom).
    pub scaling: Vec<f64>,
    theta: Vec<f64>,
    vals: Vec<f64>,
    kernel: FrfKernel,
}

impl ElasticSource {
    /// A source for `model` at its nominal unknowns; `omegas` in rad/s.
    pub fn new(model: ElasticModel, omegas: Vec<f64>, noise: NoiseModel, estimator: Estimator, output: Output, scale: ElasticScale) -> Result<ElasticSource> {
        if omegas.is_empty() || omegas.iter().any(|w| !w.is_finite() || *w <= 0.0) {
            return Err(Error::invalid(
                "elastic information",
                "frequencies_hz",
                "expected at least one positive finite frequency line",
            ));
        }
        let v = match noise {
            NoiseModel::Absolute { sigma } => sigma,
            NoiseModel::Relative { rel } => rel,
        };
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(
                "elastic information",
                "noise",
                format!("expected a positive noise level, found {v}"),
            ));
        }
        let theta = model.nominal_unknowns();
        let vals = model.full_values(&theta)?;
        let scaling = match scale {
            ElasticScale::Physical => vec![1.0; theta.len()],
            ElasticScale::Nominal => theta.iter().map(|t| if t.abs() > 0.0 && t.is_finite() { t.abs() } else { 1.0 }).collect(),
        };
        let kernel = FrfKernel::new(&model);
        Ok(ElasticSource {
            model,
            omegas,
            noise,
            estimator,
            output,
            scaling,
            theta,
            vals,
            kernel,
        })
    }

    /// The linearisation at the rigid joints `q0` (nominal parameters).
    pub fn operating_point(&self, q0: &[f64]) -> Result<OperatingPoint> {
        if q0.len() != self.model.n_motors() {
            return Err(Error::dim("joint values of a candidate", self.model.n_motors(), q0.len()));
        }
        self.model.operating_point(q0, &self.vals)
    }

    /// Rows of the stacked real Jacobian: `per` · n_a² · K (per = 2 for NLS
    /// and LLS, real and imaginary parts; 1 for the magnitude-only LLS).
    pub fn n_rows(&self) -> usize {
        self.rows_per_line() * self.omegas.len()
    }

    /// Rows of the stacked real Jacobian per frequency line.
    fn rows_per_line(&self) -> usize {
        let per = if self.estimator == Estimator::LlsMagnitude { 1 } else { 2 };
        per * self.model.n_motors().pow(2)
    }

    /// Calls `line(block)` for every frequency line with block = the rows of
    /// Gᵀ of that line (r × p column-major, r = rows per line, entry (row, k)
    /// at `block[k * r + row]`): s_k λ_e^{-1/2} (Re ψ_e,k, Im ψ_e,k) for every
    /// element e; rows of elements with zero or non-finite weight are zero.
    fn for_each_line(&self, q0: &[f64], buf: &mut Vec<f64>, mut line: impl FnMut(usize, &[f64])) -> Result<()> {
        let op = self.operating_point(q0)?;
        let lin = self.model.linear_model(&op, &self.vals);
        let p = self.theta.len();
        let na = self.model.n_motors();
        let mag = self.estimator == Estimator::LlsMagnitude;
        let r = self.rows_per_line();
        let mut dg = Vec::new();
        for (l, &w) in self.omegas.iter().enumerate() {
            let g = self.kernel.eval(&lin, &op, w, self.output, true, &mut dg)?;
            buf.clear();
            buf.resize(r * p, 0.0);
            let mut row = 0;
            for j in 0..na {
                for i in 0..na {
                    let gij = g[(i, j)];
                    let var = self.noise.variance(gij);
                    let (var_dom, scale) = match self.estimator {
                        Estimator::Nls => (var, crate::elastic::C64::new(1.0, 0.0)),
                        Estimator::Lls | Estimator::LlsMagnitude => (var / gij.norm_sqr().max(f64::MIN_POSITIVE), gij.inv()),
                    };
                    let e = row;
                    row += if mag { 1 } else { 2 };
                    if !(var_dom > 0.0 && var_dom.is_finite() && scale.re.is_finite() && scale.im.is_finite()) {
                        continue;
                    }
                    let sw = var_dom.sqrt().recip();
                    for (k, d) in dg.iter().enumerate() {
                        let psi = d[(i, j)] * scale * (sw * self.scaling[k]);
                        buf[k * r + e] = psi.re;
                        if !mag {
                            buf[k * r + e + 1] = psi.im;
                        }
                    }
                }
            }
            line(l, buf);
        }
        Ok(())
    }

    /// The thin real factor G(q0) with F = G Gᵀ (p × [`ElasticSource::n_rows`],
    /// columns ordered by line, then element (column-major over (i, j)), then
    /// real/imaginary part), rows in the scaled units (row k multiplied by
    /// s_k); columns of elements with zero or non-finite weight are zero.
    pub fn jacobian_factor(&self, q0: &[f64]) -> Result<DMatrix<f64>> {
        let p = self.theta.len();
        let r = self.rows_per_line();
        let mut g = DMatrix::zeros(p, self.n_rows());
        self.for_each_line(q0, &mut Vec::new(), |l, b| {
            for k in 0..p {
                for e in 0..r {
                    g[(k, l * r + e)] = b[k * r + e];
                }
            }
        })?;
        Ok(g)
    }

    /// F(q0) = G Gᵀ (p×p), accumulated line by line (the block of one line
    /// stays in cache) in the caller's buffer (one per thread: no allocation
    /// per candidate).
    pub fn information_with(&self, q0: &[f64], buf: &mut Vec<f64>) -> Result<DMatrix<f64>> {
        let p = self.theta.len();
        let r = self.rows_per_line();
        let mut f = DMatrix::zeros(p, p);
        self.for_each_line(q0, buf, |_, b| {
            // f += Bᵀ B with B = Gᵀ of the line (r × p, column-major), as one
            // packed matrix product (Bᵀ is the same slice read with swapped strides)
            let bm = DMatrixView::from_slice(b, r, p);
            let bt = DMatrixView::from_slice_with_strides(b, p, r, r, 1);
            f.gemm(1.0, &bt, &bm, 1.0);
        })?;
        super::problem::symmetrize(&mut f);
        Ok(f)
    }

    /// The compressed factor H (p × r, r ≤ p, F = H Hᵀ) using the caller's buffer.
    pub fn factor_with(&self, q0: &[f64], buf: &mut Vec<f64>) -> Result<DMatrix<f64>> {
        psd_factor(&self.information_with(q0, buf)?, "elastic information")
    }
}

impl InformationSource for ElasticSource {
    fn n_params(&self) -> usize {
        self.theta.len()
    }
    fn names(&self) -> Vec<String> {
        let names = self.model.unknown_names();
        if self.scaling.iter().all(|s| *s == 1.0) {
            names
        } else {
            names.into_iter().map(|n| format!("{n}/nominal")).collect()
        }
    }
    fn information(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.information_with(q, &mut Vec::new())
    }
    /// The compressed factor H (p × r, r ≤ p): F = H Hᵀ from the
    /// eigendecomposition of G Gᵀ (the Gram matrix costs p²m flops, less
    /// than a QR of the long factor).
    fn factor(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        self.factor_with(q, &mut Vec::new())
    }
}

/// Settings of the elastic source as resolved from a design file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ElasticSettings {
    /// Frequency lines (Hz).
    pub frequencies_hz: Vec<f64>,
    /// Noise model.
    pub noise: NoiseModel,
    /// Estimator.
    pub estimator: Estimator,
    /// FRF output.
    pub output: Output,
}

/// Reads the `[model]` of an elastic design (or model) file and resolves the
/// settings not given (`None`) from its other tables (typed by
/// [`crate::frf::design::SharedSections`]): the excited odd lines of
/// `[multisine]` ([`crate::trajectory::multisine::lines`]; the multisine defaults when the
/// table is absent), `[simulate].noise_rel` (relative noise, else 0.02),
/// `[fit].estimator` (else LLS) and `[frf].output` (else acceleration).
pub fn load_elastic(
    path: &std::path::Path,
    frequencies_hz: Option<&[f64]>,
    noise: Option<NoiseModel>,
    estimator: Option<Estimator>,
    output: Option<Output>,
) -> Result<(ElasticModel, ElasticSettings)> {
    let model = ElasticModel::load(path)?;
    let shared = crate::frf::design::SharedSections::read(path)?;
    let ctx = path.display().to_string();
    let frequencies_hz = match frequencies_hz {
        Some(f) => f.to_vec(),
        None => {
            let ms = shared.multisine.unwrap_or_default();
            if !(ms.rate.is_finite() && ms.rate > 0.0 && ms.period.is_finite() && ms.period > 0.0) {
                return Err(Error::invalid(&ctx, "multisine", "expected a positive rate and period"));
            }
            let (_, odd, _) = crate::trajectory::multisine::lines(&ms);
            odd.iter().map(|&k| k as f64 / ms.period).collect()
        }
    };
    if frequencies_hz.is_empty() {
        return Err(Error::invalid(
            &ctx,
            "multisine.band",
            "no excited line in the band; give information.frequencies_hz",
        ));
    }
    let noise = match noise {
        Some(n) => n,
        None => {
            let rel = match shared.simulate.noise_rel {
                Some(r) if r.is_finite() && r > 0.0 => r,
                Some(_) => return Err(Error::invalid(&ctx, "simulate.noise_rel", "expected a positive number")),
                None => 0.02,
            };
            NoiseModel::Relative { rel }
        }
    };
    let estimator = estimator.or(shared.fit.estimator).unwrap_or(Estimator::Lls);
    let output = output.or(shared.frf.output).unwrap_or(Output::Acceleration);
    Ok((
        model,
        ElasticSettings {
            frequencies_hz,
            noise,
            estimator,
            output,
        },
    ))
}
