//! Finding a ball press's contact circle in the image, for presses nobody labelled.
//!
//! The colour change of a ball press is strongest near the contact's edge, where the gel is
//! steepest, and falls off outside it as the gel relaxes to flat. Along rays from the press's
//! centre, the point where the change has fallen to half its ray's peak marks a circle just
//! outside the contact; a least-squares circle (Kåsa's algebraic fit) through those points,
//! trimmed of rays that stray (a marker, the frame's border), and scaled by
//! [`EDGE_TO_CONTACT`], is the contact circle. The centre is refined by fitting again from
//! the fitted centre.
//!
//! Measured on the real GelSight Mini presses against the hand-labelled circles
//! (`shape/tests/find_circle.rs`, docs/explanation/shape.md): the scale was taken on
//! presses 01–20 and the figures are those of presses 21–49: centre 1.8 px from the label
//! (median), radius within 2.8 % (median) and 10.4 % (worst).

use crate::ShapeError;
use crate::ball::Circle;
use crate::frame::Rgb;

/// The contact's radius as a share of the half-change circle's: the median over the real
/// GelSight Mini's presses 01–20 of label ÷ half-change radius (0.865). The other presses
/// test it.
pub const EDGE_TO_CONTACT: f64 = 0.865;
/// Smallest peak colour change (summed over channels, after the blur, grey levels) that is
/// a press: a Mini's background noise (σ 2–3 grey levels a channel) is about 0.5 a channel
/// after the 5×5 blur, so this is ten times its sum over three channels.
const MIN_PEAK_GREY: f32 = 15.0;
/// The touched blob: pixels above this share of the frame's peak change.
const BLOB_SHARE: f32 = 0.35;
/// Rays from the centre, and their step, px.
const RAYS: usize = 72;
const RAY_STEP_PX: f64 = 0.5;
/// The change falls to this share of its ray's peak at the circle the rays find.
const HALF: f32 = 0.5;

/// The contact circle of a ball press against its background, or why none was found.
pub fn find_circle(background: Rgb<'_>, frame: Rgb<'_>) -> Result<Circle, ShapeError> {
    frame.same_size(background.width, background.height, "background")?;
    let (w, h) = (frame.width, frame.height);
    let change = blurred_change(&background, &frame);
    let peak = change.iter().copied().fold(0.0f32, f32::max);
    if peak < MIN_PEAK_GREY {
        return Err(ShapeError::Circle(format!(
            "the strongest colour change is {peak:.0} grey levels (a press shows at least \
             {MIN_PEAK_GREY:.0}): is the ball pressed, and is the background of this session?"
        )));
    }
    let (mut cx, mut cy) = blob_centre(&change, w, h, BLOB_SHARE * peak);
    let mut circle = None;
    for _ in 0..3 {
        let points = half_change_points(&change, w, h, (cx, cy));
        let Some(c) = trimmed_circle(&points) else {
            break;
        };
        (cx, cy) = (c.x_px, c.y_px);
        circle = Some(c);
    }
    let c = circle.ok_or_else(|| {
        ShapeError::Circle(
            "the colour change has no ring around its centre: press a ball, one press a frame"
                .into(),
        )
    })?;
    if !(c.x_px >= 0.0 && c.y_px >= 0.0 && c.x_px < w as f64 && c.y_px < h as f64) {
        return Err(ShapeError::Circle(format!(
            "the circle found is centred at ({:.0}, {:.0}) px, outside the frame: press \
             the ball inside the view",
            c.x_px, c.y_px
        )));
    }
    Ok(Circle {
        radius_px: c.radius_px * EDGE_TO_CONTACT,
        ..c
    })
}

/// `|frame − background|` summed over the channels after a box blur (5×5 at 320×240,
/// scaled with the frame), grey levels. On a gel with markers the ink of the frame and of
/// the background is left out of the blur (normalised convolution, as the height maps do:
/// `markers`): a marker that moves changes its pixels far more than any slope does.
fn blurred_change(background: &Rgb<'_>, frame: &Rgb<'_>) -> Vec<f32> {
    let (w, h) = (frame.width, frame.height);
    let n = w * h;
    let mut ink = vec![false; n];
    let mut buffers: [Vec<f32>; 3] = Default::default();
    if crate::markers::mark_ink(background.pixels, w, h, &mut ink, &mut buffers) * 500 > n {
        crate::markers::mark_ink(frame.pixels, w, h, &mut ink, &mut buffers);
    } else {
        ink.fill(false);
    }
    let weight: Vec<f32> = ink.iter().map(|i| if *i { 0.0 } else { 1.0 }).collect();
    let r = (w.max(h) / 160).max(2);
    let (mut weight_mean, mut tmp) = (vec![0.0f32; n], Vec::new());
    crate::markers::box_mean(&weight, &mut weight_mean, &mut tmp, w, h, r);
    let mut total = vec![0.0f32; n];
    let (mut channel, mut mean) = (vec![0.0f32; n], vec![0.0f32; n]);
    for c in 0..3 {
        for (i, v) in channel.iter_mut().enumerate() {
            // Blur each channel's signed change before taking its size: the noise averages
            // out before the absolute value makes it a bias.
            *v = weight[i] * (frame.pixels[3 * i + c] as f32 - background.pixels[3 * i + c] as f32);
        }
        crate::markers::box_mean(&channel, &mut mean, &mut tmp, w, h, r);
        for ((t, m), wm) in total.iter_mut().zip(&mean).zip(&weight_mean) {
            if *wm > 0.05 {
                *t += (m / wm).abs();
            }
        }
    }
    total
}

/// The change-weighted centre of the largest 4-connected region above `limit`.
fn blob_centre(change: &[f32], w: usize, h: usize, limit: f32) -> (f64, f64) {
    let mut label = vec![0u32; change.len()];
    let mut best = (0usize, (0.0, 0.0));
    let mut stack = Vec::new();
    let mut next = 0u32;
    for start in 0..change.len() {
        if change[start] <= limit || label[start] != 0 {
            continue;
        }
        next += 1;
        label[start] = next;
        stack.push(start);
        let (mut n, mut sw, mut sx, mut sy) = (0usize, 0.0f64, 0.0f64, 0.0f64);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            let v = change[i] as f64;
            n += 1;
            sw += v;
            sx += v * x as f64;
            sy += v * y as f64;
            let mut visit = |j: usize| {
                if change[j] > limit && label[j] == 0 {
                    label[j] = next;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        if n > best.0 {
            best = (n, (sx / sw, sy / sw));
        }
    }
    best.1
}

/// Along each ray from `centre`, the first point beyond the ray's peak where the change
/// falls below [`HALF`] of it.
fn half_change_points(change: &[f32], w: usize, h: usize, centre: (f64, f64)) -> Vec<[f64; 2]> {
    // As far as the widest press a frame holds: 90 px at 320×240.
    let reach = w.max(h) as f64 * 0.28;
    let mut points = Vec::with_capacity(RAYS);
    let mut values = Vec::new();
    for k in 0..RAYS {
        let th = k as f64 * std::f64::consts::TAU / RAYS as f64;
        let (dx, dy) = (th.cos(), th.sin());
        values.clear();
        let mut r = RAY_STEP_PX;
        while r < reach {
            let (x, y) = (centre.0 + r * dx, centre.1 + r * dy);
            let Some(v) = bilinear(change, w, h, x, y) else {
                break;
            };
            values.push((r, v));
            r += RAY_STEP_PX;
        }
        let Some((peak_at, peak)) = values
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.1.total_cmp(&b.1.1))
            .map(|(i, v)| (i, v.1))
        else {
            continue;
        };
        if let Some((r, _)) = values[peak_at..].iter().find(|(_, v)| *v < HALF * peak) {
            points.push([centre.0 + r * dx, centre.1 + r * dy]);
        }
    }
    points
}

fn bilinear(img: &[f32], w: usize, h: usize, x: f64, y: f64) -> Option<f32> {
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
        return None;
    }
    let (x0, y0) = ((x as usize).min(w - 2), (y as usize).min(h - 2));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let at = |xx: usize, yy: usize| img[yy * w + xx];
    let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
    let bottom = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

/// Kåsa's algebraic circle fit (`x² + y² = 2ax + 2by + c`, least squares), three times,
/// each dropping the points whose distance from the circle exceeds 2.5 times the median
/// (at least 1 px). `None` with fewer than 8 points or a degenerate fit.
fn trimmed_circle(points: &[[f64; 2]]) -> Option<Circle> {
    let mut kept: Vec<[f64; 2]> = points.to_vec();
    let mut circle = None;
    for _ in 0..3 {
        if kept.len() < 8 {
            return circle;
        }
        let c = kasa(&kept)?;
        let mut residuals: Vec<f64> = kept
            .iter()
            .map(|p| ((p[0] - c.x_px).hypot(p[1] - c.y_px) - c.radius_px).abs())
            .collect();
        let limit = {
            let mut sorted = residuals.clone();
            sorted.sort_by(f64::total_cmp);
            (2.5 * sorted[sorted.len() / 2]).max(1.0)
        };
        let mut i = 0;
        kept.retain(|_| {
            let keep = residuals[i] < limit;
            i += 1;
            keep
        });
        residuals.clear();
        circle = Some(c);
    }
    circle
}

fn kasa(points: &[[f64; 2]]) -> Option<Circle> {
    use nalgebra::{Matrix3, Vector3};
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for p in points {
        let row = Vector3::new(2.0 * p[0], 2.0 * p[1], 1.0);
        ata += row * row.transpose();
        atb += row * (p[0] * p[0] + p[1] * p[1]);
    }
    let s = ata.cholesky()?.solve(&atb);
    let r2 = s[2] + s[0] * s[0] + s[1] * s[1];
    (r2 > 0.0 && r2.is_finite()).then(|| Circle {
        x_px: s[0],
        y_px: s[1],
        radius_px: r2.sqrt(),
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A drawn ring of change: the half-change circle is found where it was drawn.
    #[test]
    fn a_drawn_ring_is_found_where_it_was_drawn() {
        let (w, h) = (160usize, 120usize);
        let bg = vec![100u8; w * h * 3];
        let (cx, cy, a) = (70.3, 55.8, 20.0);
        let mut fr = bg.clone();
        for y in 0..h {
            for x in 0..w {
                let r = (x as f64 - cx).hypot(y as f64 - cy);
                // Rises to the edge, then falls off over 6 px.
                let v = if r < a {
                    60.0 * r / a
                } else {
                    60.0 * (-(r - a) / 6.0).exp()
                };
                let i = (y * w + x) * 3;
                fr[i] = (100.0 + v) as u8;
            }
        }
        let got = find_circle(Rgb::new(w, h, &bg).unwrap(), Rgb::new(w, h, &fr).unwrap()).unwrap();
        assert!(
            (got.x_px - cx).abs() < 0.6 && (got.y_px - cy).abs() < 0.6,
            "{got:?}"
        );
        // The half-change radius: a + 6 ln 2 ≈ 24.2 px (the blur moves it a little).
        let half_r = got.radius_px / EDGE_TO_CONTACT;
        assert!((half_r - 24.2).abs() < 1.0, "{half_r}");
    }

    #[test]
    fn an_unpressed_frame_is_refused_with_the_reason() {
        let (w, h) = (40usize, 30usize);
        let bg = vec![90u8; w * h * 3];
        let e =
            find_circle(Rgb::new(w, h, &bg).unwrap(), Rgb::new(w, h, &bg).unwrap()).unwrap_err();
        assert!(e.to_string().contains("is the ball pressed"), "{e}");
    }
}
