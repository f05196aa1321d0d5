//! Whether a frame shows the gel of the reference at all.
//!
//! A frame whose markers the tracker cannot place is one of three things, and each asks for
//! something different: the same gel in a frame the lattice makes ambiguous (keep tracking:
//! the identities come back when evidence does), a frame with almost no markers (a dark,
//! covered or defocused camera: the frames after it are still good), or another gel or
//! camera (stop: nothing after it can be tracked against this reference). The first shows as
//! markers placed on blobs with their identity withheld; the other two are told apart by the
//! blobs' own size and spacing against the reference's.

use super::{MarkerState, Pipeline, median};

/// Least share of the reference's markers that must sit on a blob (identity certain or
/// withheld) for a frame to be the reference's gel; a pressed gel keeps most (74 % at the
/// real Mini sequence's deepest frame), a frame of another sensor almost none (3 % for a
/// portable frame against a box reference).
pub const MIN_PLACED_FRACTION: f64 = 0.25;

/// Fewest whole blobs whose size and spacing are judged against the reference's.
const MIN_JUDGED: usize = 8;

/// What a frame shows, judged against the reference.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameCheck {
    /// Enough of the reference's markers sit on blobs: the same gel (some identities may be
    /// withheld as ambiguous).
    SameGel,
    /// Too few marker-like blobs to judge: a dark, covered or defocused frame, not another
    /// gel.
    FewBlobs {
        /// Whole blobs in the frame.
        blobs: usize,
        /// Markers of the reference.
        reference: usize,
    },
    /// The blobs are spaced unlike the reference's markers: another gel, or the camera
    /// zoomed or moved closer.
    OtherSpacing {
        /// Median nearest-blob distance in the frame, px.
        frame_px: f64,
        /// The reference's spacing, px.
        reference_px: f64,
    },
    /// The blobs are not the size of the reference's markers: another gel or camera.
    OtherSize {
        /// Median blob area in the frame, px².
        frame_px2: f64,
        /// The reference's marker area, px².
        reference_px2: f64,
    },
    /// The blobs have the reference's size and spacing, but no placement of the
    /// reference's markers explains them: another gel of the same kind, or a camera that
    /// moved against the gel.
    OtherPlaces {
        /// Markers placed on a blob.
        placed: usize,
        /// Markers of the reference.
        markers: usize,
    },
}

impl FrameCheck {
    /// Whether the frame is another gel or camera, so that tracking against this reference
    /// cannot go on.
    pub fn is_other_gel(&self) -> bool {
        matches!(
            self,
            Self::OtherSpacing { .. } | Self::OtherSize { .. } | Self::OtherPlaces { .. }
        )
    }

    /// What the frame shows, in words, ending with what to do about it.
    pub fn describe(&self) -> String {
        match *self {
            Self::SameGel => "the frame shows the reference's gel".into(),
            Self::FewBlobs { blobs, reference } => format!(
                "the frame shows {blobs} marker-like blobs where the reference shows \
                 {reference}: the camera is dark, covered or out of focus; fix: check the \
                 lighting and the camera (the frames after it are tracked as usual)"
            ),
            Self::OtherSpacing {
                frame_px,
                reference_px,
            } => format!(
                "its markers are {frame_px:.1} px apart where the reference's are \
                 {reference_px:.1} px: another gel, or the camera's zoom or distance changed; \
                 fix: track frames of the same sensor and camera as the reference, or take a \
                 new reference"
            ),
            Self::OtherSize {
                frame_px2,
                reference_px2,
            } => format!(
                "its markers cover {frame_px2:.0} px² where the reference's cover \
                 {reference_px2:.0} px²: another gel or camera; fix: track frames of the \
                 same sensor and camera as the reference, or take a new reference"
            ),
            Self::OtherPlaces { placed, markers } => format!(
                "its markers have the reference's size and spacing, but only {placed} of the \
                 reference's {markers} can be placed on them: another gel of the same kind, \
                 or the camera moved against the gel; fix: track frames of the same sensor \
                 and camera as the reference, or take a new reference"
            ),
        }
    }
}

impl Pipeline {
    /// Judges the last frame tracked against the reference ([`FrameCheck`]).
    pub fn check_frame(&self) -> FrameCheck {
        let tracker = self.tracker();
        let markers = tracker.len();
        let placed = tracker
            .states()
            .iter()
            .filter(|s| {
                matches!(
                    s,
                    MarkerState::Tracked
                        | MarkerState::Border
                        | MarkerState::Merged
                        | MarkerState::Ambiguous
                )
            })
            .count();
        if markers == 0 || placed as f64 >= MIN_PLACED_FRACTION * markers as f64 {
            return FrameCheck::SameGel;
        }
        let whole: Vec<[f64; 3]> = self
            .blobs()
            .iter()
            .filter(|b| !b.border)
            .map(|b| [b.x, b.y, b.area_px as f64])
            .collect();
        let few = FrameCheck::FewBlobs {
            blobs: whole.len(),
            reference: markers,
        };
        // Too few blobs for their size and spacing to say anything.
        if whole.len() < MIN_JUDGED.max(markers / 20) {
            return few;
        }
        let reference = self.reference();
        let mut nearest: Vec<f64> = whole
            .iter()
            .enumerate()
            .map(|(i, a)| {
                whole
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let mut areas: Vec<f64> = whole.iter().map(|b| b[2]).collect();
        let spacing = median(&mut nearest).unwrap_or(0.0);
        let area = median(&mut areas).unwrap_or(0.0);
        let ratio = spacing / reference.spacing_px();
        if !(0.8..=1.25).contains(&ratio) {
            return FrameCheck::OtherSpacing {
                frame_px: spacing,
                reference_px: reference.spacing_px(),
            };
        }
        let ratio = area / reference.area_px();
        if !(0.5..=2.0).contains(&ratio) {
            return FrameCheck::OtherSize {
                frame_px2: area,
                reference_px2: reference.area_px(),
            };
        }
        // Markers like the reference's, but few: part of the view dark or covered.
        if (whole.len() as f64) < MIN_PLACED_FRACTION * markers as f64 {
            return few;
        }
        FrameCheck::OtherPlaces { placed, markers }
    }
}
