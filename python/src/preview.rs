//! `write_preview`: the interactive 3D preview page (`preview.html`) of an
//! `idexp excite` output folder or of a trajectory CSV (`idexp view`).

use crate::err::{value, IntoPy};
use idexp::preview::{write_for_folder, write_for_trajectory, PreviewOptions};
use pyo3::prelude::*;
use std::path::PathBuf;

/// write_preview(source, robot=None, design=None, out=None, fps=30.0) -> path
///
/// `idexp view`: writes `preview.html`, the self-contained 3D preview of a
/// trajectory, and returns its path. `source` is an output folder of
/// `excite` or, with `robot`, a trajectory CSV (`t, q1..qn, qd1..qdn`);
/// `design` adds that design's obstacles, workspace and limits to a CSV's
/// page. `out`: the folder that receives the page (default: the output
/// folder, or the CSV's folder).
#[pyfunction]
#[pyo3(signature = (source, robot = None, design = None, out = None, fps = 30.0))]
pub fn write_preview(py: Python<'_>, source: PathBuf, robot: Option<PathBuf>, design: Option<PathBuf>, out: Option<PathBuf>, fps: f64) -> PyResult<PathBuf> {
    if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
        return Err(value(format!("fps: expected frames per second in (0, 1000], got {fps}")));
    }
    let opts = PreviewOptions { fps };
    let written = match &robot {
        None if source.is_dir() => py.detach(|| write_for_folder(&source, out.as_deref(), &opts)).py()?,
        None => {
            return Err(value(format!(
                "source: {} is not a folder; give an output folder of excite, or a trajectory CSV with robot=",
                source.display()
            )))
        }
        Some(r) => py.detach(|| write_for_trajectory(r, &source, design.as_deref(), out.as_deref(), &opts)).py()?,
    };
    Ok(written.path)
}
