//! The friction model of a drive: its regressor columns φ(w), their slopes
//! and the nominal friction torque.

use crate::robot::kinematics::Real;
use crate::robot::model::{Coulomb, Drive, Friction};

/// Friction torque of a drive at motor velocity `w` (joint-side units), with
/// its nominal coefficients: Σ_k θ_k φ_k(w) over [`friction_columns`].
pub fn friction_torque(d: &Drive, w: f64) -> f64 {
    let mut cols = [0.0; MAX_FRICTION_COLUMNS];
    let m = friction_columns(d, w, &mut cols);
    let mut coef = [0.0; MAX_FRICTION_COLUMNS];
    let mut k = 0;
    let mut push = |v: f64| {
        coef[k] = v;
        k += 1;
    };
    match d.friction {
        Friction::None => {}
        Friction::Symmetric { fc, fv, offset } => {
            push(fc);
            push(fv);
            if let Some(o) = offset {
                push(o);
            }
            if let Coulomb::Stribeck { fs, .. } = d.coulomb {
                push(fs[0]);
            }
        }
        Friction::Asymmetric {
            fc_pos,
            fc_neg,
            fv_pos,
            fv_neg,
            offset,
        } => {
            for v in [fc_pos, fc_neg, fv_pos, fv_neg] {
                push(v);
            }
            if let Some(o) = offset {
                push(o);
            }
            if let Coulomb::Stribeck { fs, .. } = d.coulomb {
                push(fs[0]);
                push(fs[1]);
            }
        }
    }
    debug_assert_eq!(k, m);
    cols[..m].iter().zip(&coef[..m]).map(|(c, v)| c * v).sum()
}

/// Most friction columns of one drive (asymmetric: Fc±, Fv±, F0, Fs±).
pub const MAX_FRICTION_COLUMNS: usize = 7;

/// The friction regressor columns φ(w) of drive `d` at motor velocity `w`
/// (joint-side units), in the parameter layout order after Ia; returns
/// how many were written into `out`. τ_f = Σ_k θ_k φ_k(w).
///
/// With s(w) the Coulomb switch of [`Coulomb`] (sign(w), or tanh(w/v_s)) and
/// e(w) = exp(−(w/v_st)²) for the Stribeck shape:
///
/// * symmetric: [s, w, (1 if F0), (s·e if Stribeck)] for [Fc, Fv, F0, Fs];
/// * asymmetric: [σ⁺, σ⁻, σ⁺w, σ⁻w, (1), (σ⁺e, σ⁻e)] for
///   [Fc⁺, Fc⁻, Fv⁺, Fv⁻, F0, Fs⁺, Fs⁻], σ± the indicators of ±w > 0 for the
///   sign shape (paper 002 eq. 2) and (1 ± tanh(w/v_s))/2 for the smooth ones.
///
/// Generic in the scalar so that dual numbers carry ∂φ/∂w (zero for sign
/// away from 0, (1 − tanh²)/v_s for tanh).
pub fn friction_columns<T: Real>(d: &Drive, w: T, out: &mut [T]) -> usize {
    let (s, e) = match d.coulomb {
        Coulomb::Sign => (sgn(w), T::zero()),
        Coulomb::Tanh { velocity_scale } => ((w / T::c(velocity_scale)).tanh(), T::zero()),
        Coulomb::Stribeck {
            velocity_scale,
            stribeck_velocity,
            ..
        } => {
            let x = w / T::c(stribeck_velocity);
            ((w / T::c(velocity_scale)).tanh(), (-(x * x)).exp())
        }
    };
    let stribeck = matches!(d.coulomb, Coulomb::Stribeck { .. });
    let mut k = 0;
    let mut push = |v: T| {
        out[k] = v;
        k += 1;
    };
    match d.friction {
        Friction::None => {}
        Friction::Symmetric { offset, .. } => {
            push(s);
            push(w);
            if offset.is_some() {
                push(T::one());
            }
            if stribeck {
                push(s * e);
            }
        }
        Friction::Asymmetric { offset, .. } => {
            let (sp, sn) = if d.coulomb.is_sign() {
                let r = w.re_();
                (if r > 0.0 { T::one() } else { T::zero() }, if r < 0.0 { T::one() } else { T::zero() })
            } else {
                let h = T::c(0.5);
                (h * (T::one() + s), h * (T::one() - s))
            };
            push(sp);
            push(sn);
            push(sp * w);
            push(sn * w);
            if offset.is_some() {
                push(T::one());
            }
            if stribeck {
                push(sp * e);
                push(sn * e);
            }
        }
    }
    k
}

/// The slopes ∂φ_k/∂w of the friction columns of [`friction_columns`] at
/// motor velocity `w`, in the same order; returns how many were written.
/// Closed form: sign switches have slope 0 (away from w = 0, where the
/// columns jump), tanh(w/v_s) has (1 − tanh²)/v_s (finite and → 0 for large
/// |w/v_s|), the Stribeck shape e = exp(−(w/v_st)²) has −2 w e / v_st².
pub fn friction_slopes(d: &Drive, w: f64, out: &mut [f64]) -> usize {
    let (s, ds, e, de) = match d.coulomb {
        Coulomb::Sign => (sgn(w), 0.0, 0.0, 0.0),
        Coulomb::Tanh { velocity_scale } => {
            let s = (w / velocity_scale).tanh();
            (s, (1.0 - s * s) / velocity_scale, 0.0, 0.0)
        }
        Coulomb::Stribeck {
            velocity_scale,
            stribeck_velocity,
            ..
        } => {
            let s = (w / velocity_scale).tanh();
            let x = w / stribeck_velocity;
            let e = (-(x * x)).exp();
            (s, (1.0 - s * s) / velocity_scale, e, -2.0 * x / stribeck_velocity * e)
        }
    };
    let stribeck = matches!(d.coulomb, Coulomb::Stribeck { .. });
    let mut k = 0;
    let mut push = |v: f64| {
        out[k] = v;
        k += 1;
    };
    match d.friction {
        Friction::None => {}
        Friction::Symmetric { offset, .. } => {
            push(ds);
            push(1.0);
            if offset.is_some() {
                push(0.0);
            }
            if stribeck {
                push(ds * e + s * de);
            }
        }
        Friction::Asymmetric { offset, .. } => {
            let (sp, sn, dsp, dsn) = if d.coulomb.is_sign() {
                (if w > 0.0 { 1.0 } else { 0.0 }, if w < 0.0 { 1.0 } else { 0.0 }, 0.0, 0.0)
            } else {
                (0.5 * (1.0 + s), 0.5 * (1.0 - s), 0.5 * ds, -0.5 * ds)
            };
            push(dsp);
            push(dsn);
            push(dsp * w + sp);
            push(dsn * w + sn);
            if offset.is_some() {
                push(0.0);
            }
            if stribeck {
                push(dsp * e + sp * de);
                push(dsn * e + sn * de);
            }
        }
    }
    k
}

#[inline]
fn sgn<T: Real>(x: T) -> T {
    let r = x.re_();
    if r > 0.0 {
        T::one()
    } else if r < 0.0 {
        -T::one()
    } else {
        T::zero()
    }
}
