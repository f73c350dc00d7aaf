//! Python bindings of the idexp library (`import idexp`).
//!
//! The binding layer is regular on purpose, so that new library calls are
//! added the same way:
//!
//! - arrays come in through [`arrays`] (float64, any memory order, shape
//!   checked against the robot with a `ValueError` naming the argument and
//!   the expected shape) and go out as owned numpy arrays;
//! - library errors become `idexp.IdexpError` (a `ValueError`) or `OSError`
//!   through [`err`], carrying idexp's message unchanged;
//! - long calls go through [`long::run_long`]: the work runs on a scoped
//!   thread with its own `optim::Control` while the calling thread, with the
//!   GIL released between polls, checks for signals; Ctrl-C sets the stop
//!   flag, waits for the work to return and raises `KeyboardInterrupt`
//!   (nothing half-done is returned);
//! - results are `#[pyclass]`es with numpy getters for the numbers and a
//!   `report` dict (the library's serde serialisation, the same JSON the
//!   command line writes) and `write(folder)` where the library has a writer.
//!
//! The bindings call the library only, never the command-line code.

use pyo3::prelude::*;

mod arrays;
mod err;
mod exports;
mod logs;
mod long;
mod mjcf;
mod payload;
mod preview;
mod problems;
mod robot;
mod study;

/// The native module `idexp._idexp`; `idexp/__init__.py` re-exports it.
#[pymodule]
fn _idexp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("IdexpError", m.py().get_type::<err::IdexpError>())?;
    m.add_class::<robot::Robot>()?;
    m.add_class::<robot::BaseParameters>()?;
    m.add_class::<problems::ExciteResult>()?;
    m.add_class::<problems::Identifiability>()?;
    m.add_class::<problems::SimRun>()?;
    m.add_class::<problems::Identification>()?;
    m.add_class::<problems::PositionsResult>()?;
    m.add_class::<problems::FitResult>()?;
    m.add_class::<study::Study>()?;
    m.add_function(wrap_pyfunction!(study::study, m)?)?;
    m.add_class::<payload::PayloadFit>()?;
    m.add_function(wrap_pyfunction!(payload::payload, m)?)?;
    m.add_function(wrap_pyfunction!(payload::with_payload, m)?)?;
    m.add_function(wrap_pyfunction!(problems::excite, m)?)?;
    m.add_function(wrap_pyfunction!(problems::assess, m)?)?;
    m.add_function(wrap_pyfunction!(problems::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(problems::identify, m)?)?;
    m.add_function(wrap_pyfunction!(problems::positions, m)?)?;
    m.add_function(wrap_pyfunction!(problems::fit, m)?)?;
    m.add_function(wrap_pyfunction!(problems::multisine, m)?)?;
    m.add_function(wrap_pyfunction!(problems::frf, m)?)?;
    m.add_function(wrap_pyfunction!(problems::export_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(logs::read_log, m)?)?;
    m.add_function(wrap_pyfunction!(logs::log_info, m)?)?;
    m.add_function(wrap_pyfunction!(mjcf::mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(mjcf::write_mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(preview::write_preview, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
