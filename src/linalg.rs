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

/// Parallel splits of faer's dense kernels (SVD, QR, their matmuls). faer's
/// own default splits by the rayon pool's thread count, which changes the
/// order of floating-point reductions and so the last bits of a result; a
/// fixed count keeps results bit-identical for any pool size (the CLI's
/// `--threads`, a Python or library caller's own pool).
pub const FAER_SPLITS: usize = 4;

/// The parallelism every faer call of the crate uses (see [`FAER_SPLITS`]).
pub fn par() -> faer::Par {
    faer::Par::rayon(FAER_SPLITS)
}

/// The thin U and V of an SVD.
type SvdVectors = (faer::Mat<f64>, faer::Mat<f64>);

/// SVD through faer's kernel with the crate's fixed parallelism: the
/// singular values (unsorted, as faer returns them) and, when `vectors`,
/// the thin U and V.
fn svd_fixed(m: &DMatrix<f64>, vectors: bool) -> Result<(faer::diag::Diag<f64>, Option<SvdVectors>)> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
    let f = to_faer(m);
    let (r, c) = (m.nrows(), m.ncols());
    let k = r.min(c);
    let mut s = faer::diag::Diag::<f64>::zeros(k);
    let compute = if vectors { ComputeSvdVectors::Thin } else { ComputeSvdVectors::No };
    let mut buf = MemBuffer::new(svd_scratch::<f64>(r, c, compute, compute, par(), Default::default()));
    let stack = MemStack::new(&mut buf);
    let err = |e| Error::Numerical(format!("SVD did not converge: {e:?}"));
    if vectors {
        let mut u = faer::Mat::<f64>::zeros(r, k);
        let mut v = faer::Mat::<f64>::zeros(c, k);
        svd(f, s.as_mut(), Some(u.as_mut()), Some(v.as_mut()), par(), stack, Default::default()).map_err(err)?;
        Ok((s, Some((u, v))))
    } else {
        svd(f, s.as_mut(), None, None, par(), stack, Default::default()).map_err(err)?;
        Ok((s, None))
    }
}

/// Singular values in decreasing order.
pub fn singular_values(m: &DMatrix<f64>) -> Result<Vec<f64>> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("matrix has non-finite entries; cannot compute singular values".into()));
    }
    let (s, _) = svd_fixed(m, false)?;
    let mut s: Vec<f64> = s.column_vector().iter().copied().collect();
    s.sort_by(|a, b| b.total_cmp(a));
    Ok(s)
}

/// Thin SVD m = U diag(s) Vᵀ with s decreasing: (U: r×k, s: k, V: c×k), k = min(r, c).
pub fn thin_svd(m: &DMatrix<f64>) -> Result<(DMatrix<f64>, DVector<f64>, DMatrix<f64>)> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical("matrix has non-finite entries; cannot compute its SVD".into()));
    }
    let (s, uv) = svd_fixed(m, true)?;
    let (u, v) = uv.expect("vectors requested");
    let k = m.nrows().min(m.ncols());
    let s_col = s.column_vector();
    let mut idx: Vec<usize> = (0..k).collect();
    idx.sort_by(|&a, &b| s_col[b].total_cmp(&s_col[a]));
    let uu = DMatrix::from_fn(m.nrows(), k, |i, j| u[(i, idx[j])]);
    let vv = DMatrix::from_fn(m.ncols(), k, |i, j| v[(i, idx[j])]);
    let ss = DVector::from_fn(k, |j, _| s_col[idx[j]]);
    Ok((uu, ss, vv))
}

/// Column-pivoted QR: returns |R_ii| (decreasing by construction) and the
/// column permutation (entry k is the original index of the k-th pivot).
pub fn col_piv_qr_diag(m: &DMatrix<f64>) -> (Vec<f64>, Vec<usize>) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::qr::col_pivoting::factor::{qr_in_place, qr_in_place_scratch};
    use faer::linalg::qr::no_pivoting::factor::recommended_block_size;
    let mut a = to_faer(m).to_owned();
    let (r, c) = (m.nrows(), m.ncols());
    let k = r.min(c);
    let bs = recommended_block_size::<f64>(r, c);
    let mut q_coeff = faer::Mat::<f64>::zeros(bs, k);
    let mut fwd = vec![0usize; c];
    let mut bwd = vec![0usize; c];
    let mut buf = MemBuffer::new(qr_in_place_scratch::<usize, f64>(r, c, bs, par(), Default::default()));
    qr_in_place(
        a.as_mut(),
        q_coeff.as_mut(),
        &mut fwd,
        &mut bwd,
        par(),
        MemStack::new(&mut buf),
        Default::default(),
    );
    let d = (0..k).map(|i| a[(i, i)].abs()).collect();
    (d, fwd)
}

/// The triangular factor R (c×c, upper) of a QR factorisation of `a`
/// (r×c, r ≥ c), through faer's blocked Householder QR on one thread (the
/// tall, narrow blocks of a streamed regressor are too small for faer's
/// threads to pay: they cost more in synchronisation than they save). R
/// has the singular values, right singular vectors and column norms of
/// `a`; the signs of its rows are those of faer's reflections.
pub fn qr_r(mut a: faer::Mat<f64>) -> DMatrix<f64> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::qr::no_pivoting::factor::{qr_in_place, qr_in_place_scratch, recommended_block_size};
    let (r, c) = (a.nrows(), a.ncols());
    let k = r.min(c);
    let bs = recommended_block_size::<f64>(r, c).max(1);
    let mut q_coeff = faer::Mat::<f64>::zeros(bs, k);
    let seq = faer::Par::Seq;
    let mut buf = MemBuffer::new(qr_in_place_scratch::<f64>(r, c, bs, seq, Default::default()));
    qr_in_place(a.as_mut(), q_coeff.as_mut(), seq, MemStack::new(&mut buf), Default::default());
    DMatrix::from_fn(k, c, |i, j| if j >= i { a[(i, j)] } else { 0.0 })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic dense test matrix (no RNG: a smooth, full-rank pattern).
    fn tall(r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |i, j| ((i * 7 + j * 13) as f64 * 0.37).sin() + if i == j { 2.0 } else { 0.0 })
    }

    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
    }

    /// The library itself (not only the CLI) gives bit-identical SVD and QR
    /// results whatever the rayon pool's size, with faer's global setting
    /// left at its thread-count-dependent default.
    #[test]
    fn faer_results_do_not_depend_on_the_pool_size() {
        let m = tall(3000, 60);
        let run = || (singular_values(&m).unwrap(), thin_svd(&m).unwrap(), col_piv_qr_diag(&m));
        let a = in_pool(1, run);
        let b = in_pool(2, run);
        let c = in_pool(3, run);
        for other in [&b, &c] {
            assert!(a.0.iter().zip(&other.0).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(a.1 .0.iter().zip(other.1 .0.iter()).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(a.1 .2.iter().zip(other.1 .2.iter()).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert!(a.2 .0.iter().zip(&other.2 .0).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert_eq!(a.2 .1, other.2 .1);
        }
        // and the decomposition is right: U diag(s) Vᵀ = m
        let (u, s, v) = &a.1;
        let rec = u * DMatrix::from_diagonal(s) * v.transpose();
        assert!((rec - &m).amax() < 1e-10);
        assert!(s.iter().zip(&a.0).all(|(x, y)| (x - y).abs() < 1e-10));
    }
}
