//! Dicts in and out: library results as Python objects ([`to_dict`], the
//! library's serde serialisation) and designs given as a file or a dict.
//!
//! Every problem function takes a design as a path (the file the command
//! line takes) or, where the design type is plain data, a dict with the
//! file's fields; relative paths inside a dict are resolved against
//! `base_dir` (default: the current directory), inside a file against the
//! file's folder, as on the command line.

use crate::err::{value, IdexpError, IntoPy};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// A serde value as Python objects (dicts, lists, floats, strings).
pub fn to_dict<'py, T: serde::Serialize + ?Sized>(py: Python<'py>, v: &T) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, v).map_err(|e| IdexpError::new_err(format!("idexp: could not convert a result to Python: {e}")))
}

/// A design given as a file or as a dict.
pub(crate) enum Source {
    File(PathBuf),
    Dict(serde_json::Value),
}

pub(crate) fn source(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
    if obj.is_instance_of::<PyDict>() {
        let v: serde_json::Value =
            pythonize::depythonize(obj).map_err(|e| value(format!("design: the dict is not plain data (str, numbers, lists, dicts): {e}")))?;
        return Ok(Source::Dict(v));
    }
    match obj.extract::<PathBuf>() {
        Ok(p) => Ok(Source::File(p)),
        Err(_) => Err(value(format!(
            "design: expected a path (str or os.PathLike) or a dict, got {}",
            obj.get_type().name()?
        ))),
    }
}

/// Deserialises a design dict; errors name the field like the file readers do.
/// A dict input as T; an error names the field it fails on (`field
/// `refine.stall`: invalid value: integer `-1`, expected usize`).
pub(crate) fn from_dict<T: serde::de::DeserializeOwned>(v: serde_json::Value, what: &str) -> PyResult<T> {
    serde_path_to_error::deserialize(v).map_err(|e| {
        let path = e.path().to_string();
        if path == "." {
            IdexpError::new_err(format!("{what} (dict): {}", e.inner()))
        } else {
            IdexpError::new_err(format!("{what} (dict): field `{path}`: {}", e.inner()))
        }
    })
}

pub(crate) fn base_dir(b: Option<PathBuf>) -> PathBuf {
    b.unwrap_or_else(|| PathBuf::from("."))
}

/// A design and the folder its relative paths start from: a file is read by
/// `read` (its folder); a dict is deserialised (`what` names it in errors),
/// given its default name by `name` and checked by `validate` (`base_dir`).
pub(crate) fn design_and_dir<T: serde::de::DeserializeOwned>(
    design: &Bound<'_, PyAny>,
    base_dir: Option<PathBuf>,
    what: &str,
    read: impl FnOnce(&Path) -> idexp::Result<T>,
    name: impl FnOnce(&mut T),
    validate: impl FnOnce(&T, &str) -> idexp::Result<()>,
) -> PyResult<(T, PathBuf)> {
    Ok(match source(design)? {
        Source::File(p) => (read(&p).py()?, p.parent().map(Path::to_path_buf).unwrap_or_default()),
        Source::Dict(v) => {
            let mut d: T = from_dict(v, what)?;
            name(&mut d);
            validate(&d, &format!("{what} (dict)")).py()?;
            (d, self::base_dir(base_dir))
        }
    })
}

pub(crate) fn resolve(dir: &Path, p: &Path) -> PathBuf {
    if p.is_relative() {
        dir.join(p)
    } else {
        p.to_path_buf()
    }
}
