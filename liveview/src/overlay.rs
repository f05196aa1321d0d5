//! The latest frame as the page draws it: the PNG, and its marker arrows and contact
//! outline. The grasp's live tracking hands its own overlay to the board; for other runs
//! the server tracks the latest frame against the run's first one when the page asks (and
//! only then: a run nobody watches tracks nothing), once per frame.

use tracking::field::MarkerField;
use tracking::{ContactParams, Method, Pipeline, RgbView, TrackParams};

use crate::board::{FrameImage, Overlay};

/// The frame as PNG bytes.
pub(crate) fn png(frame: &FrameImage) -> Result<Vec<u8>, String> {
    let mut out = std::io::Cursor::new(Vec::new());
    image::write_buffer_with_format(
        &mut out,
        &frame.rgb,
        frame.width,
        frame.height,
        image::ExtendedColorType::Rgb8,
        image::ImageFormat::Png,
    )
    .map_err(|e| format!("encoding frame {}: {e}", frame.index))?;
    Ok(out.into_inner())
}

/// The marker field of `frame` against `reference`, tracked in one jump (markers found in
/// both, identities from the reference's lattice), and the contact region.
pub(crate) fn track(reference: &FrameImage, frame: &FrameImage) -> Overlay {
    let mut overlay = Overlay {
        index: frame.index,
        ..Overlay::default()
    };
    let result = (|| {
        let rv = RgbView::new(
            reference.width as usize,
            reference.height as usize,
            &reference.rgb,
        )?;
        let fv = RgbView::new(frame.width as usize, frame.height as usize, &frame.rgb)?;
        let mut p = Pipeline::new(rv, &TrackParams::default(), Method::Centroid)?;
        p.enable_contact(rv, ContactParams::default())?;
        p.track(fv)?;
        Ok::<_, tracking::TrackError>(p)
    })();
    match result {
        Ok(p) => {
            let field = MarkerField::from_tracker(p.tracker());
            let outline = p
                .contact()
                .map(|c| c.outline_px.clone())
                .unwrap_or_default();
            overlay = from_field(frame.index, &field, &outline);
            if overlay.arrows.is_empty() {
                overlay.note = Some("no marker was tracked in this frame".into());
            }
        }
        Err(e) => overlay.note = Some(format!("markers not tracked: {e}")),
    }
    overlay
}

/// The overlay of a field measured elsewhere (the grasp's live tracking).
pub fn from_field(index: u64, field: &MarkerField, outline_px: &[[f64; 2]]) -> Overlay {
    let q = |v: f64| (v * 100.0).round() / 100.0;
    Overlay {
        index,
        arrows: field
            .reference_px
            .iter()
            .zip(&field.displacement_px)
            .zip(&field.measured)
            .filter(|(_, m)| **m)
            .map(|((r, d), _)| [q(r[0]), q(r[1]), q(d[0]), q(d[1])])
            .collect(),
        outline: outline_px.to_vec(),
        note: None,
    }
}
