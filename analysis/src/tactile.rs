//! The tactile state of a grasp, frame by frame: is the object about to slip?
//!
//! The thesis's point (§1.1, §6.3.2, Fig. 6-21 to 6-23) is that the marker field tells a
//! grasp is about to slip before it does. Per frame this module takes the total marker
//! field (from the reference, unloaded gel) and derives:
//!
//! - the **pressing field**, the total field at the end of the grip (set once per grasp);
//! - the **shear field** = total − pressing, and the **differential field** (frame to frame);
//! - the **rigid motion** of the contact — translation and rotation about the normal — fitted
//!   to the markers inside the contact that move most (under stick the contact moves with the
//!   object as one piece, Fig. 6-21: "uniform in the contact");
//! - the **stuck fraction**: the share of contact markers whose shear follows that rigid
//!   motion. Partial slip starts at the contact's edges and spreads inward as the load
//!   approaches μN (Cattaneo–Mindlin; thesis §4.4, §6.2.2: the edge region lags), so the
//!   fraction shrinks;
//! - the **contact area** from the image, against its value at the end of the grip (it
//!   shrinks fast as a loosened grasp slips, Fig. 6-23).
//!
//! The slip state combines them: `incipient` when the stuck fraction falls below
//! [`TactileParams::incipient_stuck`] (or the contact has shrunk while part of it slips),
//! `slip` when almost nothing sticks any more or the field changes faster between frames
//! than a held object can make it. A shear below [`TactileParams::min_shear_px`] is too
//! small to judge and counts as `stick`. Thresholds were set on dry runs against the
//! simulator's true stick fraction (BENCHMARKS.md, "Grasp trials").

use tracking::field::MarkerField;

/// Slip state of a grasp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SlipState {
    /// The contact moves with the object.
    Stick,
    /// Part of the contact slips: the grasp is about to lose the object.
    Incipient,
    /// The object slides through the grasp.
    Slip,
}

impl SlipState {
    /// The state's name in files and protocols.
    pub fn as_str(self) -> &'static str {
        match self {
            SlipState::Stick => "stick",
            SlipState::Incipient => "incipient",
            SlipState::Slip => "slip",
        }
    }

    /// Parses a name written by [`Self::as_str`].
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "stick" => Some(SlipState::Stick),
            "incipient" => Some(SlipState::Incipient),
            "slip" => Some(SlipState::Slip),
            _ => None,
        }
    }
}

/// Thresholds of the slip state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TactileParams {
    /// A contact marker sticks if its shear is within this fraction of the rigid motion's
    /// translation (plus [`Self::floor_px`]) of what the rigid motion predicts.
    pub stuck_tolerance: f64,
    /// Tracking noise allowance in the stuck test, px.
    pub floor_px: f64,
    /// Smallest rigid translation of the contact that can be judged, px.
    pub min_shear_px: f64,
    /// `incipient` below this stuck fraction.
    pub incipient_stuck: f64,
    /// `slip` below this stuck fraction.
    pub slip_stuck: f64,
    /// `slip` when, with the contact inhomogeneous, the differential field's rms inside it
    /// exceeds this, px/frame.
    pub slip_differential_px: f64,
    /// Contact markers are those inside the image's contact outline shrunk about its
    /// centroid by this factor (the outline reads a little wide; edge markers are biased).
    pub contact_shrink: f64,
    /// Fewest contact markers to judge a frame.
    pub min_markers: usize,
}

impl Default for TactileParams {
    fn default() -> Self {
        Self {
            stuck_tolerance: 0.25,
            floor_px: 0.15,
            min_shear_px: 0.5,
            incipient_stuck: 0.5,
            slip_stuck: 0.15,
            slip_differential_px: 1.5,
            contact_shrink: 0.9,
            min_markers: 6,
        }
    }
}

/// One frame's tactile quantities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TactileFrame {
    /// Markers inside the contact (judged).
    pub contact_markers: usize,
    /// Contact area from the image, px² (0 without contact).
    pub contact_area_px2: f64,
    /// Contact area over its value at the end of the grip (1 before then).
    pub area_ratio: f64,
    /// Rigid translation of the contact's shear field, px (x, y).
    pub shear_px: [f64; 2],
    /// Rigid rotation of the contact about the normal, degrees (counter-clockwise in the
    /// image).
    pub rotation_deg: f64,
    /// Share of contact markers that follow the rigid motion.
    pub stuck_fraction: f64,
    /// Rms of the frame-to-frame change of the field inside the contact, px.
    pub differential_px: f64,
    /// Rms of the total field over all measured markers, px.
    pub total_px: f64,
    /// The slip state.
    pub state: SlipState,
}

/// Follows one grasp frame by frame.
#[derive(Debug, Clone)]
pub struct TactileMonitor {
    params: TactileParams,
    pressing: Option<Vec<[f64; 2]>>,
    pressing_area_px2: f64,
    /// Markers inside the contact at the end of the grip: where the object touched, so a
    /// contact that shrinks as the grip loosens shows as markers no longer following it.
    pressing_contact: Option<Vec<usize>>,
    previous: Option<Vec<[f64; 2]>>,
    /// The last few frames' contact areas: the image's contact region flickers from frame
    /// to frame (±20 % on a long strip), so areas are compared as running medians.
    areas: std::collections::VecDeque<f64>,
    /// Areas of the frames in a row whose region was a sliver of the recent median (left
    /// out of it).
    slivers: Vec<f64>,
}

/// Frames in the running median of the contact area.
const AREA_FRAMES: usize = 5;

/// A region smaller than this fraction of the running median is a sliver (a frame where the
/// region finder caught only part of the contact), not the contact.
const SLIVER: f64 = 0.6;

impl TactileMonitor {
    /// A monitor before any grip.
    pub fn new(params: TactileParams) -> Self {
        Self {
            params,
            pressing: None,
            pressing_area_px2: 0.0,
            pressing_contact: None,
            previous: None,
            areas: std::collections::VecDeque::new(),
            slivers: Vec::new(),
        }
    }

    /// Adds this frame's contact area to the running median, unless it is a sliver of it:
    /// under a twist the region finder can catch only a corner of the contact in several
    /// frames running (seen at 1–8 mm² of an 85 mm² strip), which would drag the median
    /// down and read as the contact shrinking. A contact that truly shrinks does so over
    /// frames; one that stays small for [`AREA_FRAMES`] frames in a row is taken as real.
    fn push_area(&mut self, area: f64) {
        let median = self.median_area();
        if area < SLIVER * median {
            self.slivers.push(area);
            if self.slivers.len() < AREA_FRAMES {
                return;
            }
            // Small for a whole window: the contact did shrink.
            self.areas = self.slivers.drain(..).collect();
            return;
        }
        self.slivers.clear();
        self.areas.push_back(area);
        while self.areas.len() > AREA_FRAMES {
            self.areas.pop_front();
        }
    }

    fn median_area(&self) -> f64 {
        let mut v: Vec<f64> = self.areas.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    }

    /// The markers inside this frame's outline, if the outline is a fair one: at least
    /// [`TactileParams::min_markers`] of them, and an area not far below the recent median
    /// (a frame where the region finder caught only a sliver would judge a handful).
    fn fair_contact(
        &self,
        field: &MarkerField,
        contact: Option<(&[[f64; 2]], f64)>,
    ) -> Option<Vec<usize>> {
        let (o, area) = contact?;
        if area < SLIVER * self.median_area() {
            return None;
        }
        let ids = self.inside(field, o);
        (ids.len() >= self.params.min_markers).then_some(ids)
    }

    /// The end of the grip: the field now is the pressing field the shear is measured
    /// from, the markers inside the contact now are the ones judged from here on, and the
    /// contact area now is what shrinking is judged against.
    /// If this frame's contact region is not a fair one, the contact markers are taken at
    /// the first later frame whose region is.
    pub fn set_pressing(&mut self, field: &MarkerField, contact: Option<(&[[f64; 2]], f64)>) {
        self.pressing = Some(field.displacement_px.clone());
        let mut recent: Vec<f64> = self.areas.iter().copied().collect();
        recent.extend(contact.map(|(_, a)| a));
        recent.sort_by(f64::total_cmp);
        self.pressing_area_px2 = recent.get(recent.len() / 2).copied().unwrap_or(0.0);
        self.pressing_contact = self.fair_contact(field, contact);
    }

    /// Measured markers inside outline `o` (shrunk by [`TactileParams::contact_shrink`]).
    fn inside(&self, field: &MarkerField, o: &[[f64; 2]]) -> Vec<usize> {
        let o = shrink(o, self.params.contact_shrink);
        field
            .measured_ids()
            .filter(|&i| {
                let r = field.reference_px[i];
                let d = field.displacement_px[i];
                point_in_polygon([r[0] + d[0], r[1] + d[1]], &o)
            })
            .collect()
    }

    /// Forgets the grasp (the object was released): the next grip starts afresh.
    pub fn release(&mut self) {
        self.pressing = None;
        self.pressing_area_px2 = 0.0;
        self.pressing_contact = None;
        self.previous = None;
        self.areas.clear();
        self.slivers.clear();
    }

    /// Whether a pressing field is set.
    pub fn gripping(&self) -> bool {
        self.pressing.is_some()
    }

    /// Judges one frame: `field` from the reference, `contact` the image's contact outline
    /// (closed polygon, px) and its area, if found.
    pub fn update(
        &mut self,
        field: &MarkerField,
        contact: Option<(&[[f64; 2]], f64)>,
    ) -> TactileFrame {
        let p = self.params;
        let n = field.len();
        let total_px = rms(field.measured_ids().map(|i| field.displacement_px[i]));
        let area = contact.map(|(_, a)| a).unwrap_or(0.0);
        self.push_area(area);
        if self.pressing.is_some() && self.pressing_contact.is_none() {
            self.pressing_contact = self.fair_contact(field, contact);
        }
        let inside: Vec<usize> = match (&self.pressing_contact, contact) {
            (Some(ids), _) => ids
                .iter()
                .copied()
                .filter(|&i| field.measured.get(i).copied().unwrap_or(false))
                .collect(),
            (None, Some((o, _))) => self.inside(field, o),
            (None, None) => Vec::new(),
        };
        let differential_px = match &self.previous {
            Some(prev) if prev.len() == n => rms(inside.iter().map(|&i| {
                let (a, b) = (field.displacement_px[i], prev[i]);
                [a[0] - b[0], a[1] - b[1]]
            })),
            _ => 0.0,
        };
        self.previous = Some(field.displacement_px.clone());
        let area_ratio = if self.pressing_area_px2 > 0.0 {
            self.median_area() / self.pressing_area_px2
        } else {
            1.0
        };
        let mut out = TactileFrame {
            contact_markers: inside.len(),
            contact_area_px2: area,
            area_ratio,
            shear_px: [0.0; 2],
            rotation_deg: 0.0,
            stuck_fraction: 1.0,
            differential_px,
            total_px,
            state: SlipState::Stick,
        };
        let Some(pressing) = self.pressing.as_ref().filter(|v| v.len() == n) else {
            return out;
        };
        if inside.len() < p.min_markers {
            return out;
        }
        let pts: Vec<[f64; 2]> = inside.iter().map(|&i| field.reference_px[i]).collect();
        let shear: Vec<[f64; 2]> = inside
            .iter()
            .map(|&i| {
                let (a, b) = (field.displacement_px[i], pressing[i]);
                [a[0] - b[0], a[1] - b[1]]
            })
            .collect();
        let centre = mean(&pts);
        // The part that moves most moves with the object: fit there, then judge everyone.
        // "Most" along the load once the contact's overall rotation is taken out, so a twist
        // does not pick one side of the contact.
        let everyone: Vec<usize> = (0..shear.len()).collect();
        let (_, theta0) = rigid_fit(&pts, &shear, centre, &everyone);
        let untwisted: Vec<[f64; 2]> = (0..shear.len())
            .map(|k| {
                let r = [pts[k][0] - centre[0], pts[k][1] - centre[1]];
                [shear[k][0] + theta0 * r[1], shear[k][1] - theta0 * r[0]]
            })
            .collect();
        let dir = mean(&untwisted);
        let norm = dir[0].hypot(dir[1]);
        let mut order = everyone;
        let along = |w: [f64; 2]| {
            if norm > 0.0 {
                (w[0] * dir[0] + w[1] * dir[1]) / norm
            } else {
                w[0].hypot(w[1])
            }
        };
        order.sort_by(|&a, &b| along(untwisted[b]).total_cmp(&along(untwisted[a])));
        let top: Vec<usize> = order[..shear.len().div_ceil(2)].to_vec();
        let (mut t, mut theta) = rigid_fit(&pts, &shear, centre, &top);
        // A marker follows the object if it is where the rigid motion puts it, within a
        // fraction of that motion there, judged along the translation: the object slipping out
        // of the grasp is a lag along the load. A twist's own partial slip (the contact's
        // ends lagging across it) is reported as rotation, not as the grasp letting go
        // (Fig. 6-24: "a rotating pattern about a centre").
        let stuck_set = |t: [f64; 2], theta: f64| -> Vec<usize> {
            let t_mag = t[0].hypot(t[1]);
            let along = if t_mag > 0.0 {
                [t[0] / t_mag, t[1] / t_mag]
            } else {
                [0.0; 2]
            };
            (0..shear.len())
                .filter(|&k| {
                    let r = [pts[k][0] - centre[0], pts[k][1] - centre[1]];
                    let pred = [t[0] - theta * r[1], t[1] + theta * r[0]];
                    let miss = [shear[k][0] - pred[0], shear[k][1] - pred[1]];
                    let tol = p.stuck_tolerance * t_mag.max(pred[0].hypot(pred[1])) + p.floor_px;
                    (miss[0] * along[0] + miss[1] * along[1]).abs() <= tol
                })
                .collect()
        };
        let first = stuck_set(t, theta);
        if first.len() >= 3 {
            (t, theta) = rigid_fit(&pts, &shear, centre, &first);
        }
        let stuck = stuck_set(t, theta);
        out.shear_px = t;
        out.rotation_deg = theta.to_degrees();
        let magnitude = t[0].hypot(t[1]);
        // Slip along a load too small to see is not judged (a pure twist included).
        if magnitude < p.min_shear_px {
            return out;
        }
        out.stuck_fraction = stuck.len() as f64 / shear.len() as f64;
        let inhomogeneous = out.stuck_fraction < p.incipient_stuck;
        out.state = if out.stuck_fraction < p.slip_stuck
            || (inhomogeneous && out.differential_px > p.slip_differential_px)
        {
            SlipState::Slip
        } else if inhomogeneous || (area_ratio < 0.7 && out.stuck_fraction < 0.8) {
            SlipState::Incipient
        } else {
            SlipState::Stick
        };
        out
    }
}

/// Least-squares translation and small rotation about `centre` of displacements `w` at
/// points `pts`, over the indices `use_`: w ≈ t + θ·ẑ×(p − centre).
fn rigid_fit(
    pts: &[[f64; 2]],
    w: &[[f64; 2]],
    centre: [f64; 2],
    use_: &[usize],
) -> ([f64; 2], f64) {
    if use_.is_empty() {
        return ([0.0; 2], 0.0);
    }
    let k = use_.len() as f64;
    let (mut t, mut rc) = ([0.0; 2], [0.0; 2]);
    for &i in use_ {
        t[0] += w[i][0] / k;
        t[1] += w[i][1] / k;
        rc[0] += (pts[i][0] - centre[0]) / k;
        rc[1] += (pts[i][1] - centre[1]) / k;
    }
    // Rotation about the subset's own centroid, then the translation at `centre`.
    let (mut num, mut den) = (0.0, 0.0);
    for &i in use_ {
        let r = [pts[i][0] - centre[0] - rc[0], pts[i][1] - centre[1] - rc[1]];
        let d = [w[i][0] - t[0], w[i][1] - t[1]];
        num += r[0] * d[1] - r[1] * d[0];
        den += r[0] * r[0] + r[1] * r[1];
    }
    let theta = if den > 0.0 { num / den } else { 0.0 };
    ([t[0] + theta * rc[1], t[1] - theta * rc[0]], theta)
}

fn mean(v: &[[f64; 2]]) -> [f64; 2] {
    let n = v.len().max(1) as f64;
    v.iter()
        .fold([0.0; 2], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n])
}

fn rms(v: impl Iterator<Item = [f64; 2]>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for d in v {
        s += d[0] * d[0] + d[1] * d[1];
        n += 1;
    }
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

/// The polygon scaled about its vertex centroid by `k`.
fn shrink(poly: &[[f64; 2]], k: f64) -> Vec<[f64; 2]> {
    let c = mean(poly);
    poly.iter()
        .map(|p| [c[0] + (p[0] - c[0]) * k, c[1] + (p[1] - c[1]) * k])
        .collect()
}

/// Even–odd rule.
fn point_in_polygon(p: [f64; 2], poly: &[[f64; 2]]) -> bool {
    let mut inside = false;
    let n = poly.len();
    if n < 3 {
        return false;
    }
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
        j = i;
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 30 × 17 lattice of markers 5 px apart; the contact is the band |y − 40| < 28.
    fn lattice() -> Vec<[f64; 2]> {
        let mut v = Vec::new();
        for j in 0..17 {
            for i in 0..30 {
                v.push([i as f64 * 5.0, j as f64 * 5.0]);
            }
        }
        v
    }

    fn band() -> Vec<[f64; 2]> {
        vec![[-5.0, 12.0], [150.0, 12.0], [150.0, 68.0], [-5.0, 68.0]]
    }

    fn field(refs: &[[f64; 2]], f: impl Fn([f64; 2]) -> [f64; 2]) -> MarkerField {
        MarkerField {
            displacement_px: refs.iter().map(|&r| f(r)).collect(),
            reference_px: refs.to_vec(),
            measured: vec![true; refs.len()],
        }
    }

    fn pressed(r: [f64; 2]) -> [f64; 2] {
        // Spreading out from the axis line y = 40 (a cylinder indentation).
        [0.0, (r[1] - 40.0) * 0.02]
    }

    fn monitor(refs: &[[f64; 2]]) -> TactileMonitor {
        let mut m = TactileMonitor::new(TactileParams::default());
        let poly = band();
        m.update(&field(refs, pressed), Some((&poly, 6000.0)));
        m.set_pressing(&field(refs, pressed), Some((&poly, 6000.0)));
        m
    }

    #[test]
    fn uniform_shear_in_the_contact_sticks() {
        let refs = lattice();
        let mut m = monitor(&refs);
        let poly = band();
        let f = field(&refs, |r| {
            let p = pressed(r);
            let inside = (r[1] - 40.0).abs() < 28.0;
            let s = if inside { 3.0 } else { 0.5 };
            [p[0] - s, p[1]]
        });
        let t = m.update(&f, Some((&poly, 6000.0)));
        assert_eq!(t.state, SlipState::Stick, "{t:?}");
        assert!(
            (t.shear_px[0] + 3.0).abs() < 1e-9 && t.stuck_fraction > 0.99,
            "{t:?}"
        );
    }

    #[test]
    fn edges_lagging_is_incipient_and_nothing_following_is_slip() {
        let refs = lattice();
        let poly = band();
        // Cattaneo–Mindlin in 2-D: the centre sticks (|y − 40| < c), the edges lag.
        let partial = |c: f64, lag: f64| {
            move |r: [f64; 2]| {
                let p = pressed(r);
                let y = (r[1] - 40.0).abs();
                let s = if y < c {
                    3.0
                } else {
                    (3.0 - (y - c) * lag).max(0.0)
                };
                [p[0] - s, p[1]]
            }
        };
        // (Each field shown twice: judged at rest, the differential field is zero.)
        let mut m = monitor(&refs);
        m.update(&field(&refs, partial(2.0, 0.25)), Some((&poly, 6000.0)));
        let t = m.update(&field(&refs, partial(2.0, 0.25)), Some((&poly, 6000.0)));
        assert_eq!(t.state, SlipState::Incipient, "{t:?}");
        let mut m = monitor(&refs);
        let t = m.update(&field(&refs, partial(22.0, 0.15)), Some((&poly, 6000.0)));
        assert_eq!(t.state, SlipState::Stick, "{t:?}");
        // A field changing by px between frames, its edges lagging: the object is sliding.
        let mut m = monitor(&refs);
        m.update(&field(&refs, partial(22.0, 0.15)), Some((&poly, 6000.0)));
        let t = m.update(
            &field(&refs, |r| {
                let p = pressed(r);
                let y = (r[1] - 40.0).abs();
                [p[0] - (6.0 - y * 0.3).max(0.0), p[1]]
            }),
            Some((&poly, 6000.0)),
        );
        assert_eq!(t.state, SlipState::Slip, "{t:?}");
    }

    #[test]
    fn a_rotation_is_not_slip() {
        let refs = lattice();
        let poly = band();
        let mut m = monitor(&refs);
        let theta = 0.02f64;
        let f = field(&refs, |r| {
            let p = pressed(r);
            let (x, y) = (r[0] - 72.5, r[1] - 40.0);
            [p[0] - theta * y, p[1] + theta * x]
        });
        let t = m.update(&f, Some((&poly, 6000.0)));
        assert_eq!(t.state, SlipState::Stick, "{t:?}");
        assert!((t.rotation_deg - theta.to_degrees()).abs() < 0.05, "{t:?}");
    }

    #[test]
    fn slivers_of_the_region_do_not_shrink_the_contact_but_a_lasting_shrink_does() {
        let refs = lattice();
        let poly = band();
        // Partly stuck (between the two thresholds), so only the area cue can alarm.
        let f = field(&refs, |r| {
            let p = pressed(r);
            let y = (r[1] - 40.0).abs();
            let s = if y < 14.0 { 3.0 } else { 2.0 };
            [p[0] - s, p[1]]
        });
        let mut m = monitor(&refs);
        // Three frames in a row where the region finder caught a corner of the contact.
        for _ in 0..3 {
            let t = m.update(&f, Some((&poly, 300.0)));
            assert!(t.area_ratio > 0.99, "{t:?}");
        }
        let t = m.update(&f, Some((&poly, 6000.0)));
        assert_eq!(t.state, SlipState::Stick, "{t:?}");
        assert!(t.stuck_fraction < 0.8, "{t:?}");
        // The contact stays at a third: after a median window of frames it is believed.
        let mut last = t;
        for _ in 0..2 * AREA_FRAMES + 1 {
            last = m.update(&f, Some((&poly, 2000.0)));
        }
        assert!(last.area_ratio < 0.4, "{last:?}");
        assert_eq!(last.state, SlipState::Incipient, "{last:?}");
    }

    #[test]
    fn names_round_trip() {
        for s in [SlipState::Stick, SlipState::Incipient, SlipState::Slip] {
            assert_eq!(SlipState::parse(s.as_str()), Some(s));
        }
        assert_eq!(SlipState::parse("slipping"), None);
    }
}
