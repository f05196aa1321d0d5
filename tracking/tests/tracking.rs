//! Tracking on synthetic GelSight frames with exact marker centres (the simulator's
//! renderer), and on the real GelSight Mini frames in `../shared/data` (skipped, with a
//! message, when that folder is absent).

use mechanics::operator::Grid;
use mechanics::response::Field;
use simbench::{MarkerLayout, Renderer, SurfaceView};
use tracking::{Detector, MarkerState, Reference, RgbView, TrackError, TrackParams, Tracker};

fn box_grid() -> MarkerLayout {
    MarkerLayout::Grid {
        columns: 18,
        rows: 16,
        spacing_mm: 2.52,
        diameter_mm: 1.4,
    }
}

fn triangles() -> MarkerLayout {
    MarkerLayout::Random {
        spacing_mm: 2.0,
        size_mm: 0.7,
    }
}

/// A renderer, its reference frame, and the tracker's identities mapped to the truth.
struct Scene {
    renderer: Renderer,
    truth_ref: Vec<[f64; 2]>,
    w: usize,
    h: usize,
    reference: Reference,
    tracker: Tracker,
    detector: Detector,
    /// Tracker id → renderer marker index.
    ids: Vec<usize>,
}

impl Scene {
    /// The tracker id of a marker within 0.8 spacing of the frame centre (640×480).
    fn central_marker(&self) -> usize {
        let sp = self.spacing();
        self.ids
            .iter()
            .position(|&t| dist(self.truth_ref[t], [320.0, 240.0]) < 0.8 * sp)
            .expect("a central marker")
    }

    fn new(layout: MarkerLayout, view_mm: (f64, f64), size: (u32, u32), noisy: bool) -> Self {
        let mut renderer = Renderer::for_view(&layout, view_mm.0, view_mm.1, size.0, size.1);
        if !noisy {
            renderer = renderer.without_noise();
        }
        let truth_ref = renderer.reference_px();
        let (w, h) = (size.0 as usize, size.1 as usize);
        let rgb = renderer.render_at(None, &truth_ref, 0.0, 0);
        let reference = Reference::new(
            RgbView::new(w, h, &rgb).expect("size"),
            &TrackParams::default(),
        )
        .expect("a clean reference");
        let tracker = Tracker::new(&reference);
        let ids = tracker
            .reference_px()
            .iter()
            .map(|p| {
                (0..truth_ref.len())
                    .min_by(|&a, &b| dist(truth_ref[a], *p).total_cmp(&dist(truth_ref[b], *p)))
                    .expect("markers")
            })
            .collect();
        Self {
            renderer,
            truth_ref,
            w,
            h,
            detector: Detector::new(w, h),
            reference,
            tracker,
            ids,
        }
    }

    fn spacing(&self) -> f64 {
        self.reference.spacing_px()
    }

    /// Renders the markers at `truth` and tracks the frame.
    fn step(&mut self, truth: &[[f64; 2]], seq: u64) {
        let rgb = self.renderer.render_at(None, truth, 0.0, seq);
        self.step_rgb(&rgb);
    }

    fn step_rgb(&mut self, rgb: &[u8]) {
        let blobs = self
            .detector
            .detect(
                RgbView::new(self.w, self.h, rgb).expect("size"),
                &self.reference,
            )
            .expect("same size");
        self.tracker.update(blobs);
    }

    /// Whether a truth position is far enough inside the view that its marker is whole.
    fn whole(&self, p: [f64; 2]) -> bool {
        let m = self.reference.radius_px() + 2.0;
        p[0] > m && p[1] > m && p[0] < self.w as f64 - 1.0 - m && p[1] < self.h as f64 - 1.0 - m
    }

    /// (tracker id, state, error vector) for every marker.
    fn errors<'a>(
        &'a self,
        truth: &'a [[f64; 2]],
    ) -> impl Iterator<Item = (usize, MarkerState, [f64; 2])> + 'a {
        (0..self.tracker.len()).map(move |k| {
            let t = truth[self.ids[k]];
            let p = self.tracker.positions_px()[k];
            (k, self.tracker.states()[k], [p[0] - t[0], p[1] - t[1]])
        })
    }

    /// Asserts that every measured marker is where the truth says (never a swap), and that
    /// every whole marker is measured when `all_whole_measured`.
    fn check(&self, truth: &[[f64; 2]], tolerance_px: f64, all_whole_measured: bool, what: &str) {
        for (k, state, e) in self.errors(truth) {
            let t = truth[self.ids[k]];
            if state.is_measured() {
                let tol = if state == MarkerState::Tracked {
                    tolerance_px
                } else {
                    0.35 * self.spacing()
                };
                assert!(
                    e[0].hypot(e[1]) < tol,
                    "{what}: marker {k} ({state:?}) is {:.2} px from the truth",
                    e[0].hypot(e[1])
                );
            } else if all_whole_measured && self.whole(t) {
                panic!("{what}: whole marker {k} at {t:?} is {state:?}");
            }
        }
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn moved(base: &[[f64; 2]], f: impl Fn([f64; 2]) -> [f64; 2]) -> Vec<[f64; 2]> {
    base.iter()
        .map(|&p| {
            let u = f(p);
            [p[0] + u[0], p[1] + u[1]]
        })
        .collect()
}

#[test]
fn centroids_are_unbiased_to_a_twentieth_of_a_pixel() {
    for (layout, view, size) in [
        (box_grid(), (45.36, 40.32), (640, 480)),
        (box_grid(), (45.36, 40.32), (320, 240)),
        (triangles(), (20.0, 15.0), (640, 480)),
    ] {
        for noisy in [false, true] {
            let mut s = Scene::new(layout.clone(), view, size, noisy);
            let base = s.truth_ref.clone();
            let (cx, cy) = (s.w as f64 / 2.0, s.h as f64 / 2.0);
            let (mut sum, mut sq, mut n) = ([0.0; 2], 0.0, 0.0);
            for f in 1..=12u64 {
                // A smooth field with a sub-pixel phase that changes every frame.
                let a = 0.37 * f as f64;
                let truth = moved(&base, |p| {
                    let g = (-((p[0] - cx).powi(2) + (p[1] - cy).powi(2))
                        / (2.0 * 90.0f64.powi(2)))
                    .exp();
                    [a.sin() * 0.9 + 2.0 * g * a.cos(), a.cos() * 0.7 + 1.5 * g]
                });
                s.step(&truth, f);
                s.check(&truth, 0.2, true, "smooth field");
                for (k, state, e) in s.errors(&truth) {
                    if state == MarkerState::Tracked && s.whole(truth[s.ids[k]]) {
                        sum[0] += e[0];
                        sum[1] += e[1];
                        sq += e[0] * e[0] + e[1] * e[1];
                        n += 1.0;
                    }
                }
            }
            let bias = [sum[0] / n, sum[1] / n];
            let rms = (sq / n).sqrt();
            assert!(n > 500.0, "{n} samples");
            assert!(
                bias[0].abs() <= 0.05 && bias[1].abs() <= 0.05,
                "bias {bias:?}"
            );
            assert!(rms <= 0.05, "{size:?} noisy {noisy}: rms {rms:.4} px");
        }
    }
}

#[test]
fn large_smooth_shear_and_torsion_keep_every_identity() {
    let mut s = Scene::new(box_grid(), (45.36, 40.32), (640, 480), true);
    let sp = s.spacing();
    let base = s.truth_ref.clone();
    let (cx, cy) = (s.w as f64 / 2.0 + 7.0, s.h as f64 / 2.0 - 5.0);
    let sigma = 3.0 * sp;
    let bump =
        |p: [f64; 2]| (-((p[0] - cx).powi(2) + (p[1] - cy).powi(2)) / (2.0 * sigma * sigma)).exp();
    // Peak shear 0 → 0.6 → 1.2 → 1.5 spacings and back: steps of 0.6 spacing per frame.
    let amplitudes = [0.6, 1.2, 1.5, 0.9, 0.3, 0.0];
    for (f, a) in amplitudes.iter().enumerate() {
        let dir = 25f64.to_radians();
        let truth = moved(&base, |p| {
            let m = a * sp * bump(p);
            [m * dir.cos(), m * dir.sin()]
        });
        s.step(&truth, f as u64 + 1);
        s.check(&truth, 0.2, true, &format!("shear {a} spacings"));
    }
    // Torsion: the contact turns by up to 1.5 spacings at its rim, 0.5 per frame.
    for (f, a) in [0.5, 1.0, 1.5, 1.0, 0.5, 0.0].iter().enumerate() {
        let truth = moved(&base, |p| {
            let (dx, dy) = (p[0] - cx, p[1] - cy);
            let r = dx.hypot(dy).max(1e-9);
            let theta = a * sp / (1.5 * sigma) * bump(p);
            let _ = r;
            [
                dx * theta.cos() - dy * theta.sin() - dx,
                dx * theta.sin() + dy * theta.cos() - dy,
            ]
        });
        s.step(&truth, 20 + f as u64);
        s.check(&truth, 0.2, true, &format!("torsion {a}"));
    }
}

#[test]
fn translation_through_the_border_keeps_identities() {
    for (layout, view, size) in [
        (box_grid(), (45.36, 40.32), (640, 480)),
        (triangles(), (20.0, 15.0), (640, 480)),
    ] {
        let mut s = Scene::new(layout, view, size, true);
        let sp = s.spacing();
        let base = s.truth_ref.clone();
        // Out by 0.3 spacing per frame to 2.4 spacings (markers leave the view), and back.
        let steps: Vec<f64> = (1..=8)
            .chain((0..8).rev())
            .map(|k| 0.3 * k as f64)
            .collect();
        let mut out_of_view = 0;
        for (f, d) in steps.iter().enumerate() {
            let truth = moved(&base, |_| [d * sp, 0.4 * d * sp]);
            s.step(&truth, f as u64 + 1);
            s.check(&truth, 0.2, false, &format!("translation {d}"));
            out_of_view += s
                .tracker
                .states()
                .iter()
                .filter(|st| **st == MarkerState::OutOfView)
                .count();
        }
        assert!(out_of_view > 0, "markers left the view");
        // Back at rest, every whole marker is tracked again under its own identity.
        s.check(&base, 0.2, true, "back at rest");
    }
}

#[test]
fn a_sudden_jump_of_a_periodic_grid_is_tracked_or_lost_never_swapped() {
    // The whole grid in view: the grid's edges tell the jump from its one-spacing alias.
    let mut s = Scene::new(box_grid(), (45.36, 40.32), (640, 480), true);
    let sp = s.spacing();
    let base = s.truth_ref.clone();
    let truth = moved(&base, |_| [0.6 * sp, 0.0]);
    s.step(&truth, 1);
    s.check(&truth, 0.2, true, "jump of 0.6 spacing, grid in view");
    s.step(&base, 2);
    s.check(&base, 0.2, true, "back at rest");

    // The grid runs beyond the view on every side: a jump of half a spacing along a row
    // looks exactly like one of half a spacing back. Nothing may be guessed: each marker is
    // right or not measured. (A jump of 0.6 spacing is the same image as one of 0.4 back,
    // and is taken for it: no tracker can tell them apart.)
    let mut s = Scene::new(box_grid(), (30.0, 22.5), (640, 480), true);
    let sp = s.spacing();
    let base = s.truth_ref.clone();
    let truth = moved(&base, |_| [0.5 * sp, 0.0]);
    s.step(&truth, 1);
    s.check(
        &truth,
        0.2,
        false,
        "jump of 0.5 spacing, grid beyond the view",
    );
    let measured = s
        .tracker
        .states()
        .iter()
        .filter(|st| st.is_measured())
        .count();
    eprintln!(
        "grid beyond the view: {measured} of {} measured after the jump",
        s.tracker.len()
    );
    // Back at rest the frame is the reference's image, and so is the frame one spacing
    // away: after a frame no evidence could resolve, nothing in this view tells the two
    // apart, so the identities stay withheld (never guessed) until something does.
    s.step(&base, 2);
    s.step(&base, 3);
    s.check(&base, 0.2, false, "back at rest");
    assert!(
        s.tracker.states().iter().all(|st| !st.is_measured()),
        "back at rest after an unresolved half-spacing jump, nothing may be claimed"
    );
    assert!(!s.tracker.aliases_px().is_empty());
}

#[test]
fn a_jump_beyond_the_gate_is_reported_lost_not_swapped() {
    let mut s = Scene::new(box_grid(), (45.36, 40.32), (640, 480), true);
    let sp = s.spacing();
    let base = s.truth_ref.clone();
    // An interior marker jumps half a spacing diagonally; its neighbours stay.
    let victim = s.central_marker();
    let mut truth = base.clone();
    let t = s.ids[victim];
    truth[t] = [base[t][0] + 0.35 * sp, base[t][1] + 0.35 * sp];
    s.step(&truth, 1);
    assert_eq!(s.tracker.states()[victim], MarkerState::Lost);
    s.check(&truth, 0.2, false, "one marker jumped");
    let measured = s
        .tracker
        .states()
        .iter()
        .filter(|st| st.is_measured())
        .count();
    assert_eq!(
        measured,
        s.tracker.len() - 1,
        "only the jumping marker is not measured"
    );
    // When it comes back, it is found again under its own identity.
    s.step(&base, 2);
    assert_eq!(s.tracker.states()[victim], MarkerState::Tracked);
    s.check(&base, 0.2, true, "back");
}

#[test]
fn merged_markers_are_split_and_flagged() {
    let mut s = Scene::new(box_grid(), (45.36, 40.32), (640, 480), true);
    let sp = s.spacing();
    let base = s.truth_ref.clone();
    let a = s.central_marker();
    let b = (0..s.tracker.len())
        .find(|&k| {
            let (pa, pb) = (base[s.ids[a]], base[s.ids[k]]);
            (pb[0] - pa[0] - sp).abs() < 1.0 && (pb[1] - pa[1]).abs() < 1.0
        })
        .expect("right neighbour");
    // The two are pushed together until their rims overlap (as at a contact edge).
    let mut truth = base.clone();
    for (f, push) in [0.12, 0.24].iter().enumerate() {
        truth[s.ids[a]] = [base[s.ids[a]][0] + push * sp, base[s.ids[a]][1]];
        truth[s.ids[b]] = [base[s.ids[b]][0] - push * sp, base[s.ids[b]][1]];
        s.step(&truth, f as u64 + 1);
    }
    assert!(
        dist(truth[s.ids[a]], truth[s.ids[b]]) < 2.0 * s.reference.radius_px(),
        "the markers overlap"
    );
    for k in [a, b] {
        assert_eq!(s.tracker.states()[k], MarkerState::Merged, "marker {k}");
        let e = dist(s.tracker.positions_px()[k], truth[s.ids[k]]);
        assert!(e < 1.0, "split marker {k} off by {e:.2} px");
    }
    s.check(&truth, 0.2, true, "merged pair");
}

#[test]
fn blank_saturated_and_markerless_frames_are_survived() {
    let mut s = Scene::new(box_grid(), (45.36, 40.32), (640, 480), true);
    let base = s.truth_ref.clone();
    let shifted = moved(&base, |_| [3.0, -2.0]);
    s.step(&shifted, 1);
    let n = s.w * s.h * 3;
    let markerless = s.renderer.render_at(None, &[], 0.0, 5);
    for (what, rgb) in [
        ("blank", vec![128u8; n]),
        ("black", vec![0u8; n]),
        ("saturated", vec![255u8; n]),
        ("no markers", markerless),
    ] {
        s.step_rgb(&rgb);
        let measured = s
            .tracker
            .states()
            .iter()
            .filter(|st| st.is_measured())
            .count();
        assert_eq!(measured, 0, "{what}: nothing can be measured");
        assert!(
            s.tracker
                .positions_px()
                .iter()
                .all(|p| p[0].is_finite() && p[1].is_finite()),
            "{what}: positions stay finite"
        );
    }
    // The next real frame is tracked again, identities intact.
    s.step(&shifted, 9);
    s.check(&shifted, 0.2, true, "after the dropouts");
}

#[test]
fn bad_references_and_frames_are_refused_with_the_fix() {
    let (w, h) = (320usize, 240usize);
    let params = TrackParams::default();
    let blank = vec![128u8; w * h * 3];
    let e = Reference::new(RgbView::new(w, h, &blank).expect("size"), &params).expect_err("blank");
    assert!(matches!(e, TrackError::NoMarkers { .. }), "{e}");
    assert!(e.to_string().contains("fix:"));
    let white = vec![255u8; w * h * 3];
    let e = Reference::new(RgbView::new(w, h, &white).expect("size"), &params).expect_err("white");
    assert!(matches!(e, TrackError::ReferenceSaturated { .. }), "{e}");
    let renderer = Renderer::for_view(&box_grid(), 45.36, 40.32, w as u32, h as u32);
    let markerless = renderer.render_at(None, &[], 0.0, 0);
    let e = Reference::new(RgbView::new(w, h, &markerless).expect("size"), &params)
        .expect_err("no markers");
    assert!(matches!(e, TrackError::NoMarkers { .. }), "{e}");
    assert!(matches!(
        RgbView::new(w, h, &blank[1..]),
        Err(TrackError::BufferLength { .. })
    ));
    assert!(matches!(
        RgbView::new(8, 8, &blank[..192]),
        Err(TrackError::TooSmall { .. })
    ));

    // A frame of another size than the reference.
    let good = renderer.render_at(None, &renderer.reference_px(), 0.0, 0);
    let reference = Reference::new(RgbView::new(w, h, &good).expect("size"), &params).expect("ok");
    let small = vec![100u8; 160 * 120 * 3];
    let mut det = Detector::new(w, h);
    let e = det
        .detect(RgbView::new(160, 120, &small).expect("size"), &reference)
        .expect_err("size mismatch");
    assert!(matches!(e, TrackError::SizeMismatch { .. }), "{e}");

    // A reference taken with something pressed in: its imprint's coloured shading.
    let grid = Grid { n: 128, dx: 0.2 };
    let mut uz = vec![0.0; 128 * 128];
    for j in 0..128 {
        for i in 0..128 {
            let r2 = grid.coord(i).powi(2) + grid.coord(j).powi(2);
            uz[j * 128 + i] = 2.0 * (-r2 / (2.0 * 2.0f64.powi(2))).exp();
        }
    }
    let zeros = vec![0.0; 128 * 128];
    let pressed = SurfaceView {
        field: Field {
            grid,
            ux: zeros.clone(),
            uy: zeros,
            uz,
        },
        centre_mm: (0.0, 0.0),
        rotation_rad: 0.0,
    };
    let (rgb, _) = renderer.render(Some(&pressed), 1);
    let e =
        Reference::new(RgbView::new(w, h, &rgb).expect("size"), &params).expect_err("in contact");
    assert!(matches!(e, TrackError::ReferenceInContact { .. }), "{e}");
    assert!(e.to_string().contains("before anything touches the gel"));
    // The untouched frame scores well below the limit.
    assert!(reference.contact_score() < 0.5 * params.contact_imprint_limit);
}

/// The real GelSight Mini sequence, if `../shared/data` is beside the repository.
fn mini_frames() -> Option<Vec<(usize, usize, Vec<u8>)>> {
    let dir = testkit::shared_data(
        env!("CARGO_MANIFEST_DIR"),
        "gelsight-mini-press",
        "tracking the real GelSight Mini press",
    )?;
    let frames = (0..219)
        .map(|k| {
            let img = image::open(dir.join(format!("frame_{k:04}.png")))
                .expect("a readable frame")
                .to_rgb8();
            (img.width() as usize, img.height() as usize, img.into_raw())
        })
        .collect();
    Some(frames)
}

/// Reads ../shared/data (skips when absent).
#[test]
fn real_mini_sequence_keeps_identities_and_is_quiet_when_still() {
    let Some(frames) = mini_frames() else { return };
    let (w, h, ref_rgb) = &frames[0];
    let reference = Reference::new(
        RgbView::new(*w, *h, ref_rgb).expect("size"),
        &TrackParams::default(),
    )
    .expect("frame 0 is untouched");
    let mut tracker = Tracker::new(&reference);
    let mut detector = Detector::new(*w, *h);
    let sp = reference.spacing_px();
    assert!((28.0..33.0).contains(&sp), "spacing {sp}");
    assert!(
        tracker.len() >= 75,
        "{} markers on the reference",
        tracker.len()
    );
    let interior =
        |p: [f64; 2]| p[0] > sp && p[1] > sp && p[0] < *w as f64 - sp && p[1] < *h as f64 - sp;
    let mut prev = tracker.positions_px().to_vec();
    let mut still_motion = Vec::new();
    for (k, (_, _, rgb)) in frames.iter().enumerate().skip(1) {
        let blobs = detector
            .detect(RgbView::new(*w, *h, rgb).expect("size"), &reference)
            .expect("same size");
        assert!(blobs.len() >= 68, "frame {k}: {} blobs", blobs.len());
        tracker.update(blobs);
        let measured = tracker.states().iter().filter(|s| s.is_measured()).count();
        assert!(measured >= 68, "frame {k}: {measured} markers measured");
        // No swaps: every interior marker moves with the median of its neighbours (a
        // swap with a neighbour would stand out by about one spacing).
        for i in 0..tracker.len() {
            if tracker.states()[i] != MarkerState::Tracked || !interior(tracker.reference_px()[i]) {
                continue;
            }
            let (mut dx, mut dy): (Vec<f64>, Vec<f64>) = tracker
                .neighbours(i)
                .iter()
                .filter(|&&j| tracker.states()[j as usize].is_measured())
                .map(|&j| {
                    let d = tracker.displacement_px(j as usize);
                    (d[0], d[1])
                })
                .unzip();
            if dx.len() < 2 {
                continue;
            }
            dx.sort_by(f64::total_cmp);
            dy.sort_by(f64::total_cmp);
            let m = [dx[dx.len() / 2], dy[dy.len() / 2]];
            let d = tracker.displacement_px(i);
            assert!(
                (d[0] - m[0]).hypot(d[1] - m[1]) < 0.5 * sp,
                "frame {k}: marker {i} disagrees with its neighbours"
            );
        }
        // The gel is untouched in frames 1–56: frame-to-frame motion is jitter.
        if k <= 56 {
            for (i, before) in prev.iter().enumerate() {
                if tracker.states()[i] == MarkerState::Tracked
                    && interior(tracker.reference_px()[i])
                {
                    let p = tracker.positions_px()[i];
                    still_motion.push(dist(p, *before));
                }
            }
        }
        prev = tracker.positions_px().to_vec();
    }
    still_motion.sort_by(f64::total_cmp);
    let median = still_motion[still_motion.len() / 2];
    let at = |q: f64| {
        still_motion[((still_motion.len() as f64 * q) as usize).min(still_motion.len() - 1)]
    };
    eprintln!(
        "Mini still frames 1-56: jitter median {median:.3} px, p95 {:.3}, p99 {:.3}, max {:.3} ({} positions)",
        at(0.95),
        at(0.99),
        still_motion.last().copied().unwrap_or(0.0),
        still_motion.len()
    );
    assert!(median <= 0.05, "still-frame jitter median {median:.3} px");
    // Identities survive the whole press, shear and release: back at rest at the end,
    // every interior marker is within a pixel of where it started.
    for i in 0..tracker.len() {
        if tracker.states()[i] == MarkerState::Tracked && interior(tracker.reference_px()[i]) {
            let d = tracker.displacement_px(i);
            assert!(
                d[0].hypot(d[1]) < 1.5,
                "marker {i} ends {d:?} from its start"
            );
        }
    }
}

/// Reads ../shared/data (skips when absent).
#[test]
fn real_frames_in_contact_are_refused_as_reference() {
    let Some(frames) = mini_frames() else { return };
    for k in [80, 133, 190] {
        let (w, h, rgb) = &frames[k];
        let e = Reference::new(
            RgbView::new(*w, *h, rgb).expect("size"),
            &TrackParams::default(),
        )
        .expect_err("a contact frame");
        assert!(
            matches!(e, TrackError::ReferenceInContact { .. }),
            "frame {k}: {e}"
        );
    }
    for k in [0, 30, 218] {
        let (w, h, rgb) = &frames[k];
        Reference::new(
            RgbView::new(*w, *h, rgb).expect("size"),
            &TrackParams::default(),
        )
        .unwrap_or_else(|e| panic!("frame {k} is untouched: {e}"));
    }
}

/// Tracks `frame` against `reference` (RGB8 at 640×480) and judges it.
fn judged(reference: &[u8], frame: &[u8]) -> tracking::FrameCheck {
    use tracking::{Method, Pipeline};
    let view = |px| RgbView::new(640, 480, px).expect("size");
    let mut p = Pipeline::new(view(reference), &TrackParams::default(), Method::Centroid)
        .expect("a reference");
    p.track(view(frame)).expect("same size");
    p.check_frame()
}

#[test]
fn a_frame_is_judged_the_same_gel_dark_or_another_gel() {
    use simbench::{Look, Motion, Scene};
    use tracking::FrameCheck;
    let look = Look::default();
    let grid = Scene::new(&box_grid(), (45.36, 40.32), (640, 480), 3);
    let (reference, _) = grid.frame(&Motion::Rest { frames: 1 }, 0, &look);
    // Half a spacing along a row, the grid beyond the view: ambiguous, but the same gel.
    let half = Motion::Jump {
        by_px: [0.5 * grid.spacing_px(), 0.0],
        hold: 1,
    };
    let (frame, _) = grid.frame(&half, 1, &look);
    assert_eq!(judged(&reference, &frame), FrameCheck::SameGel);
    // A dark frame: a few blobs of noise at most.
    let dark = vec![12u8; reference.len()];
    let check = judged(&reference, &dark);
    assert!(matches!(check, FrameCheck::FewBlobs { .. }), "{check:?}");
    assert!(!check.is_other_gel());
    // The portable sensor's triangles, about twice as far apart: another gel.
    let other = Scene::new(&triangles(), (20.0, 15.0), (640, 480), 2);
    let (frame, _) = other.frame(&Motion::Rest { frames: 1 }, 0, &look);
    let check = judged(&reference, &frame);
    assert!(
        matches!(check, FrameCheck::OtherSpacing { .. }),
        "{check:?}"
    );
    assert!(check.describe().contains("fix:"));
}
