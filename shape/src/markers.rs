//! Markers: the dark dots printed on many gels, for tracking. Their ink is not the gel's
//! shading, and a marker that moves changes the colour around it by far more than any slope
//! does; so marker pixels — of the frame, and of the background where they started — are
//! left out of the colour change, and the slope there is filled from the pixels around
//! (normalised convolution: Knutsson & Westin, CVPR 1993) before integration.

/// Darker than the local mean by this share (and by at least [`DARK_MIN_GREY`]) is ink.
const DARK_SHARE: f32 = 0.2;
/// The least darkening, grey levels, that counts as ink (the background's noise is 2–3).
const DARK_MIN_GREY: f32 = 15.0;

/// Box-mean of `src` (w × h, one channel) with radius `r` into `dst`, two running sums.
pub(crate) fn box_mean(
    src: &[f32],
    dst: &mut [f32],
    tmp: &mut Vec<f32>,
    w: usize,
    h: usize,
    r: usize,
) {
    tmp.resize(w * h, 0.0);
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        let out = &mut tmp[y * w..(y + 1) * w];
        let (mut sum, mut count) = (0.0f32, 0.0f32);
        for v in row.iter().take(r.min(w)) {
            sum += v;
            count += 1.0;
        }
        for x in 0..w {
            if x + r < w {
                sum += row[x + r];
                count += 1.0;
            }
            if x > r {
                sum -= row[x - r - 1];
                count -= 1.0;
            }
            out[x] = sum / count;
        }
    }
    let mut sums = vec![0.0f32; w];
    let mut count = 0.0f32;
    for yy in 0..r.min(h) {
        for (s, v) in sums.iter_mut().zip(&tmp[yy * w..(yy + 1) * w]) {
            *s += v;
        }
        count += 1.0;
    }
    for y in 0..h {
        if y + r < h {
            for (s, v) in sums.iter_mut().zip(&tmp[(y + r) * w..(y + r + 1) * w]) {
                *s += v;
            }
            count += 1.0;
        }
        if y > r {
            for (s, v) in sums.iter_mut().zip(&tmp[(y - r - 1) * w..(y - r) * w]) {
                *s -= v;
            }
            count -= 1.0;
        }
        for (o, s) in dst[y * w..(y + 1) * w].iter_mut().zip(&sums) {
            *o = s / count;
        }
    }
}

/// The radius of the local mean, px: large against a marker (a GelSight Mini's dots are
/// about 6–10 px across at 320×240), small against the lights' gradient.
pub(crate) fn local_radius(w: usize) -> usize {
    (w / 32).max(6)
}

/// Marks (`mask[i] = true`) the ink of an RGB frame: pixels darker than their
/// neighbourhood's mean by [`DARK_SHARE`] (at least [`DARK_MIN_GREY`]), grown by one pixel.
/// Returns how many pixels it marked.
pub(crate) fn mark_ink(
    rgb: &[u8],
    w: usize,
    h: usize,
    mask: &mut [bool],
    buf: &mut [Vec<f32>; 3],
) -> usize {
    let [lum, mean, tmp] = buf;
    lum.clear();
    lum.extend(
        rgb.chunks_exact(3)
            .map(|p| (p[0] as f32 + p[1] as f32 + p[2] as f32) / 3.0),
    );
    mean.resize(w * h, 0.0);
    box_mean(lum, mean, tmp, w, h, local_radius(w));
    let mut marked = 0;
    let mut ink = vec![false; w * h];
    for ((i, l), m) in lum.iter().enumerate().zip(mean.iter()) {
        if m - l > (DARK_SHARE * m).max(DARK_MIN_GREY) {
            ink[i] = true;
        }
    }
    for y in 0..h {
        for x in 0..w {
            if !ink[y * w + x] {
                continue;
            }
            for (dx, dy) in [(0i64, 0i64), (1, 0), (-1, 0), (0, 1), (0, -1)] {
                let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                if xx >= 0 && yy >= 0 && (xx as usize) < w && (yy as usize) < h {
                    let j = yy as usize * w + xx as usize;
                    if !mask[j] {
                        mask[j] = true;
                        marked += 1;
                    }
                }
            }
        }
    }
    marked
}

/// Fills `g` (w × h) where `hole` from the valid pixels around, by normalised convolution
/// with a box of radius `r`, growing the radius until every hole is filled (or 4 rounds).
pub(crate) fn fill(
    g: &mut [f32],
    hole: &[bool],
    w: usize,
    h: usize,
    r: usize,
    buf: &mut [Vec<f32>; 3],
) {
    let [num, den, tmp] = buf;
    let mut r = r;
    for _ in 0..4 {
        num.clear();
        num.extend(g.iter().zip(hole).map(|(v, h)| if *h { 0.0 } else { *v }));
        den.clear();
        den.extend(hole.iter().map(|h| if *h { 0.0 } else { 1.0 }));
        let (mut n_out, mut d_out) = (vec![0.0f32; w * h], vec![0.0f32; w * h]);
        box_mean(num, &mut n_out, tmp, w, h, r);
        box_mean(den, &mut d_out, tmp, w, h, r);
        let mut left = false;
        for i in 0..w * h {
            if hole[i] {
                if d_out[i] > 1e-3 {
                    g[i] = n_out[i] / d_out[i];
                } else {
                    left = true;
                }
            }
        }
        if !left {
            return;
        }
        r *= 2;
    }
}

/// The background's marker ink; `None` on a markerless gel (fewer than 0.2 % of its pixels
/// read as ink), whose colour change then keeps every pixel.
pub(crate) fn background_ink(
    background: &crate::frame::Rgb<'_>,
    buf: &mut [Vec<f32>; 3],
) -> Option<Vec<bool>> {
    let (w, h) = (background.width, background.height);
    let mut ink = vec![false; w * h];
    let marked = mark_ink(background.pixels, w, h, &mut ink, buf);
    (marked * 500 > w * h).then_some(ink)
}

/// Each frame's marker ink with the background's (as [`crate::depth::Depth`] leaves it out of
/// the colour change), for fitting the presses without it; all `None` on a markerless gel.
pub(crate) fn press_inks<'a>(
    background: &crate::frame::Rgb<'_>,
    frames: impl Iterator<Item = &'a crate::frame::Rgb<'a>>,
) -> Vec<Option<Vec<bool>>> {
    let (w, h) = (background.width, background.height);
    let mut buf: [Vec<f32>; 3] = Default::default();
    let bg_ink = background_ink(background, &mut buf);
    frames
        .map(|f| {
            bg_ink.as_ref().map(|bg| {
                let mut ink = bg.clone();
                mark_ink(f.pixels, w, h, &mut ink, &mut buf);
                ink
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::frame::Rgb;

    /// A markerless gel gives no ink to leave out; a gel with dots gives the background's
    /// dots and the frame's (moved) ones, and nothing else.
    #[test]
    fn presses_are_fitted_without_the_ink_of_either_frame() {
        let (w, h) = (64, 48);
        let dots = |dx: usize| -> Vec<u8> {
            let mut px = vec![150u8; w * h * 3];
            for cy in (6..h).step_by(12) {
                for cx in (6..w - 8).step_by(12) {
                    for y in cy - 1..=cy + 1 {
                        for x in cx + dx - 1..=cx + dx + 1 {
                            px[3 * (y * w + x)..3 * (y * w + x) + 3].fill(40);
                        }
                    }
                }
            }
            px
        };
        let plain = vec![150u8; w * h * 3];
        let bg = Rgb::new(w, h, &plain).unwrap();
        assert!(press_inks(&bg, [bg].iter()).iter().all(Option::is_none));
        let (bg_px, moved_px) = (dots(0), dots(6));
        let (bg, moved) = (
            Rgb::new(w, h, &bg_px).unwrap(),
            Rgb::new(w, h, &moved_px).unwrap(),
        );
        let inks = press_inks(&bg, [moved].iter());
        let ink = inks[0].as_ref().unwrap();
        // The background's dot at (6, 6) and the frame's at (12, 6) (each grown by a pixel); not
        // the gel between them or away from the dots.
        assert!(ink[6 * w + 6] && ink[6 * w + 12] && !ink[6 * w + 9] && !ink[12 * w + 3]);
    }
}
