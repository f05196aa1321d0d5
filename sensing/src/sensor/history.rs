//! The gel's load history as a reading follows a recording frame by frame: what the
//! hereditary Fz ([`analysis::force_sensor::memory`]) takes in, and what it must not. Shared
//! by the live tactile path and `gelrig track --sensor`, so both read a recording alike.
//!
//! Two things stay out of the history:
//! - **a contact the image missed for a frame.** The contact finder can miss a frame in a
//!   loaded grasp (a swing blurs the colour change; once in the shipped `lifting-can`,
//!   seed 2, with the gel pressed at 2.9 px rms). Read without a region, that frame would
//!   count as the gel letting go (its elastic force dropped to zero in the history). While
//!   the field's rms is at least half what it was at the last region, the last region
//!   stands in.
//! - **an elastic force the calibration cannot vouch for.** A gel pressed by an object
//!   carries no pulling normal force, and an elastic reading far beyond the calibrated
//!   range is the linear model extrapolating: both are the model outside its calibration
//!   (a twist's field, on a sensor calibrated by pressing and shearing, reads 0–36 N at
//!   2 Hz under a steady 5 N squeeze). A swing up and back leaves a residue in the slow
//!   terms, so the twist would stay in the history: `lifting-can`'s lowering read 36 % above
//!   the Nano17 instead of the hold's 13 % (BENCHMARKS.md, "What the load history must not
//!   take in"). Such a frame's force is the last credible one: below zero, or beyond the
//!   calibrated Fz range by more than a quarter of its span.
//!
//! And one thing stays in: **the free gel between contacts**. Where contact regions are
//! looked for, a frame without one is a gel whose elastic force has gone to zero, applied to
//! the history like any change ([`Memory::free`]): the next contact's force is applied from
//! zero, and a gel gripped again before it has recovered from the last grip pushes back
//! less, as a viscoelastic gel does.

use analysis::force_sensor::memory::Memory;
use tracking::field::MarkerField;

/// A contact region as the image shows it: centroid and equivalent radius, px, and the
/// central second moments of its area ([σxx, σyy, σxy], px²) where they were recorded (a
/// `contact.csv` written before 27 Nov has none: the region reads as a disc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub centroid_px: [f64; 2],
    pub radius_px: f64,
    pub second_moments_px2: Option<[f64; 3]>,
}

impl Region {
    /// A disc: no second moments recorded.
    pub fn disc(centroid_px: [f64; 2], radius_px: f64) -> Self {
        Self {
            centroid_px,
            radius_px,
            second_moments_px2: None,
        }
    }
}

/// The load history of one recording (or one record block).
#[derive(Debug, Clone)]
pub struct LoadHistory {
    memory: Option<Memory>,
    /// The elastic forces the calibration vouches for, N.
    credible_n: [f64; 2],
    /// The last credible elastic force, N.
    last_fe: f64,
    /// Whether the recording's contact regions were looked for: then a frame without one
    /// is a free gel.
    contact_found: bool,
    /// The last region the image showed, and the field's rms then, px.
    last_region: Option<(Region, f64)>,
}

impl LoadHistory {
    /// A gel with no history; `memory` is the sensor's ([`super::reader::Reader::memory`]),
    /// `None` for a sensor that does not know its gel's relaxation; `fz_range_n` the Fz its
    /// calibration's force sensor saw (the sensor file's `ranges`); `contact_found` whether
    /// the recording's contact regions were looked for (false for one tracked without).
    pub fn new(memory: Option<Memory>, fz_range_n: Option<[f64; 2]>, contact_found: bool) -> Self {
        let credible_n = match fz_range_n {
            Some([lo, hi]) if hi > lo => [0.0, hi + 0.25 * (hi - lo)],
            _ => [0.0, f64::INFINITY],
        };
        Self {
            memory,
            credible_n,
            last_fe: 0.0,
            contact_found,
            last_region: None,
        }
    }

    /// The region a frame with `field` is read with: the image's (`seen`), or the last one
    /// while the gel still carries the load.
    pub fn region(&mut self, field: &MarkerField, seen: Option<Region>) -> Option<Region> {
        bridge(&mut self.last_region, seen, rms_px(field))
    }

    /// The wrench `v` (Fx, Fy, Fz, Tz as the model reads them from the field) of a frame at
    /// `t_ns` with `region` (from [`Self::region`]): Fz through the gel's memory; and where
    /// the image shows no contact and none is bridged, nothing — a free gel carries no load,
    /// and the model's reading of an untouched field is its intercept, not a force (a jig
    /// calibration read 0.40 N on the untouched gel before every grip, 8 % of the squeeze).
    pub fn wrench(&mut self, t_ns: u64, v: &mut [f64], region: Option<Region>) {
        if let Some(fz) = v.get_mut(2) {
            *fz = self.fz(t_ns, *fz, region);
        }
        if region.is_none() && self.contact_found {
            v.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// The force at `t_ns` of a frame whose field reads the elastic force `f_e`, in contact
    /// with `region` (from [`Self::region`]); `f_e` itself for a sensor without memory.
    fn fz(&mut self, t_ns: u64, f_e: f64, region: Option<Region>) -> f64 {
        let Some(m) = self.memory.as_mut() else {
            return f_e;
        };
        let f_e = if (self.credible_n[0]..=self.credible_n[1]).contains(&f_e) {
            self.last_fe = f_e;
            f_e
        } else if region.is_some() {
            self.last_fe
        } else {
            f_e.max(0.0)
        };
        match region {
            Some(_) => m.apply(t_ns, f_e),
            None if self.contact_found => m.free(t_ns),
            None => m.release(t_ns, f_e),
        }
    }
}

/// Rms of the field over its measured markers, px.
fn rms_px(field: &MarkerField) -> f64 {
    let (sum, n) = field
        .measured_ids()
        .map(|i| field.displacement_px[i])
        .fold((0.0, 0usize), |(s, n), d| {
            (s + d[0] * d[0] + d[1] * d[1], n + 1)
        });
    if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
}

/// The image's region, or the last one while the field's rms (`total_px`) is at least half
/// what it was then.
fn bridge(last: &mut Option<(Region, f64)>, seen: Option<Region>, total_px: f64) -> Option<Region> {
    match seen {
        Some(r) => {
            *last = Some((r, total_px));
            Some(r)
        }
        None => match *last {
            Some((r, then_px)) if total_px >= 0.5 * then_px => Some(r),
            _ => {
                *last = None;
                None
            }
        },
    }
}

#[cfg(test)]
mod tests {
    use super::{LoadHistory, Region, bridge};

    /// Where contact regions are looked for, a frame without one reads no load; where they
    /// are not (a recording tracked without), the field's reading stands.
    #[test]
    fn a_free_gel_reads_no_load_where_contact_is_looked_for() {
        let region = Some(Region::disc([320.0, 240.0], 40.0));
        for (found, want) in [(true, [0.0; 4]), (false, [0.1, -0.05, 0.4, 0.02])] {
            let mut h = LoadHistory::new(None, Some([0.0, 24.0]), found);
            let mut v = [0.1, -0.05, 0.4, 0.02];
            h.wrench(1, &mut v, None);
            assert_eq!(v, want, "contact looked for: {found}");
            let mut v = [0.1, -0.05, 4.0, 0.02];
            h.wrench(2, &mut v, region);
            assert_eq!(v, [0.1, -0.05, 4.0, 0.02], "in contact, the reading stands");
        }
    }

    /// A contact the image first shows loaded, after free frames, is applied from zero: its
    /// first reading carries the gel's overshoot (the bench's gel does; a history started
    /// "at rest" read the can's lift and hold 0.3–0.4 N low).
    #[test]
    fn a_contact_after_a_free_gel_is_applied_from_zero() {
        let prony = mechanics::Prony::new(vec![mechanics::PronyTerm {
            weight: 0.5,
            tau_s: 10.0,
        }])
        .expect("valid");
        let memory = analysis::force_sensor::memory::Memory::new(prony);
        let mut h = LoadHistory::new(Some(memory), Some([0.0, 24.0]), true);
        for k in 0..5u64 {
            let mut v = [0.0, 0.0, 0.3, 0.0];
            h.wrench(k * 40_000_000, &mut v, None);
            assert_eq!(v[2], 0.0, "a free gel reads no load");
        }
        let mut v = [0.0, 0.0, 2.0, 0.0];
        h.wrench(
            5 * 40_000_000,
            &mut v,
            Some(Region::disc([320.0, 240.0], 40.0)),
        );
        // A ramp from 0 to 2 N over 40 ms: 2·(1 + 0.5·(1 − e^{−x})/x), x = 0.004.
        let x: f64 = 0.04 / 10.0;
        let want = 2.0 * (1.0 + 0.5 * (-(-x).exp_m1() / x));
        assert!((v[2] - want).abs() < 1e-9, "{} vs {want}", v[2]);
    }

    #[test]
    fn a_frame_without_a_region_in_a_loaded_grasp_keeps_the_last_one_and_an_unloaded_gel_lets_go() {
        let mut last = None;
        assert_eq!(bridge(&mut last, None, 0.01), None, "no contact yet");
        let r = Region::disc([320.0, 240.0], 40.0);
        assert_eq!(bridge(&mut last, Some(r), 2.5), Some(r));
        // The finder misses a frame; the field still carries the load.
        assert_eq!(bridge(&mut last, None, 2.9), Some(r));
        assert_eq!(
            bridge(&mut last, None, 1.3),
            Some(r),
            "half the load: still held"
        );
        // The gel has let go: the field fell below half of what it was.
        assert_eq!(bridge(&mut last, None, 1.0), None);
        assert_eq!(
            bridge(&mut last, None, 2.0),
            None,
            "nothing left to bridge with"
        );
        let r2 = Region::disc([300.0, 250.0], 35.0);
        assert_eq!(bridge(&mut last, Some(r2), 2.0), Some(r2));
    }
}
