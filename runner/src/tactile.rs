//! The live tactile path: every frame of a `record` block with frames goes through the
//! tracker (markers, identities, contact region) and the grasp's slip monitor
//! ([`analysis::tactile`]); the result is a row of `tactile.csv`, the slip state in the
//! progress line, and what a move's `until: {slip: …}` stops on.
//!
//! The first frame of each record block is the reference (the grip has not closed yet:
//! the gel is untouched); the pressing field is taken at the first frame after each grip
//! (an approach, or a move of the grip axis that ends in contact, such as a regrip).

use std::time::Instant;

use analysis::tactile::{SlipState, TactileFrame, TactileMonitor, TactileParams};
use rig::{Frame, SimTruth};
use tracking::field::MarkerField;
use tracking::{ContactParams, Method, Pipeline, RgbView, TrackParams};

use rundir::write::TactileRow;

/// One record block's tactile state.
pub(super) struct LiveTactile {
    pipeline: Option<Pipeline>,
    monitor: TactileMonitor,
    last: Option<TactileFrame>,
    /// The pressing field is to be taken at the next frame.
    pending_pressing: bool,
    mm_per_px: Option<f64>,
    /// Why tracking stopped in this block, if it did.
    failed: Option<String>,
    /// The failure was handed out.
    reported: bool,
    /// The GelSight's force, when the protocol records it: the calibrated reader, matched
    /// to this block's reference at its first tracked frame.
    gelsight: Option<sensing::sensor::live::LiveReader>,
    /// Why the GelSight's force cannot be read in this block, until handed out.
    gelsight_error: Option<String>,
    /// The live view watches: keep the last frame's arrows and contact outline for it.
    pub(super) want_overlay: bool,
    overlay: Option<liveview::Overlay>,
}

impl LiveTactile {
    pub(super) fn new(
        mm_per_px: Option<f64>,
        sensor: Option<&sensing::sensor::SensorFile>,
    ) -> Self {
        Self {
            gelsight: sensor.map(sensing::sensor::live::LiveReader::new),
            gelsight_error: None,
            pipeline: None,
            monitor: TactileMonitor::new(TactileParams::default()),
            last: None,
            pending_pressing: false,
            mm_per_px,
            failed: None,
            reported: false,
            want_overlay: false,
            overlay: None,
        }
    }

    /// The arrows and contact outline of frame `index`, when it was the last tracked.
    pub(super) fn overlay(&self, index: u64) -> Option<liveview::Overlay> {
        self.overlay.as_ref().filter(|o| o.index == index).cloned()
    }

    /// Why tracking stopped in this block, the first time it is asked after it did.
    pub(super) fn new_failure(&mut self) -> Option<&str> {
        if self.reported {
            return None;
        }
        self.reported = self.failed.is_some();
        self.failed.as_deref()
    }

    /// Why the GelSight's force is not read in this block, once.
    pub(super) fn gelsight_failure(&mut self) -> Option<String> {
        self.gelsight_error.take()
    }

    /// The GelSight's wrench of this frame with the protocol's sensor file, if any; `seen`
    /// the image's contact region (centroid, equivalent radius, px).
    fn gelsight_wrench(
        &mut self,
        field: &MarkerField,
        seen: Option<sensing::sensor::history::Region>,
        t_ns: u64,
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let reader = self.gelsight.as_mut()?;
        match reader.read_field(field, seen, t_ns) {
            Ok(w) => Some((w.value, w.sd)),
            Err(e) => {
                self.gelsight_error = Some(format!(
                    "the GelSight's force is not read in this record block: {e}"
                ));
                self.gelsight = None;
                None
            }
        }
    }

    /// The grip has closed (or re-closed): the next frame's field is the pressing field.
    pub(super) fn gripped(&mut self) {
        self.pending_pressing = true;
    }

    /// The grip has opened: the next grip starts afresh.
    pub(super) fn released(&mut self) {
        self.monitor.release();
        self.pending_pressing = false;
    }

    /// The slip state of the last frame (stick before any).
    pub(super) fn state(&self) -> SlipState {
        self.last.map(|t| t.state).unwrap_or(SlipState::Stick)
    }

    /// Tracks `frame` and judges it. `None` for the reference frame, or once tracking has
    /// failed in this block (the reason is in [`Self::failed`]).
    pub(super) fn frame(
        &mut self,
        frame: &Frame,
        index: u64,
        step: u32,
        trial: u32,
        truth: Option<&SimTruth>,
    ) -> Option<TactileRow> {
        if self.failed.is_some() {
            return None;
        }
        let started = Instant::now();
        let view = match RgbView::new(frame.width as usize, frame.height as usize, &frame.rgb) {
            Ok(v) => v,
            Err(e) => {
                self.failed = Some(e.to_string());
                return None;
            }
        };
        let Some(pipeline) = self.pipeline.as_mut() else {
            let made =
                Pipeline::new(view, &TrackParams::default(), Method::Centroid).and_then(|mut p| {
                    p.enable_contact(view, ContactParams::default())?;
                    Ok(p)
                });
            match made {
                Ok(p) => self.pipeline = Some(p),
                Err(e) => self.failed = Some(format!("reference frame {index}: {e}")),
            }
            return None;
        };
        if let Err(e) = pipeline.track(view) {
            self.failed = Some(format!("frame {index}: {e}"));
            return None;
        }
        let field = MarkerField::from_tracker(pipeline.tracker());
        let contact = pipeline
            .contact()
            .map(|c| (c.outline_px.as_slice(), c.area_px2));
        if self.want_overlay {
            let outline = pipeline
                .contact()
                .map(|c| c.outline_px.as_slice())
                .unwrap_or_default();
            self.overlay = Some(liveview::overlay::from_field(index, &field, outline));
        }
        if self.pending_pressing {
            self.monitor.set_pressing(&field, contact);
            self.pending_pressing = false;
        }
        let region = pipeline
            .contact()
            .map(|c| sensing::sensor::history::Region {
                centroid_px: c.centroid_px,
                radius_px: c.radius_px,
                second_moments_px2: Some(c.second_moments_px2),
            });
        let t = self.monitor.update(&field, contact);
        // The GelSight's force reads the interior field (`sensing::sensor::live`).
        let gelsight = if self.gelsight.is_some() {
            let interior = MarkerField::interior_from_tracker(pipeline.tracker());
            self.gelsight_wrench(&interior, region, frame.t_ns)
        } else {
            None
        };
        let pick = |sd: bool, i: usize| {
            gelsight
                .as_ref()
                .and_then(|(v, s)| if sd { s.get(i) } else { v.get(i) })
                .map(|v| (v * 1e4).round() / 1e4)
        };
        let (gw, gs) = (|i| pick(false, i), |i| pick(true, i));
        self.last = Some(t);
        let ms = started.elapsed().as_secs_f64() * 1e3;
        let g = truth.and_then(|t| t.grasp);
        let r4 = |v: f64| (v * 1e4).round() / 1e4 + 0.0;
        Some(TactileRow {
            frame: index,
            t_ns: frame.t_ns,
            step,
            trial,
            state: t.state.as_str().into(),
            gripping: self.monitor.gripping(),
            stuck_fraction: r4(t.stuck_fraction),
            shear_x_px: r4(t.shear_px[0]),
            shear_y_px: r4(t.shear_px[1]),
            rotation_deg: r4(t.rotation_deg),
            differential_px: r4(t.differential_px),
            total_px: r4(t.total_px),
            contact_markers: t.contact_markers as u32,
            contact_area_mm2: self.mm_per_px.map(|s| r4(t.contact_area_px2 * s * s)),
            area_ratio: r4(t.area_ratio),
            ms: r4(ms),
            true_stick_fraction: g.map(|g| r4(g.gel_stick_fraction)),
            true_twist_stick_fraction: g.map(|g| r4(g.gel_twist_stick_fraction)),
            true_margin: g.map(|g| r4(g.gel_margin)),
            true_twist_margin: g.map(|g| r4(g.gel_twist_margin)),
            true_slip_mm_s: g.map(|g| r4(g.slip_mm_s)),
            true_height_mm: g.map(|g| r4(g.height_mm)),
            true_sliding: g.map(|g| g.sliding),
            true_rotating: g.map(|g| g.rotating),
            true_on_table: g.map(|g| g.on_table),
            gelsight_fx_n: gw(0),
            gelsight_fy_n: gw(1),
            gelsight_fz_n: gw(2),
            gelsight_tz_nmm: gw(3),
            gelsight_fx_sd_n: gs(0),
            gelsight_fy_sd_n: gs(1),
            gelsight_fz_sd_n: gs(2),
            gelsight_tz_sd_nmm: gs(3),
        })
    }
}
