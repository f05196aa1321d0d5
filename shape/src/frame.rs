//! Frames as 8-bit RGB, and the colour change against the unpressed background.

use crate::ShapeError;

/// A row-major 8-bit RGB frame (3 bytes a pixel), borrowed.
#[derive(Debug, Clone, Copy)]
pub struct Rgb<'a> {
    /// Width, px.
    pub width: usize,
    /// Height, px.
    pub height: usize,
    /// `width × height × 3` bytes.
    pub pixels: &'a [u8],
}

impl<'a> Rgb<'a> {
    /// Checks that `pixels` holds the frame.
    pub fn new(width: usize, height: usize, pixels: &'a [u8]) -> Result<Self, ShapeError> {
        let need = width * height * 3;
        if pixels.len() != need || width < 2 || height < 2 {
            return Err(ShapeError::Bytes {
                len: pixels.len(),
                width,
                height,
                need,
            });
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// Refuses a frame of another size than `other` (`what` names it in the message).
    pub(crate) fn same_size(
        &self,
        width: usize,
        height: usize,
        what: &'static str,
    ) -> Result<(), ShapeError> {
        if (self.width, self.height) == (width, height) {
            return Ok(());
        }
        Err(ShapeError::Size {
            what,
            got_w: self.width,
            got_h: self.height,
            want_w: width,
            want_h: height,
        })
    }
}

/// The colour change `(frame − background) / 64` per pixel and channel, interleaved RGB:
/// 64 grey levels to one unit keeps the models' inputs near 1 where the gel is steep.
pub(crate) const CHANGE_SCALE: f32 = 1.0 / 64.0;

/// Writes the colour change of `frame` against `background` into `out` (3 per pixel).
pub(crate) fn colour_change(frame: &Rgb<'_>, background: &Rgb<'_>, out: &mut Vec<f32>) {
    out.clear();
    out.extend(
        frame
            .pixels
            .iter()
            .zip(background.pixels)
            .map(|(a, b)| (*a as f32 - *b as f32) * CHANGE_SCALE),
    );
}

/// Standard deviation of the blur the flat field takes of the background, px.
pub(crate) const FLAT_FIELD_SIGMA_PX: f64 = 2.0;

/// The flat field of `background`: per pixel and channel, 128 over the background blurred
/// by a Gaussian of [`FLAT_FIELD_SIGMA_PX`] (clamped at one grey level), so that the colour
/// change times it is the change relative to how lit that point of the gel is.
///
/// Why: a GelSight Mini's lights vignette, and the colour change one slope makes scales
/// with the light that reaches the point (the right and bottom of the frame get a third to
/// a half of the middle's). Relative to its own light a press's response varies far less
/// across the frame, so the spline between calibration presses has less to bridge: on the
/// 39 real ball presses left out in turn, the worst fitted sphere radius 14.6 → 8.9 %
/// (docs/explanation/shape.md, "Flat field"). The blur keeps the sensor's noise out; the
/// kernel reaches 4σ (17 taps, as OpenCV's default for this σ on floating-point images; the
/// prototype the figures were first measured with blurred the background as floats),
/// mirrored at the borders.
pub(crate) fn flat_field(background: &Rgb<'_>) -> Vec<f32> {
    let (w, h) = (background.width, background.height);
    let radius = (4.0 * FLAT_FIELD_SIGMA_PX).round() as isize;
    let taps: Vec<f64> = (-radius..=radius)
        .map(|k| (-0.5 * (k as f64 / FLAT_FIELD_SIGMA_PX).powi(2)).exp())
        .collect();
    let total: f64 = taps.iter().sum();
    let taps: Vec<f64> = taps.iter().map(|t| t / total).collect();
    let src: Vec<f64> = background.pixels.iter().map(|v| f64::from(*v)).collect();
    let rows = blur_axis(&src, (w, h), &taps, true);
    let both = blur_axis(&rows, (w, h), &taps, false);
    both.iter().map(|b| (128.0 / b.max(1.0)) as f32).collect()
}

/// One pass of the separable blur over interleaved RGB: along the rows (`along_x`) or the
/// columns, with the taps centred and mirrored at the borders without repeating the edge
/// pixel (…2 1 | 0 1 2…).
fn blur_axis(src: &[f64], (w, h): (usize, usize), taps: &[f64], along_x: bool) -> Vec<f64> {
    let radius = (taps.len() / 2) as isize;
    let n = if along_x { w } else { h } as isize;
    let mirror = |i: isize| -> isize {
        let mut i = i;
        while n > 1 && (i < 0 || i >= n) {
            i = if i < 0 { -i } else { 2 * (n - 1) - i };
        }
        if n > 1 { i } else { 0 }
    };
    let mut out = vec![0.0f64; src.len()];
    for y in 0..h {
        for x in 0..w {
            let at = if along_x { x } else { y } as isize;
            for c in 0..3 {
                let mut acc = 0.0;
                for (k, t) in taps.iter().enumerate() {
                    let m = mirror(at + k as isize - radius) as usize;
                    let (xx, yy) = if along_x { (m, y) } else { (x, m) };
                    acc += t * src[3 * (yy * w + xx) + c];
                }
                out[3 * (y * w + x) + c] = acc;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// An evenly lit background's flat field is 128 over its level in every channel, to
    /// the borders (the mirror keeps the weights whole); a step is blurred over about 4σ,
    /// and a black pixel is clamped at one grey level.
    #[test]
    fn the_flat_field_is_128_over_the_blurred_light() {
        let (w, h) = (21, 13);
        let even: Vec<u8> = (0..w * h * 3).map(|i| [64, 128, 200][i % 3]).collect();
        let f = flat_field(&Rgb::new(w, h, &even).unwrap());
        for (i, v) in f.iter().enumerate() {
            let want = 128.0 / [64.0, 128.0, 200.0][i % 3];
            assert!((v - want).abs() < 1e-5, "{i}: {v}");
        }
        // Left half dark (32), right half bright (160), every channel.
        let step: Vec<u8> = (0..w * h * 3)
            .map(|i| if (i / 3) % w < 10 { 32 } else { 160 })
            .collect();
        let f = flat_field(&Rgb::new(w, h, &step).unwrap());
        let at = |x: usize| 128.0 / f[3 * (6 * w + x)];
        assert!((at(0) - 32.0).abs() < 0.5, "{}", at(0));
        assert!((at(20) - 160.0).abs() < 0.5, "{}", at(20));
        assert!(at(8) > 40.0 && at(8) < 96.0 && at(11) > 96.0 && at(11) < 152.0);
        let black = vec![0u8; w * h * 3];
        assert!(
            flat_field(&Rgb::new(w, h, &black).unwrap())
                .iter()
                .all(|v| *v == 128.0)
        );
    }
}
