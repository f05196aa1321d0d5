//! The Rust side of the Python tracker's cost (python/benches/bench.py): the same 16 frames
//! of a 12.68 mm sphere pressed into the box sensor's gel, 640×480, tracked by
//! `gelrig::track::Pipeline` (centroid, no contact region) in turn, 400 calls after 50 of
//! warm-up; prints the median ms per call.
//!
//! Run with a folder of raw frames to track those instead (see [`frames`]).
//!
//! Run: `cargo run --release -p gelrig --example track_cost`

use std::collections::BTreeMap;
use std::time::Instant;

use gelrig::{protocol, sim, track};

fn view(rgb: &[u8]) -> Result<track::RgbView<'_>, String> {
    track::RgbView::new(640, 480, rgb).map_err(|e| e.to_string())
}

/// The reference and the 16 frames: drawn here, or read from `DIR` (`ref.rgb`, `00.rgb` …
/// `15.rgb`, raw 640×480 RGB) when run as `track_cost DIR` — the Python benchmark passes the
/// very frames it tracks, so both sides see the same pixels.
fn frames() -> Result<(Vec<u8>, Vec<Vec<u8>>), String> {
    if let Some(dir) = std::env::args().nth(1) {
        let read = |name: String| {
            let p = std::path::Path::new(&dir).join(&name);
            std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))
        };
        let rest = read("ref.rgb".into())?;
        let frames = (0..16)
            .map(|k| read(format!("{k:02}.rgb")))
            .collect::<Result<_, _>>()?;
        return Ok((rest, frames));
    }
    let path = protocol::shipped::resolve("box-normal-flat".as_ref()).0;
    let set = vec!["indenter={\"shape\": \"sphere\", \"diameter\": \"12.68 mm\"}".to_string()];
    let edit = protocol::Overrides {
        set,
        ..Default::default()
    };
    let loaded = protocol::load_with_overrides(&path, None, &Default::default(), &edit)
        .map_err(|d| format!("{d:?}"))?;
    let spec = sim::plant_spec(&loaded.protocol, &loaded.compiled)?;
    let mut camera = sim::ContactCamera::new(&spec, 640, 480)?;
    let rest = camera.at_rest(1).rgb;
    let frames = (0..16)
        .map(|k| {
            let depth_mm = 0.05 + 0.05 * k as f64;
            let pose = sim::ContactPose {
                depth_mm,
                ..Default::default()
            };
            camera.frame(&pose, k + 2).map(|f| f.rgb)
        })
        .collect::<Result<_, _>>()?;
    Ok((rest, frames))
}

fn main() -> Result<(), String> {
    let (rest, frames) = frames()?;
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
