//! Marker identity across frames.
//!
//! Nearest-neighbour matching to the reference (MIT 2014, GelSlim) fails beyond half a
//! spacing of displacement, and a hand-set grid (Wang 2018) fails when the grid is damaged
//! or mis-sized. Here identities come from the reference detections and a neighbour graph
//! (Delaunay edges shorter than twice the spacing), and each frame is matched in four steps:
//!
//! 1. **Hypotheses.** Every marker is predicted under "nothing moved" and under "each
//!    marker keeps the median velocity of itself and its neighbours"; a hypothesis seeds a
//!    marker when exactly one detection lies within `seed_radius` of its prediction, nothing
//!    else within 0.6 spacing, and the detection's nearest prediction is that marker. The
//!    hypothesis with more seeds wins. If neither seeds a tenth of the markers (a sudden
//!    large jump), a global vote over marker→detection vectors proposes a translation — and
//!    if a second, different translation is nearly as well supported (a periodic grid moved
//!    by about half a spacing is ambiguous), nothing is seeded.
//! 2. **Propagation.** From the seeds, wave by wave through the neighbour graph: a marker's
//!    motion is predicted from its matched neighbours (inverse-square-distance mean), and it
//!    takes the nearest free detection within the gate. Claims on one detection are settled
//!    by a minimum-cost assignment (Kuhn–Munkres) over the conflicting markers, with "stay
//!    unmatched" as an option at the cost of the gate. Only the difference of motion between
//!    neighbours must stay below the gate, so large but smooth fields track.
//! 3. **Validation.** A match whose motion differs from the median of its matched
//!    neighbours' by more than the gate is undone (Wang's neighbour-flow consistency, used as
//!    a check rather than as an exponential search).
//!
//! Blobs of merged markers (pushed together at a contact edge) arrive already split by the
//! detector; markers matched to them are reported as [`MarkerState::Merged`].
//!
//! Unmatched markers are placed by their neighbours' motion and reported as
//! [`MarkerState::Predicted`] (for a few frames), [`MarkerState::OutOfView`] (predicted at
//! or beyond the border) or [`MarkerState::Lost`] — lost also, at once, when a free
//! detection lies within a spacing of the prediction: then the marker may have jumped, and
//! guessing would risk a silent swap.

use delaunator::{Point, triangulate};
use pathfinding::kuhn_munkres::kuhn_munkres_min;
use pathfinding::matrix::Matrix;

use super::detect::Blob;
use super::reference::Reference;
use super::{TrackParams, median};

/// What the tracker knows about one marker in the current frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MarkerState {
    /// Matched to its own blob.
    Tracked,
    /// Matched, but its blob touches the image border: the centroid is biased inward.
    Border,
    /// Matched to a blob it shares with a neighbour; position from splitting the blob.
    Merged,
    /// Not seen this frame; placed by its neighbours' motion.
    Predicted,
    /// Predicted at or beyond the image border.
    OutOfView,
    /// Not seen, and its whereabouts are uncertain; its position is a guess.
    Lost,
}

impl MarkerState {
    /// The name written to `markers.csv`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Tracked => "tracked",
            Self::Border => "border",
            Self::Merged => "merged",
            Self::Predicted => "predicted",
            Self::OutOfView => "out_of_view",
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
    missed: Vec<u32>,
    // Scratch, kept to avoid allocating per frame.
    hyp: Vec<[f64; 2]>,
    best_hyp: Vec<[f64; 2]>,
    assigned: Vec<u32>,
    owner: Vec<u32>,
    tentative: Vec<(u32, f64)>,
    frontier: Vec<u32>,
    next_frontier: Vec<u32>,
    in_frontier: Vec<bool>,
    buckets: Buckets,
    new_pos: Vec<[f64; 2]>,
    /// Whether only markers that were not lost may seed.
    confident_only: bool,
}

impl Tracker {
    /// Starts tracking at the reference: every marker at its reference position.
    pub fn new(reference: &Reference) -> Self {
        let reference_px: Vec<[f64; 2]> = reference.markers.iter().map(|m| [m.x, m.y]).collect();
        let n = reference_px.len();
        let (nbr_start, nbr) = neighbour_graph(&reference_px, reference.spacing_px());
        let state = reference
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
            state,
            missed: vec![0; n],
            nbr_start,
            nbr,
            spacing_px: reference.spacing_px(),
            radius_px: reference.radius_px(),
            width: reference.width() as f64,
            height: reference.height() as f64,
            params: reference.params.clone(),
            hyp: vec![[0.0; 2]; n],
            best_hyp: vec![[0.0; 2]; n],
            assigned: vec![NONE; n],
            owner: Vec::new(),
            tentative: vec![(NONE, 0.0); n],
            frontier: Vec::new(),
            next_frontier: Vec::new(),
            in_frontier: vec![false; n],
            buckets: Buckets::default(),
            new_pos: vec![[0.0; 2]; n],
            confident_only: true,
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
        self.buckets.build(blobs, self.width, self.height, 0.5 * s);

        // 1. Hypotheses: "nothing moved", "everything keeps its velocity", and common
        // translations voted by the blobs; the one that explains the frame best seeds.
        self.choose_hypothesis(blobs);
        self.seed(blobs);

        // 2. Propagation.
        self.propagate(blobs);
        // Markers no seed reached: their own hypothesis, under the seed rule.
        self.seed(blobs);
        self.propagate(blobs);

        // 3. Validation.
        self.validate(blobs);

        // 4. Positions of unmatched markers from their neighbours.
        for i in 0..n {
            self.new_pos[i] = match self.assigned[i] {
                // From the matched neighbours' total displacement, so an unmatched marker
                // does not drift by accumulating frame-to-frame guesses.
                NONE => match self.neighbour_displacement(i, blobs) {
                    Some(d) => [
                        self.reference_px[i][0] + d[0],
                        self.reference_px[i][1] + d[1],
                    ],
                    None => [
                        self.pos[i][0] + self.best_hyp[i][0],
                        self.pos[i][1] + self.best_hyp[i][1],
                    ],
                },
                b => [blobs[b as usize].x, blobs[b as usize].y],
            };
        }

        // 5. States.
        for i in 0..n {
            let p = self.new_pos[i];
            let state = match self.assigned[i] {
                NONE => {
                    self.missed[i] = self.missed[i].saturating_add(1);
                    if !self.inside(p, self.radius_px) {
                        MarkerState::OutOfView
                    } else if self.free_blob_near(p, s, blobs) {
                        MarkerState::Lost
                    } else if self.missed[i] <= self.params.max_predicted_frames
                        && self.matched_neighbours(i) > 0
                    {
                        MarkerState::Predicted
                    } else {
                        MarkerState::Lost
                    }
                }
                b => {
                    self.missed[i] = 0;
                    if blobs[b as usize].merged {
                        MarkerState::Merged
                    } else if blobs[b as usize].border {
                        MarkerState::Border
                    } else {
                        MarkerState::Tracked
                    }
                }
            };
            self.state[i] = state;
            self.vel[i] = [p[0] - self.pos[i][0], p[1] - self.pos[i][1]];
            self.pos[i] = p;
        }
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

    /// Per marker, the component-wise median velocity of itself and its neighbours.
    fn smoothed_velocity(&mut self) {
        let mut vx = Vec::with_capacity(16);
        let mut vy = Vec::with_capacity(16);
        for i in 0..self.len() {
            vx.clear();
            vy.clear();
            for &j in std::iter::once(&(i as u32)).chain(self.neighbours(i)) {
                vx.push(self.vel[j as usize][0]);
                vy.push(self.vel[j as usize][1]);
            }
            self.hyp[i] = [
                median(&mut vx).unwrap_or(0.0),
                median(&mut vy).unwrap_or(0.0),
            ];
        }
    }

    /// For each marker, the detection the seed rule gives it under `self.hyp`.
    fn seed_candidates(&self, blobs: &[Blob]) -> Vec<Option<u32>> {
        let s = self.spacing_px;
        let seed_r = self.params.seed_radius * s;
        let n = self.len();
        let mut nearest: Vec<Option<(u32, f64)>> = vec![None; n];
        // Per blob, the closest prediction.
        let mut closest = vec![(NONE, f64::INFINITY); blobs.len()];
        for (i, slot) in nearest.iter_mut().enumerate() {
            if self.assigned[i] != NONE
                || (self.confident_only && self.state[i] == MarkerState::Lost)
            {
                continue;
            }
            let q = self.predicted(i);
            let (mut b1, mut d1, mut d2) = (NONE, f64::INFINITY, f64::INFINITY);
            self.buckets.for_each_near(q, 0.6 * s, |b| {
                if self.owner[b as usize] != NONE {
                    return;
                }
                let d = dist(q, [blobs[b as usize].x, blobs[b as usize].y]);
                if d > 0.6 * s {
                    return;
                }
                if d < d1 {
                    d2 = d1;
                    (b1, d1) = (b, d);
                } else if d < d2 {
                    d2 = d;
                }
                if d < closest[b as usize].1 {
                    closest[b as usize] = (i as u32, d);
                }
            });
            if b1 != NONE && d1 < seed_r && d2 == f64::INFINITY {
                *slot = Some((b1, d1));
            }
        }
        nearest
            .iter()
            .enumerate()
            .map(|(i, c)| {
                c.filter(|(b, _)| closest[*b as usize].0 == i as u32)
                    .map(|(b, _)| b)
            })
            .collect()
    }

    fn predicted(&self, i: usize) -> [f64; 2] {
        [
            self.pos[i][0] + self.hyp[i][0],
            self.pos[i][1] + self.hyp[i][1],
        ]
    }

    /// Assigns every seed under `self.hyp`.
    fn seed(&mut self, blobs: &[Blob]) {
        let picks = self.seed_candidates(blobs);
        for (i, p) in picks.into_iter().enumerate() {
            if let Some(b) = p {
                self.assigned[i] = b;
                self.owner[b as usize] = i as u32;
            }
        }
    }

    /// Picks the hypothesis that explains the frame best (see the module doc) into
    /// `self.hyp`, and whether lost markers may seed under it.
    ///
    /// Lost markers may seed only under a hypothesis that explains the whole frame: it
    /// leaves at most 5 % of the markers it keeps in view without a blob (a stale guess
    /// aligned with a shifted copy of a grid leaves a row or column), and no clearly
    /// different hypothesis comes within 5 % of its score (a periodic grid moved by about
    /// half a spacing, with markers beyond the view, looks the same either way). A voted
    /// translation is used only under those conditions; otherwise nothing is guessed.
    fn choose_hypothesis(&mut self, blobs: &[Blob]) {
        let s = self.spacing_px;
        let n = self.len();
        // (vectors, explanation, voted)
        let mut hyps: Vec<(Vec<[f64; 2]>, Explanation, bool)> = Vec::with_capacity(6);
        self.hyp.fill([0.0; 2]);
        hyps.push((self.hyp.clone(), self.explain(blobs), false));
        self.smoothed_velocity();
        if self.hyp.iter().any(|v| v[0].hypot(v[1]) > 0.02 * s) {
            hyps.push((self.hyp.clone(), self.explain(blobs), false));
        }
        for v in self.vote_translations(blobs) {
            self.hyp.fill(v);
            hyps.push((self.hyp.clone(), self.explain(blobs), true));
        }
        let differs = |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.iter().zip(b).map(|(x, y)| dist(*x, *y)).sum::<f64>() / n.max(1) as f64 > 0.3 * s
        };
        let whole_frame = |k: usize| {
            let (v, e, _) = &hyps[k];
            let best = e.score();
            e.missing as f64 <= 0.05 * e.kept as f64 + 2.0
                && e.matched >= 3
                && hyps
                    .iter()
                    .filter(|(w, _, _)| differs(v, w))
                    .all(|(_, r, _)| r.score() < best - (0.05 * best).max(3.0))
        };
        let by_score = |pool: &mut dyn Iterator<Item = usize>| {
            pool.max_by(|&a, &b| {
                hyps[a]
                    .1
                    .score()
                    .total_cmp(&hyps[b].1.score())
                    .then(b.cmp(&a))
            })
        };
        let best = by_score(&mut (0..hyps.len())).unwrap_or(0);

        let (pick, confident_only) = if hyps[best].2 && !whole_frame(best) {
            let local = by_score(&mut (0..hyps.len()).filter(|&k| !hyps[k].2)).unwrap_or(0);
            (local, true)
        } else {
            (best, !whole_frame(best))
        };
        self.confident_only = confident_only;
        self.hyp.copy_from_slice(&hyps[pick].0);
        self.best_hyp.copy_from_slice(&hyps[pick].0);
    }

    /// Common translations of the markers supported by the blobs: the vectors from each
    /// marker to the blobs within 0.75 spacing, voted into bins of 0.1 spacing; the
    /// strongest bins (up to four, 0.3 spacing apart), each refined to the mean of its
    /// vectors.
    fn vote_translations(&self, blobs: &[Blob]) -> Vec<[f64; 2]> {
        let s = self.spacing_px;
        const BINS: usize = 17;
        let bin = 0.1 * s;
        let mut cands: Vec<[f64; 2]> = Vec::new();
        let mut hist = [[0u32; BINS]; BINS];
        for i in 0..self.len() {
            let p = self.pos[i];
            if !self.in_view(p) {
                continue;
            }
            self.buckets.for_each_near(p, 0.75 * s, |b| {
                let v = [blobs[b as usize].x - p[0], blobs[b as usize].y - p[1]];
                if v[0].hypot(v[1]) <= 0.75 * s {
                    let bx = ((v[0] / bin).round() + 8.0) as usize;
                    let by = ((v[1] / bin).round() + 8.0) as usize;
                    hist[by.min(BINS - 1)][bx.min(BINS - 1)] += 1;
                    cands.push(v);
                }
            });
        }
        let mut smooth = [[0u32; BINS]; BINS];
        for y in 0..BINS {
            for x in 0..BINS {
                for row in &hist[y.saturating_sub(1)..=(y + 1).min(BINS - 1)] {
                    smooth[y][x] += row[x.saturating_sub(1)..=(x + 1).min(BINS - 1)]
                        .iter()
                        .sum::<u32>();
                }
            }
        }
        let mut modes: Vec<[f64; 2]> = Vec::new();
        while modes.len() < 4 {
            // The strongest neighbourhood, at its strongest bin.
            let (mut top, mut key, mut at) = (0u32, 0u64, (0, 0));
            for (y, row) in smooth.iter().enumerate() {
                for (x, &v) in row.iter().enumerate() {
                    let k = ((v as u64) << 32) | hist[y][x] as u64;
                    if k > key {
                        (top, key, at) = (v, k, (x, y));
                    }
                }
            }
            if top < 3 {
                break;
            }
            let centre = [(at.0 as f64 - 8.0) * bin, (at.1 as f64 - 8.0) * bin];
            let (mut sx, mut sy, mut k) = (0.0, 0.0, 0.0);
            for c in &cands {
                if dist(*c, centre) < 1.5 * bin {
                    sx += c[0];
                    sy += c[1];
                    k += 1.0;
                }
            }
            if k > 0.0 {
                modes.push([sx / k, sy / k]);
            }
            for (y, row) in smooth.iter_mut().enumerate() {
                for (x, v) in row.iter_mut().enumerate() {
                    let d = (x as f64 - at.0 as f64).hypot(y as f64 - at.1 as f64) * bin;
                    if d < 0.3 * s {
                        *v = 0;
                    }
                }
            }
        }
        modes
    }

    /// How well the predictions under `self.hyp` explain the blobs of the frame.
    fn explain(&self, blobs: &[Blob]) -> Explanation {
        let tol = self.params.seed_radius * self.spacing_px;
        let mut hit = vec![false; blobs.len()];
        let mut e = Explanation::default();
        for i in 0..self.len() {
            let q = self.predicted(i);
            if !self.inside(q, self.radius_px) {
                continue;
            }
            e.kept += 1;
            let mut found = false;
            self.buckets.for_each_near(q, tol, |b| {
                if dist(q, [blobs[b as usize].x, blobs[b as usize].y]) < tol {
                    hit[b as usize] = true;
                    found = true;
                }
            });
            if found {
                e.matched += 1;
            } else {
                e.missing += 1;
            }
        }
        e.unexplained = blobs
            .iter()
            .zip(&hit)
            .filter(|(b, h)| !**h && !b.border)
            .count();
        e
    }

    /// Motion of marker `i` since the previous frame, predicted from its matched neighbours.
    fn neighbour_motion(&self, i: usize, blobs: &[Blob]) -> Option<[f64; 2]> {
        self.neighbour_mean(i, blobs, |j| self.pos[j])
    }

    /// Displacement from the reference of marker `i`, interpolated from its matched
    /// neighbours.
    fn neighbour_displacement(&self, i: usize, blobs: &[Blob]) -> Option<[f64; 2]> {
        self.neighbour_mean(i, blobs, |j| self.reference_px[j])
    }

    /// Inverse-square-distance mean over the matched neighbours of marker `i` of the
    /// vector from `origin(j)` to neighbour `j`'s blob.
    fn neighbour_mean(
        &self,
        i: usize,
        blobs: &[Blob],
        origin: impl Fn(usize) -> [f64; 2],
    ) -> Option<[f64; 2]> {
        let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
        let r = self.reference_px[i];
        for &j in self.neighbours(i) {
            let j = j as usize;
            let b = self.assigned[j];
            if b == NONE {
                continue;
            }
            let rj = self.reference_px[j];
            let w = 1.0 / ((r[0] - rj[0]).powi(2) + (r[1] - rj[1]).powi(2)).max(1e-6);
            let o = origin(j);
            sx += w * (blobs[b as usize].x - o[0]);
            sy += w * (blobs[b as usize].y - o[1]);
            sw += w;
        }
        (sw > 0.0).then(|| [sx / sw, sy / sw])
    }

    fn matched_neighbours(&self, i: usize) -> usize {
        self.neighbours(i)
            .iter()
            .filter(|&&j| self.assigned[j as usize] != NONE)
            .count()
    }

    /// Wave-by-wave matching from the matched markers outward.
    fn propagate(&mut self, blobs: &[Blob]) {
        let gate = self.params.gate * self.spacing_px;
        self.frontier.clear();
        self.in_frontier.fill(false);
        for i in 0..self.len() {
            if self.assigned[i] == NONE && self.matched_neighbours(i) > 0 {
                self.frontier.push(i as u32);
                self.in_frontier[i] = true;
            }
        }
        while !self.frontier.is_empty() {
            // Tentative nearest free detection for each frontier marker.
            for k in 0..self.frontier.len() {
                let i = self.frontier[k] as usize;
                self.tentative[i] = (NONE, f64::INFINITY);
                let Some(m) = self.neighbour_motion(i, blobs) else {
                    continue;
                };
                let q = [self.pos[i][0] + m[0], self.pos[i][1] + m[1]];
                let mut best = (NONE, f64::INFINITY);
                self.buckets.for_each_near(q, gate, |b| {
                    if self.owner[b as usize] != NONE {
                        return;
                    }
                    let d = dist(q, [blobs[b as usize].x, blobs[b as usize].y]);
                    if d < gate && d < best.1 {
                        best = (b, d);
                    }
                });
                self.tentative[i] = best;
            }
            // Settle claims: unique claims directly, shared ones by assignment.
            let frontier = std::mem::take(&mut self.frontier);
            let mut claims: Vec<(u32, u32)> = frontier
                .iter()
                .filter(|&&i| self.tentative[i as usize].0 != NONE)
                .map(|&i| (self.tentative[i as usize].0, i))
                .collect();
            claims.sort_unstable();
            let mut newly = Vec::new();
            let mut k = 0;
            while k < claims.len() {
                let mut e = k + 1;
                while e < claims.len() && claims[e].0 == claims[k].0 {
                    e += 1;
                }
                if e - k == 1 {
                    let (b, i) = claims[k];
                    if self.owner[b as usize] == NONE {
                        self.assigned[i as usize] = b;
                        self.owner[b as usize] = i;
                        newly.push(i);
                    }
                } else {
                    let markers: Vec<u32> = claims[k..e].iter().map(|c| c.1).collect();
                    newly.extend(self.resolve_conflict(&markers, blobs, gate));
                }
                k = e;
            }
            for &i in &frontier {
                self.in_frontier[i as usize] = false;
            }
            self.frontier = frontier;
            self.frontier.clear();
            // Next wave: unmatched neighbours of the newly matched.
            self.next_frontier.clear();
            for &i in &newly {
                let (a, b) = (
                    self.nbr_start[i as usize] as usize,
                    self.nbr_start[i as usize + 1] as usize,
                );
                for t in a..b {
                    let j = self.nbr[t] as usize;
                    if self.assigned[j] == NONE && !self.in_frontier[j] {
                        self.in_frontier[j] = true;
                        self.next_frontier.push(j as u32);
                    }
                }
            }
            std::mem::swap(&mut self.frontier, &mut self.next_frontier);
        }
    }

    /// Minimum-cost matching of `markers` to the free detections within the gate of their
    /// neighbour-predicted positions; returns the markers matched.
    fn resolve_conflict(&mut self, markers: &[u32], blobs: &[Blob], gate: f64) -> Vec<u32> {
        let mut cols: Vec<u32> = Vec::new();
        let mut preds = Vec::with_capacity(markers.len());
        for &i in markers {
            let m = self.neighbour_motion(i as usize, blobs).unwrap_or([0.0; 2]);
            let q = [
                self.pos[i as usize][0] + m[0],
                self.pos[i as usize][1] + m[1],
            ];
            preds.push(q);
            self.buckets.for_each_near(q, gate, |b| {
                if self.owner[b as usize] == NONE && !cols.contains(&b) {
                    cols.push(b);
                }
            });
        }
        // Costs in 1/1000 px²; extra columns mean "stays unmatched" at the gate's cost.
        let (r, c) = (markers.len(), cols.len() + markers.len());
        let scale = 1000.0;
        let unmatched = (gate * gate * scale) as i64;
        let mut costs = Matrix::new(r, c, unmatched);
        for (row, q) in preds.iter().enumerate() {
            for (col, &b) in cols.iter().enumerate() {
                let d = dist(*q, [blobs[b as usize].x, blobs[b as usize].y]);
                costs[(row, col)] = if d < gate {
                    (d * d * scale) as i64
                } else {
                    100 * unmatched + 1
                };
            }
        }
        let (_, pick) = kuhn_munkres_min(&costs);
        let mut matched = Vec::new();
        for (row, &col) in pick.iter().enumerate() {
            if col < cols.len() && costs[(row, col)] < unmatched {
                let (i, b) = (markers[row], cols[col]);
                self.assigned[i as usize] = b;
                self.owner[b as usize] = i;
                matched.push(i);
            }
        }
        matched
    }

    /// Undoes matches whose motion since the last frame, or whose displacement from the
    /// reference, disagrees with the median of their matched neighbours'.
    fn validate(&mut self, blobs: &[Blob]) {
        let gate = self.params.gate * self.spacing_px;
        let strain = self.params.strain_limit * self.spacing_px;
        let mut undo = Vec::new();
        let (mut mx, mut my, mut dx, mut dy) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for i in 0..self.len() {
            let b = self.assigned[i];
            if b == NONE {
                continue;
            }
            mx.clear();
            my.clear();
            dx.clear();
            dy.clear();
            for &j in self.neighbours(i) {
                let (j, bj) = (j as usize, self.assigned[j as usize]);
                if bj != NONE {
                    let (x, y) = (blobs[bj as usize].x, blobs[bj as usize].y);
                    mx.push(x - self.pos[j][0]);
                    my.push(y - self.pos[j][1]);
                    dx.push(x - self.reference_px[j][0]);
                    dy.push(y - self.reference_px[j][1]);
                }
            }
            if mx.is_empty() {
                continue;
            }
            let m = [
                median(&mut mx).unwrap_or(0.0),
                median(&mut my).unwrap_or(0.0),
            ];
            let d = [
                median(&mut dx).unwrap_or(0.0),
                median(&mut dy).unwrap_or(0.0),
            ];
            let (x, y) = (blobs[b as usize].x, blobs[b as usize].y);
            let own_motion = [x - self.pos[i][0], y - self.pos[i][1]];
            let own_total = [x - self.reference_px[i][0], y - self.reference_px[i][1]];
            // One neighbour can vouch for a displacement but not veto a motion.
            if (mx.len() >= 2 && dist(own_motion, m) > gate) || dist(own_total, d) > strain {
                undo.push(i);
            }
        }
        for i in undo {
            let b = self.assigned[i];
            self.owner[b as usize] = NONE;
            self.assigned[i] = NONE;
        }
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

/// How a hypothesis explains a frame.
#[derive(Debug, Clone, Copy, Default)]
struct Explanation {
    /// Markers whose prediction lands on a blob.
    matched: usize,
    /// Markers predicted whole in view that land on no blob.
    missing: usize,
    /// Interior blobs no prediction lands on.
    unexplained: usize,
    /// Markers predicted whole in view.
    kept: usize,
}

impl Explanation {
    /// Matched minus missing minus unexplained: a hypothesis that is one spacing off on a
    /// grid fully in view loses a column of markers and leaves a column of blobs over.
    fn score(&self) -> f64 {
        self.matched as f64 - self.missing as f64 - self.unexplained as f64
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Delaunay edges shorter than twice the spacing, plus each marker's nearest neighbour
/// (so collinear or sparse layouts still connect), as compressed rows.
fn neighbour_graph(points: &[[f64; 2]], spacing_px: f64) -> (Vec<u32>, Vec<u32>) {
    let n = points.len();
    let mut adj: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut link = |a: usize, b: usize| {
        if a != b && !adj[a].contains(&(b as u32)) {
            adj[a].push(b as u32);
            adj[b].push(a as u32);
        }
    };
    let pts: Vec<Point> = points.iter().map(|p| Point { x: p[0], y: p[1] }).collect();
    let tri = triangulate(&pts);
    for t in tri.triangles.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if dist(points[a], points[b]) < 2.0 * spacing_px {
                link(a, b);
            }
        }
    }
    for a in 0..n {
        let nearest = (0..n)
            .filter(|&b| b != a)
            .min_by(|&x, &y| dist(points[a], points[x]).total_cmp(&dist(points[a], points[y])));
        if let Some(b) = nearest {
            link(a, b);
        }
    }
    let mut start = Vec::with_capacity(n + 1);
    let mut flat = Vec::new();
    start.push(0);
    for mut list in adj {
        list.sort_unstable();
        flat.extend(list);
        start.push(flat.len() as u32);
    }
    (start, flat)
}

/// A uniform grid of blob indices for radius queries.
#[derive(Debug, Clone, Default)]
struct Buckets {
    cell: f64,
    cols: usize,
    rows: usize,
    start: Vec<u32>,
    items: Vec<u32>,
    xy: Vec<[f64; 2]>,
}

impl Buckets {
    fn build(&mut self, blobs: &[Blob], width: f64, height: f64, cell: f64) {
        self.cell = cell.max(1.0);
        self.cols = (width / self.cell).ceil() as usize + 1;
        self.rows = (height / self.cell).ceil() as usize + 1;
        let cells = self.cols * self.rows;
        self.start.clear();
        self.start.resize(cells + 1, 0);
        self.xy.clear();
        self.xy.extend(blobs.iter().map(|b| [b.x, b.y]));
        let cell_of = |p: [f64; 2], cols: usize, rows: usize, size: f64| {
            let cx = ((p[0] / size).floor().max(0.0) as usize).min(cols - 1);
            let cy = ((p[1] / size).floor().max(0.0) as usize).min(rows - 1);
            cy * cols + cx
        };
        for p in &self.xy {
            self.start[cell_of(*p, self.cols, self.rows, self.cell) + 1] += 1;
        }
        for c in 0..cells {
            self.start[c + 1] += self.start[c];
        }
        self.items.clear();
        self.items.resize(blobs.len(), 0);
        let mut fill = self.start.clone();
        for (i, p) in self.xy.iter().enumerate() {
            let c = cell_of(*p, self.cols, self.rows, self.cell);
            self.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
    }

    /// Calls `f` for every blob in the cells that overlap the disc (a superset of it).
    fn for_each_near(&self, p: [f64; 2], radius: f64, mut f: impl FnMut(u32)) {
        if self.cols == 0 || !p[0].is_finite() || !p[1].is_finite() {
            return;
        }
        let lo = |v: f64| ((v - radius) / self.cell).floor().max(0.0) as usize;
        let hi =
            |v: f64, n: usize| (((v + radius) / self.cell).floor().max(0.0) as usize).min(n - 1);
        let (x0, x1) = (lo(p[0]).min(self.cols - 1), hi(p[0], self.cols));
        let (y0, y1) = (lo(p[1]).min(self.rows - 1), hi(p[1], self.rows));
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                let c = cy * self.cols + cx;
                for k in self.start[c]..self.start[c + 1] {
                    f(self.items[k as usize]);
                }
            }
        }
    }
}
