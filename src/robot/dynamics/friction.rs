//! The friction model of a drive: its regressor columns φ(w), their slopes
//! and the nominal friction torque.

use crate::robot::kinematics::Real;
use crate::robot::model::{Coulomb, Drive, Friction, ParamKind};

/// Friction torque of a drive at motor velocity `w` (joint-side units), with
/// its nominal coefficients: Σ_k θ_k φ_k(w) over [`friction_columns`].
pub fn friction_torque(d: &Drive, w: f64) -> f64 {
    // the coefficients read in place in the order of `visit_drive_params`
    // (the walk through `drive_params` costs ~100 ns per RNEA call here)
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

/// Visits the drive parameters of one joint in the layout order of
/// [`Robot::params`](crate::robot::Robot::params) after its ten inertials:
/// Ia (if modelled), then the friction coefficients in the order of
/// [`friction_columns`] (Fc, Fv, F0, Fs or Fc±, Fv±, F0, Fs±), each with
/// its kind and its value in `d`. The one place the drive part of the
/// parameter layout is written down: the layout, the nominal values,
/// [`Robot::with_params`](crate::robot::Robot::with_params), the robot
/// summary and the exported robot file walk it; the kernels
/// ([`friction_torque`], [`friction_columns`]) read the same order in place.
pub fn visit_drive_params(d: &mut Drive, mut f: impl FnMut(ParamKind, &mut f64)) {
    if let Some(ia) = d.rotor_inertia.as_mut() {
        f(ParamKind::Ia, ia);
    }
    let stribeck = match &mut d.coulomb {
        Coulomb::Stribeck { fs, .. } => Some(fs),
        _ => None,
    };
    match &mut d.friction {
        Friction::None => {}
        Friction::Symmetric { fc, fv, offset } => {
            f(ParamKind::Fc, fc);
            f(ParamKind::Fv, fv);
            if let Some(o) = offset {
                f(ParamKind::F0, o);
            }
            if let Some(fs) = stribeck {
                f(ParamKind::Fs, &mut fs[0]);
            }
        }
        Friction::Asymmetric {
            fc_pos,
            fc_neg,
            fv_pos,
            fv_neg,
            offset,
        } => {
            f(ParamKind::FcPos, fc_pos);
            f(ParamKind::FcNeg, fc_neg);
            f(ParamKind::FvPos, fv_pos);
            f(ParamKind::FvNeg, fv_neg);
            if let Some(o) = offset {
                f(ParamKind::F0, o);
            }
            if let Some([p, n]) = stribeck {
                f(ParamKind::FsPos, p);
                f(ParamKind::FsNeg, n);
            }
        }
    }
}

/// The drive parameters of one joint, (kind, nominal value) in layout order
/// ([`visit_drive_params`]); at most Ia and [`MAX_FRICTION_COLUMNS`]
/// coefficients, kept inline (no allocation).
#[derive(Debug, Clone, Copy)]
pub struct DriveParams {
    len: usize,
    items: [(ParamKind, f64); 1 + MAX_FRICTION_COLUMNS],
}

impl DriveParams {
    /// The parameters, Ia first when modelled.
    pub fn as_slice(&self) -> &[(ParamKind, f64)] {
        &self.items[..self.len]
    }

    /// The friction coefficients only (without Ia), in the order of [`friction_columns`].
    pub fn friction(&self) -> &[(ParamKind, f64)] {
        let s = self.as_slice();
        match s.first() {
            Some((ParamKind::Ia, _)) => &s[1..],
            _ => s,
        }
    }
}

/// The drive parameters of `d` with their nominal values ([`visit_drive_params`]).
pub fn drive_params(d: &Drive) -> DriveParams {
    let mut d = *d;
    let mut out = DriveParams {
        len: 0,
        items: [(ParamKind::Ia, 0.0); 1 + MAX_FRICTION_COLUMNS],
    };
    visit_drive_params(&mut d, |k, v| {
        out.items[out.len] = (k, *v);
        out.len += 1;
    });
    out
}
