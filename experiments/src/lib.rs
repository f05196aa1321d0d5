//! Experiments on a GelSight bench: protocols in, run directories out.
//!
//! This crate turns a YAML protocol into a run. It parses and checks the protocol against
//! a rig file ([`protocol`]), expands it into steps with durations and data volumes
//! ([`plan`]), executes it on the devices the rig crate opens — real or simulated — with
//! settling, capture, a safety watchdog and a safe stop ([`runner`]), and records everything
//! into a crash-safe run directory (the `rundir` crate; listed by [`runs`]). [`track`] runs the
//! marker tracker over image files or a run's frames.
//!
//! The `gelrig` binary is a thin CLI over these modules.

mod artifact;
pub mod bench;
pub mod diag;
pub mod material;
pub mod plan;
pub mod progress;
pub mod protocol;
pub mod report;
pub(crate) mod run_data;
pub mod runner;
pub mod runs;
pub mod sensor;
pub mod track;
pub mod view;

pub use diag::{Diagnostic, Severity};
