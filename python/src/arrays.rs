//! numpy arrays in and out: float64 in any memory order (C, Fortran or
//! strided views; integer and list input is converted), shapes checked with
//! `ValueError`s naming the argument and the expected shape.

use crate::err::value;
use numpy::ndarray::{Array1, Array2, ArrayViewD, Ix1, Ix2};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLikeDyn};
use pyo3::prelude::*;

/// An array argument converted to float64.
pub type Arg<'py> = PyArrayLikeDyn<'py, f64, AllowTypeChange>;

fn shape_str(v: &ArrayViewD<f64>) -> String {
    let s: Vec<String> = v.shape().iter().map(|d| d.to_string()).collect();
    if s.len() == 1 {
        format!("({},)", s[0])
    } else {
        format!("({})", s.join(", "))
    }
}

fn check_finite(name: &str, v: &[f64]) -> PyResult<()> {
    if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(value(format!("{name}: element {i} (in C order) is {x}: expected finite numbers")));
    }
    Ok(())
}

/// The values of `v` in C (row-major) order, checked finite. A C-contiguous
/// array is one `memcpy`; Fortran-ordered and strided 1-D/2-D arrays are
/// gathered through fixed-dimension views (the dynamic-dimension iterator
/// costs ~0.2 µs per element: 20 ms for a (10,000 × 6) Fortran array).
fn c_order(name: &str, v: &ArrayViewD<f64>) -> PyResult<Vec<f64>> {
    let data: Vec<f64> = if let Some(s) = v.as_slice() {
        s.to_vec()
    } else {
        match v.ndim() {
            1 => v.view().into_dimensionality::<Ix1>().expect("1-D").iter().copied().collect(),
            2 => {
                let m = v.view().into_dimensionality::<Ix2>().expect("2-D");
                let mut out = Vec::with_capacity(m.len());
                // rows of a Fortran array are strided, its columns contiguous:
                // write column by column into the row-major buffer
                let (r, c) = m.dim();
                out.resize(r * c, 0.0);
                for (j, col) in m.columns().into_iter().enumerate() {
                    for (i, x) in col.iter().enumerate() {
                        out[i * c + j] = *x;
                    }
                }
                out
            }
            _ => v.iter().copied().collect(),
        }
    };
    check_finite(name, &data)?;
    Ok(data)
}

/// Joint-space states: shape (n,) (one state) or (N, n) (a batch).
pub struct States {
    /// Row-major N×n values.
    pub data: Vec<f64>,
    /// Number of states N.
    pub rows: usize,
    /// Whether a batch (2-D) was given.
    pub batch: bool,
}

impl States {
    /// State `k` (length n).
    pub fn row(&self, k: usize, n: usize) -> &[f64] {
        &self.data[k * n..(k + 1) * n]
    }
}

/// Reads `arg` as one state (n,) or a batch (N, n).
pub fn states(name: &str, arg: &Arg, n: usize) -> PyResult<States> {
    let v = arg.as_array();
    let bad = || value(format!("{name}: expected shape ({n},) or (N, {n}), got {}", shape_str(&v)));
    let (rows, batch) = match v.shape() {
        [k] if *k == n => (1, false),
        [r, k] if *k == n => (*r, true),
        _ => return Err(bad()),
    };
    Ok(States {
        data: c_order(name, &v)?,
        rows,
        batch,
    })
}

/// Reads the three state arrays and checks they agree.
pub fn state_triple(q: &Arg, qd: &Arg, qdd: &Arg, n: usize) -> PyResult<(States, States, States)> {
    let q = states("q", q, n)?;
    let qd = states("qd", qd, n)?;
    let qdd = states("qdd", qdd, n)?;
    for (name, s) in [("qd", &qd), ("qdd", &qdd)] {
        if s.rows != q.rows || s.batch != q.batch {
            let want = if q.batch { format!("({}, {n})", q.rows) } else { format!("({n},)") };
            return Err(value(format!("{name}: expected the shape of q, {want}")));
        }
    }
    Ok((q, qd, qdd))
}

/// A vector of length `len` (`what` describes it in the message).
pub fn vector(name: &str, arg: &Arg, len: usize, what: &str) -> PyResult<Vec<f64>> {
    let v = arg.as_array();
    match v.shape() {
        [k] if *k == len => {}
        _ => return Err(value(format!("{name}: expected shape ({len},) ({what}), got {}", shape_str(&v)))),
    }
    c_order(name, &v)
}

/// A vector of any length ≥ 1.
pub fn any_vector(name: &str, arg: &Arg) -> PyResult<Vec<f64>> {
    let v = arg.as_array();
    if v.ndim() != 1 || v.is_empty() {
        return Err(value(format!("{name}: expected shape (N,) with N ≥ 1, got {}", shape_str(&v))));
    }
    c_order(name, &v)
}

/// A matrix (rows, n) as row vectors; `rows`: the required row count, if any.
pub fn matrix_rows(name: &str, arg: &Arg, rows: Option<usize>, n: usize) -> PyResult<Vec<Vec<f64>>> {
    let v = arg.as_array();
    let ok = matches!(v.shape(), [r, k] if *k == n && rows.is_none_or(|want| *r == want));
    if !ok {
        let r = rows.map(|r| r.to_string()).unwrap_or_else(|| "N".into());
        return Err(value(format!("{name}: expected shape ({r}, {n}), got {}", shape_str(&v))));
    }
    let data = c_order(name, &v)?;
    Ok(data.chunks(n).map(<[f64]>::to_vec).collect())
}

/// A 1-D numpy array.
pub fn out1<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    Array1::from_vec(v).into_pyarray(py)
}

/// A 2-D numpy array from row-major data.
pub fn out2<'py>(py: Python<'py>, rows: usize, cols: usize, v: Vec<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_vec((rows, cols), v)
        .expect("row-major data of rows·cols values")
        .into_pyarray(py)
}

/// A 2-D numpy array from rows of equal length `cols`.
pub fn out_rows<'py>(py: Python<'py>, rows: &[Vec<f64>], cols: usize) -> Bound<'py, PyArray2<f64>> {
    out2(py, rows.len(), cols, rows.iter().flatten().copied().collect())
}

/// A 2-D numpy array from a nalgebra matrix.
pub fn out_matrix<'py>(py: Python<'py>, m: &nalgebra::DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    let (r, c) = m.shape();
    out2(py, r, c, (0..r * c).map(|k| m[(k / c, k % c)]).collect())
}
