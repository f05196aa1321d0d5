//! The `gelrig` command inside the Python package: the script `gelrig` that the wheel
//! installs runs the same command as the Rust binary, in-process.

use pyo3::prelude::*;

/// Runs the command line `argv` (program name first) and returns its exit code.
#[pyfunction]
pub(crate) fn cli(py: Python<'_>, argv: Vec<String>) -> u8 {
    py.detach(|| gelrig::cli::main(argv).0)
}
