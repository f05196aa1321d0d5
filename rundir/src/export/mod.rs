//! `gelrig export RUN_DIR --format mcap`: a run in the formats the field already uses.
//!
//! MCAP with ROS 2 message types, CDR-encoded, so a run plays with `ros2 bag play` and opens
//! in Foxglove and Rerun:
//!
//! | topic | type | from |
//! |---|---|---|
//! | `/force` | `geometry_msgs/msg/WrenchStamped` (N and N·m, SI) | `force.csv` |
//! | `/camera/image/compressed` | `sensor_msgs/msg/CompressedImage` (the recorded PNGs) | `frames.csv`, `frames/` |
//! | `/camera/markers` | `visualization_msgs/msg/ImageMarker` (LINE_LIST: each marker from its reference to where it is, px) | `markers.csv` (a tracked run) |
//! | `/stages` | `sensor_msgs/msg/JointState` (m and rad, SI) | `axes.csv` |
//! | `/steps` | `std_msgs/msg/String` (each step's row as JSON, at its end) | `steps.csv` |
//! | `/tactile` | `std_msgs/msg/String` (each frame's tactile state as JSON) | `tactile.csv` |
//!
//! Timestamps are the run's timebase (virtual time from 0 on a dry run, CLOCK_MONOTONIC on a
//! bench). `protocol.yaml`, `rig.yaml` and `run.yaml` travel as attachments, the manifest's
//! protocol, status and seed as metadata.

//!
//! Parquet: every table of the run (force, axes, steps, frames, markers, contact, tactile,
//! wrench, sim_steps) as a typed file with units in the field metadata; a folder of runs
//! becomes one file per table with a `run` column ([`parquet_tables`]).

pub mod dataset;
mod mcap_file;
pub mod parquet_tables;

pub use dataset::{DatasetExport, export_dataset};
pub use mcap_file::{ExportError, Exported, export_mcap};
pub(crate) use mcap_file::{RecordsError, write_records};
pub use parquet_tables::{ParquetExport, export_parquet};
