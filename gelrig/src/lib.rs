//! gelrig's public API: what the `gelrig` command, the Python package and any other program
//! use to load and plan a protocol, run it and receive its events, read a run directory's
//! tables, track frames from pixels in memory, read a calibrated GelSight force sensor from a
//! frame, and render a frame of the simulated bench.

pub mod view;

pub use experiments;
pub use report;
pub use runner;
pub use sensing;
