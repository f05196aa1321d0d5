//! The run directory, in one place (ARCHITECTURE.md): what every file holds, how a run writes
//! it without losing data ([`write`]; `run.yaml` in [`manifest`]), how everything else reads
//! it back ([`read`]), and the formats it leaves in ([`export`]: MCAP with ROS 2 message
//! types, Parquet). A new column is added to the writer's row; readers that want it add it to
//! their view of the row, and a test holds every view to the columns the writer writes.
//!
//! Layout: `protocol.yaml` (resolved, as run), `rig.yaml`, `run.yaml`, `journal.jsonl`,
//! `steps.csv`, and — only for streams the protocol records — `force.csv`, `axes.csv`,
//! `frames.csv` with `frames/*.png`, `tactile.csv`, `sim_steps.csv` (simulated benches);
//! `markers.csv` and `contact.csv` once tracked; `run.reserve` while running.

pub mod campaign_dir;
pub mod export;
pub mod listing;
pub mod manifest;
pub mod names;
pub mod npy;
pub mod read;
pub mod resumed;
mod ros2;
pub mod write;
