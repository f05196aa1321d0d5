//! Pictures of a displacement field: the thesis's colour-vector image and quiver plots.
//!
//! Both come back as data (an RGB buffer, an SVG string), never as files: the caller
//! decides where they go. Plots carry no text, so no font library is needed; a scale bar
//! of one marker spacing at the arrows' magnification is drawn instead, and its meaning is
//! stated where the picture is used.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{DenseField, MarkerField};

/// Why a picture could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("could not draw the field picture: {detail}; fix: report this as a bug")]
pub struct PictureError {
    detail: String,
}

fn err(e: impl std::fmt::Display) -> PictureError {
    PictureError {
        detail: e.to_string(),
    }
}

/// HSV (h in turns, s and v in [0, 1]) to RGB bytes.
fn hsv(h: f64, s: f64, v: f64) -> [u8; 3] {
    let h6 = h.rem_euclid(1.0) * 6.0;
    let c = v * s;
    let x = c * (1.0 - (h6 % 2.0 - 1.0).abs());
    let (r, g, b) = match h6 as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r, g, b].map(|ch| ((ch + m) * 255.0).round().clamp(0.0, 255.0) as u8)
}

/// The colour-vector image at grid resolution (`nx × ny`, RGB8): hue is the direction of
/// the displacement (red = +x, then counter-clockwise on screen through yellow, green …),
/// value is its magnitude relative to `full_scale_px` (brighter = larger; ≥ full scale is
/// full brightness). Extrapolated points are drawn at half saturation.
pub fn colour_image(field: &DenseField, full_scale_px: f64) -> Vec<u8> {
    let scale = full_scale_px.max(1e-9);
    let mut out = Vec::with_capacity(field.displacement_px.len() * 3);
    for (u, s) in field.displacement_px.iter().zip(&field.support) {
        let (ux, uy) = (u[0] as f64, u[1] as f64);
        // y points down in images; turn it up so the hue circle reads as on paper.
        let hue = (-uy).atan2(ux) / std::f64::consts::TAU;
        let value = (ux.hypot(uy) / scale).min(1.0);
        let sat = if *s == super::Support::Extrapolated {
            0.5
        } else {
            1.0
        };
        out.extend(hsv(hue, sat, value));
    }
    out
}

/// Scales an RGB8 image by an integer factor (nearest neighbour), for display.
pub fn upscale(rgb: &[u8], width: usize, height: usize, factor: usize) -> Vec<u8> {
    let f = factor.max(1);
    let mut out = Vec::with_capacity(rgb.len() * f * f);
    for y in 0..height * f {
        let row = &rgb[(y / f) * width * 3..][..width * 3];
        for x in 0..width * f {
            out.extend_from_slice(&row[(x / f) * 3..(x / f) * 3 + 3]);
        }
    }
    out
}

/// How a quiver plot is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quiver {
    /// Size of the frame the markers were tracked in, px.
    pub frame_px: (usize, usize),
    /// Picture pixels per frame pixel.
    pub zoom: f64,
    /// Arrow length per displacement pixel.
    pub magnify: f64,
    /// Marker spacing, px (length of the scale bar before magnification).
    pub spacing_px: f64,
}

impl Quiver {
    fn size(&self) -> (u32, u32) {
        (
            (self.frame_px.0 as f64 * self.zoom).round() as u32,
            (self.frame_px.1 as f64 * self.zoom).round() as u32,
        )
    }
}

fn draw<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    field: &MarkerField,
    q: &Quiver,
    on_white: bool,
    contact: Option<&[[f64; 2]]>,
) -> Result<(), PictureError> {
    if on_white {
        area.fill(&WHITE).map_err(err)?;
    }
    let z = q.zoom;
    let px = |p: [f64; 2]| ((p[0] * z).round() as i32, (p[1] * z).round() as i32);
    // Dark arrows on white; light ones over the (mostly dark) colour-vector image.
    let (measured, ink) = if on_white {
        (RGBColor(20, 30, 120), BLACK)
    } else {
        (RGBColor(255, 255, 255), WHITE)
    };
    let inferred = RGBColor(230, 120, 0);
    // The contact outline, dashed magenta, under the arrows.
    if let Some(outline) = contact.filter(|o| o.len() >= 3) {
        let mut ring: Vec<(i32, i32)> = outline.iter().map(|p| px(*p)).collect();
        ring.push(ring[0]);
        let style =
            ShapeStyle::from(&RGBColor(230, 0, 200)).stroke_width((z.round() as u32).max(1));
        for pair in ring.windows(2).step_by(2) {
            area.draw(&PathElement::new(pair.to_vec(), style))
                .map_err(err)?;
        }
    }
    for i in 0..field.len() {
        let r = field.reference_px[i];
        area.draw(&Circle::new(
            px(r),
            (1.5 * z).max(1.0) as i32,
            RGBColor(150, 150, 150).filled(),
        ))
        .map_err(err)?;
        let u = field.displacement_px[i];
        let len = u[0].hypot(u[1]) * q.magnify;
        if len < 0.5 {
            continue;
        }
        let colour = if field.measured[i] {
            measured
        } else {
            inferred
        };
        let tip = [r[0] + u[0] * q.magnify, r[1] + u[1] * q.magnify];
        let style = ShapeStyle::from(&colour).stroke_width((z.round() as u32).max(1));
        area.draw(&PathElement::new(vec![px(r), px(tip)], style))
            .map_err(err)?;
        // Head: two barbs at ±25°, a quarter of the arrow long, at most 4 px.
        let head = (0.25 * len).min(4.0);
        let (dx, dy) = (u[0] / u[0].hypot(u[1]), u[1] / u[0].hypot(u[1]));
        for sign in [-1.0f64, 1.0] {
            let a = sign * 25f64.to_radians();
            let (bx, by) = (dx * a.cos() - dy * a.sin(), dx * a.sin() + dy * a.cos());
            let barb = [tip[0] - head * bx, tip[1] - head * by];
            area.draw(&PathElement::new(vec![px(tip), px(barb)], style))
                .map_err(err)?;
        }
    }
    // Scale bar: one spacing of displacement at this magnification, bottom left.
    let (w, h) = q.size();
    let y = h as i32 - (6.0 * z) as i32;
    let x0 = (6.0 * z) as i32;
    let bar = (q.spacing_px * q.magnify * z).round() as i32;
    area.draw(&PathElement::new(
        vec![(x0, y), (x0 + bar.min(w as i32 - 2 * x0), y)],
        ShapeStyle::from(&ink).stroke_width((2.0 * z).round().max(1.0) as u32),
    ))
    .map_err(err)?;
    Ok(())
}

/// The quiver plot as SVG: grey dots at the reference markers, arrows to their displaced
/// positions (blue measured, orange inferred), and a black bar one spacing long (times the
/// magnification) in the bottom left; the contact outline (px), if given, dashed magenta.
pub fn quiver_svg(
    field: &MarkerField,
    q: &Quiver,
    contact: Option<&[[f64; 2]]>,
) -> Result<String, PictureError> {
    let mut s = String::new();
    {
        let area = SVGBackend::with_string(&mut s, q.size()).into_drawing_area();
        draw(&area, field, q, true, contact)?;
        area.present().map_err(err)?;
    }
    Ok(s)
}

/// The quiver plot as RGB8 pixels of `q`'s size, over `background` (an RGB8 image of the
/// same size, e.g. an upscaled [`colour_image`]; arrows and bar then white) or over white
/// (arrows dark blue, bar black); the contact outline (px), if given, dashed magenta.
pub fn quiver_rgb(
    field: &MarkerField,
    q: &Quiver,
    background: Option<&[u8]>,
    contact: Option<&[[f64; 2]]>,
) -> Result<(u32, u32, Vec<u8>), PictureError> {
    let (w, h) = q.size();
    let n = (w * h * 3) as usize;
    let on_white = background.is_none();
    let mut buf = match background {
        Some(b) if b.len() == n => b.to_vec(),
        Some(b) => {
            return Err(err(format!(
                "background holds {} bytes, the picture needs {n}",
                b.len()
            )));
        }
        None => vec![255u8; n],
    };
    {
        let area = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw(&area, field, q, on_white, contact)?;
        area.present().map_err(err)?;
    }
    Ok((w, h, buf))
}

#[cfg(test)]
mod tests {
    use super::super::{DenseGrid, Support};
    use super::*;

    #[test]
    fn hue_encodes_direction_and_value_magnitude() {
        let field = DenseField {
            grid: DenseGrid::over_frame(4, 1, 1.0),
            displacement_px: vec![[2.0, 0.0], [0.0, -2.0], [-1.0, 0.0], [0.0, 0.0]],
            support: vec![Support::Measured; 4],
        };
        let img = colour_image(&field, 2.0);
        assert_eq!(&img[0..3], &[255, 0, 0], "+x is red at full scale");
        // Up on screen (−y in the image) is a quarter turn: between green and cyan.
        assert_eq!(&img[3..6], &[128, 255, 0], "+90° on the hue circle");
        assert_eq!(&img[6..9], &[0, 128, 128], "−x at half scale is dim cyan");
        assert_eq!(&img[9..12], &[0, 0, 0], "no displacement is black");
    }

    #[test]
    fn quiver_draws_arrows_where_markers_moved() {
        let field = MarkerField {
            reference_px: vec![[20.0, 20.0], [60.0, 20.0]],
            displacement_px: vec![[10.0, 0.0], [0.0, 0.0]],
            measured: vec![true, false],
        };
        let q = Quiver {
            frame_px: (80, 40),
            zoom: 2.0,
            magnify: 1.0,
            spacing_px: 10.0,
        };
        let (w, h, rgb) = quiver_rgb(&field, &q, None, None).expect("draws");
        assert_eq!((w, h), (160, 80));
        // A pixel on the first arrow's shaft is dark blue; the still marker draws no arrow.
        let at = |x: usize, y: usize| &rgb[(y * w as usize + x) * 3..][..3];
        assert_eq!(at(50, 40), &[20, 30, 120]);
        assert!(rgb.chunks(3).all(|p| p != [230, 120, 0]));
        let svg = quiver_svg(&field, &q, None).expect("draws");
        assert!(svg.starts_with("<svg") && svg.contains("polyline"));
        assert!(
            !rgb.chunks(3).any(|p| p == [230, 0, 200]),
            "no contact, no outline"
        );
        let ring: Vec<[f64; 2]> = (0..36)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 36.0;
                [40.0 + 12.0 * a.cos(), 20.0 + 12.0 * a.sin()]
            })
            .collect();
        let (_, _, rgb) = quiver_rgb(&field, &q, None, Some(&ring)).expect("draws");
        let magenta = rgb.chunks(3).filter(|p| *p == [230, 0, 200]).count();
        assert!(magenta > 50, "the outline is drawn ({magenta} px)");
        let svg = quiver_svg(&field, &q, Some(&ring)).expect("draws");
        assert!(
            svg.contains("#E600C8") || svg.to_lowercase().contains("e600c8"),
            "{svg}"
        );
    }
}
