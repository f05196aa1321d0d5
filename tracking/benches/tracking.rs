//! Tracking cost per frame on one core, decoding excluded (issue 4 targets:
//! ≤ 0.5 ms at 320×240 and ≤ 2 ms at 640×480 for detection + identity).
//!
//! Frames: the real GelSight Mini sequence in `../shared/data/gelsight-mini-press` (219
//! frames, 320×240) and the same frames upscaled 2× with bilinear interpolation for
//! 640×480 — the same frames `opencv_baseline.py --scale 2` reads, so the ratio is like
//! for like. Without `../shared`, a rendered sequence of the box sensor stands in (said on
//! stderr).
//!
//! Run: `cargo bench -p tracking --bench tracking`

use std::hint::black_box;
use std::path::Path;

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use simbench::{MarkerLayout, Renderer};
use tracking::field::{DenseGrid, Interpolator, MarkerField, picture};
use tracking::lk::{LkParams, LkTracker, Pyramid};
use tracking::{
    ContactFinder, ContactParams, Detector, Method, Pipeline, Reference, RgbView, TrackParams,
    Tracker,
};

/// One sequence of RGB frames; frame 0 is the reference.
struct Sequence {
    name: String,
    w: usize,
    h: usize,
    frames: Vec<Vec<u8>>,
}

fn mini(scale: u32) -> Option<Sequence> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/gelsight-mini-press");
    if !dir.is_dir() {
        return None;
    }
    let mut frames = Vec::new();
    let (mut w, mut h) = (0, 0);
    for k in 0..219 {
        let img = image::open(dir.join(format!("frame_{k:04}.png")))
            .ok()?
            .to_rgb8();
        let img = if scale == 1 {
            img
        } else {
            image::imageops::resize(
                &img,
                img.width() * scale,
                img.height() * scale,
                image::imageops::FilterType::Triangle,
            )
        };
        (w, h) = (img.width() as usize, img.height() as usize);
        frames.push(img.into_raw());
    }
    Some(Sequence {
        name: format!("mini {w}x{h}"),
        w,
        h,
        frames,
    })
}

/// A box-sensor sequence drifting by sub-pixel steps, for machines without `../shared`.
fn rendered(width: u32, height: u32) -> Sequence {
    eprintln!("../shared/data absent: benchmarking rendered frames instead of the Mini sequence");
    let layout = MarkerLayout::Grid {
        columns: 18,
        rows: 16,
        spacing_mm: 2.52,
        diameter_mm: 1.4,
    };
    let renderer = Renderer::for_view(&layout, 45.36, 40.32, width, height);
    let reference = renderer.reference_px();
    let frames = (0..60)
        .map(|k| {
            let s = 0.15 * k as f64;
            let centres: Vec<[f64; 2]> = reference
                .iter()
                .map(|p| [p[0] + s, p[1] + 0.5 * s])
                .collect();
            renderer.render_at(None, &centres, 0.0, k)
        })
        .collect();
    Sequence {
        name: format!("rendered {width}x{height}"),
        w: width as usize,
        h: height as usize,
        frames,
    }
}

fn sequences() -> Vec<Sequence> {
    match (mini(1), mini(2)) {
        (Some(a), Some(b)) => vec![a, b],
        _ => vec![rendered(320, 240), rendered(640, 480)],
    }
}

fn bench(c: &mut Criterion) {
    let params = TrackParams::default();
    for s in sequences() {
        // Sizes come from the decoder, so a view cannot fail here.
        let views: Vec<RgbView<'_>> = s
            .frames
            .iter()
            .map(|f| RgbView::new(s.w, s.h, f).expect("frame size matches"))
            .collect();
        let reference = Reference::new(views[0], &params).expect("frame 0 is untouched");
        let n = views.len() - 1;

        // Detection + identity: the default pipeline, one whole pass over the sequence per
        // iteration (identity needs the frames in order), reported per frame.
        let mut g = c.benchmark_group(format!("track {}", s.name));
        g.sample_size(20);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_function("detect+identity per sequence", |b| {
            b.iter(|| {
                let mut detector = Detector::new(s.w, s.h);
                let mut tracker = Tracker::new(&reference);
                for v in &views[1..] {
                    let blobs = detector.detect(*v, &reference).expect("same size");
                    tracker.update(blobs);
                }
                black_box(tracker.positions_px()[0])
            })
        });
        g.bench_function("detect only per sequence", |b| {
            b.iter(|| {
                let mut detector = Detector::new(s.w, s.h);
                let mut count = 0;
                for v in &views[1..] {
                    count += detector.detect(*v, &reference).expect("same size").len();
                }
                black_box(count)
            })
        });
        // The live path a runner calls per frame: pixels in; markers (detection, identity),
        // the marker field and the contact region out.
        // Set-up (reference, contact noise floor) once per run is outside the timing.
        let mut live = Pipeline::new(views[0], &params, Method::Centroid).expect("reference");
        live.enable_contact(views[0], ContactParams::default())
            .expect("reference");
        g.bench_function("live: markers + field + contact per sequence", |b| {
            b.iter_batched(
                || live.clone(),
                |mut p| {
                    let mut area = 0.0;
                    for v in &views[1..] {
                        p.track(*v).expect("same size");
                        let field = MarkerField::interior_from_tracker(p.tracker());
                        area += p.contact().map_or(0.0, |c| c.area_px2) + field.len() as f64;
                    }
                    black_box(area)
                },
                BatchSize::LargeInput,
            )
        });
        g.bench_function("contact only per sequence", |b| {
            let mut detector = Detector::new(s.w, s.h);
            let darkness: Vec<Vec<u8>> = views[1..]
                .iter()
                .map(|v| {
                    detector.detect(*v, &reference).expect("same size");
                    detector.smoothed().to_vec()
                })
                .collect();
            b.iter(|| {
                let mut finder = ContactFinder::new(views[0], &reference, ContactParams::default())
                    .expect("reference");
                let mut area = 0.0;
                for (v, d) in views[1..].iter().zip(&darkness) {
                    area += finder
                        .find(*v, &reference, d)
                        .expect("same size")
                        .map_or(0.0, |c| c.area_px2);
                }
                black_box(area)
            })
        });
        for method in [Method::CentroidLk, Method::Lk] {
            g.bench_function(format!("pipeline {method:?} per sequence"), |b| {
                b.iter(|| {
                    let mut p = Pipeline::new(views[0], &params, method).expect("reference");
                    for v in &views[1..] {
                        p.track(*v).expect("same size");
                    }
                    black_box(p.tracker().positions_px()[0])
                })
            });
        }
        g.finish();

        // Weighted LK alone on one frame (the largest deformation of the Mini sequence).
        let k = 133.min(n);
        let mut detector = Detector::new(s.w, s.h);
        detector.detect(views[k], &reference).expect("same size");
        let tracker = Tracker::new(&reference);
        let ref_pyr = Pyramid::new(s.w, s.h, reference.darkness(), 3);
        let lk = LkTracker::new(
            &ref_pyr,
            tracker.reference_px(),
            LkParams::for_radius(reference.radius_px(), 3),
        );
        let mut g = c.benchmark_group(format!("lk {}", s.name));
        g.sample_size(30);
        for levels in [1usize, 3] {
            g.bench_function(
                format!("weighted LK {levels} level(s), all markers, one frame"),
                |b| {
                    b.iter(|| {
                        let pyr = Pyramid::new(s.w, s.h, detector.smoothed(), levels);
                        let mut sum = 0.0;
                        for id in 0..tracker.len() {
                            if let Some((u, _)) = lk.track(&pyr, id, [0.0, 0.0], levels) {
                                sum += u[0];
                            }
                        }
                        black_box(sum)
                    })
                },
            );
        }
        g.finish();

        // Dense field: interpolation at every pixel and the colour-vector image.
        let mut pipeline = Pipeline::new(views[0], &params, Method::Centroid).expect("reference");
        for v in &views[1..=k] {
            pipeline.track(*v).expect("same size");
        }
        let field = MarkerField::from_tracker(pipeline.tracker());
        let grid = DenseGrid::over_frame(s.w, s.h, 1.0);
        let interp = Interpolator::new(pipeline.tracker().reference_px(), grid);
        let mut g = c.benchmark_group(format!("field {}", s.name));
        g.sample_size(30);
        g.bench_function("interpolator setup (once per run)", |b| {
            b.iter(|| black_box(Interpolator::new(pipeline.tracker().reference_px(), grid).grid()))
        });
        g.bench_function("dense field, every pixel", |b| {
            b.iter(|| black_box(interp.interpolate(&field)))
        });
        let dense = interp.interpolate(&field);
        g.bench_function("colour-vector image", |b| {
            b.iter(|| black_box(picture::colour_image(&dense, dense.max_magnitude_px())))
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
