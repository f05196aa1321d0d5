//! Time from pixels to height map, one core (BENCHMARKS.md, "Shape from the GelSight's light"):
//! the real GelSight Mini's ball presses at 320×240, and the same frames scaled to 640×480.
//!
//! ```text
//! cargo run --release -p shape --example speed -- ../shared/data/gelsight-mini-ball
//! ```

use std::time::Instant;

use shape::ball::Circle;
use shape::{Depth, Press, Rgb, calibrate};

fn load(path: &std::path::Path, scale: u32) -> (usize, usize, Vec<u8>) {
    let img = image::open(path)
        .map(|i| i.to_rgb8())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let img = if scale > 1 {
        image::imageops::resize(
            &img,
            img.width() * scale,
            img.height() * scale,
            image::imageops::FilterType::Triangle,
        )
    } else {
        img
    };
    (img.width() as usize, img.height() as usize, img.into_raw())
}

fn main() {
    let dir = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "../shared/data/gelsight-mini-ball".into()),
    );
    let mm_per_px = 0.0634;
    for scale in [1u32, 2] {
        let bg = load(&dir.join("background.png"), scale);
        let mut rd = csv::Reader::from_path(dir.join("labels.csv")).expect("labels.csv");
        let mut frames = Vec::new();
        for r in rd.records() {
            let r = r.expect("labels.csv row");
            if &r[0] == "press_50.png" {
                continue;
            }
            let f = |i: usize| r[i].parse::<f64>().expect("number") * scale as f64;
            frames.push((
                r[0].to_string(),
                load(&dir.join(&r[0]), scale),
                Circle {
                    x_px: f(1),
                    y_px: f(2),
                    radius_px: f(3),
                },
            ));
        }
        let background = Rgb::new(bg.0, bg.1, &bg.2).expect("background");
        let presses: Vec<Press<'_>> = frames
            .iter()
            .map(|(n, (w, h, p), c)| Press {
                name: n.clone(),
                frame: Rgb::new(*w, *h, p).expect("frame"),
                circle: *c,
            })
            .collect();
        let cal = calibrate(
            background,
            &presses,
            4.735 / mm_per_px * scale as f64,
            mm_per_px / scale as f64,
        )
        .expect("calibrate");
        let model = shape::SlopeModel::LocalLinear(cal.local_linear);
        let map = model.prepare(bg.0, bg.1).expect("model");
        let mut depth = Depth::new(map, background, mm_per_px / scale as f64).expect("depth");
        let mut times = Vec::new();
        for _ in 0..5 {
            for p in &presses {
                let t = Instant::now();
                depth.height(p.frame).expect("height");
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{}×{}: {:.2} ms a frame (median of {}; fastest {:.2}, slowest {:.2})",
            bg.0,
            bg.1,
            times[times.len() / 2],
            times.len(),
            times[0],
            times[times.len() - 1]
        );
    }
}
