//! `gelrig.run`: a protocol run as the command runs it — the same run directory, seed for
//! seed — with its events handed to a Python callable as they happen. The GIL is released
//! while the run goes; Ctrl-C (or an exception in the callable) stops it cleanly: the stages
//! retract and the run ends `aborted`, as after Ctrl-C in the command.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};

use gelrig::run::{Cancel, ClockMode, Event, Launch};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::protocol::Protocol;

/// Runs `protocol` into a new directory under `out` and returns `(run directory, status,
/// message)`. `time_scale`: `None` for virtual time on a simulated rig (real time on any
/// real device), or a speed-up over the wall clock. `on_event` receives each event as JSON
/// text (the Python package parses it).
#[pyfunction]
#[pyo3(signature = (protocol, out, seed=0, time_scale=None, on_event=None))]
pub(crate) fn run(
    py: Python<'_>,
    protocol: &Protocol,
    out: PathBuf,
    seed: u64,
    time_scale: Option<f64>,
    on_event: Option<Py<PyAny>>,
) -> PyResult<(PathBuf, String, Option<String>)> {
    let loaded = protocol.checked(py)?.clone();
    let requested = match time_scale {
        None => None,
        Some(s) if s.is_finite() && (0.01..=1e5).contains(&s) => {
            Some(ClockMode::Scaled { scale: s })
        }
        Some(s) => {
            return Err(PyValueError::new_err(format!(
                "time_scale={s}: give None (virtual time) or a speed-up between 0.01 and 100000"
            )));
        }
    };
    let clock = gelrig::run::clock_for(&loaded, requested).map_err(crate::gelrig_err)?;
    let cancel = Cancel::new();
    // The first Python error seen while the run goes (KeyboardInterrupt, or one raised by
    // `on_event`): the run is stopped, then it is raised.
    let raised: Arc<Mutex<Option<PyErr>>> = Arc::default();
    let observer = {
        let (cancel, raised) = (cancel.clone(), raised.clone());
        Arc::new(move |event: &Event| {
            Python::attach(|py| {
                let mut first = raised.lock().unwrap_or_else(PoisonError::into_inner);
                if first.is_some() {
                    return;
                }
                let outcome = py.check_signals().and_then(|()| match &on_event {
                    Some(f) => {
                        let json = serde_json::to_string(event).unwrap_or_default();
                        f.call1(py, (json,)).map(drop)
                    }
                    None => Ok(()),
                });
                if let Err(e) = outcome {
                    *first = Some(e);
                    cancel.interrupt();
                }
            });
        })
    };
    let outcome = py
        .detach(|| {
            Launch::new(&loaded)
                .out(&out)
                .seed(seed)
                .clock(clock)
                .on_event(observer)
                .run_blocking(cancel)
        })
        .map_err(crate::gelrig_err)?;
    if let Some(e) = raised.lock().unwrap_or_else(PoisonError::into_inner).take() {
        return Err(e);
    }
    Ok((
        outcome.dir,
        outcome.status.name().to_string(),
        outcome.message,
    ))
}
