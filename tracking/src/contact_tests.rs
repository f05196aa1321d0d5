//! Tests of the contact region ([`super`]): synthetic gels with a known change.

use super::*;
use crate::{Reference as Ref, TrackParams};

/// A 240×180 gel: a smooth coloured background, dark markers on a 20 px grid, pixel
/// noise of σ ≈ 1.1 % (the simulated camera's), and `change(x, y)` (relative) added.
fn gel(seed: u64, change: impl Fn(f64, f64) -> f64) -> Vec<u8> {
    let (w, h) = (240usize, 180usize);
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut gauss = move || {
        // Sum of four uniforms on ±½ (variance ⅓), scaled to σ = 1.
        let mut acc = 0.0;
        for _ in 0..4 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            acc += (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        acc * 3f64.sqrt()
    };
    let mut rgb = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            let (mx, my) = ((x % 20) as f64 - 10.0, (y % 20) as f64 - 10.0);
            let marker = mx * mx + my * my < 16.0;
            let k = 1.0 + change(x as f64, y as f64);
            for c in 0..3 {
                let bg = 150.0 + 30.0 * c as f64 + 20.0 * (x as f64 / w as f64);
                let v = if marker {
                    25.0
                } else {
                    bg * k * (1.0 + 0.011 * gauss())
                };
                rgb[3 * (y * w + x) + c] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    rgb
}

fn finder_on(reference: &[u8]) -> (Ref, ContactFinder) {
    let view = RgbView::new(240, 180, reference).expect("size");
    let r = Ref::new(view, &TrackParams::default()).expect("reference");
    let f = ContactFinder::new(view, &r, ContactParams::default()).expect("finder");
    (r, f)
}

fn find(r: &Ref, f: &mut ContactFinder, frame: &[u8]) -> Option<ContactRegion> {
    let view = RgbView::new(240, 180, frame).expect("size");
    let mut d = crate::Detector::new(240, 180);
    d.detect(view, r).expect("size");
    f.find(view, r, d.smoothed()).expect("size")
}

/// Noise that lifts one small spot above the floor is not a contact; a broad, faint
/// colour change (a gently curved contact's tilt) is, though its peak is lower.
#[test]
fn a_noise_spike_is_not_a_contact_and_a_faint_broad_tilt_is() {
    let (r, mut f) = finder_on(&gel(1, |_, _| 0.0));
    // A 4 px spot lifting the map to about 1.4 × the floor, the rest of it at 0.4 × (as
    // on the simulated portable sensor's untouched gel: peaks 0.025–0.031, floor 0.022).
    let spike = gel(2, |x, y| {
        if (x - 80.0).abs() < 2.0 && (y - 40.0).abs() < 2.0 {
            0.2
        } else {
            0.0
        }
    });
    assert!(
        find(&r, &mut f, &spike).is_none(),
        "a 4 px spike read as contact"
    );
    let floor = f.noise_floor();
    let peak = f.map().0.iter().copied().fold(0.0f32, f32::max) as f64;
    assert!(
        peak > floor,
        "the spike {peak} is not above the floor {floor}"
    );
    // A band 60 px wide across the image, its change twice the floor.
    let k = 2.0 * floor / 3f64.sqrt();
    let band = gel(3, |_, y| if (y - 90.0).abs() < 30.0 { k } else { 0.0 });
    let region = find(&r, &mut f, &band).expect("a broad faint change is contact");
    assert!(region.area_px2 > 5000.0, "{}", region.area_px2);
}

/// A can lying across the pad: its strip runs to the image's sides, the gel tilts along
/// the strip's two edges and not on its flat top. The region is the whole strip, not the
/// side that holds the peak.
#[test]
fn a_strip_across_the_view_is_found_whole_from_its_two_tilting_sides() {
    let (r, mut f) = finder_on(&gel(1, |_, _| 0.0));
    let strip = gel(4, |_, y| {
        if (60.0..75.0).contains(&y) {
            0.05
        } else if (105.0..120.0).contains(&y) {
            0.045
        } else {
            0.0
        }
    });
    let region = find(&r, &mut f, &strip).expect("contact");
    // It spans both sides: 60 px from the one's outer edge to the other's.
    let ys = region.outline_px.iter().map(|p| p[1]);
    let (top, bottom) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), y| (a.min(y), b.max(y)));
    assert!(
        (top - 60.0).abs() < 6.0 && (bottom - 120.0).abs() < 6.0,
        "from y {top} to {bottom}"
    );
    // 240 × 60 px between them, less where rays along the flat top stop in its noise;
    // one side alone is 240 × 15.
    assert!(
        region.area_px2 > 0.6 * 240.0 * 60.0 && region.area_px2 < 1.2 * 240.0 * 60.0,
        "area {} px²",
        region.area_px2
    );
    assert!(
        (region.centroid_px[1] - 90.0).abs() < 8.0,
        "centroid {:?}",
        region.centroid_px
    );
}
