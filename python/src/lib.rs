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
mod assess;
mod dicts;
mod elastic;
mod err;
mod excite;
mod exports;
mod gains;
mod identify;
mod logs;
mod long;
mod mjcf;
mod payload;
mod plan;
mod positions;
mod preview;
mod robot;
mod simulate;
mod study;

/// The native module `idexp._idexp`; `idexp/__init__.py` re-exports it.
#[pymodule]
fn _idexp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("IdexpError", m.py().get_type::<err::IdexpError>())?;
    m.add_class::<robot::Robot>()?;
    m.add_class::<robot::BaseParameters>()?;
    m.add_class::<excite::ExciteResult>()?;
    m.add_class::<assess::Identifiability>()?;
    m.add_class::<simulate::SimRun>()?;
    m.add_class::<identify::Identification>()?;
    m.add_class::<positions::PositionsResult>()?;
    m.add_class::<elastic::FitResult>()?;
    m.add_class::<study::Study>()?;
    m.add_class::<study::JointFits>()?;
    m.add_function(wrap_pyfunction!(study::study, m)?)?;
    m.add_class::<payload::PayloadFit>()?;
    m.add_function(wrap_pyfunction!(payload::payload, m)?)?;
    m.add_function(wrap_pyfunction!(payload::with_payload, m)?)?;
    m.add_class::<gains::GainsFit>()?;
    m.add_function(wrap_pyfunction!(gains::calibrate_gains, m)?)?;
    m.add_function(wrap_pyfunction!(gains::rtde_gains, m)?)?;
    m.add_class::<plan::Plan>()?;
    m.add_function(wrap_pyfunction!(plan::plan, m)?)?;
    m.add_function(wrap_pyfunction!(excite::excite, m)?)?;
    m.add_function(wrap_pyfunction!(assess::assess, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(identify::identify, m)?)?;
    m.add_function(wrap_pyfunction!(positions::positions, m)?)?;
    m.add_function(wrap_pyfunction!(elastic::fit, m)?)?;
    m.add_function(wrap_pyfunction!(elastic::multisine, m)?)?;
    m.add_function(wrap_pyfunction!(elastic::frf, m)?)?;
    m.add_function(wrap_pyfunction!(excite::export_trajectory, m)?)?;
    m.add_function(wrap_pyfunction!(logs::read_log, m)?)?;
    m.add_function(wrap_pyfunction!(logs::log_info, m)?)?;
    m.add_function(wrap_pyfunction!(mjcf::mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(mjcf::write_mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(preview::write_preview, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
