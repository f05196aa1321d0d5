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
