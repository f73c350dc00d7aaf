//! Long calls: the work runs on a scoped thread with its own `Control`; the
//! caller's thread releases the GIL, polls the interpreter's signal handlers
//! every 20 ms and, on Ctrl-C (or any exception a handler raises), requests a
//! stop, waits for the work to return and re-raises the exception. Progress
//! reported through the `Control`'s observer is handed to an optional Python
//! callback `progress(phase, done, total, message)` from the polling thread.

use idexp::optim::{Control, Observer, StopFlag};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The latest progress of the work, read by the polling thread.
#[derive(Default)]
struct Latest {
    phase: String,
    total: Option<u64>,
    done: u64,
    msg: String,
    changed: bool,
}

#[derive(Default)]
struct Recorder(Mutex<Latest>);

impl Observer for Recorder {
    fn phase(&self, name: &str, total: Option<u64>) {
        let mut l = self.0.lock().unwrap_or_else(|e| e.into_inner());
        *l = Latest {
            phase: name.to_string(),
            total,
            done: 0,
            msg: String::new(),
            changed: true,
        };
    }
    fn progress(&self, done: u64, msg: &str) {
        let mut l = self.0.lock().unwrap_or_else(|e| e.into_inner());
        l.done = done;
        l.msg = msg.to_string();
        l.changed = true;
    }
}

/// Runs `work` with a `Control` (time limit `time_limit`, if any) while
/// keeping the interpreter responsive; see the module documentation.
pub fn run_long<T, F>(py: Python<'_>, time_limit: Option<f64>, progress: Option<&Bound<'_, PyAny>>, work: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce(&Control) -> idexp::Result<T> + Send,
{
    if let Some(t) = time_limit {
        if !(t.is_finite() && t > 0.0) {
            return Err(crate::err::value(format!("time_limit: expected a positive number of seconds, got {t}")));
        }
    }
    let stop = StopFlag::new();
    let rec = Arc::new(Recorder::default());
    let ctl = Control::new().with_stop(stop.clone()).with_time_limit(time_limit).with_observer(rec.clone());
    std::thread::scope(|s| {
        let h = s.spawn(|| work(&ctl));
        let mut raised: Option<PyErr> = None;
        while !h.is_finished() {
            py.detach(|| std::thread::sleep(Duration::from_millis(20)));
            if raised.is_some() {
                continue;
            }
            if let Err(e) = py.check_signals() {
                stop.request();
                raised = Some(e);
                continue;
            }
            if let Some(cb) = progress {
                let snap = {
                    let mut l = rec.0.lock().unwrap_or_else(|e| e.into_inner());
                    let c = l.changed;
                    l.changed = false;
                    c.then(|| (l.phase.clone(), l.done, l.total, l.msg.clone()))
                };
                if let Some(args) = snap {
                    if let Err(e) = cb.call1(args) {
                        stop.request();
                        raised = Some(e);
                    }
                }
            }
        }
        let out = h.join();
        if let Some(e) = raised {
            return Err(e);
        }
        match out {
            Ok(r) => r.map_err(crate::err::to_py),
            Err(_) => Err(PyRuntimeError::new_err("idexp: internal error (a panic in the library); please report it")),
        }
    })
}
