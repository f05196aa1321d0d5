//! Marker tracking on GelSight frames (thesis §3.4, made robust).
//!
//! The camera sees printed markers riding on the elastomer. Their planar displacement is the
//! signal everything downstream uses (force from the field, slip), so it must be sub-pixel,
//! keep each marker's identity through large deformations, and never silently report a
//! wrong marker. The pipeline, per frame:
//!
//! 1. [`Reference`] (once): from the no-contact frame, a marker-free background per colour
//!    channel, the marker contrast and size, the lattice spacing, and a check that the
//!    frame really shows no contact imprint.
//! 2. [`Detector`]: darkness relative to that background, `1 − max_c(I_c/B_c)` — a pixel
//!    must darken in *every* channel, which rejects the contact imprint's coloured shading
//!    (thesis §3.4) — a 3×3 binomial low-pass, a hysteresis threshold relative to the
//!    marker contrast, and one pass of run-based connected components that accumulates
//!    darkness-weighted moments. A change of exposure since the reference is divided out
//!    per block. Blobs touching the image border are flagged.
//! 3. [`Tracker`]: identities from the reference detections, given only when certain: a
//!    global motion first (or the frame declared ambiguous), best-first growth through the
//!    neighbour graph, and a check that the whole field is one field; a per-marker
//!    [`MarkerState`] and confidence.
//! 4. [`ContactFinder`] (when asked for): the contact region from the colour change against
//!    the reference, markers masked.
//! 5. [`lk`]: weighted Lucas–Kanade (thesis eq. 3.9–3.11) on darkness pyramids, as a second
//!    method and as a refinement of the centroids.
//!
//! Coordinates are pixels with the centre of pixel (i, j) at (i, j) (the OpenCV
//! convention), x to the right, y down. Nothing here does I/O: frames come in as RGB8
//! slices.

mod contact;
mod detect;
pub mod field;
mod frame_check;
pub mod lattice;
pub mod lk;
mod outline;
mod pixels;
mod reference;
mod runs;
mod tracker;

pub use contact::{ContactFinder, ContactParams, ContactRegion};
pub use detect::{Blob, Detector};
pub use frame_check::{FrameCheck, MIN_PLACED_FRACTION};
pub use reference::{Reference, ReferenceMarker};
pub use tracker::{MarkerState, Tracker};

/// An RGB8 frame borrowed from the caller: row-major, three bytes per pixel.
#[derive(Debug, Clone, Copy)]
pub struct RgbView<'a> {
    width: usize,
    height: usize,
    data: &'a [u8],
}

impl<'a> RgbView<'a> {
    /// Wraps `data`, checking its length against the size.
    pub fn new(width: usize, height: usize, data: &'a [u8]) -> Result<Self, TrackError> {
        if width < MIN_SIDE_PX || height < MIN_SIDE_PX {
            return Err(TrackError::TooSmall { width, height });
        }
        if data.len() != width * height * 3 {
            return Err(TrackError::BufferLength {
                expected: width * height * 3,
                got: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixels, RGB8 row-major.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }
}

/// Smallest frame side the background model works on.
const MIN_SIDE_PX: usize = 16;

/// Tuning of detection and identity. The defaults suit every GelSight we know of; all
/// lengths are relative to the marker spacing or contrast measured on the reference, so no
/// grid size or marker size is set by hand.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackParams {
    /// Low (weight baseline) threshold as a fraction of the marker contrast.
    pub low_fraction: f64,
    /// High (seed) threshold as a fraction of the marker contrast.
    pub high_fraction: f64,
    /// Blobs smaller than this fraction of the reference marker area are noise.
    pub min_area_fraction: f64,
    /// Blobs larger than this multiple of the reference marker area are shading, not markers.
    pub max_area_factor: f64,
    /// A marker is seeded only if a detection lies within this fraction of the spacing of
    /// its prediction (and nothing else comes close).
    pub seed_radius: f64,
    /// Gate for matching a marker to a detection, as a fraction of the spacing.
    pub gate: f64,
    /// Largest difference between a marker's displacement from the reference and the
    /// median of its neighbours', as a fraction of the spacing; beyond it a match is
    /// undone (a swap with a neighbour differs by about one spacing).
    pub strain_limit: f64,
    /// After this many frames without a detection a predicted marker is reported lost.
    pub max_predicted_frames: u32,
    /// Chromatic high-pass level (99th percentile) above which the reference is taken to
    /// show a contact imprint and is refused.
    pub contact_imprint_limit: f64,
}

impl Default for TrackParams {
    fn default() -> Self {
        Self {
            low_fraction: 0.2,
            high_fraction: 0.5,
            min_area_fraction: 0.25,
            max_area_factor: 4.5,
            seed_radius: 0.25,
            gate: 0.35,
            strain_limit: 0.6,
            max_predicted_frames: 10,
            contact_imprint_limit: 0.08,
        }
    }
}

/// Why a frame could not be used. Every message ends with what to do about it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackError {
    /// The frame is too small to model.
    #[error("the frame is {width}×{height} px; fix: use frames of at least 16×16 px")]
    TooSmall {
        /// Width in pixels.
        width: usize,
        /// Height in pixels.
        height: usize,
    },
    /// The pixel buffer does not match the stated size.
    #[error(
        "the frame holds {got} bytes where its size needs {expected} (RGB8); fix: pass \
         three bytes per pixel, row by row"
    )]
    BufferLength {
        /// Bytes expected.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// A frame differs in size from the reference.
    #[error(
        "the frame is {got_w}×{got_h} px but the reference is {ref_w}×{ref_h} px; fix: track \
         frames from the same camera mode as the reference"
    )]
    SizeMismatch {
        /// Reference width.
        ref_w: usize,
        /// Reference height.
        ref_h: usize,
        /// Frame width.
        got_w: usize,
        /// Frame height.
        got_h: usize,
    },
    /// The reference frame is mostly saturated.
    #[error(
        "the reference frame is saturated ({percent:.0} % of pixels at 255); fix: lower the \
         camera's exposure or gain and take a new reference"
    )]
    ReferenceSaturated {
        /// Share of saturated pixels, %.
        percent: f64,
    },
    /// No markers could be found on the reference frame.
    #[error(
        "found {found} marker(s) on the reference frame, too few to track; fix: pass a frame \
         of the gel with its markers in view and in focus (not blank, not covered)"
    )]
    NoMarkers {
        /// Markers found.
        found: usize,
    },
    /// A reference-free start found no regular lattice of markers.
    #[error(
        "the markers do not form a regular lattice ({inliers} of {detections} fit one, rms \
         {rms_fraction:.3} of a spacing); a reference-free start needs grid markers; fix: pass \
         --reference with a frame of the untouched gel"
    )]
    NotALattice {
        /// Markers the best lattice explains.
        inliers: usize,
        /// Markers detected.
        detections: usize,
        /// Their rms distance from their sites, in spacings.
        rms_fraction: f64,
    },
    /// A reference-free start with a method that needs the untouched gel's image.
    #[error(
        "a reference-free start has no image of the untouched gel, which the {method} method \
         takes its templates from; fix: use --method centroid, or pass --reference"
    )]
    ReferenceFreeMethod {
        /// The method asked for.
        method: &'static str,
    },
    /// The reference frame shows a contact imprint.
    #[error(
        "the reference frame shows a contact imprint (chromatic residual {score:.3} > \
         {limit:.3}); displacements are measured from the reference, so it must show the gel \
         untouched; fix: use a frame taken before anything touches the gel"
    )]
    ReferenceInContact {
        /// 99th percentile of the chromatic high-pass of the marker-free background.
        score: f64,
        /// Limit it exceeded.
        limit: f64,
    },
}

/// Median of a slice (the upper one of an even count; reordered in place); `None` when
/// empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    if let Some(m) = median_of_few(v) {
        return Some(m);
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// [`median`] of one to eight values without a branch on them: the tracker takes two per
/// marker and frame (a marker and its neighbours), where the selection's comparisons, each
/// a coin toss to the branch predictor, cost about a fiftieth of a 640×480 frame. The
/// values' `total_cmp` order is the order of integer keys; padded with the largest key to
/// eight, they are sorted by the 19 exchanges of Batcher's odd–even merge sort (Knuth,
/// TAOCP vol. 3, §5.3.4), and the middle one is read back. `None` outside 1–8 values.
fn median_of_few(v: &[f64]) -> Option<f64> {
    if v.is_empty() || v.len() > 8 {
        return None;
    }
    // `f64::total_cmp`'s key: negative values' magnitude bits flipped.
    let key = |x: f64| {
        let b = x.to_bits() as i64;
        b ^ (((b >> 63) as u64) >> 1) as i64
    };
    let mut k = [i64::MAX; 8];
    for (o, &x) in k.iter_mut().zip(v) {
        *o = key(x);
    }
    #[rustfmt::skip]
    const PAIRS: [(usize, usize); 19] = [
        (0, 1), (2, 3), (4, 5), (6, 7),
        (0, 2), (1, 3), (4, 6), (5, 7),
        (1, 2), (5, 6),
        (0, 4), (1, 5), (2, 6), (3, 7),
        (2, 4), (3, 5),
        (1, 2), (3, 4), (5, 6),
    ];
    for (a, b) in PAIRS {
        let (lo, hi) = (k[a].min(k[b]), k[a].max(k[b]));
        (k[a], k[b]) = (lo, hi);
    }
    let m = k[v.len() / 2];
    // The key's inverse (the flip is its own inverse).
    Some(f64::from_bits(
        (m ^ (((m >> 63) as u64) >> 1) as i64) as u64,
    ))
}

/// Which estimate of the marker positions a [`Pipeline`] reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Darkness-weighted centroids of the detected blobs (the thesis's final method).
    #[default]
    Centroid,
    /// Weighted Lucas–Kanade alone, three pyramid levels, each marker started from its
    /// previous displacement (the thesis's first method, for comparison).
    Lk,
    /// Centroids refined by one level of weighted Lucas–Kanade.
    CentroidLk,
}

impl Method {
    /// The name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Centroid => "centroid",
            Self::Lk => "lk",
            Self::CentroidLk => "centroid+lk",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "centroid" => Ok(Self::Centroid),
            "lk" => Ok(Self::Lk),
            "centroid+lk" => Ok(Self::CentroidLk),
            other => Err(format!(
                "unknown tracking method `{other}`; fix: use centroid, lk or centroid+lk"
            )),
        }
    }
}

/// Detection, identity and (optionally) Lucas–Kanade, frame after frame.
///
/// Identities and states always come from the centroid tracker, which is what guards
/// against swaps; the LK methods only change where a marker is placed, and only for
/// markers the tracker has not lost.
#[derive(Debug, Clone)]
pub struct Pipeline {
    reference: Reference,
    detector: Detector,
    tracker: Tracker,
    method: Method,
    lk: Option<lk::LkTracker>,
    lk_displacement: Vec<[f64; 2]>,
    contact: Option<ContactFinder>,
    last_contact: Option<ContactRegion>,
}

impl Pipeline {
    /// Measures the reference frame and prepares the tracker.
    pub fn new(
        reference_frame: RgbView<'_>,
        params: &TrackParams,
        method: Method,
    ) -> Result<Self, TrackError> {
        Ok(Self::around(
            Reference::new(reference_frame, params)?,
            method,
        ))
    }

    /// A pipeline around a measured reference (LK templates from its image when the
    /// method uses them).
    fn around(reference: Reference, method: Method) -> Self {
        let tracker = Tracker::new(&reference);
        let (w, h) = (reference.width(), reference.height());
        let lk = (method != Method::Centroid).then(|| {
            let pyramid = lk::Pyramid::new(w, h, reference.darkness(), 3);
            lk::LkTracker::new(
                &pyramid,
                tracker.reference_px(),
                lk::LkParams::for_radius(reference.radius_px(), 3),
            )
        });
        Self {
            detector: Detector::new(w, h),
            lk_displacement: vec![[0.0; 2]; tracker.len()],
            tracker,
            reference,
            method,
            lk,
            contact: None,
            last_contact: None,
        }
    }

    /// A pipeline for a recording that starts mid-contact, with no image of the untouched
    /// gel: the undeformed lattice is fitted to the periphery of `first_frame`
    /// ([`lattice::fit`]), its sites become the reference markers, and `first_frame` is
    /// tracked against them (its displacements are relative to the lattice). Grid markers
    /// and the centroid method only; no contact region (it needs the untouched gel).
    pub fn reference_free(
        first_frame: RgbView<'_>,
        params: &TrackParams,
        method: Method,
    ) -> Result<(Self, lattice::Lattice), TrackError> {
        if method != Method::Centroid {
            return Err(TrackError::ReferenceFreeMethod {
                method: method.as_str(),
            });
        }
        let seen = Reference::of_any_frame(first_frame, params)?;
        let points: Vec<[f64; 2]> = seen
            .markers()
            .iter()
            .filter(|m| !m.border)
            .map(|m| [m.x, m.y])
            .collect();
        let fit = lattice::fit(&points, seen.spacing_px())?;
        let (w, h) = (seen.width(), seen.height());
        let (r, area) = (seen.radius_px(), seen.area_px());
        let sites: Vec<ReferenceMarker> = fit
            .sites_in(w, h)
            .into_iter()
            .map(|p| ReferenceMarker {
                x: p[0],
                y: p[1],
                area_px: area.round() as u32,
                border: p[0] < r + 1.0
                    || p[1] < r + 1.0
                    || p[0] > w as f64 - 2.0 - r
                    || p[1] > h as f64 - 2.0 - r,
            })
            .collect();
        let mut pipeline = Self::around(seen.with_markers(sites, fit.spacing_px()), method);
        pipeline.track(first_frame)?;
        Ok((pipeline, fit))
    }

    /// Also finds the contact region of every frame from now on ([`ContactFinder`]); its
    /// noise floor is measured on `reference_frame`, the frame this pipeline was made from.
    pub fn enable_contact(
        &mut self,
        reference_frame: RgbView<'_>,
        params: ContactParams,
    ) -> Result<(), TrackError> {
        self.contact = Some(ContactFinder::new(
            reference_frame,
            &self.reference,
            params,
        )?);
        Ok(())
    }

    /// The contact region of the last frame (`None` without contact, or when not enabled).
    pub fn contact(&self) -> Option<&ContactRegion> {
        self.last_contact.as_ref()
    }

    /// Tracks one frame.
    pub fn track(&mut self, frame: RgbView<'_>) -> Result<(), TrackError> {
        let blobs = self.detector.detect(frame, &self.reference)?;
        self.tracker.update(blobs);
        if let Some(finder) = &mut self.contact {
            self.last_contact = finder.find(frame, &self.reference, self.detector.smoothed())?;
        }
        let Some(lk) = &self.lk else {
            return Ok(());
        };
        let (w, h) = (self.reference.width(), self.reference.height());
        let levels = if self.method == Method::Lk { 3 } else { 1 };
        let pyramid = lk::Pyramid::new(w, h, self.detector.smoothed(), levels);
        let mut positions = self.tracker.positions_px().to_vec();
        for (k, p) in positions.iter_mut().enumerate() {
            let state = self.tracker.states()[k];
            if matches!(state, MarkerState::Lost | MarkerState::OutOfView) {
                continue;
            }
            let init = match self.method {
                Method::Lk => self.lk_displacement[k],
                _ if state.is_measured() => self.tracker.displacement_px(k),
                _ => continue,
            };
            if let Some((u, _)) = lk.track(&pyramid, k, init, levels) {
                self.lk_displacement[k] = u;
                let r = self.tracker.reference_px()[k];
                *p = [r[0] + u[0], r[1] + u[1]];
            }
        }
        self.tracker.set_positions(&positions);
        Ok(())
    }

    /// The reference measurements.
    pub fn reference(&self) -> &Reference {
        &self.reference
    }

    /// The tracker (positions, states, identities).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The blobs of the last frame.
    pub fn blobs(&self) -> &[Blob] {
        self.detector.blobs()
    }
}

#[cfg(test)]
mod tests {
    /// One to eight values give the selection's median, bit for bit: ties, signed zeros,
    /// infinities and NaNs of either sign included (`total_cmp`'s order).
    #[test]
    fn the_median_of_a_few_is_the_selections() {
        let special = [
            0.0,
            -0.0,
            1.5,
            -1.5,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
        ];
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for n in 1..=8usize {
            for _ in 0..2000 {
                let v: Vec<f64> = (0..n)
                    .map(|_| match next() % 4 {
                        0 => special[(next() % 8) as usize],
                        1 => (next() % 5) as f64 - 2.0,
                        _ => (next() % 2_000_001) as f64 * 1e-3 - 1e3,
                    })
                    .collect();
                let mut sorted = v.clone();
                let (_, want, _) = sorted.select_nth_unstable_by(n / 2, f64::total_cmp);
                let got = super::median_of_few(&v).map(f64::to_bits);
                assert_eq!(got, Some(want.to_bits()), "{v:?}");
            }
        }
        assert_eq!(super::median_of_few(&[]), None);
        assert_eq!(super::median_of_few(&[1.0; 9]), None);
        assert_eq!(
            super::median(&mut [3.0, 1.0, 2.0, 5.0, 4.0, 0.0, 9.0, 8.0, 7.0]),
            Some(4.0)
        );
    }
}
