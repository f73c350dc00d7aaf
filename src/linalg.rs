//! Dense linear algebra on large matrices through faer, and the one place
//! where nalgebra matrices are converted to and from faer.

use crate::error::{Error, Result};
use faer_ext::{IntoFaer, IntoNalgebra};
use nalgebra::{DMatrix, DVector};

/// A faer view of a nalgebra matrix (no copy: faer-ext's zero-copy view).
pub fn to_faer(m: &DMatrix<f64>) -> faer::MatRef<'_, f64> {
    let v: nalgebra::DMatrixView<f64> = m.as_view();
    v.into_faer()
}

/// Copies a faer matrix view into a nalgebra matrix (through faer-ext's view).
pub fn from_faer(m: faer::MatRef<'_, f64>) -> DMatrix<f64> {
    m.into_nalgebra().into_owned()
}

/// Singular values in decreasing order.
pub fn singular_values(m: &DMatrix<f64>) -> Result<Vec<f64>> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("matrix has non-finite entries; cannot compute singular values".into()));
    }
    let f = to_faer(m);
    let mut s = f.singular_values().map_err(|e| Error::Numerical(format!("SVD did not converge: {e:?}")))?;
    s.sort_by(|a, b| b.total_cmp(a));
    Ok(s)
}

/// Thin SVD m = U diag(s) Vᵀ with s decreasing: (U: r×k, s: k, V: c×k), k = min(r, c).
pub fn thin_svd(m: &DMatrix<f64>) -> Result<(DMatrix<f64>, DVector<f64>, DMatrix<f64>)> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("matrix has non-finite entries; cannot compute its SVD".into()));
    }
    let f = to_faer(m);
    let svd = f.thin_svd().map_err(|e| Error::Numerical(format!("SVD did not converge: {e:?}")))?;
    let k = m.nrows().min(m.ncols());
    let s_diag = svd.S();
    let s_col = s_diag.column_vector();
    let mut idx: Vec<usize> = (0..k).collect();
    idx.sort_by(|&a, &b| s_col[b].total_cmp(&s_col[a]));
    let u = svd.U();
    let v = svd.V();
    let uu = DMatrix::from_fn(m.nrows(), k, |i, j| u[(i, idx[j])]);
    let vv = DMatrix::from_fn(m.ncols(), k, |i, j| v[(i, idx[j])]);
    let ss = DVector::from_fn(k, |j, _| s_col[idx[j]]);
    Ok((uu, ss, vv))
}

/// Column-pivoted QR: returns |R_ii| (decreasing by construction) and the
/// column permutation (entry k is the original index of the k-th pivot).
pub fn col_piv_qr_diag(m: &DMatrix<f64>) -> (Vec<f64>, Vec<usize>) {
    let f = to_faer(m);
    let qr = f.col_piv_qr();
    let r = qr.thin_R();
    let k = r.nrows().min(r.ncols());
    let d = (0..k).map(|i| r[(i, i)].abs()).collect();
    let perm = qr.P().arrays().0.to_vec();
    (d, perm)
}

/// Removes from `v` its components along the orthonormal vectors `basis`:
/// two passes of modified Gram–Schmidt (the second re-orthogonalises against
/// the rounding left by the first), v ← v − Σ_b (bᵀv) b each pass. The norm of
/// the result is the distance of v from span(basis).
pub fn orthogonalize(basis: &[DVector<f64>], v: &mut DVector<f64>) {
    for _ in 0..2 {
        for b in basis {
            let d = b.dot(v);
            v.axpy(-d, b, 1.0);
        }
    }
}
