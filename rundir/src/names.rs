//! Every file of a run directory, by name: spelled here and nowhere else, so a reader finds
//! what a run holds in one place and a rename cannot leave a reader behind.

/// The protocol as run (resolved: a fitted material's values in place).
pub const PROTOCOL: &str = "protocol.yaml";
/// The rig file the run used.
pub const RIG: &str = "rig.yaml";
/// How the run went: status, devices, tare, warnings (the manifest).
pub const MANIFEST: &str = "run.yaml";
/// Every event of the run, one JSON object a line.
pub const JOURNAL: &str = "journal.jsonl";
/// One row per step: its target, settle and quasistatic force.
pub const STEPS: &str = "steps.csv";
/// The force sensor's stream.
pub const FORCE: &str = "force.csv";
/// The stages' positions.
pub const AXES: &str = "axes.csv";
/// One row per frame: time, step, the force inside its exposure.
pub const FRAMES: &str = "frames.csv";
/// The frames' images, `frames/NNNNNN.png`.
pub const FRAMES_DIR: &str = "frames";
/// The live tactile state of every tracked frame.
pub const TACTILE: &str = "tactile.csv";
/// The simulated bench's truth per step.
pub const SIM_STEPS: &str = "sim_steps.csv";
/// The simulated camera's exact marker centres.
pub const SIM_MARKERS: &str = "sim_markers.csv";
/// The simulator's state and loads per frame, when the run recorded traction maps.
pub const SIM_FRAMES: &str = "sim_frames.csv";
/// The simulator's traction maps per frame, `sim_maps/NNNNNN.npy`.
pub const SIM_MAPS_DIR: &str = "sim_maps";
/// The tracked markers, once tracked.
pub const MARKERS: &str = "markers.csv";
/// The contact region per frame, once tracked.
pub const CONTACT: &str = "contact.csv";
/// The contact read from depth per frame (`gelrig track --shape`).
pub const DEPTH: &str = "depth.csv";
/// Height maps of each step's last frame (`gelrig track --shape` on a run).
pub const DEPTH_DIR: &str = "depth";
/// The GelSight's wrench per frame (`gelrig track --sensor`).
pub const WRENCH: &str = "wrench.csv";
/// The run as MCAP, written as it goes (`gelrig run --record mcap`).
pub const MCAP: &str = "run.mcap";
/// The copy of the sensor file the live GelSight force was read with.
pub const GELSIGHT_SENSOR: &str = "gelsight_sensor.yaml";
/// Space held back while the run writes, so a full disk ends it cleanly.
pub const RESERVE: &str = "run.reserve";
/// Held by the process that writes the run.
pub const LOCK: &str = "run.lock";
/// Where `gelrig report` writes by default.
pub const REPORT_DIR: &str = "report";

/// The image file of frame `index`, relative to the run directory.
pub fn frame_png(index: u64) -> String {
    format!("{FRAMES_DIR}/{index:06}.png")
}

/// The traction maps of frame `index`, relative to the run directory: float32, shape
/// (4, H, W): pressure, shear x, shear y (kPa), contact (0 or 1).
pub fn sim_maps_npy(index: u64) -> String {
    format!("{SIM_MAPS_DIR}/{index:06}.npy")
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_frame_is_a_six_digit_png_under_frames() {
        assert_eq!(super::frame_png(7), "frames/000007.png");
    }
}
