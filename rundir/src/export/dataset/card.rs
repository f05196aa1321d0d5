//! The dataset card (`README.md`): what the dataset is, how it was made, its columns and
//! units, and the licence of the generator's assumptions; its front matter tells
//! `datasets` where the shards are.

/// The dataset card: what, how it was made, the columns and their units, and the licence of
/// the generator's assumptions.
pub(super) fn card_text(frames: usize, runs: usize, params: &[String]) -> String {
    let params_text = if params.is_empty() {
        "none (a run or a folder of runs)".to_string()
    } else {
        params
            .iter()
            .map(|p| format!("`{p}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "---\nconfigs:\n- config_name: default\n  data_files:\n  - split: train\n    path: data/train-*.parquet\ntask_categories:\n- image-to-image\n- tabular-regression\ntags:\n- tactile\n- gelsight\n- simulation\n---\n\n\
# gelrig tactile dataset\n\n\
{frames} frames of {runs} runs written by `gelrig export --format dataset`: each row a \
GelSight frame (PNG) and what the run recorded and the simulated bench knew at that frame.\n\n\
Load it with `datasets.load_dataset(\"parquet\", data_files=\"data/*.parquet\")` or from this \
folder (`load_dataset(\"path/to/folder\")`); pandas and pyarrow read the shards too.\n\n\
## How it was made\n\n\
Dry runs of gelrig protocols on its simulated bench: a bonded viscoelastic gel layer pressed, \
sheared and twisted by a rigid indenter (the contact mechanics checked against finite \
elements: docs/benchmarks/pressing.md), its camera frames rendered with markers, shading and \
sensor noise, a Nano17-like force sensor sampled through the exposure. The gel's values of \
each protocol are assumed, not measured (the protocol file states them); the renderer is not \
a calibrated photometric model of any real sensor.\n\n\
Swept parameters (one column each; a quantity with one unit is a number column named with \
the unit): {params_text}.\n\n\
## Columns\n\n\
| column | what | unit |\n|---|---|---|\n\
| `image` | the frame (PNG; the `Image` feature) and its path in the run | — |\n\
| `run` | the run directory's name | — |\n\
| `frame`, `step`, `t_ns` | frame number, protocol step, time on the run's clock | —, —, ns |\n\
| `fx_n` … `tz_nmm` | the force sensor during the exposure (tared) | N, N·mm |\n\
| `axis`, `position`, `position_unit` | the step's axis and where it ended | the step's unit |\n\
| `sim_depth_mm` | the simulator's indentation depth at the step's end | mm |\n\
| `sim_contact_radius_mm` | the simulated contact's radius (equivalent, √(area/π)) | mm |\n\
| `sim_fz_n`, `sim_fx_n`, `sim_tz_nmm` | the simulator's equilibrium wrench at the step's end | N, N·mm |\n\
| `indenter` | the protocol's indenter, as JSON | — |\n\
| `marker_x_px`, `marker_y_px` | every marker's true centre in this frame, in id order | px |\n\
| `marker_dx_px`, `marker_dy_px` | its displacement from the run's first frame | px |\n\
| `maps_width`, `maps_height`, `maps_cell_mm` | the traction maps' size and cell side (runs recorded with `traction_maps`) | cells, mm |\n\
| `pressure_kpa` | the indenter's pressure on the gel, each cell's mean, row-major H×W, compressive positive | kPa |\n\
| `shear_x_kpa`, `shear_y_kpa` | the tangential traction on the gel along the frame's x (right) and y (down) | kPa |\n\
| `contact_mask` | the contact (an 8-bit grey image of the maps' size, 255 in contact) | — |\n\
| `sim_frame_depth_mm`, `sim_frame_shear_n`, `sim_frame_torque_nmm` | the simulator's depth and the elastic shear and twist the contact carries at this frame | mm, N, N·mm |\n\
| `sim_centre_x_mm`, `sim_centre_y_mm`, `sim_rotation_rad` | the contact's centre in the view and its turn by slipping | mm, rad |\n\
| `sim_frame_fz_n`, `sim_contact_area_mm2` | the maps' normal force and contact area | N, mm² |\n\n\
The maps carry the simulator's loads within 1 % (pressure against its normal force, shear and \
twist against what the contact carries; a line contact, a cylinder lying on the gel, within 7 %); \
the mask's area is within 7 % of the simulated contact's once its radius is 1 mm or more \
(gelrig's docs/reference/dataset.md).\n\n\
## Licence\n\n\
The frames and labels are generated; gelrig is MIT OR Apache-2.0, and so is what it \
generates. The assumptions behind them (gel values, indenters, the renderer) are the \
protocols'.\n"
    )
}
