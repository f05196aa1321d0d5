//! Steps 2 and 3: seeds under the chosen motion, best-first growth through the neighbour
//! graph, and the local check of each match against its neighbours.
//!
//! Growth is greedy on certainty rather than on graph order: a heap holds, for every
//! unmatched marker next to a match (and every seed), the distance from its prediction to
//! the nearest free blob, and the smallest is matched first. A marker's prediction comes
//! from a weighted least-squares affine fit of its matched neighbours' motion (exact for
//! translation, rotation and uniform strain), recomputed when the marker comes up, so a
//! region is followed by the field around it before any guess elsewhere can claim its
//! blobs.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::super::detect::Blob;
use super::super::median;
use super::{NONE, Tracker, dist};

/// A candidate match on the heap: cost (distance / spacing, as ordered bits), marker, blob,
/// and whether it is a seed (whose prediction is the hypothesis, not the neighbours).
type Candidate = Reverse<(u64, u32, u32, bool)>;

fn key(cost: f64) -> u64 {
    // Non-negative finite floats order like their bits.
    cost.max(0.0).to_bits()
}

impl Tracker {
    /// For each marker, the detection the seed rule gives it under `self.hyp`: exactly one
    /// blob within `seed_radius` of its prediction, nothing else within 0.6 spacing, and
    /// no other prediction nearer to that blob.
    fn seeds(&self, blobs: &[Blob]) -> Vec<(u32, u32, f64)> {
        let s = self.spacing_px;
        let seed_r = self.params.seed_radius * s;
        let n = self.len();
        let mut nearest: Vec<Option<(u32, f64)>> = vec![None; n];
        let mut closest = vec![(NONE, f64::INFINITY); blobs.len()];
        for (i, slot) in nearest.iter_mut().enumerate() {
            if self.confident_only
                && !self.prev_matched[i]
                && matches!(
                    self.prev_state[i],
                    super::MarkerState::Lost | super::MarkerState::Ambiguous
                )
            {
                continue;
            }
            let q = self.predicted(i);
            let (mut b1, mut d1, mut d2) = (NONE, f64::INFINITY, f64::INFINITY);
            self.buckets.for_each_near(q, 0.6 * s, |b| {
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
            .filter_map(|(i, c)| {
                c.filter(|(b, _)| closest[*b as usize].0 == i as u32)
                    .map(|(b, d)| (i as u32, b, d / s))
            })
            .collect()
    }

    fn predicted(&self, i: usize) -> [f64; 2] {
        [
            self.pos[i][0] + self.hyp[i][0],
            self.pos[i][1] + self.hyp[i][1],
        ]
    }

    /// Seeds, then growth from them.
    pub(super) fn seed_and_grow(&mut self, blobs: &[Blob]) {
        let mut heap: BinaryHeap<Candidate> = self
            .seeds(blobs)
            .into_iter()
            .map(|(i, b, c)| Reverse((key(c), i, b, true)))
            .collect();
        self.grow(blobs, &mut heap);
    }

    /// Growth from the current matches into every unmatched marker next to one.
    pub(super) fn regrow(&mut self, blobs: &[Blob]) {
        let mut heap = BinaryHeap::new();
        for i in 0..self.len() {
            if self.assigned[i] == NONE
                && self.matched_neighbours(i) > 0
                && let Some((b, c)) = self.candidate(i, blobs)
            {
                heap.push(Reverse((key(c), i as u32, b, false)));
            }
        }
        self.grow(blobs, &mut heap);
    }

    fn grow(&mut self, blobs: &[Blob], heap: &mut BinaryHeap<Candidate>) {
        while let Some(Reverse((cost, i, b, seed))) = heap.pop() {
            let iu = i as usize;
            if self.assigned[iu] != NONE {
                continue;
            }
            let (b, fresh) = if seed && self.owner[b as usize] == NONE {
                (b, true)
            } else {
                // Re-predict from the neighbours matched since; take it if no dearer.
                match self.candidate(iu, blobs) {
                    Some((nb, c)) if key(c) <= cost || nb == b => (nb, true),
                    Some((nb, c)) => {
                        heap.push(Reverse((key(c), i, nb, false)));
                        (nb, false)
                    }
                    None => continue,
                }
            };
            if !fresh || self.owner[b as usize] != NONE {
                continue;
            }
            self.assigned[iu] = b;
            self.owner[b as usize] = i;
            for k in self.nbr_start[iu] as usize..self.nbr_start[iu + 1] as usize {
                let j = self.nbr[k] as usize;
                if self.assigned[j] == NONE
                    && let Some((bj, c)) = self.candidate(j, blobs)
                {
                    heap.push(Reverse((key(c), j as u32, bj, false)));
                }
            }
        }
    }

    /// Marker `i`'s nearest free blob within the gate of its neighbour-predicted position,
    /// and the distance in spacings.
    fn candidate(&self, i: usize, blobs: &[Blob]) -> Option<(u32, f64)> {
        let gate = self.params.gate * self.spacing_px;
        let m = self.neighbour_motion(i, blobs)?;
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
        (best.0 != NONE).then(|| (best.0, best.1 / self.spacing_px))
    }

    /// Motion of marker `i` since the previous frame, predicted from its matched neighbours.
    pub(super) fn neighbour_motion(&self, i: usize, blobs: &[Blob]) -> Option<[f64; 2]> {
        self.neighbour_affine(i, blobs, |j| self.pos[j])
    }

    /// Displacement from the reference of marker `i`, interpolated from its matched
    /// neighbours (inverse-square-distance mean: a placement, not a prediction).
    pub(super) fn neighbour_displacement(&self, i: usize, blobs: &[Blob]) -> Option<[f64; 2]> {
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
            sx += w * (blobs[b as usize].x - rj[0]);
            sy += w * (blobs[b as usize].y - rj[1]);
            sw += w;
        }
        (sw > 0.0).then(|| [sx / sw, sy / sw])
    }

    /// The vector from `origin(j)` to each matched neighbour `j`'s blob, fitted as an
    /// affine function of the reference position by least squares weighted by inverse
    /// square distance, evaluated at marker `i` (exact for rotation and uniform strain);
    /// with fewer than three matched neighbours, or nearly collinear ones, their weighted
    /// mean.
    fn neighbour_affine(
        &self,
        i: usize,
        blobs: &[Blob],
        origin: impl Fn(usize) -> [f64; 2],
    ) -> Option<[f64; 2]> {
        let r = self.reference_px[i];
        let s = self.spacing_px;
        // Normal equations of v = a + B·(x/s), x = r_j − r_i.
        let mut m = [[0.0f64; 3]; 3];
        let mut rhs = [[0.0f64; 3]; 2];
        let mut count = 0;
        for &j in self.neighbours(i) {
            let j = j as usize;
            let b = self.assigned[j];
            if b == NONE {
                continue;
            }
            let rj = self.reference_px[j];
            let x = [(rj[0] - r[0]) / s, (rj[1] - r[1]) / s];
            let w = 1.0 / (x[0] * x[0] + x[1] * x[1]).max(1e-6);
            let o = origin(j);
            let v = [blobs[b as usize].x - o[0], blobs[b as usize].y - o[1]];
            let f = [1.0, x[0], x[1]];
            for a in 0..3 {
                for c in 0..3 {
                    m[a][c] += w * f[a] * f[c];
                }
                rhs[0][a] += w * f[a] * v[0];
                rhs[1][a] += w * f[a] * v[1];
            }
            count += 1;
        }
        if count == 0 {
            return None;
        }
        let mean = [rhs[0][0] / m[0][0], rhs[1][0] / m[0][0]];
        if count < 3 {
            return Some(mean);
        }
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        // Collinear neighbours leave the slope across the line undetermined.
        if det.abs() < 1e-3 * m[0][0].powi(3) {
            return Some(mean);
        }
        // The intercept by Cramer's rule.
        let solve = |b: [f64; 3]| {
            (b[0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (b[1] * m[2][2] - m[1][2] * b[2])
                + m[0][2] * (b[1] * m[2][1] - m[1][1] * b[2]))
                / det
        };
        Some([solve(rhs[0]), solve(rhs[1])])
    }

    /// Undoes matches whose motion since the last frame disagrees with their neighbours'
    /// affine prediction by more than the gate, or whose displacement from the reference
    /// differs from the median of their matched neighbours' by more than `strain_limit`.
    pub(super) fn validate(&mut self, blobs: &[Blob]) {
        let gate = self.params.gate * self.spacing_px;
        let strain = self.params.strain_limit * self.spacing_px;
        let mut undo = Vec::new();
        let (mut dx, mut dy) = (Vec::new(), Vec::new());
        for i in 0..self.len() {
            let b = self.assigned[i];
            if b == NONE {
                continue;
            }
            dx.clear();
            dy.clear();
            for &j in self.neighbours(i) {
                let (j, bj) = (j as usize, self.assigned[j as usize]);
                if bj != NONE {
                    dx.push(blobs[bj as usize].x - self.reference_px[j][0]);
                    dy.push(blobs[bj as usize].y - self.reference_px[j][1]);
                }
            }
            if dx.is_empty() {
                continue;
            }
            let matched = dx.len();
            let d = [
                median(&mut dx).unwrap_or(0.0),
                median(&mut dy).unwrap_or(0.0),
            ];
            let (x, y) = (blobs[b as usize].x, blobs[b as usize].y);
            let own_total = [x - self.reference_px[i][0], y - self.reference_px[i][1]];
            // One neighbour can vouch for a displacement but not veto a motion.
            let motion_off = matched >= 2
                && self
                    .neighbour_motion(i, blobs)
                    .is_some_and(|m| dist([x - self.pos[i][0], y - self.pos[i][1]], m) > gate);
            if motion_off || dist(own_total, d) > strain {
                undo.push(i);
            }
        }
        for i in undo {
            let b = self.assigned[i];
            self.owner[b as usize] = NONE;
            self.assigned[i] = NONE;
        }
    }
}
