//! The native module of the `gelrig` Python package (`gelrig._gelrig`): thin bindings over
//! gelrig's public API (the `gelrig` crate). The Python package (`python/gelrig/`) wraps
//! these in the classes users see and turns tables into pandas DataFrames.
//!
//! Every error is a Python exception carrying the Rust message; long work (a run, tracking
//! a frame, a report) releases the GIL.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

mod cli;
mod frames;
mod protocol;
mod run;
mod runs;
mod sensor;
mod shape;
mod sim;
mod tracker;

create_exception!(
    _gelrig,
    GelrigError,
    PyException,
    "An error from gelrig, with its message (the place and the fix)."
);
create_exception!(
    _gelrig,
    ProtocolError,
    GelrigError,
    "A protocol or rig that does not check: `.diagnostics` lists every problem (file, line, column, message, fix)."
);

/// `err` as a [`GelrigError`] with its message.
pub(crate) fn gelrig_err(err: impl std::fmt::Display) -> PyErr {
    GelrigError::new_err(err.to_string())
}

/// Finds the shipped protocols in `dir` (the wheel's copy) when `$GELRIG_PROTOCOLS` is not
/// set, for this process only (a subprocess does not inherit it).
#[pyfunction]
fn use_packaged_protocols(dir: std::path::PathBuf) -> bool {
    gelrig::protocol::shipped::use_packaged(dir)
}

#[pymodule]
fn _gelrig(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("GelrigError", py.get_type::<GelrigError>())?;
    m.add("ProtocolError", py.get_type::<ProtocolError>())?;
    m.add_class::<protocol::Protocol>()?;
    m.add_class::<tracker::Tracker>()?;
    m.add_class::<tracker::TrackResult>()?;
    m.add_class::<sensor::ForceSensor>()?;
    m.add_class::<shape::Shape>()?;
    m.add_class::<sim::Bench>()?;
    m.add_function(wrap_pyfunction!(run::run, m)?)?;
    m.add_function(wrap_pyfunction!(runs::read_manifest, m)?)?;
    m.add_function(wrap_pyfunction!(runs::run_status, m)?)?;
    m.add_function(wrap_pyfunction!(runs::read_frame, m)?)?;
    m.add_function(wrap_pyfunction!(runs::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(runs::report, m)?)?;
    m.add_function(wrap_pyfunction!(runs::export, m)?)?;
    m.add_function(wrap_pyfunction!(runs::list_runs, m)?)?;
    m.add_function(wrap_pyfunction!(cli::cli, m)?)?;
    m.add_function(wrap_pyfunction!(use_packaged_protocols, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
