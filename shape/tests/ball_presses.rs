//! The real GelSight Mini's ball presses (`../shared/data/gelsight-mini-ball`, 39 of its 40
//! labelled presses): calibrated leaving one press out at a time, every press read by models
//! that never saw it. The figures the docs state (docs/explanation/shape.md) are asserted here
//! at the tolerance they state.

// A test fails by panicking: unwrapping is how it says what broke.
#![allow(clippy::unwrap_used)]

use shape::ball::Circle;
use shape::{ModelKind, Press, Rgb, calibrate};

const MM_PER_PX: f64 = 0.0634;
const BALL_MM: f64 = 9.47;

fn load(path: &std::path::Path) -> Frame {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    (img.width() as usize, img.height() as usize, img.into_raw())
}

/// The presses and their labels; `press_50`'s label is `press_49`'s copied (same centre, the
/// ball visibly elsewhere, about (174, 67)), so it is left out.
/// A frame: width, height, RGB bytes.
type Frame = (usize, usize, Vec<u8>);

fn presses(dir: &std::path::Path) -> Vec<(String, Frame, Circle)> {
    let mut rd = csv::Reader::from_path(dir.join("labels.csv")).unwrap();
    let mut out = Vec::new();
    for r in rd.records() {
        let r = r.unwrap();
        if &r[0] == "press_50.png" {
            continue;
        }
        let circle = Circle {
            x_px: r[1].parse().unwrap(),
            y_px: r[2].parse().unwrap(),
            radius_px: r[3].parse().unwrap(),
        };
        out.push((r[0].to_string(), load(&dir.join(&r[0])), circle));
    }
    out
}

#[test]
fn held_out_ball_presses_read_the_balls_shape() {
    let Some(dir) = testkit::shared_data(
        env!("CARGO_MANIFEST_DIR"),
        "gelsight-mini-ball",
        "shape from the real ball presses",
    ) else {
        return;
    };
    let bg = load(&dir.join("background.png"));
    let frames = presses(&dir);
    assert_eq!(frames.len(), 39);
    let background = Rgb::new(bg.0, bg.1, &bg.2).unwrap();
    let presses: Vec<Press<'_>> = frames
        .iter()
        .map(|(name, (w, h, px), circle)| Press {
            name: name.clone(),
            frame: Rgb::new(*w, *h, px).unwrap(),
            circle: *circle,
        })
        .collect();
    let ball_px = BALL_MM / 2.0 / MM_PER_PX;
    let cal = calibrate(background, &presses, ball_px, MM_PER_PX).unwrap();
    for h in &cal.held_out {
        eprintln!(
            "{:>12}: height {:.1} % median, {:.1} % worst ({}); radius {:.1} % / {:.1} %; slope rms {:.1}°; spurious {:.2}; sign errors {}",
            h.model.name(),
            h.height_median_pct,
            h.height_worst_pct,
            h.height_worst_press,
            h.radius_median_pct,
            h.radius_worst_pct,
            h.slope_rms_median_deg,
            h.spurious_worst,
            h.sign_errors
        );
    }
    let ll = &cal.held_out[0];
    let lut = &cal.held_out[1];
    assert_eq!(ll.model, ModelKind::LocalLinear);
    assert_eq!(cal.chosen, ModelKind::LocalLinear);
    for h in [ll, lut] {
        assert_eq!(h.presses.len(), 39);
        assert_eq!(h.sign_errors, 0);
    }
    // Stated in docs/explanation/shape.md (measured 30 Nov, with the flat field:
    // local-linear 3.4 % / 14.2 % (press_08), radius 2.5 % / 8.9 %, slope 3.9°, spurious
    // 0.22; the table 9.2 % / 40.8 %, 8.8 % / 56.4 %). The radius meets the targets
    // (3 % median, 10 % on every press); the cap height does not: the worst presses sit in
    // the dim right of the frame and at its top-left border.
    assert!(ll.height_median_pct <= 3.5, "{ll:?}");
    assert!(ll.height_worst_pct <= 15.0, "{ll:?}");
    assert!(ll.radius_median_pct <= 3.0, "{ll:?}");
    assert!(ll.radius_worst_pct <= 10.0, "{ll:?}");
    assert!(ll.slope_rms_median_deg <= 4.2, "{ll:?}");
    assert!(ll.spurious_worst <= 0.3, "{ll:?}");
    // The table, which cannot see the lights' vignetting, reads the caps at least twice as
    // far off, on the median and on the worst press.
    assert!(
        lut.height_median_pct >= 2.0 * ll.height_median_pct,
        "{lut:?}"
    );
    assert!(lut.height_worst_pct >= 1.5 * ll.height_worst_pct, "{lut:?}");
}
