//! What a calibration saw, and what a reading outside it is worth.
//!
//! A linear map from field to wrench fitted on some contacts reads others with an error its
//! own residual scale does not know: read by a sensor calibrated on a flat punch and a sphere,
//! the lifting can's squeeze came out 21 % low (scale fit) to 2.2× (moments on every
//! feature) while its stated uncertainty was a tenth of the error. The calibration records
//! what it saw ([`Envelope`]): the contact regions' sizes, elongations and places, the
//! fields' features, and the gel pad's extent. Each frame is judged against it
//! ([`Envelope::judge`]) and its uncertainty widened by what the calibration measured about
//! such frames ([`widen`]):
//!
//! - a contact of another **shape, size or place**, or a **field** beyond the calibration's,
//!   adds the error the calibration measured on indenters it left out of its own fit
//!   (`unseen_shape`: absolute, or relative to the reading, whichever is larger), or — where
//!   it could leave none out — a stated quarter of the reading;
//! - a contact that **leaves the view** adds the share of it the view does not see, as a
//!   share of the reading (the field inside the view cannot tell what the load beyond it is);
//! - a reading **beyond the calibrated load range** adds the unseen-shape relative error
//!   again (the linear map extrapolating).
//!
//! One of them is also a correction, where the geometry tells it: a contact elongated along
//! the view from one edge to the other (a can or a bar across the pad) runs on to the pad's
//! edge, as the indenter is longer than the pad; the view sees `L_view / L_pad` of it, and the
//! forces are read divided by that share. The assumption is the pad's: it is stated in the
//! sensor file (`envelope.pad_mm`), and a frame read so says `view_edge` among its reasons.

use super::file::{ContactRange, Envelope, UnseenShape, View};
use super::history::Region;

/// Why a frame is outside the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outside {
    /// The contact is more (or less) elongated than any the calibration saw.
    Shape,
    /// The contact is larger or smaller than any the calibration saw.
    Size,
    /// The contact lies farther from the view's centre than any the calibration saw.
    Place,
    /// The contact runs out of the view.
    ViewEdge,
    /// A feature of the field lies beyond the calibration's range.
    Field,
    /// The reading lies beyond the calibrated load range.
    Load,
}

impl Outside {
    /// The name written to `wrench.csv`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Shape => "shape",
            Self::Size => "size",
            Self::Place => "place",
            Self::ViewEdge => "view_edge",
            Self::Field => "field",
            Self::Load => "load",
        }
    }
}

/// A frame judged against the calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Judgement {
    /// Why it is outside (empty: inside).
    pub outside: Vec<Outside>,
    /// The share of the contact the view sees (1 where it is whole in view, or there is none).
    pub in_view: f64,
    /// Whether `in_view` is a correction the geometry supports (a contact across the view
    /// running on to the pad's edge), not only an uncertainty.
    pub corrected: bool,
}

impl Judgement {
    /// The reasons, `;`-separated (empty inside the calibration).
    pub fn reasons(&self) -> String {
        self.outside
            .iter()
            .map(|o| o.as_str())
            .collect::<Vec<_>>()
            .join(";")
    }
}

/// Sizes, elongations and places are judged with this much room beyond the calibration's
/// own (a fifth: the region's edge is found within a few per cent).
const ROOM: f64 = 1.2;
/// And places with this much, mm.
const PLACE_ROOM_MM: f64 = 1.0;
/// A feature may lie this share of its calibrated span beyond it.
const FIELD_ROOM: f64 = 0.1;
/// A contact across the view is one at least this elongated.
const STRIP: f64 = 2.0;
/// The share of a reading an unseen contact is taken to move where the calibration could
/// not measure it (every run pressed one indenter): stated, not measured.
pub const UNKNOWN_SHAPE_SHARE: f64 = 0.25;

/// A region's moment ellipse: centre, semi-axes (major, minor) and the major axis's angle,
/// px. A uniform ellipse of semi-axes a, b has second moments a²/4, b²/4.
fn ellipse(r: &Region) -> ([f64; 2], f64, f64, f64) {
    let [sxx, syy, sxy] = r.second_moments_px2.unwrap_or([
        r.radius_px * r.radius_px / 4.0,
        r.radius_px * r.radius_px / 4.0,
        0.0,
    ]);
    let (l1, l2, theta) = analysis::force_sensor::traction::moment_axes([sxx, syy, sxy]);
    (
        r.centroid_px,
        2.0 * l1.max(0.0).sqrt(),
        2.0 * l2.max(0.0).sqrt(),
        theta,
    )
}

/// The angle of a region's major axis.
fn theta_of(r: &Region) -> f64 {
    ellipse(r).3
}

/// Length of the line through `c` along `dir` inside the rectangle centred on `centre` of
/// half-sizes `half`, px.
fn chord(c: [f64; 2], dir: [f64; 2], centre: [f64; 2], half: [f64; 2]) -> f64 {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..2 {
        let (p, d) = (c[a] - centre[a], dir[a]);
        if d.abs() < 1e-12 {
            if p.abs() > half[a] {
                return 0.0;
            }
            continue;
        }
        let (t1, t2) = ((-half[a] - p) / d, (half[a] - p) / d);
        lo = lo.max(t1.min(t2));
        hi = hi.min(t1.max(t2));
    }
    (hi - lo).max(0.0)
}

impl Envelope {
    /// What the calibration's frames show: each frame's features and contact region.
    pub(super) fn of<'a>(
        frames: impl IntoIterator<Item = (&'a [f64], Option<&'a Region>)>,
        view: &View,
        pad_mm: Option<[f64; 2]>,
    ) -> Self {
        let frames: Vec<(&[f64], Option<&Region>)> = frames.into_iter().collect();
        let p = frames.first().map_or(0, |f| f.0.len());
        let features = (0..p)
            .map(|j| {
                frames
                    .iter()
                    .filter_map(|f| f.0.get(j).copied())
                    .filter(|v| v.is_finite())
                    .fold([f64::INFINITY, f64::NEG_INFINITY], |r, v| {
                        [r[0].min(v), r[1].max(v)]
                    })
            })
            .collect();
        let s = view.mm_per_px;
        let centre = [
            view.width_px as f64 / 2.0 - 0.5,
            view.height_px as f64 / 2.0 - 0.5,
        ];
        let regions: Vec<&Region> = frames.iter().filter_map(|f| f.1).collect();
        let contact = (!regions.is_empty()).then(|| {
            let mut c = ContactRange {
                radius_mm: [f64::INFINITY, f64::NEG_INFINITY],
                elongation: [f64::INFINITY, f64::NEG_INFINITY],
                offset_mm: 0.0,
                across_view: false,
            };
            let half_view = [view.width_px as f64 / 2.0, view.height_px as f64 / 2.0];
            for r in regions {
                let (at, a, b, _) = ellipse(r);
                let e = a / b.max(1e-9);
                let radius = r.radius_px * s;
                c.radius_mm = [c.radius_mm[0].min(radius), c.radius_mm[1].max(radius)];
                c.elongation = [c.elongation[0].min(e), c.elongation[1].max(e)];
                let off = (at[0] - centre[0]).hypot(at[1] - centre[1]) * s;
                c.offset_mm = c.offset_mm.max(off);
                let (_, strip) = view_share(at, a, b, theta_of(r), centre, half_view);
                c.across_view |= strip && e >= STRIP;
            }
            c
        });
        Self {
            contact,
            features,
            pad_mm,
        }
    }

    /// Judges a frame's contact `region` and `features` against what the calibration saw.
    pub fn judge(&self, region: Option<&Region>, features: &[f64], view: &View) -> Judgement {
        let mut outside = Vec::new();
        for (v, r) in features.iter().zip(&self.features) {
            let room = FIELD_ROOM * (r[1] - r[0]).abs();
            if v.is_finite() && (*v < r[0] - room || *v > r[1] + room) {
                outside.push(Outside::Field);
                break;
            }
        }
        let (mut in_view, mut corrected) = (1.0, false);
        if let Some(r) = region {
            let s = view.mm_per_px;
            let centre = [
                view.width_px as f64 / 2.0 - 0.5,
                view.height_px as f64 / 2.0 - 0.5,
            ];
            let (at, a, b, theta) = ellipse(r);
            let e = a / b.max(1e-9);
            if let Some(c) = &self.contact {
                if e > c.elongation[1] * ROOM || e < c.elongation[0] / ROOM {
                    outside.push(Outside::Shape);
                }
                let radius = r.radius_px * s;
                if radius > c.radius_mm[1] * ROOM || radius < c.radius_mm[0] / ROOM {
                    outside.push(Outside::Size);
                }
                let off = (at[0] - centre[0]).hypot(at[1] - centre[1]) * s;
                if off > c.offset_mm + PLACE_ROOM_MM {
                    outside.push(Outside::Place);
                }
            }
            let half_view = [view.width_px as f64 / 2.0, view.height_px as f64 / 2.0];
            let (share, strip) = view_share(at, a, b, theta, centre, half_view);
            let learnt = self.contact.is_some_and(|c| c.across_view) && strip && e >= STRIP;
            if share < 0.999 && !learnt {
                outside.push(Outside::ViewEdge);
                in_view = share;
                // Across the view from edge to edge: it runs on to the pad's edge.
                if strip
                    && e >= STRIP
                    && let Some(pad) = self.pad_mm
                {
                    let dir = [theta.cos(), theta.sin()];
                    let half_pad = [pad[0] / s / 2.0, pad[1] / s / 2.0];
                    let seen = chord(at, dir, centre, half_view);
                    let whole = chord(at, dir, centre, half_pad).max(seen);
                    if whole > 0.0 {
                        in_view = seen / whole;
                        corrected = true;
                    }
                }
            }
        }
        Judgement {
            outside,
            in_view,
            corrected,
        }
    }
}

/// The share of the moment ellipse inside the view, and whether the ellipse runs out of
/// the view at both ends of its major axis (a contact across the view).
fn view_share(
    at: [f64; 2],
    a: f64,
    b: f64,
    theta: f64,
    centre: [f64; 2],
    half: [f64; 2],
) -> (f64, bool) {
    let (c, s) = (theta.cos(), theta.sin());
    let inside =
        |p: [f64; 2]| (p[0] - centre[0]).abs() <= half[0] && (p[1] - centre[1]).abs() <= half[1];
    let end = |t: f64| [at[0] + t * a * c, at[1] + t * a * s];
    let strip = !inside(end(1.0)) && !inside(end(-1.0));
    // Sample the ellipse on a polar grid of equal areas.
    let (n_r, n_t) = (12, 48);
    let (mut hit, mut all) = (0usize, 0usize);
    for i in 0..n_r {
        let rho = ((i as f64 + 0.5) / n_r as f64).sqrt();
        for k in 0..n_t {
            let phi = std::f64::consts::TAU * k as f64 / n_t as f64;
            let (u, v) = (rho * a * phi.cos(), rho * b * phi.sin());
            let p = [at[0] + u * c - v * s, at[1] + u * s + v * c];
            all += 1;
            hit += usize::from(inside(p));
        }
    }
    (hit as f64 / all.max(1) as f64, strip)
}

/// Corrects a reading's forces for the part of the contact beyond the view, where the
/// judgement's geometry supports it ([`Judgement::corrected`]).
pub fn correct(value: &mut [f64], judgement: &Judgement) {
    if judgement.corrected && judgement.in_view > 0.0 {
        // Forces integrate the tractions over the contact: the part beyond the view is
        // read at the seen part's rate. The torque's arm is not known beyond the view.
        for v in value.iter_mut().take(3) {
            *v /= judgement.in_view;
        }
    }
}

/// Widens a reading's standard uncertainty per channel by what its judgement says the
/// calibration does not know: `value` and `sd` as read (corrected), `ranges` the calibrated
/// ranges per channel, `unseen` the calibration's unseen-shape error. A reading beyond the
/// calibrated range adds [`Outside::Load`] to the judgement.
pub fn widen(
    value: &[f64],
    sd: &mut [f64],
    judgement: &mut Judgement,
    unseen: Option<&UnseenShape>,
    ranges: &std::collections::BTreeMap<String, [f64; 2]>,
) {
    const NAMES: [&str; 4] = ["fx_n", "fy_n", "fz_n", "tz_nmm"];
    let unlike = judgement.outside.iter().any(|o| {
        matches!(
            o,
            Outside::Shape | Outside::Size | Outside::Place | Outside::Field
        )
    });
    for (c, name) in NAMES.iter().enumerate() {
        let (Some(v), Some(u)) = (value.get(c).copied(), sd.get(c).copied()) else {
            continue;
        };
        let span = ranges.get(*name).map_or(0.0, |r| r[1] - r[0]);
        let magnitude = v.abs();
        // What an unseen contact moves this reading by: the calibration's own measure (its
        // absolute error as a floor where `floor`), or a stated share without one.
        let shape_share = |floor: bool| -> f64 {
            match unseen {
                Some(us) => {
                    let abs = us.channels.get(*name).map_or(0.0, |s| s.rmse);
                    let rel = us.relative.get(*name).copied().unwrap_or(0.0);
                    if floor {
                        abs.max(rel * magnitude)
                    } else {
                        rel * magnitude
                    }
                }
                None => UNKNOWN_SHAPE_SHARE * magnitude.max(0.1 * span),
            }
        };
        let mut var = u * u;
        if unlike {
            var += shape_share(true).powi(2);
        }
        if judgement.outside.contains(&Outside::ViewEdge) {
            var += ((1.0 - judgement.in_view) * magnitude).powi(2);
        }
        if let Some(r) = ranges.get(*name) {
            let room = 0.1 * (r[1] - r[0]);
            if v > r[1] + room || v < r[0] - room {
                if !judgement.outside.contains(&Outside::Load) {
                    judgement.outside.push(Outside::Load);
                }
                var += shape_share(false).powi(2);
            }
        }
        sd[c] = var.sqrt();
    }
}
