//! Tracking error against run time on synthetic GelSight frames with known marker centres.
//!
//! Frames come from the simulator's renderer (`simbench::Renderer`): markers drawn with
//! blurred edges at exact positions, coloured contact shading from a surface bump, and
//! optionally sensor noise. The markers follow a smooth deformation (a pressing bump plus a
//! shear and a twist that grow over the sequence). For each method the error of every
//! measured interior marker is collected over all frames:
//!
//! - `centroid`: detection + identity (the default pipeline);
//! - `lk`: weighted Lucas–Kanade alone, 3 pyramid levels, started from the previous frame;
//! - `centroid+lk`: the centroid refined by one level of weighted LK.
//!
//! Run: `cargo run --release -p tracking --example tracking_accuracy`

use std::time::Instant;

use mechanics::operator::Grid;
use mechanics::response::Field;
use simbench::{MarkerLayout, Renderer, SurfaceView};
use tracking::lk::{LkParams, LkTracker, Pyramid};
use tracking::{Detector, MarkerState, Reference, RgbView, TrackParams, Tracker};

struct Case {
    name: &'static str,
    layout: MarkerLayout,
    view_mm: (f64, f64),
    size: (u32, u32),
}

#[derive(Default)]
struct Stats {
    errors: Vec<f64>,
    bias: [f64; 2],
    seconds: f64,
    frames: usize,
}

impl Stats {
    fn push(&mut self, e: [f64; 2]) {
        self.bias[0] += e[0];
        self.bias[1] += e[1];
        self.errors.push(e[0].hypot(e[1]));
    }

    fn row(&mut self, case: &str, noise: &str, method: &str) -> String {
        let n = self.errors.len().max(1) as f64;
        self.errors.sort_by(f64::total_cmp);
        let rms = (self.errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        let p99 = self
            .errors
            .get(
                ((self.errors.len() as f64 * 0.99) as usize)
                    .min(self.errors.len().saturating_sub(1)),
            )
            .copied()
            .unwrap_or(f64::NAN);
        format!(
            "| {case} | {noise} | {method} | {:+.4}, {:+.4} | {rms:.4} | {p99:.3} | {} | {:.3} |",
            self.bias[0] / n,
            self.bias[1] / n,
            self.errors.len(),
            1e3 * self.seconds / self.frames.max(1) as f64
        )
    }
}

/// A pressing bump with growing shear and twist, in mm, at view point (x, y) mm.
fn deformation(x: f64, y: f64, t: f64, radius_mm: f64) -> (f64, f64, f64) {
    let r2 = (x * x + y * y) / (radius_mm * radius_mm);
    let g = (-r2).exp();
    let radial = 0.25 * t * g;
    let (sx, sy) = (1.2 * t * g, 0.4 * t * g);
    let twist = 0.1 * t * g;
    (
        radial * x / radius_mm + sx - twist * y,
        radial * y / radius_mm + sy + twist * x,
        1.0 * t * g,
    )
}

fn surface(t: f64, radius_mm: f64) -> SurfaceView {
    let grid = Grid {
        n: 128,
        dx: 4.0 * radius_mm / 128.0,
    };
    let mut uz = vec![0.0; grid.n * grid.n];
    for j in 0..grid.n {
        for i in 0..grid.n {
            uz[j * grid.n + i] = deformation(grid.coord(i), grid.coord(j), t, radius_mm).2;
        }
    }
    let zeros = vec![0.0; grid.n * grid.n];
    SurfaceView {
        field: Field {
            grid,
            ux: zeros.clone(),
            uy: zeros,
            uz,
        },
        centre_mm: (0.0, 0.0),
        rotation_rad: 0.0,
    }
}

/// The benches studied: the box sensor's grid at two sizes and the portable's random dots.
fn cases() -> [Case; 3] {
    [
        Case {
            name: "box 640×480",
            layout: MarkerLayout::Grid {
                columns: 18,
                rows: 16,
                spacing_mm: 2.52,
                diameter_mm: 1.4,
            },
            view_mm: (45.36, 40.32),
            size: (640, 480),
        },
        Case {
            name: "box 320×240",
            layout: MarkerLayout::Grid {
                columns: 18,
                rows: 16,
                spacing_mm: 2.52,
                diameter_mm: 1.4,
            },
            view_mm: (45.36, 40.32),
            size: (320, 240),
        },
        Case {
            name: "portable 640×480",
            layout: MarkerLayout::Random {
                spacing_mm: 2.0,
                size_mm: 0.7,
            },
            view_mm: (20.0, 15.0),
            size: (640, 480),
        },
    ]
}

/// Tracks one case's 24 frames of a growing contact, `noisy` or clean, and prints a row per
/// method.
fn study(case: &Case, noisy: bool) {
    let (w, h) = (case.size.0 as usize, case.size.1 as usize);
    let mut renderer = Renderer::for_view(
        &case.layout,
        case.view_mm.0,
        case.view_mm.1,
        case.size.0,
        case.size.1,
    );
    if !noisy {
        renderer = renderer.without_noise();
    }
    let truth_ref = renderer.reference_px();
    let mm_per_px = renderer.mm_per_px();
    let rgb = renderer.render_at(None, &truth_ref, 0.0, 0);
    let reference = Reference::new(
        RgbView::new(w, h, &rgb).expect("frame size"),
        &TrackParams::default(),
    )
    .expect("reference");
    let mut tracker = Tracker::new(&reference);
    let mut detector = Detector::new(w, h);
    // Identity of tracker marker k = nearest truth marker in the reference.
    let ids: Vec<usize> = tracker
        .reference_px()
        .iter()
        .map(|p| {
            (0..truth_ref.len())
                .min_by(|&a, &b| {
                    let da = (truth_ref[a][0] - p[0]).hypot(truth_ref[a][1] - p[1]);
                    let db = (truth_ref[b][0] - p[0]).hypot(truth_ref[b][1] - p[1]);
                    da.total_cmp(&db)
                })
                .unwrap_or(0)
        })
        .collect();
    let radius = reference.radius_px();
    let ref_pyr = Pyramid::new(w, h, reference.darkness(), 3);
    let lk = LkTracker::new(
        &ref_pyr,
        tracker.reference_px(),
        LkParams::for_radius(radius, 3),
    );
    let mut lk_disp = vec![[0.0; 2]; tracker.len()];
    let (mut centroid, mut lk_only, mut combined) =
        (Stats::default(), Stats::default(), Stats::default());
    let frames = 24;
    let contact_mm = 0.22 * case.view_mm.0.min(case.view_mm.1);
    let interior = |p: [f64; 2]| {
        let m = 2.0 * radius;
        p[0] > m && p[1] > m && p[0] < w as f64 - 1.0 - m && p[1] < h as f64 - 1.0 - m
    };
    for f in 1..=frames {
        let t = f as f64 / frames as f64;
        let truth: Vec<[f64; 2]> = truth_ref
            .iter()
            .map(|p| {
                let (x, y) = (
                    (p[0] + 0.5 - w as f64 / 2.0) * mm_per_px,
                    (p[1] + 0.5 - h as f64 / 2.0) * mm_per_px,
                );
                let (ux, uy, _) = deformation(x, y, t, contact_mm);
                [p[0] + ux / mm_per_px, p[1] + uy / mm_per_px]
            })
            .collect();
        let view = surface(t, contact_mm);
        let rgb = renderer.render_at(Some(&view), &truth, 0.0, f as u64);
        let frame = RgbView::new(w, h, &rgb).expect("frame size");

        let t0 = Instant::now();
        let blobs = detector.detect(frame, &reference).expect("same size");
        tracker.update(blobs);
        centroid.seconds += t0.elapsed().as_secs_f64();
        centroid.frames += 1;

        let t1 = Instant::now();
        let pyr = Pyramid::new(w, h, detector.smoothed(), 3);
        let lk_result: Vec<Option<[f64; 2]>> = (0..tracker.len())
            .map(|k| lk.track(&pyr, k, lk_disp[k], 3).map(|(u, _)| u))
            .collect();
        lk_only.seconds += t1.elapsed().as_secs_f64();
        lk_only.frames += 1;

        let t2 = Instant::now();
        let pyr1 = Pyramid::new(w, h, detector.smoothed(), 1);
        let refined: Vec<Option<[f64; 2]>> = (0..tracker.len())
            .map(|k| {
                if !tracker.states()[k].is_measured() {
                    return None;
                }
                lk.track(&pyr1, k, tracker.displacement_px(k), 1)
                    .map(|(u, _)| u)
            })
            .collect();
        combined.seconds += centroid.seconds / centroid.frames as f64 + t2.elapsed().as_secs_f64();
        combined.frames += 1;

        for k in 0..tracker.len() {
            let truth_p = truth[ids[k]];
            if !interior(truth_p) {
                continue;
            }
            let r = tracker.reference_px()[k];
            if tracker.states()[k] == MarkerState::Tracked {
                let p = tracker.positions_px()[k];
                centroid.push([p[0] - truth_p[0], p[1] - truth_p[1]]);
                if let Some(u) = refined[k] {
                    combined.push([r[0] + u[0] - truth_p[0], r[1] + u[1] - truth_p[1]]);
                }
            }
            if let Some(u) = lk_result[k] {
                lk_disp[k] = u;
                lk_only.push([r[0] + u[0] - truth_p[0], r[1] + u[1] - truth_p[1]]);
            }
        }
    }
    let noise = if noisy { "σ 1.5 levels" } else { "clean" };
    println!("{}", centroid.row(case.name, noise, "centroid"));
    println!("{}", lk_only.row(case.name, noise, "weighted LK, 3 levels"));
    println!(
        "{}",
        combined.row(case.name, noise, "centroid + LK refinement")
    );
}

fn main() {
    println!(
        "| frames | noise | method | bias x, y (px) | rms (px) | p99 (px) | markers | ms/frame |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for case in &cases() {
        for noisy in [false, true] {
            study(case, noisy);
        }
    }
}
