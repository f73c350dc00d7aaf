//! idexp errors as Python exceptions.

use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::PyErr;

pyo3::create_exception!(
    _idexp,
    IdexpError,
    PyValueError,
    "Bad input found by idexp: the message names the file, the field or row, the value and what is allowed."
);

/// Maps a library error to a Python exception with idexp's message: I/O
/// failures are `OSError`, everything else `idexp.IdexpError` (a `ValueError`).
pub fn to_py(e: idexp::Error) -> PyErr {
    match e {
        idexp::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        _ => IdexpError::new_err(e.to_string()),
    }
}

/// `ValueError` for a bad argument of a binding.
pub fn value(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// `.map_err(err::to_py)` in short.
pub trait IntoPy<T> {
    /// The library result as a Python result.
    fn py(self) -> pyo3::PyResult<T>;
}

impl<T> IntoPy<T> for idexp::Result<T> {
    fn py(self) -> pyo3::PyResult<T> {
        self.map_err(to_py)
    }
}
