//! Marker identity across frames, reported only when it is certain.
//!
//! Nearest-neighbour matching to the reference (MIT 2014, GelSlim) fails beyond half a
//! spacing of displacement, and a hand-set grid (Wang 2018) fails when the grid is damaged
//! or mis-sized. Worse than failing, a matcher on a periodic lattice can be *confidently
//! wrong*: a whole region, or the whole grid, slips by one lattice step and still matches
//! every blob. Identities here come from the reference detections and a neighbour graph
//! (Delaunay edges shorter than twice the spacing), and each frame is matched in four
//! steps, each of which can only withhold an identity, never guess one:
//!
//! 1. **A global motion first** ([`hypotheses`]). Candidate motions of the whole gel since
//!    the last frame: none, each marker's velocity (smoothed over its neighbours), common
//!    translations voted by all marker→blob vectors up to 1.6 spacings around the velocity
//!    and around standing still (2.6 when nothing nearer explains the frame), and — when
//!    none of these explains the frame — similarity transforms (rotation, translation,
//!    scale) by RANSAC. Each is scored by what cannot alias: predictions in view landing on
//!    nothing (the lattice's edges and holes), and blobs no prediction explains that could
//!    not have entered the view under that motion. Among the motions the evidence leaves
//!    standing, the **smaller** is taken (a gel's motion between two frames is bounded;
//!    the velocity is not used to choose, since at a reversal it points at the neighbouring
//!    alias); two clearly different motions about equally small are *aliases*.
//!    **Aliases are carried** ([`aliases`]): the frame is followed provisionally, and its
//!    identities are withheld ([`MarkerState::Ambiguous`]) until the evidence of a later
//!    frame leaves only one placement standing.
//! 2. **Most certain first** ([`grow`]). Seeds: markers with exactly one blob near their
//!    prediction and no other within 0.6 spacing, mutually nearest. From them, best-first:
//!    the cheapest (prediction, blob) pair anywhere is matched next, and each match predicts
//!    its unmatched neighbours by a local affine fit of their matched neighbours' motion —
//!    exact for rotation, twist and strain, so a twisted contact is followed from its centre
//!    and from outside inwards before an aliased seed can spread.
//! 3. **Local checks.** A match whose displacement differs from the median of its matched
//!    neighbours' by more than `strain_limit` is undone (a swap differs by a spacing).
//! 4. **The whole field must be one field** ([`consistency`]). Matched markers joined by
//!    edges of consistent displacement form components; a component that meets a larger one
//!    across inconsistent edges has slipped by a lattice step and is undone, and the larger
//!    one grows into the space it leaves. A component no other one reaches is kept only if
//!    its motion since the last frame was small (temporal continuity); otherwise its markers
//!    are reported ambiguous.
//!
//! Blobs of merged markers (pushed together at a contact edge) arrive already split by the
//! detector; markers matched to them are reported as [`MarkerState::Merged`].
//!
//! Unmatched markers are placed by their neighbours' motion and reported as
//! [`MarkerState::Predicted`] (for a few frames), [`MarkerState::OutOfView`] (predicted at
//! or beyond the border), [`MarkerState::Ambiguous`] (a blob is there but the identity was
//! withheld) or [`MarkerState::Lost`].
//!
//! Each marker also carries a confidence in [0, 1]: for a measured marker, the lower of the
//! frame's hypothesis margin and the local margin between its blob and the next blob
//! around its prediction; 0 for a marker not measured.

mod aliases;
mod consistency;
mod grow;
mod hypotheses;
mod spatial;

use super::TrackParams;
use super::detect::Blob;
use super::reference::Reference;
use spatial::{Buckets, neighbour_graph};

/// What the tracker knows about one marker in the current frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MarkerState {
    /// Matched to its own blob, identity certain.
    Tracked,
    /// Matched, but its blob touches the image border: the centroid is biased inward.
    Border,
    /// Matched to a blob it shares with a neighbour; position from splitting the blob.
    Merged,
    /// Not seen this frame; placed by its neighbours' motion.
    Predicted,
    /// Predicted at or beyond the image border.
    OutOfView,
    /// Two placements of the markers explain the frame (and every frame since the last
    /// certain one) about equally well — a periodic grid moved by about half a spacing, or
    /// by a whole one with its edges out of view — or the marker's region contradicts the
    /// rest of the field; the identity is withheld rather than guessed. The position is
    /// where the smaller motion puts it (a blob, when one is there), not a measurement.
    Ambiguous,
    /// Not seen, and its whereabouts are uncertain; its position is a guess.
    Lost,
}

impl MarkerState {
    /// Every state, in the order summaries list them.
    pub const ALL: [Self; 7] = [
        Self::Tracked,
        Self::Border,
        Self::Merged,
        Self::Predicted,
        Self::OutOfView,
        Self::Ambiguous,
        Self::Lost,
    ];

    /// The name written to `markers.csv`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Tracked => "tracked",
            Self::Border => "border",
            Self::Merged => "merged",
            Self::Predicted => "predicted",
            Self::OutOfView => "out_of_view",
            Self::Ambiguous => "ambiguous",
            Self::Lost => "lost",
        }
    }

    /// Whether the position was measured in this frame (not inferred).
    pub fn is_measured(self) -> bool {
        matches!(self, Self::Tracked | Self::Border | Self::Merged)
    }
}

const NONE: u32 = u32::MAX;

/// Keeps every reference marker's identity, position and state from frame to frame.
#[derive(Debug, Clone)]
pub struct Tracker {
    reference_px: Vec<[f64; 2]>,
    nbr_start: Vec<u32>,
    nbr: Vec<u32>,
    spacing_px: f64,
    radius_px: f64,
    width: f64,
    height: f64,
    params: TrackParams,
    pos: Vec<[f64; 2]>,
    vel: Vec<[f64; 2]>,
    state: Vec<MarkerState>,
    prev_state: Vec<MarkerState>,
    missed: Vec<u32>,
    confidence: Vec<f64>,
    /// Motion since the last frame under the chosen hypothesis, per marker.
    hyp: Vec<[f64; 2]>,
    /// Matched blob per marker.
    assigned: Vec<u32>,
    /// Marker per blob.
    owner: Vec<u32>,
    /// Identity withheld this frame (ambiguous hypothesis or contradicting region).
    withheld: Vec<bool>,
    buckets: Buckets,
    /// Blobs no marker held in the last frame (markers beyond the reference's, entering).
    foreign_px: Vec<[f64; 2]>,
    foreign: Buckets,
    new_pos: Vec<[f64; 2]>,
    /// Whether only markers whose identity was certain last frame may seed.
    confident_only: bool,
    /// The chosen hypothesis's margin over its nearest rival, in [0, 1].
    global_confidence: f64,
    /// Consecutive frames with fewer than three blobs (camera dark or covered).
    blind_run: u32,
    /// The frame follows blind frames.
    after_blind: bool,
    /// Which markers were measured in the last frame that showed blobs.
    measured_before_blind: Vec<bool>,
    /// Which markers were matched to a blob last frame, their identity certain or not.
    prev_matched: Vec<bool>,
    /// Which of them to a whole blob (not touching the border).
    prev_whole: Vec<bool>,
    /// Uniform offsets, px, at which the markers would explain every frame since their
    /// identities were last certain as well as where they are placed ([`aliases`]).
    aliases: Vec<[f64; 2]>,
}

impl Tracker {
    /// Starts tracking at the reference: every marker at its reference position.
    pub fn new(reference: &Reference) -> Self {
        let reference_px: Vec<[f64; 2]> = reference.markers.iter().map(|m| [m.x, m.y]).collect();
        let n = reference_px.len();
        let (nbr_start, nbr) = neighbour_graph(&reference_px, reference.spacing_px());
        let state: Vec<MarkerState> = reference
            .markers
            .iter()
            .map(|m| {
                if m.border {
                    MarkerState::Border
                } else {
                    MarkerState::Tracked
                }
            })
            .collect();
        Self {
            pos: reference_px.clone(),
            vel: vec![[0.0; 2]; n],
            prev_state: state.clone(),
            state,
            missed: vec![0; n],
            confidence: vec![1.0; n],
            nbr_start,
            nbr,
            spacing_px: reference.spacing_px(),
            radius_px: reference.radius_px(),
            width: reference.width() as f64,
            height: reference.height() as f64,
            params: reference.params.clone(),
            hyp: vec![[0.0; 2]; n],
            assigned: vec![NONE; n],
            owner: Vec::new(),
            withheld: vec![false; n],
            buckets: Buckets::default(),
            foreign_px: Vec::new(),
            foreign: Buckets::default(),
            new_pos: vec![[0.0; 2]; n],
            confident_only: true,
            global_confidence: 1.0,
            blind_run: 0,
            after_blind: false,
            measured_before_blind: vec![true; n],
            prev_matched: vec![true; n],
            prev_whole: reference.markers.iter().map(|m| !m.border).collect(),
            aliases: Vec::new(),
            reference_px,
        }
    }

    /// Number of markers (identities).
    pub fn len(&self) -> usize {
        self.reference_px.len()
    }

    /// Whether there are no markers.
    pub fn is_empty(&self) -> bool {
        self.reference_px.is_empty()
    }

    /// Reference positions, px; index = identity.
    pub fn reference_px(&self) -> &[[f64; 2]] {
        &self.reference_px
    }

    /// Current positions, px.
    pub fn positions_px(&self) -> &[[f64; 2]] {
        &self.pos
    }

    /// Current displacement of marker `id` from the reference, px.
    pub fn displacement_px(&self, id: usize) -> [f64; 2] {
        [
            self.pos[id][0] - self.reference_px[id][0],
            self.pos[id][1] - self.reference_px[id][1],
        ]
    }

    /// Current states.
    pub fn states(&self) -> &[MarkerState] {
        &self.state
    }

    /// Per-marker confidence in the identity, in [0, 1] (0 when not measured).
    pub fn confidences(&self) -> &[f64] {
        &self.confidence
    }

    /// Neighbours of marker `id` in the reference graph.
    pub fn neighbours(&self, id: usize) -> &[u32] {
        &self.nbr[self.nbr_start[id] as usize..self.nbr_start[id + 1] as usize]
    }

    /// Marker spacing, px.
    pub fn spacing_px(&self) -> f64 {
        self.spacing_px
    }

    /// Overwrites the current positions (after an external refinement such as
    /// [`super::lk`]); states are kept.
    pub fn set_positions(&mut self, positions_px: &[[f64; 2]]) {
        for (p, q) in self.pos.iter_mut().zip(positions_px) {
            *p = *q;
        }
    }

    /// Matches the blobs found in the current frame ([`super::Detector::detect`]) to the
    /// markers.
    pub fn update(&mut self, blobs: &[Blob]) {
        let n = self.len();
        let s = self.spacing_px;
        self.owner.clear();
        self.owner.resize(blobs.len(), NONE);
        self.assigned.fill(NONE);
        self.withheld.fill(false);
        self.buckets.build(blobs, self.width, self.height, 0.5 * s);
        self.prev_state.copy_from_slice(&self.state);
        let blind = blobs.len() < 3;
        self.after_blind = !blind && self.blind_run > 0;

        // 1. The global motion, and the aliases the lattice leaves it (an ambiguous frame
        // is followed provisionally, its identities withheld).
        let tie = self.choose_hypothesis(blobs);
        let certain = self.settle_aliases(&tie, blobs);
        // 2–4. Seeds, best-first growth, local checks, one field.
        self.seed_and_grow(blobs);
        self.validate(blobs);
        self.enforce_consistency(blobs);
        if !certain {
            self.withheld.fill(true);
        }

        // Positions of unmatched markers: from their matched neighbours' displacement (so
        // they do not drift by accumulating guesses), else their own prediction.
        for i in 0..n {
            self.new_pos[i] = match self.assigned[i] {
                NONE => match self.neighbour_displacement(i, blobs) {
                    Some(d) => [
                        self.reference_px[i][0] + d[0],
                        self.reference_px[i][1] + d[1],
                    ],
                    None => [
                        self.pos[i][0] + self.hyp[i][0],
                        self.pos[i][1] + self.hyp[i][1],
                    ],
                },
                b => [blobs[b as usize].x, blobs[b as usize].y],
            };
        }

        // States and confidences.
        for i in 0..n {
            let p = self.new_pos[i];
            let (state, confidence) = match self.assigned[i] {
                NONE => {
                    self.missed[i] = self.missed[i].saturating_add(1);
                    let state = if !self.inside(p, self.radius_px) {
                        MarkerState::OutOfView
                    } else if self.free_blob_near(p, 0.6 * s, blobs) {
                        // A blob is there and nobody holds it: the marker may have jumped
                        // onto it, so its identity is withheld (ambiguous when a hypothesis
                        // or a region was refused, lost otherwise).
                        if self.withheld[i] {
                            MarkerState::Ambiguous
                        } else {
                            MarkerState::Lost
                        }
                    } else if self.missed[i] <= self.params.max_predicted_frames
                        && self.matched_neighbours(i) > 0
                    {
                        MarkerState::Predicted
                    } else if self.withheld[i] {
                        MarkerState::Ambiguous
                    } else {
                        MarkerState::Lost
                    };
                    (state, 0.0)
                }
                _ if !certain => {
                    self.missed[i] = 0;
                    (MarkerState::Ambiguous, 0.0)
                }
                b => {
                    self.missed[i] = 0;
                    let blob = &blobs[b as usize];
                    let state = if blob.merged {
                        MarkerState::Merged
                    } else if blob.border {
                        MarkerState::Border
                    } else {
                        MarkerState::Tracked
                    };
                    (
                        state,
                        self.global_confidence.min(self.local_margin(i, b, blobs)),
                    )
                }
            };
            self.state[i] = state;
            self.confidence[i] = confidence;
            // Velocity is the motion prior of the next frame: only a measured motion is one
            // (a provisional one included).
            self.vel[i] = if self.assigned[i] != NONE
                || matches!(
                    state,
                    MarkerState::Tracked
                        | MarkerState::Border
                        | MarkerState::Merged
                        | MarkerState::Predicted
                        | MarkerState::OutOfView
                ) {
                [p[0] - self.pos[i][0], p[1] - self.pos[i][1]]
            } else {
                [0.0; 2]
            };
            self.pos[i] = p;
        }
        for i in 0..n {
            let b = self.assigned[i];
            self.prev_matched[i] = b != NONE;
            self.prev_whole[i] = b != NONE && !blobs[b as usize].border;
        }
        if blind {
            self.blind_run = self.blind_run.saturating_add(1);
        } else {
            self.blind_run = 0;
            for (m, st) in self.measured_before_blind.iter_mut().zip(&self.state) {
                *m = st.is_measured();
            }
        }
        self.foreign_px.clear();
        self.foreign_px.extend(
            (0..blobs.len())
                .filter(|&b| self.owner[b] == NONE)
                .map(|b| [blobs[b].x, blobs[b].y]),
        );
        self.foreign.build_points(
            self.foreign_px.iter().copied(),
            self.width,
            self.height,
            0.5 * s,
        );
    }

    fn inside(&self, p: [f64; 2], margin: f64) -> bool {
        p[0] >= margin - 0.5
            && p[1] >= margin - 0.5
            && p[0] <= self.width - 0.5 - margin
            && p[1] <= self.height - 0.5 - margin
    }

    fn in_view(&self, p: [f64; 2]) -> bool {
        self.inside(p, 0.0)
    }

    /// Local margin of marker `i`'s match to blob `b`: how much nearer its blob is to where
    /// its neighbours put it than the next blob, `(d₂ − d₁)/(d₂ + d₁)`.
    fn local_margin(&self, i: usize, b: u32, blobs: &[Blob]) -> f64 {
        let q = match self.neighbour_motion(i, blobs) {
            Some(m) => [self.pos[i][0] + m[0], self.pos[i][1] + m[1]],
            None => [
                self.pos[i][0] + self.hyp[i][0],
                self.pos[i][1] + self.hyp[i][1],
            ],
        };
        let own = [blobs[b as usize].x, blobs[b as usize].y];
        let d1 = dist(q, own);
        let mut d2 = self.spacing_px;
        self.buckets.for_each_near(q, self.spacing_px, |c| {
            if c != b {
                d2 = d2.min(dist(q, [blobs[c as usize].x, blobs[c as usize].y]));
            }
        });
        ((d2 - d1) / (d2 + d1).max(1e-9)).clamp(0.0, 1.0)
    }

    /// Number of matched neighbours of marker `i`.
    fn matched_neighbours(&self, i: usize) -> usize {
        self.neighbours(i)
            .iter()
            .filter(|&&j| self.assigned[j as usize] != NONE)
            .count()
    }

    /// Whether a blob nobody holds lies within `radius` of `p`.
    fn free_blob_near(&self, p: [f64; 2], radius: f64, blobs: &[Blob]) -> bool {
        let mut found = false;
        self.buckets.for_each_near(p, radius, |b| {
            if self.owner[b as usize] == NONE
                && dist(p, [blobs[b as usize].x, blobs[b as usize].y]) < radius
            {
                found = true;
            }
        });
        found
    }
}

/// Euclidean distance; `sqrt` of the squares rather than `hypot`, whose overflow care costs
/// a tenth of the tracker's time and is not needed at pixel scale.
fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    norm([a[0] - b[0], a[1] - b[1]])
}

/// A vector's length. Not `f64::hypot`: its guard against overflow is a library call that
/// cost about a hundredth of a frame's tracking, and no displacement here comes near it.
fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}
