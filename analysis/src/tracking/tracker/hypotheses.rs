//! Step 1: the global motion since the last frame, or the admission that it is ambiguous.
//!
//! On a periodic lattice every shift by a lattice vector matches the interior equally well,
//! so the choice between candidate motions rests on what breaks the periodicity: the
//! lattice's edges and holes (predictions in view landing on nothing), blobs the candidate
//! leaves unexplained *among* its predictions (not markers entering at the border, which no
//! identity could explain), and the motion prior (the velocity each marker had). A
//! translation vote finds jumps up to 1.6 spacings; when no translation explains the frame,
//! a RANSAC over two-point similarity transforms (Fischler & Bolles 1981) finds whole-view
//! rotations.

use super::super::detect::Blob;
use super::super::median;
use super::spatial::Buckets;
use super::{NONE, Tracker, dist};

/// How a hypothesis explains a frame.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Explanation {
    /// Markers whose prediction lands on a blob.
    pub(super) matched: usize,
    /// Markers predicted whole in view that land on no blob.
    pub(super) missing: usize,
    /// Interior blobs surrounded by predictions that none lands on.
    pub(super) unexplained: usize,
    /// Markers predicted whole in view.
    pub(super) kept: usize,
    /// Σ over blobs of how well the nearest prediction lands on it, `1 − d/tol`.
    fit: f64,
}

impl Explanation {
    /// The hard evidence against the hypothesis: predictions in view with no blob (the
    /// lattice's edges and holes) and blobs it leaves unexplained where no new marker can
    /// be (among its predictions, or deeper in the view than a marker could have entered).
    /// Blobs explained are not counted for it: an alias explains markers entering the view
    /// that the truth, knowing only the reference's markers, cannot.
    fn against(&self) -> usize {
        self.missing + self.unexplained
    }

    /// How well the matched predictions land, `1 − d/tol` averaged.
    fn mean_fit(&self) -> f64 {
        self.fit / self.matched.max(1) as f64
    }
}

struct Hypothesis {
    motion: Vec<[f64; 2]>,
    e: Explanation,
}

/// Votes reach this far from the prior prediction, in spacings (a one-spacing jump of a
/// grid or of random triangles is inside it).
const VOTE_REACH: f64 = 1.6;
/// Vote bin, in spacings.
const VOTE_BIN: f64 = 0.1;
/// An unexplained blob this far from the image border, in spacings, and as far from every
/// blob no marker held in the last frame, cannot be a marker that entered the view.
const ENTRY_DEPTH: f64 = 1.6;
/// Two hypotheses differ when their motions differ by this much on average, in spacings.
const DIFFERENT: f64 = 0.3;
/// The motion prior breaks a tie only when one hypothesis is this much nearer to it than
/// every rival, in spacings (far beyond any centroid error, and a quarter of the way to
/// the next lattice alias).
const PRIOR_MARGIN: f64 = 0.1;

impl Tracker {
    /// Per marker, the component-wise median velocity of itself and its neighbours.
    fn smoothed_velocity(&self) -> Vec<[f64; 2]> {
        let mut vx = Vec::with_capacity(16);
        let mut vy = Vec::with_capacity(16);
        (0..self.len())
            .map(|i| {
                vx.clear();
                vy.clear();
                for &j in std::iter::once(&(i as u32)).chain(self.neighbours(i)) {
                    vx.push(self.vel[j as usize][0]);
                    vy.push(self.vel[j as usize][1]);
                }
                [
                    median(&mut vx).unwrap_or(0.0),
                    median(&mut vy).unwrap_or(0.0),
                ]
            })
            .collect()
    }

    /// Picks the motion that explains the frame into `self.hyp`. Returns `false` when two
    /// clearly different motions explain it about equally and the motion prior cannot tell
    /// them apart: the frame is ambiguous.
    pub(super) fn choose_hypothesis(&mut self, blobs: &[Blob]) -> bool {
        let s = self.spacing_px;
        let n = self.len();
        let prior = self.smoothed_velocity();
        let mut hyps: Vec<Hypothesis> = Vec::with_capacity(16);
        let zero = vec![[0.0; 2]; n];
        hyps.push(self.hypothesis(zero, blobs));
        if prior.iter().any(|v| v[0].hypot(v[1]) > 0.02 * s) {
            hyps.push(self.hypothesis(prior.clone(), blobs));
        }
        let (votes, pairs) = self.vote_translations(&prior, blobs);
        for v in votes {
            let motion = prior.iter().map(|p| [p[0] + v[0], p[1] + v[1]]).collect();
            hyps.push(self.hypothesis(motion, blobs));
        }
        let best_matched = hyps.iter().map(|h| h.e.matched).max().unwrap_or(0);
        let kept = hyps.iter().map(|h| h.e.kept).max().unwrap_or(0);
        if (best_matched as f64) < 0.9 * kept as f64
            && let Some(motion) = self.similarity(&pairs, blobs)
        {
            hyps.push(self.hypothesis(motion, blobs));
        }

        let differs = |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.iter().zip(b).map(|(x, y)| dist(*x, *y)).sum::<f64>() / n.max(1) as f64
                > DIFFERENT * s
        };
        // Rank, then add the motions one lattice step (one vote) around the best and rank
        // again: every alias of the winner must face it, however far the gel has moved
        // since the last certain frame.
        // (Needed only when the winner is not the motion prior itself: around the prior the
        // first vote already saw them.)
        let (_, best0, _) = rank(&hyps, &differs);
        let needs_aliases =
            self.prior_cost(&prior, &prior).is_none() || differs(&hyps[best0].motion, &prior);
        let around = if needs_aliases {
            hyps[best0].motion.clone()
        } else {
            Vec::new()
        };
        let votes = if needs_aliases {
            self.vote_translations(&around, blobs).0
        } else {
            Vec::new()
        };
        for v in votes {
            if v[0].hypot(v[1]) > DIFFERENT * s {
                let motion = around.iter().map(|p| [p[0] + v[0], p[1] + v[1]]).collect();
                hyps.push(self.hypothesis(motion, blobs));
            }
        }
        let (candidates, best, rivals) = rank(&hyps, &differs);
        let e = &hyps[best].e;
        let whole_frame = e.missing as f64 <= 0.05 * e.kept as f64 + 2.0 && e.matched >= 3;
        let pick = if rivals.is_empty() || e.matched < 3 {
            self.global_confidence = 1.0;
            best
        } else {
            // The motion prior decides, if one candidate is clearly nearer to it.
            let mut costs: Vec<(f64, usize)> = std::iter::once(best)
                .chain(rivals.iter().copied())
                .filter_map(|k| self.prior_cost(&hyps[k].motion, &prior).map(|c| (c, k)))
                .collect();
            costs.sort_by(|a, b| a.0.total_cmp(&b.0));
            // The nearest to the prior against the nearest clearly different one.
            let first = costs.first().copied();
            let second = first.and_then(|(_, k1)| {
                costs
                    .iter()
                    .find(|(_, k)| differs(&hyps[*k].motion, &hyps[k1].motion))
                    .copied()
            });
            match (first, second) {
                (Some((c1, k)), Some((c2, _))) if c2 - c1 >= PRIOR_MARGIN * s => {
                    self.global_confidence = ((c2 - c1) / (3.0 * PRIOR_MARGIN * s)).min(1.0);
                    k
                }
                // No prior at all (the last frames were ambiguous), but the markers stand
                // exactly where they last were certain (within 2 % of a spacing): the gel
                // came back. Anything else stays ambiguous.
                _ if costs.is_empty()
                    && candidates.contains(&0)
                    && hyps[0].e.mean_fit() >= 0.92 =>
                {
                    self.global_confidence = 0.5;
                    0
                }
                _ => {
                    self.global_confidence = 0.0;
                    self.confident_only = true;
                    return false;
                }
            }
        };
        self.confident_only = !whole_frame;
        let chosen = std::mem::take(&mut hyps[pick].motion);
        self.hyp.copy_from_slice(&chosen);
        true
    }

    fn hypothesis(&self, motion: Vec<[f64; 2]>, blobs: &[Blob]) -> Hypothesis {
        let e = self.explain(&motion, blobs);
        Hypothesis { motion, e }
    }

    /// How far `motion` lies from the motion priors: the mean distance, over the markers in
    /// view that were measured last frame (whose velocity is a measurement), from the
    /// constant-velocity prior or from standing still, whichever is nearer (a gel that
    /// reverses or stops is as plausible as one that keeps going); `None` with fewer than
    /// three such markers. After frames with no markers at all (a dark or covered camera)
    /// the markers measured before them count, at their last positions: nothing was seen
    /// to move. After ambiguous frames nothing counts: the gel was seen moving, by how much
    /// is what was not known.
    fn prior_cost(&self, motion: &[[f64; 2]], prior: &[[f64; 2]]) -> Option<f64> {
        let (mut moving, mut still, mut k) = (0.0, 0.0, 0usize);
        for (i, p) in prior.iter().enumerate() {
            let known = self.prev_state[i].is_measured()
                || (self.after_blind && self.measured_before_blind[i]);
            if known && self.in_view(self.pos[i]) {
                moving += dist(motion[i], *p);
                still += motion[i][0].hypot(motion[i][1]);
                k += 1;
            }
        }
        (k >= 3).then(|| moving.min(still) / k as f64)
    }

    /// Common translations of the markers away from the motion prior: the vectors from each
    /// prior prediction to the blobs within [`VOTE_REACH`] spacings, voted into bins of
    /// [`VOTE_BIN`]; the strongest bins (up to six, 0.3 spacing apart), each refined to the
    /// mean of its vectors. Also returns the (marker, blob) pairs voted.
    fn vote_translations(
        &self,
        prior: &[[f64; 2]],
        blobs: &[Blob],
    ) -> (Vec<[f64; 2]>, Vec<(u32, u32)>) {
        let s = self.spacing_px;
        let half = (VOTE_REACH / VOTE_BIN).round() as usize;
        let bins = 2 * half + 1;
        let bin = VOTE_BIN * s;
        let reach = VOTE_REACH * s;
        let mut cands: Vec<[f64; 2]> = Vec::new();
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        let mut hist = vec![0u32; bins * bins];
        for (i, (q, v)) in self.pos.iter().zip(prior).enumerate() {
            let p = [q[0] + v[0], q[1] + v[1]];
            if !self.in_view(p) {
                continue;
            }
            self.buckets.for_each_near(p, reach, |b| {
                let v = [blobs[b as usize].x - p[0], blobs[b as usize].y - p[1]];
                if v[0] * v[0] + v[1] * v[1] <= reach * reach {
                    // Both are ≥ 0 after the offset, so +0.5 and truncation round.
                    let bx = (v[0] / bin + half as f64 + 0.5) as usize;
                    let by = (v[1] / bin + half as f64 + 0.5) as usize;
                    hist[by.min(bins - 1) * bins + bx.min(bins - 1)] += 1;
                    cands.push(v);
                    pairs.push((i as u32, b));
                }
            });
        }
        let mut smooth = vec![0u32; bins * bins];
        for y in 0..bins {
            for x in 0..bins {
                for yy in y.saturating_sub(1)..=(y + 1).min(bins - 1) {
                    for xx in x.saturating_sub(1)..=(x + 1).min(bins - 1) {
                        smooth[y * bins + x] += hist[yy * bins + xx];
                    }
                }
            }
        }
        let mut modes: Vec<[f64; 2]> = Vec::new();
        while modes.len() < 6 {
            // The strongest neighbourhood, at its strongest bin.
            let (mut top, mut key, mut at) = (0u32, 0u64, (0, 0));
            for y in 0..bins {
                for x in 0..bins {
                    let v = smooth[y * bins + x];
                    let k = ((v as u64) << 32) | hist[y * bins + x] as u64;
                    if k > key {
                        (top, key, at) = (v, k, (x, y));
                    }
                }
            }
            if top < 3 {
                break;
            }
            let centre = [
                (at.0 as f64 - half as f64) * bin,
                (at.1 as f64 - half as f64) * bin,
            ];
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
            let clear = (DIFFERENT * s / bin).powi(2);
            for y in 0..bins {
                for x in 0..bins {
                    let (dx, dy) = (x as f64 - at.0 as f64, y as f64 - at.1 as f64);
                    if dx * dx + dy * dy < clear {
                        smooth[y * bins + x] = 0;
                    }
                }
            }
        }
        (modes, pairs)
    }

    /// The similarity transform (turn, scale, shift) of the previous positions that explains
    /// the most markers: RANSAC over pairs of voted (marker, blob) pairs at least three
    /// spacings apart, scored on a quarter of the markers, refined by least squares over
    /// the inliers (complex-number form of Umeyama 1991). As a per-marker motion.
    fn similarity(&self, pairs: &[(u32, u32)], blobs: &[Blob]) -> Option<Vec<[f64; 2]>> {
        if pairs.len() < 2 {
            return None;
        }
        let s = self.spacing_px;
        let tol = self.params.seed_radius * s;
        let blob = |b: u32| [blobs[b as usize].x, blobs[b as usize].y];
        let apply = |t: &[f64; 4], p: [f64; 2]| {
            [
                t[0] * p[0] - t[1] * p[1] + t[2],
                t[1] * p[0] + t[0] * p[1] + t[3],
            ]
        };
        let hits = |t: &[f64; 4], stride: usize| {
            (0..self.len())
                .step_by(stride)
                .filter(|&i| {
                    let q = apply(t, self.pos[i]);
                    let mut hit = false;
                    self.buckets
                        .for_each_near(q, tol, |b| hit |= dist(q, blob(b)) < tol);
                    hit
                })
                .count()
        };
        // A fixed xorshift sequence: the same frame always gives the same answer.
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = |m: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % m as u64) as usize
        };
        let (mut best, mut best_hits) = (None, 0usize);
        for _ in 0..256 {
            let (a, b) = (pairs[next(pairs.len())], pairs[next(pairs.len())]);
            let (za, zb) = (self.pos[a.0 as usize], self.pos[b.0 as usize]);
            if dist(za, zb) < 3.0 * s {
                continue;
            }
            let (wa, wb) = (blob(a.1), blob(b.1));
            // w = c·z + t with complex c = (wb − wa)/(zb − za).
            let (dz, dw) = (
                [zb[0] - za[0], zb[1] - za[1]],
                [wb[0] - wa[0], wb[1] - wa[1]],
            );
            let den = dz[0] * dz[0] + dz[1] * dz[1];
            let c = [
                (dw[0] * dz[0] + dw[1] * dz[1]) / den,
                (dw[1] * dz[0] - dw[0] * dz[1]) / den,
            ];
            let scale = c[0].hypot(c[1]);
            if !(0.8..=1.25).contains(&scale) || c[1].atan2(c[0]).abs() > 0.6 {
                continue;
            }
            let t = [
                c[0],
                c[1],
                wa[0] - (c[0] * za[0] - c[1] * za[1]),
                wa[1] - (c[1] * za[0] + c[0] * za[1]),
            ];
            let h = hits(&t, 4);
            if h > best_hits {
                (best, best_hits) = (Some(t), h);
            }
        }
        let mut t = best?;
        // Least squares over the inliers, twice.
        for _ in 0..2 {
            let mut inl: Vec<([f64; 2], [f64; 2])> = Vec::new();
            for i in 0..self.len() {
                let q = apply(&t, self.pos[i]);
                let (mut bb, mut bd) = (NONE, tol);
                self.buckets.for_each_near(q, tol, |b| {
                    let d = dist(q, blob(b));
                    if d < bd {
                        (bb, bd) = (b, d);
                    }
                });
                if bb != NONE {
                    inl.push((self.pos[i], blob(bb)));
                }
            }
            if inl.len() < 3 {
                break;
            }
            let k = inl.len() as f64;
            let zm = inl
                .iter()
                .fold([0.0; 2], |a, (z, _)| [a[0] + z[0] / k, a[1] + z[1] / k]);
            let wm = inl
                .iter()
                .fold([0.0; 2], |a, (_, w)| [a[0] + w[0] / k, a[1] + w[1] / k]);
            let (mut num, mut den) = ([0.0; 2], 0.0);
            for (z, w) in &inl {
                let (dz, dw) = ([z[0] - zm[0], z[1] - zm[1]], [w[0] - wm[0], w[1] - wm[1]]);
                num[0] += dw[0] * dz[0] + dw[1] * dz[1];
                num[1] += dw[1] * dz[0] - dw[0] * dz[1];
                den += dz[0] * dz[0] + dz[1] * dz[1];
            }
            if den <= 0.0 {
                break;
            }
            let c = [num[0] / den, num[1] / den];
            t = [
                c[0],
                c[1],
                wm[0] - (c[0] * zm[0] - c[1] * zm[1]),
                wm[1] - (c[1] * zm[0] + c[0] * zm[1]),
            ];
        }
        Some(
            self.pos
                .iter()
                .map(|&p| {
                    let q = apply(&t, p);
                    [q[0] - p[0], q[1] - p[1]]
                })
                .collect(),
        )
    }

    /// How well the predictions `pos + motion` explain the blobs of the frame.
    pub(super) fn explain(&self, motion: &[[f64; 2]], blobs: &[Blob]) -> Explanation {
        let s = self.spacing_px;
        let tol = self.params.seed_radius * s;
        let mut e = Explanation::default();
        // Per blob, how well the nearest prediction lands on it; −1: none does.
        let mut fit = vec![-1.0f64; blobs.len()];
        for (p, m) in self.pos.iter().zip(motion) {
            let q = [p[0] + m[0], p[1] + m[1]];
            if !self.inside(q, self.radius_px) {
                continue;
            }
            e.kept += 1;
            let (mut nearest, mut at) = (tol, NONE);
            self.buckets.for_each_near(q, tol, |b| {
                let d = dist(q, [blobs[b as usize].x, blobs[b as usize].y]);
                if d < nearest {
                    (nearest, at) = (d, b);
                }
            });
            if at == NONE {
                e.missing += 1;
            } else {
                e.matched += 1;
                fit[at as usize] = fit[at as usize].max(1.0 - nearest / tol);
            }
        }
        e.fit = fit.iter().filter(|&&f| f > 0.0).sum();
        let unhit: Vec<usize> = (0..blobs.len())
            .filter(|&b| fit[b] < 0.0 && !blobs[b].border)
            .collect();
        if !unhit.is_empty() {
            let predicted: Vec<[f64; 2]> = self
                .pos
                .iter()
                .zip(motion)
                .map(|(p, m)| [p[0] + m[0], p[1] + m[1]])
                .collect();
            let mut grid = Buckets::default();
            grid.build_points(predicted.iter().copied(), self.width, self.height, 0.5 * s);
            let depth = ENTRY_DEPTH * s;
            e.unexplained = unhit
                .into_iter()
                .filter(|&b| {
                    let p = [blobs[b].x, blobs[b].y];
                    surrounded(p, &predicted, &grid, 1.5 * s)
                        || (self.inside(p, depth) && !self.foreign_near(p, depth))
                })
                .count();
        }
        e
    }
}

/// Candidates (not refuted: no more hard evidence against them than the least refuted,
/// within a few markers or as much again, and explaining at least half as many markers), the best of them
/// (fewest against, then closest fit), and its rivals (clearly different candidates that
/// fit about as well).
fn rank(
    hyps: &[Hypothesis],
    differs: &impl Fn(&[[f64; 2]], &[[f64; 2]]) -> bool,
) -> (Vec<usize>, usize, Vec<usize>) {
    let most = hyps.iter().map(|h| h.e.matched).max().unwrap_or(0);
    let least_against = hyps
        .iter()
        .filter(|h| 2 * h.e.matched >= most)
        .map(|h| h.e.against())
        .min()
        .unwrap_or(0);
    // When even the best leaves much unexplained (a local motion inside the contact that no
    // global motion follows), the frame's evidence between global motions is weak: widen
    // the candidates by that much and let the prior and the later steps decide.
    let slack = 3.max(most / 50).max(least_against);
    let candidates: Vec<usize> = (0..hyps.len())
        .filter(|&k| 2 * hyps[k].e.matched >= most && hyps[k].e.against() <= least_against + slack)
        .collect();
    let best = candidates
        .iter()
        .copied()
        .min_by(|&a, &b| {
            hyps[a]
                .e
                .against()
                .cmp(&hyps[b].e.against())
                .then(hyps[b].e.mean_fit().total_cmp(&hyps[a].e.mean_fit()))
                .then(a.cmp(&b))
        })
        .unwrap_or(0);
    let rivals = candidates
        .iter()
        .copied()
        .filter(|&k| k != best && differs(&hyps[k].motion, &hyps[best].motion))
        .filter(|&k| hyps[k].e.mean_fit() >= 0.6 * hyps[best].e.mean_fit())
        .collect();
    (candidates, best, rivals)
}

impl Tracker {
    /// Whether a blob that no marker held in the last frame lay within `reach` of `p`.
    fn foreign_near(&self, p: [f64; 2], reach: f64) -> bool {
        let mut near = false;
        self.foreign.for_each_near(p, reach, |k| {
            near |= dist(p, self.foreign_px[k as usize]) < reach;
        });
        near
    }
}

/// Whether predictions within `reach` of `p` lie all around it (no angular gap over 150°):
/// a blob among the predictions that none explains counts against a hypothesis, a marker
/// entering the view beyond them does not.
fn surrounded(p: [f64; 2], predicted: &[[f64; 2]], grid: &Buckets, reach: f64) -> bool {
    let mut angles: Vec<f64> = Vec::with_capacity(12);
    grid.for_each_near(p, reach, |k| {
        let q = predicted[k as usize];
        let d = dist(p, q);
        if d < reach && d > 1e-9 {
            angles.push((q[1] - p[1]).atan2(q[0] - p[0]));
        }
    });
    if angles.len() < 3 {
        return false;
    }
    angles.sort_by(f64::total_cmp);
    let wrap = angles[0] + std::f64::consts::TAU - angles[angles.len() - 1];
    let gap = angles.windows(2).map(|w| w[1] - w[0]).fold(wrap, f64::max);
    gap < 150f64.to_radians()
}
