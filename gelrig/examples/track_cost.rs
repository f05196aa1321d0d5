//! The Rust side of the Python tracker's cost (python/benches/bench.py): the same 16 frames
//! of a 12.68 mm sphere pressed into the box sensor's gel, 640×480, tracked by
//! `gelrig::track::Pipeline` (centroid, no contact region) in turn, 400 calls after 50 of
//! warm-up; prints the median ms per call.
//!
//! Run: `cargo run --release -p gelrig --example track_cost`

use std::collections::BTreeMap;
use std::time::Instant;

use gelrig::{protocol, sim, track};

fn view(f: &sim::ContactFrame) -> Result<track::RgbView<'_>, String> {
    track::RgbView::new(640, 480, &f.rgb).map_err(|e| e.to_string())
}

fn main() -> Result<(), String> {
    let path = protocol::shipped::resolve("box-normal-flat".as_ref()).0;
    let set = vec!["indenter={\"shape\": \"sphere\", \"diameter\": \"12.68 mm\"}".to_string()];
    let edit = protocol::Overrides { set, name: None };
    let loaded = protocol::load_with_overrides(&path, None, &Default::default(), &edit)
        .map_err(|d| format!("{d:?}"))?;
    let spec = sim::plant_spec(&loaded.protocol, &loaded.compiled)?;
    let mut camera = sim::ContactCamera::new(&spec, 640, 480)?;
    let rest = camera.at_rest(1);
    let frames: Vec<sim::ContactFrame> = (0..16)
        .map(|k| {
            let depth_mm = 0.05 + 0.05 * k as f64;
            camera.frame(
                &sim::ContactPose {
                    depth_mm,
                    ..Default::default()
                },
                k + 2,
            )
        })
        .collect::<Result<_, _>>()?;
    let params = track::TrackParams::default();
    let mut pipeline = track::Pipeline::new(view(&rest)?, &params, track::Method::Centroid)
        .map_err(|e| e.to_string())?;
    let mut ms = Vec::new();
    for k in 0..450 {
        let f = &frames[k % frames.len()];
        let started = Instant::now();
        pipeline.track(view(f)?).map_err(|e| e.to_string())?;
        if k >= 50 {
            ms.push(started.elapsed().as_secs_f64() * 1e3);
        }
    }
    ms.sort_by(f64::total_cmp);
    let states: BTreeMap<&str, usize> =
        pipeline
            .tracker()
            .states()
            .iter()
            .fold(BTreeMap::new(), |mut m, s| {
                *m.entry(s.as_str()).or_default() += 1;
                m
            });
    println!(
        "Rust Pipeline::track, 640×480: {:.3} ms median ({states:?})",
        ms[ms.len() / 2]
    );
    Ok(())
}
