//! `gelrig.Protocol`: a protocol file (or a shipped protocol's name) loaded with its rig,
//! checked and planned — once, as the command does.

use std::collections::BTreeMap;
use std::path::PathBuf;

use gelrig::protocol::{Diagnostic, Loaded, Overrides, shipped};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::ProtocolError;

/// A loaded protocol: valid (with its plan), or the diagnostics that say why not.
#[pyclass(module = "gelrig._gelrig", frozen)]
pub(crate) struct Protocol {
    path: PathBuf,
    pub(crate) loaded: Option<Loaded>,
    diagnostics: Vec<Diagnostic>,
}

impl Protocol {
    /// The loaded protocol, or the `ProtocolError` listing why it does not check.
    pub(crate) fn checked(&self, py: Python<'_>) -> PyResult<&Loaded> {
        match &self.loaded {
            Some(l) => Ok(l),
            None => Err(protocol_error(py, &self.diagnostics)),
        }
    }
}

/// A `ProtocolError` whose message is the command's (every diagnostic, located, with its
/// fix) and whose `.diagnostics` lists them as dicts.
fn protocol_error(py: Python<'_>, diagnostics: &[Diagnostic]) -> PyErr {
    let message = diagnostics
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("\n");
    let err = ProtocolError::new_err(message);
    let list = diagnostics_list(py, diagnostics);
    if let Ok(list) = list {
        let _ = err.value(py).setattr("diagnostics", list);
    }
    err
}

fn diagnostics_list<'py>(
    py: Python<'py>,
    diagnostics: &[Diagnostic],
) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for d in diagnostics {
        let item = PyDict::new(py);
        item.set_item("severity", if d.is_error() { "error" } else { "warning" })?;
        item.set_item("file", d.file.to_string_lossy())?;
        item.set_item("line", d.line)?;
        item.set_item("column", d.column)?;
        item.set_item("message", &d.message)?;
        item.set_item("fix", &d.fix)?;
        list.append(item)?;
    }
    Ok(list)
}

#[pymethods]
impl Protocol {
    /// Loads `path` (a file, or the name of a shipped protocol such as `box-normal-flat`)
    /// with `rig` (default: the protocol's own `rig:`) and `set` (values in place of the
    /// protocol's, as `--set KEY=VALUE`: `{"indenter.diameter": "10 mm"}`). Never raises
    /// for a protocol that does not check: `.validate()` does.
    #[staticmethod]
    #[pyo3(signature = (path, rig=None, set=None, name=None))]
    fn load(
        py: Python<'_>,
        path: PathBuf,
        rig: Option<PathBuf>,
        set: Option<BTreeMap<String, String>>,
        name: Option<String>,
    ) -> Self {
        let (path, _) = shipped::resolve(&path);
        let overrides = Overrides {
            set: set
                .unwrap_or_default()
                .into_iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect(),
            name,
            fidelity: None,
        };
        let budget = Default::default();
        let result = py.detach(|| {
            gelrig::protocol::load_with_overrides(&path, rig.as_deref(), &budget, &overrides)
        });
        match result {
            Ok(l) => Self {
                path,
                diagnostics: l.warnings.clone(),
                loaded: Some(l),
            },
            Err(d) => Self {
                path,
                loaded: None,
                diagnostics: d,
            },
        }
    }

    /// The protocol file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The protocol's name (its runs are named after it).
    #[getter]
    fn name(&self, py: Python<'_>) -> PyResult<String> {
        Ok(self.checked(py)?.protocol.name.clone())
    }

    /// The rig file it runs on.
    #[getter]
    fn rig_path(&self, py: Python<'_>) -> PyResult<PathBuf> {
        Ok(self.checked(py)?.rig_path.clone())
    }

    /// Whether it checks (no errors).
    #[getter]
    fn valid(&self) -> bool {
        self.loaded.is_some()
    }

    /// Every diagnostic (errors, or the warnings of a valid protocol), as dicts.
    #[getter]
    fn diagnostics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        diagnostics_list(py, &self.diagnostics)
    }

    /// Raises `ProtocolError` (the command's message, `.diagnostics`) unless the protocol
    /// checks; returns its warnings as text.
    fn validate(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        self.checked(py)?;
        Ok(self.diagnostics.iter().map(ToString::to_string).collect())
    }

    /// The plan as JSON (`gelrig plan --json`): steps with their end times, the run's
    /// duration, frames, rows and bytes, each a (min, max) range.
    fn plan_json(&self, py: Python<'_>) -> PyResult<String> {
        let loaded = self.checked(py)?;
        serde_json::to_string(&loaded.plan).map_err(crate::gelrig_err)
    }

    fn __repr__(&self) -> String {
        let state = if self.loaded.is_some() {
            "valid".to_string()
        } else {
            format!("{} problems", self.diagnostics.len())
        };
        format!("Protocol({:?}, {state})", self.path)
    }
}
