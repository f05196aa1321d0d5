//! End-to-end tests of gelrig: protocols validated, planned and dry-run on the simulated
//! bench, through the library and through the `gelrig` binary with real signals.

// Test code: panicking on a broken fixture is the point.
#![allow(clippy::unwrap_used)]

mod api;
mod bonded_punch;
mod bonded_sphere;
mod cache;
mod clocked;
mod dataset_maps;
mod dry_run;
mod export;
mod faults;
mod finite_strain;
mod force_sensing;
mod force_sensing_can;
mod force_unseen;
mod fuzz;
mod grasp;
mod guide;
mod hostile;
mod live;
mod material;
mod motion;
mod peers;
mod physics;
mod plan;
mod queue;
mod report;
mod report_cli;
mod resume;
mod settle;
mod shape;
mod signals;
mod support;
mod sweep;
mod timing;
mod track;
mod unloading;
mod validate;
mod wire;
