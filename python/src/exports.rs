//! The exports: a delivered trajectory (lead-in, periods, lead-out) as
//! arrays with its phase labels, and in controller formats (URScript, ROS 2
//! YAML, CSV: `idexp excite --export`, `idexp export`); the plan poses of
//! `idexp positions --export`; identified models (robot TOML, URDF:
//! `idexp identify --export`). Every writer is the library's; this module
//! turns the Python arguments into its options, with `ValueError`s naming
//! the argument.

use crate::arrays::{out1, out_rows};
use crate::err::{value, IntoPy};
use idexp::robot::export::{self as rx, Source};
use idexp::trajectory::export::{program_name, CsvOptions, ExportOptions, Format, UrController};
use idexp::trajectory::lead::{Delivered, LEAD_IN, LEAD_OUT};
use numpy::ndarray::Array1;
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use std::path::{Path, PathBuf};

/// A list of format names: `"ur,ros2"` or `["ur", "ros2"]`.
pub fn names(arg: &Bound<'_, PyAny>, what: &str, allowed: &str) -> PyResult<Vec<String>> {
    let list: Vec<String> = if arg.is_instance_of::<PyString>() {
        arg.extract::<String>()?
            .split(',')
            .map(|x| x.trim().to_string())
            .filter(|x| !x.is_empty())
            .collect()
    } else if let Ok(v) = arg.extract::<Vec<String>>() {
        v
    } else {
        return Err(value(format!("{what}: expected a list of names ({allowed}) or a comma-separated string")));
    };
    if list.is_empty() {
        return Err(value(format!("{what}: expected at least one of {allowed}")));
    }
    Ok(list)
}

/// Controller formats (`ur`, `ros2`, `csv`), parsed by the library.
pub fn formats(arg: &Bound<'_, PyAny>) -> PyResult<Vec<Format>> {
    names(arg, "formats", "ur, ros2, csv")?
        .iter()
        .map(|s| Format::parse(s).map_err(|_| value(format!("formats: `{s}`: expected ur, ros2 or csv"))))
        .collect()
}

fn positive(name: &str, v: f64, unit: &str) -> PyResult<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(value(format!("{name}: expected a positive value ({unit}), got {v}")))
    }
}

/// The keyword arguments of a trajectory export (those of `idexp export`).
pub struct TrajectoryArgs<'a> {
    /// Rate of the ROS 2 and CSV files (Hz), None: the design's controller rate.
    pub rate: Option<f64>,
    /// `e-series` or `cb3`.
    pub ur: &'a str,
    /// `rad` or `deg`.
    pub csv_units: &'a str,
    /// Velocities and accelerations in the CSV.
    pub csv_derivatives: bool,
    /// URScript `movej` to the start: speed (rad/s).
    pub approach_speed: f64,
    /// … and acceleration (rad/s²).
    pub approach_acceleration: f64,
}

impl TrajectoryArgs<'_> {
    /// The library's options (the command line's checks and defaults).
    pub fn options(&self, formats: Vec<Format>, default_rate: f64, design: &str) -> PyResult<ExportOptions> {
        let rate = self.rate.unwrap_or(default_rate);
        if !(rate.is_finite() && rate > 0.0 && rate <= 100_000.0) {
            return Err(value(format!("rate: expected a rate in (0, 100000] Hz, got {rate}")));
        }
        let ur = match self.ur.to_ascii_lowercase().as_str() {
            "e-series" | "e_series" | "eseries" => UrController::ESeries,
            "cb3" => UrController::Cb3,
            u => return Err(value(format!("ur: expected \"e-series\" (servoj at 500 Hz) or \"cb3\" (125 Hz), got {u:?}"))),
        };
        let degrees = match self.csv_units {
            "rad" => false,
            "deg" => true,
            u => return Err(value(format!("csv_units: expected \"rad\" or \"deg\", got {u:?}"))),
        };
        Ok(ExportOptions {
            formats,
            rate,
            ur,
            csv: CsvOptions {
                derivatives: self.csv_derivatives,
                degrees,
            },
            stem: program_name(design),
            approach: (
                positive("approach_acceleration", self.approach_acceleration, "rad/s²")?,
                positive("approach_speed", self.approach_speed, "rad/s")?,
            ),
        })
    }
}

/// Label of a segment code of `Delivered::eval` (0 lead-in, k period k, −1 lead-out).
fn label(code: i64) -> String {
    match code {
        LEAD_IN => "lead_in".to_string(),
        LEAD_OUT => "lead_out".to_string(),
        k => format!("period {k}"),
    }
}

/// The delivered trajectory sampled at `rate` Hz (the rows of trajectory.csv
/// at the controller rate) as a dict of arrays, with the phase labels.
pub fn delivered_dict<'py>(py: Python<'py>, d: &Delivered, rate: f64, n: usize) -> PyResult<Bound<'py, PyDict>> {
    let s = py.detach(|| d.sample(rate)).py()?;
    let out = PyDict::new(py);
    out.set_item("t", out1(py, s.t))?;
    out.set_item("q", out_rows(py, &s.q, n))?;
    out.set_item("qd", out_rows(py, &s.qd, n))?;
    out.set_item("qdd", out_rows(py, &s.qdd, n))?;
    out.set_item("segment", Array1::from_vec(s.segment).into_pyarray(py))?;
    let source: Vec<i64> = s.source.iter().map(|&k| k as i64).collect();
    out.set_item("source", Array1::from_vec(source).into_pyarray(py))?;
    let labels = PyDict::new(py);
    let phases = PyList::empty(py);
    let mut codes = Vec::new();
    if d.lead_in.is_some() {
        codes.push((LEAD_IN, 0.0, d.lead_in_duration()));
    }
    let period = idexp::trajectory::Motion::duration(&d.periodic);
    for k in 1..=d.periods {
        let start = d.periodic_start() + (k - 1) as f64 * period;
        codes.push((k as i64, start, start + period));
    }
    if d.lead_out.is_some() {
        codes.push((LEAD_OUT, d.periodic_end(), d.duration()));
    }
    for (code, a, b) in codes {
        phases.append((label(code), a, b))?;
    }
    for code in std::iter::once(LEAD_IN).chain(1..=d.periods as i64).chain(std::iter::once(LEAD_OUT)) {
        labels.set_item(code, label(code))?;
    }
    out.set_item("labels", labels)?;
    out.set_item("phases", phases)?;
    out.set_item("home", out1(py, d.home.clone()))?;
    out.set_item("periods", d.periods)?;
    out.set_item("period", period)?;
    out.set_item("lead_in_duration", d.lead_in_duration())?;
    out.set_item("lead_out_duration", d.lead_out_duration())?;
    out.set_item("duration", d.duration())?;
    out.set_item("rate", rate)?;
    Ok(out)
}

/// Model export kinds (`urdf`, `toml`, and for an identification `csv`).
pub fn model_kinds(arg: &Bound<'_, PyAny>, allowed: &[&str]) -> PyResult<Vec<String>> {
    let list = names(arg, "formats", &allowed.join(", "))?;
    for s in &list {
        if !allowed.contains(&s.as_str()) {
            return Err(value(format!("formats: `{s}`: expected {}", allowed.join(", "))));
        }
    }
    Ok(list)
}

/// Writes `robot` (identified parameters) as `robot.urdf` and/or
/// `robot.toml` into `dir`, the way `idexp identify --export urdf,toml`
/// does: the URDF copies the kinematics of the source file `source`; the
/// TOML of a URDF robot points at the exported URDF (written also when only
/// "toml" is asked: robot.toml must carry this robot's inertials).
pub fn write_model(source: &Path, robot: &idexp::robot::Robot, dir: &Path, kinds: &[String]) -> PyResult<Vec<PathBuf>> {
    let src = rx::source_of(source).py()?;
    // robot.toml of a URDF robot points at a URDF: this robot's, written beside it
    let urdf = kinds.iter().any(|k| k == "urdf") || (kinds.iter().any(|k| k == "toml") && matches!(src, Source::Urdf { .. }));
    if urdf {
        if let Source::Dh { toml } = &src {
            return Err(value(format!(
                "formats: \"urdf\": {} is a DH table, not a URDF: there is no URDF to copy the kinematics from; export \"toml\" (the DH table with the identified inertials and drive parameters)",
                toml.display()
            )));
        }
    }
    std::fs::create_dir_all(dir).map_err(|e| crate::err::to_py(idexp::Error::io(dir, e)))?;
    let mut files = Vec::new();
    if urdf {
        files.push(rx::write_urdf(&src, robot, dir).py()?);
    }
    if kinds.iter().any(|k| k == "toml") {
        let urdf_ref = urdf.then(|| "robot.urdf".to_string());
        files.push(rx::write_robot_toml(&src, robot, dir, urdf_ref.as_deref()).py()?);
    }
    Ok(files)
}
