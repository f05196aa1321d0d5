//! Writes the frames of identity-table conditions as PNG files with their exact marker
//! centres, so other pipelines (`benches/opencv_precision.py`) and `gelrig track` can be
//! scored on the very same frames.
//!
//! Run: `cargo run --release -p tracking --example tracking_frames -- "noise σ 30" /tmp/noise30`
//! (the first argument picks conditions by name, as in `tracking_identity`). Writes
//! `frame_NNNN.png` (frame 0 is the reference) and `truth.csv` (`frame,marker,x_px,y_px`),
//! and prints the spacing and marker radius in pixels.

#[path = "../tests/common/identity.rs"]
mod identity;

use std::io::Write;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(filter), Some(out)) = (args.get(1), args.get(2)) else {
        return Err("usage: tracking_frames CONDITION_FILTER OUT_DIR".into());
    };
    let Some(c) = identity::conditions()
        .into_iter()
        .find(|c| c.name.contains(filter.as_str()))
    else {
        return Err(format!("no condition named like {filter:?}").into());
    };
    std::fs::create_dir_all(out)?;
    let (w, h) = c.scene.size();
    let mut truth = std::fs::File::create(format!("{out}/truth.csv"))?;
    writeln!(truth, "frame,marker,x_px,y_px")?;
    for k in 0..c.motion.frames() {
        let look = if k == 0 { &c.reference_look } else { &c.look };
        let (rgb, centres) = c.scene.frame(&c.motion, k, look);
        image::save_buffer(
            format!("{out}/frame_{k:04}.png"),
            &rgb,
            w,
            h,
            image::ColorType::Rgb8,
        )?;
        for (m, p) in centres.iter().enumerate() {
            writeln!(truth, "{k},{m},{:.5},{:.5}", p[0], p[1])?;
        }
    }
    println!(
        "{}: {} frames, spacing {:.2} px, marker radius {:.2} px",
        c.name,
        c.motion.frames(),
        c.spacing(),
        c.scene.radius_px()
    );
    Ok(())
}
