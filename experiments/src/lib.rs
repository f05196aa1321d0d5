//! The protocol language of gelrig experiments: a YAML protocol read and checked against a
//! rig file, every problem located at its file, line and column with a fix ([`protocol`],
//! [`diag`]), and expanded into the steps it will take with their durations and data volumes
//! ([`plan`]). [`load`] does all of it once for a protocol file and carries the plan with the
//! loaded protocol. The runner (`runner`)
//! executes what this crate loads; nothing here moves a device.

pub mod artifact;
pub mod diag;
pub mod load;
pub mod plan;
pub mod protocol;
pub mod sim_models;

pub use diag::{Diagnostic, Severity};
