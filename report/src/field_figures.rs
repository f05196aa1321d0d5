//! The thesis's field pictures in the report: for chosen steps of a block, the displacement
//! field as a colour-vector map with arrows (Fig. 4-7, 4-11) beside its magnitude map
//! (Fig. 6-11, 6-16), the contact outline, a title with the step and its load, and labelled
//! scales (px and mm, arrow magnification). For a rotation block the field is the twist.
//!
//! Each figure is one SVG: the two maps as embedded PNGs (rendered here with
//! `tracking::field::picture`) and the text as SVG text, so no font is needed to draw it.

use std::fmt::Write as _;
use std::fs;

use base64::Engine as _;
use tracking::field::picture::{Quiver, colour_image, quiver_rgb, upscale};
use tracking::field::{DenseGrid, Interpolator, MarkerField};

use super::html::esc;
use super::out::{Out, werr};
use super::results::{Block, BlockStep, Kind};
use super::{ReportError, RunData};

/// Grid step of the dense maps, px (upscaled back to the frame for display).
const GRID_STEP_PX: usize = 2;

/// The loading steps pictured: about a third, two thirds and all of the block's largest
/// load (the thesis shows a field at a few loads, not every one).
fn chosen(b: &Block) -> Vec<&BlockStep> {
    let loading: Vec<&BlockStep> = b.steps.iter().filter(|s| !s.unloading).collect();
    let n = loading.len();
    if n == 0 {
        return Vec::new();
    }
    let mut picks: Vec<usize> = [n / 3, 2 * n / 3, n - 1]
        .into_iter()
        .map(|k| k.min(n - 1))
        .collect();
    picks.dedup();
    picks.into_iter().map(|k| loading[k]).collect()
}

/// The block's field figures, written into the report folder; their file names.
pub(super) fn figures(data: &RunData, b: &Block, out: &Out) -> Result<Vec<String>, ReportError> {
    let Some((w, h)) = data.frame_size else {
        return Ok(Vec::new());
    };
    let mm_per_px = sensing::sensor::run_mm_per_px(data);
    let mut names = Vec::new();
    let mut interpolator: Option<Interpolator> = None;
    for s in chosen(b) {
        let Some(frame) = data.last_frame_of(s.step) else {
            continue;
        };
        let Some(field) = sensing::run_data::frame_field(data, frame) else {
            continue;
        };
        let interp = interpolator.get_or_insert_with(|| {
            Interpolator::new(
                &field.reference_px,
                DenseGrid::over_frame(w, h, GRID_STEP_PX as f64),
            )
        });
        let contact = data
            .contact
            .iter()
            .find(|c| c.frame == frame)
            .and_then(|c| {
                let (cx, cy) = (c.cx_px?, c.cy_px?);
                (c.radius_px > 0.0).then(|| circle([cx, cy], c.radius_px))
            });
        let svg = figure(&field, interp, (w, h), contact.as_deref(), mm_per_px, b, s)
            .map_err(werr(&out.dir))?;
        let name = format!("field_{}_step{}.svg", b.kind.name(), s.step);
        let p = out.dir.join(&name);
        fs::write(&p, svg).map_err(|e| werr(&p)(e.to_string()))?;
        names.push(name);
    }
    Ok(names)
}

/// A polygon of 48 points on the circle of radius `r` about `c`, px.
fn circle(c: [f64; 2], r: f64) -> Vec<[f64; 2]> {
    (0..48)
        .map(|k| {
            let a = k as f64 / 48.0 * std::f64::consts::TAU;
            [c[0] + r * a.cos(), c[1] + r * a.sin()]
        })
        .collect()
}

/// The largest measured displacement, px.
fn largest(field: &MarkerField) -> f64 {
    field
        .measured_ids()
        .map(|i| field.displacement_px[i][0].hypot(field.displacement_px[i][1]))
        .fold(0.0, f64::max)
}

/// Viridis-like ramp (dark blue → green → yellow) for the magnitude map.
fn ramp(t: f64) -> [u8; 3] {
    use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};
    let c = ViridisRGB.get_color(t.clamp(0.0, 1.0));
    [c.0, c.1, c.2]
}

fn png_data_uri(rgb: &[u8], w: u32, h: u32) -> Result<String, String> {
    use image::ImageEncoder as _;
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(rgb, w, h, image::ExtendedColorType::Rgb8)
        .map_err(|e| e.to_string())?;
    Ok(format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    ))
}

/// One step's figure as SVG.
fn figure(
    field: &MarkerField,
    interp: &Interpolator,
    (w, h): (usize, usize),
    contact: Option<&[[f64; 2]]>,
    mm_per_px: Option<f64>,
    b: &Block,
    s: &BlockStep,
) -> Result<String, String> {
    let full = largest(field).max(1e-3);
    let dense = interp.interpolate(field);
    let (gx, gy) = (dense.grid.nx, dense.grid.ny);
    // Colour-vector map, brightest at the largest displacement, arrows over it.
    let colours = colour_image(&dense, full);
    let background = crop(
        &upscale(&colours, gx, gy, GRID_STEP_PX),
        gx * GRID_STEP_PX,
        w,
        h,
    );
    let spacing = super::field_analysis::spacing_px(field);
    let magnify = (0.8 * spacing / full).clamp(1.0, 50.0);
    let q = Quiver {
        frame_px: (w, h),
        zoom: 1.0,
        magnify,
        spacing_px: spacing,
    };
    // The outline is drawn as SVG over the picture (a one-pixel line would vanish at the
    // figure's half scale).
    let (qw, qh, quiver) =
        quiver_rgb(field, &q, Some(&background), None).map_err(|e| e.to_string())?;
    // Magnitude map.
    let mut mag = Vec::with_capacity(gx * gy * 3);
    for u in &dense.displacement_px {
        mag.extend(ramp((u[0] as f64).hypot(u[1] as f64) / full));
    }
    let mag = crop(
        &upscale(&mag, gx, gy, GRID_STEP_PX),
        gx * GRID_STEP_PX,
        w,
        h,
    );
    let left = png_data_uri(&quiver, qw, qh)?;
    let right = png_data_uri(&mag, w as u32, h as u32)?;
    // Layout: two panels at half size, a title above, scales below.
    let (pw, ph) = (w as f64 / 2.0, h as f64 / 2.0);
    let (width, height) = (2.0 * pw + 90.0, ph + 110.0);
    let load = match b.kind {
        Kind::Normal => format!("depth {} {}", trim(s.load), b.unit),
        Kind::Shear => format!("shear offset {} {}", trim(s.load), b.unit),
        Kind::Rotation => format!("angle {} {}", trim(s.load), b.unit),
    };
    let title = format!(
        "step {} — {load}, {} {} {} ({})",
        s.step,
        match b.kind {
            Kind::Rotation => "Tz",
            Kind::Shear => "shear force",
            Kind::Normal => "Fz",
        },
        trim(s.force),
        b.kind.force_unit(),
        match b.kind {
            Kind::Rotation => "twist field",
            _ => "displacement field",
        }
    );
    let in_mm = |px: f64| mm_per_px.map_or(String::new(), |k| format!(" = {} mm", trim(px * k)));
    let mut svg = String::new();
    let _ = write!(
        svg,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="12">
<rect width="100%" height="100%" fill="white"/>
<text x="10" y="20" font-size="15">{title}</text>
<text x="10" y="40">hue = direction, brightness = magnitude; arrows ×{mag_x}</text>
<text x="{rx}" y="40">displacement magnitude</text>
<image x="10" y="48" width="{pw}" height="{ph}" href="{left}"/>
<image x="{rx}" y="48" width="{pw}" height="{ph}" href="{right}"/>
"##,
        title = esc(&title),
        mag_x = trim(magnify),
        rx = pw + 20.0,
        pw = pw,
        ph = ph,
    );
    if let Some(outline) = contact {
        for x0 in [10.0, pw + 20.0] {
            let points: String = outline
                .iter()
                .map(|p| format!("{:.1},{:.1} ", x0 + p[0] / 2.0, 48.0 + p[1] / 2.0))
                .collect();
            let _ = writeln!(
                svg,
                r#"<polygon points="{points}" fill="none" stroke="rgb(230,0,200)" stroke-width="1.5" stroke-dasharray="4 3"/>"#
            );
        }
    }
    // The arrow scale: the quiver's bar is one marker spacing of displacement, magnified.
    let _ = writeln!(
        svg,
        r#"<text x="10" y="{y}">arrow bar (bottom left): {} px of displacement{}</text>"#,
        trim(spacing),
        in_mm(spacing),
        y = ph + 66.0
    );
    if contact.is_some() {
        let _ = writeln!(
            svg,
            r#"<text x="10" y="{}">contact region (from the image): dashed magenta</text>"#,
            ph + 84.0
        );
    }
    // Colour bar of the magnitude map, 0 … largest, in px and mm.
    let (bx, by, bw) = (pw + 20.0, ph + 56.0, pw);
    for k in 0..64 {
        let c = ramp(k as f64 / 63.0);
        let _ = writeln!(
            svg,
            r#"<rect x="{:.2}" y="{by}" width="{:.2}" height="10" fill="rgb({},{},{})"/>"#,
            bx + bw * k as f64 / 64.0,
            bw / 64.0 + 0.5,
            c[0],
            c[1],
            c[2]
        );
    }
    let _ = writeln!(
        svg,
        r#"<text x="{bx}" y="{}">0</text><text x="{}" y="{}" text-anchor="end">{} px{}</text>"#,
        by + 24.0,
        bx + bw,
        by + 24.0,
        trim(full),
        in_mm(full)
    );
    svg.push_str("</svg>\n");
    Ok(svg)
}

/// The top-left `w × h` of an RGB8 image `stride` px wide (the upscaled grid may overhang
/// the frame by a pixel).
fn crop(rgb: &[u8], stride: usize, w: usize, h: usize) -> Vec<u8> {
    let rows = rgb.len() / (3 * stride.max(1));
    let mut out = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        let yy = y.min(rows.saturating_sub(1));
        for x in 0..w {
            let xx = x.min(stride.saturating_sub(1));
            let i = (yy * stride + xx) * 3;
            out.extend_from_slice(rgb.get(i..i + 3).unwrap_or(&[0, 0, 0]));
        }
    }
    out
}

/// A number with 3 significant digits and no float noise.
fn trim(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    let d = (2.0 - v.abs().max(1e-12).log10().floor()).clamp(0.0, 6.0) as usize;
    let s = format!("{v:.d$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_shown_without_noise() {
        assert_eq!(trim(0.30000000000000004), "0.3");
        assert_eq!(trim(24.537), "24.5");
        assert_eq!(trim(0.0125), "0.0125");
    }
}
