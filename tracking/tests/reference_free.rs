//! A reference-free start (a recording that begins mid-contact): the undeformed lattice
//! fitted to the periphery of the first frame, then tracking on, scored on synthetic scenes
//! with exact truth (`simbench::scenes`).

mod common;

use common::identity::{box_grid, triangles};
use simbench::{Look, Motion, Scene};
use tracking::{Method, Pipeline, RgbView, TrackError, TrackParams};

#[test]
fn a_recording_that_starts_twisted_finds_the_printed_grid_and_keeps_every_identity() {
    // A 20° twist of a contact 1.5 spacings in radius: its far field (u_θ = θa³/r²) leaves
    // the corners within about 0.4 px of rest, and the lattice fitted to the markers that
    // moved least absorbs a little of the far field's turn (≈ 1 px at the corners). (A
    // contact of 3 spacings moves every marker in view by 3 px or more: no lattice fit can
    // then know where the gel was at rest.)
    let scene = Scene::new(&box_grid(), (45.36, 40.32), (640, 480), 0);
    let spacing = scene.spacing_px();
    let motion = Motion::Twist {
        centre_px: [330.0, 230.0],
        radius_px: 1.5 * spacing,
        angle_rad: 20f64.to_radians(),
        hold: 3,
    };
    let look = Look::default();
    // Frame 1 is the first frame of the recording: already twisted.
    let (first, _) = scene.frame(&motion, 1, &look);
    let view = RgbView::new(640, 480, &first).expect("test setup");
    let (mut pipeline, lattice) =
        Pipeline::reference_free(view, &TrackParams::default(), Method::Centroid)
            .expect("test setup");
    assert!(
        (lattice.spacing_px() - spacing).abs() < 0.02 * spacing,
        "spacing {} against {spacing}",
        lattice.spacing_px()
    );
    // Every site is a printed marker's rest position.
    let rest = scene.rest_px();
    let owner: Vec<usize> = pipeline
        .tracker()
        .reference_px()
        .iter()
        .map(|s| {
            let (k, d) = rest
                .iter()
                .enumerate()
                .map(|(k, r)| (k, (r[0] - s[0]).hypot(r[1] - s[1])))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .expect("test setup");
            assert!(
                d < 0.06 * spacing,
                "site {s:?} is {d:.3} px from the nearest printed marker"
            );
            k
        })
        .collect();
    // Frames 1 (the start) to the end (back at rest): measured rows carry their own marker.
    let (mut claimed, mut wrong, mut sq) = (0usize, 0usize, 0.0f64);
    for k in 1..motion.frames() {
        if k > 1 {
            let (rgb, _) = scene.frame(&motion, k, &look);
            pipeline
                .track(RgbView::new(640, 480, &rgb).expect("test setup"))
                .expect("test setup");
        }
        let t = pipeline.tracker();
        for (id, &m) in owner.iter().enumerate() {
            if !t.states()[id].is_measured() {
                continue;
            }
            let truth = motion.place(rest[m], k).0;
            let p = t.positions_px()[id];
            let e = (p[0] - truth[0]).hypot(p[1] - truth[1]);
            claimed += 1;
            if e > 0.3 * spacing {
                wrong += 1;
            } else {
                sq += e * e;
            }
        }
    }
    assert_eq!(
        wrong, 0,
        "{wrong} of {claimed} measured rows carry another marker"
    );
    let rms = (sq / claimed as f64).sqrt();
    assert!(rms < 0.05, "rms {rms} px");
    // Back at rest, what is left is the lattice's own error (the far field it absorbed).
    let t = pipeline.tracker();
    let left = (0..t.len())
        .filter(|&i| t.states()[i].is_measured())
        .map(|i| {
            let d = t.displacement_px(i);
            d[0].hypot(d[1])
        })
        .fold(0.0, f64::max);
    assert!(left < 0.06 * spacing, "{left} px left at rest");
    eprintln!("reference-free start, twist 20°: {left:.3} px left at rest");
    let measured = (0..t.len())
        .filter(|&i| t.states()[i].is_measured())
        .count();
    assert!(
        measured * 100 >= 99 * t.len(),
        "{measured} of {} measured",
        t.len()
    );
}

#[test]
fn random_triangles_are_refused_with_the_fix() {
    let scene = Scene::new(&triangles(), (20.0, 15.0), (640, 480), 0);
    let (first, _) = scene.frame(&Motion::Rest { frames: 1 }, 0, &Look::default());
    let view = RgbView::new(640, 480, &first).expect("test setup");
    let err = Pipeline::reference_free(view, &TrackParams::default(), Method::Centroid)
        .expect_err("triangles are no lattice");
    assert!(matches!(err, TrackError::NotALattice { .. }), "{err}");
    assert!(err.to_string().contains("fix: pass --reference"), "{err}");
    let err = Pipeline::reference_free(view, &TrackParams::default(), Method::Lk)
        .expect_err("LK needs the untouched gel");
    assert!(
        matches!(err, TrackError::ReferenceFreeMethod { .. }),
        "{err}"
    );
}
