//! Step 1: the global motion since the last frame, and the aliases the frame leaves it.
//!
//! On a periodic lattice every shift by a lattice vector matches the interior equally well,
//! so the choice between candidate motions rests on what breaks the periodicity: the
//! lattice's edges and holes (predictions in view landing on nothing, at the border too
//! where the marker was seen there last frame), and blobs a candidate leaves unexplained
//! that could not have entered the view under it (moved back by the motion, they lay in
//! the open view where nothing was). Between motions that evidence leaves standing, the
//! smaller is taken, if it is clearly smaller; otherwise they are the frame's aliases
//! ([`super::aliases`]). A translation vote finds jumps up to 1.6 spacings (2.6 when
//! nothing nearer explains the frame); when no translation explains the frame, a RANSAC
//! over two-point similarity transforms (Fischler & Bolles 1981) finds whole-view
//! rotations.

use super::super::detect::Blob;
use super::super::median;
use super::spatial::Buckets;
use super::{NONE, Tracker, dist, norm};

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
    pub(super) fn against(&self) -> usize {
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
/// When no motion within [`VOTE_REACH`] explains the frame cleanly, votes reach this far
/// from where the markers were (a jump of two whole spacings is inside it).
const WIDE_REACH: f64 = 2.6;
/// Vote bin, in spacings.
const VOTE_BIN: f64 = 0.1;
/// Two hypotheses differ when their motions differ by this much on average, in spacings.
const DIFFERENT: f64 = 0.3;
/// The smaller of two motions is taken only when it is smaller by this much, in spacings
/// (far beyond any centroid error; along a lattice axis it leaves pans between 0.45 and
/// 0.55 spacing per frame ambiguous, where the two aliases are nearly as large).
const SMALLER_MARGIN: f64 = 0.1;

impl Tracker {
    /// Per marker, the component-wise median velocity of itself and its neighbours that
    /// were matched to a blob last frame (a measured motion); a marker with none of those
    /// (out of view, or among lost ones) takes the median of every matched marker, so that
    /// it keeps moving with the gel instead of standing where it was last placed.
    fn smoothed_velocity(&self) -> Vec<[f64; 2]> {
        let mut vx = Vec::with_capacity(16);
        let mut vy = Vec::with_capacity(16);
        let (mut gx, mut gy): (Vec<f64>, Vec<f64>) = (0..self.len())
            .filter(|&i| self.prev_matched[i])
            .map(|i| (self.vel[i][0], self.vel[i][1]))
            .unzip();
        let global = [median(&mut gx), median(&mut gy)];
        (0..self.len())
            .map(|i| {
                vx.clear();
                vy.clear();
                for &j in std::iter::once(&(i as u32)).chain(self.neighbours(i)) {
                    if self.prev_matched[j as usize] {
                        vx.push(self.vel[j as usize][0]);
                        vy.push(self.vel[j as usize][1]);
                    }
                }
                match (median(&mut vx), median(&mut vy), global) {
                    (Some(x), Some(y), _) => [x, y],
                    (_, _, [Some(x), Some(y)]) => [x, y],
                    _ => self.vel[i],
                }
            })
            .collect()
    }

    /// Picks the motion that explains the frame into `self.hyp`. Returns the uniform
    /// offsets from it of the rivals that explain the frame about as well and are about as
    /// small (empty when the choice is certain): the frame's aliases.
    ///
    /// Between motions the frame cannot tell apart (on a periodic lattice, every shift by a
    /// lattice vector), the smaller one since the last frame is taken: a gel's motion from
    /// one frame to the next is bounded, and the smaller of two aliases is the true one
    /// whenever that bound is under half a spacing. The velocity is not a tie-breaker: at a
    /// reversal it points at the neighbouring alias (a pan of 0.4 spacing per frame turning
    /// back lies 0.2 spacing from its alias continuing, and 0.4 from standing still).
    pub(super) fn choose_hypothesis(&mut self, blobs: &[Blob]) -> Vec<[f64; 2]> {
        let s = self.spacing_px;
        let n = self.len();
        let prior = self.smoothed_velocity();
        let zero = vec![[0.0; 2]; n];
        let moving = prior.iter().any(|v| norm(*v) > 0.02 * s);
        let mut hyps: Vec<Hypothesis> = Vec::with_capacity(24);
        hyps.push(self.hypothesis(zero.clone(), blobs));
        if moving {
            hyps.push(self.hypothesis(prior.clone(), blobs));
        }
        // Translations voted around the velocity, and around standing still when the gel
        // was moving and nothing found so far is small enough that no alias left unvoted
        // could be smaller (a reversal lies near standing still).
        let (votes, mut pairs) = self.vote_translations(&prior, VOTE_REACH, blobs);
        self.push_shifted(&mut hyps, &prior, &votes, 0.0, blobs);
        let still_voted = !moving || self.has_small_candidate(&hyps);
        if !still_voted {
            let (votes, more) = self.vote_translations(&zero, VOTE_REACH, blobs);
            self.push_shifted(&mut hyps, &zero, &votes, 0.0, blobs);
            pairs.extend(more);
        }
        let best_matched = hyps.iter().map(|h| h.e.matched).max().unwrap_or(0);
        let kept = hyps.iter().map(|h| h.e.kept).max().unwrap_or(0);
        if (best_matched as f64) < 0.9 * kept as f64
            && let Some(motion) = self.similarity(&pairs, blobs)
        {
            hyps.push(self.hypothesis(motion, blobs));
        }
        let differs = self.differs();
        // When nothing within reach explains the frame cleanly, look further: a jump of
        // two whole spacings.
        let (_, best0, _) = rank(&hyps, &differs);
        if hyps[best0].e.against() > clean(&hyps[best0].e) {
            let (votes, _) = self.vote_translations(&zero, WIDE_REACH, blobs);
            self.push_shifted(&mut hyps, &zero, &votes, 0.0, blobs);
        }
        // Every alias of the winner (one vote around it) must face it, however far the gel
        // has moved since the last certain frame; around the velocity (or standing still,
        // when voted there) the first votes already saw them.
        let (_, best0, _) = rank(&hyps, &differs);
        let around = hyps[best0].motion.clone();
        if differs(&around, &prior) && (!still_voted || differs(&around, &zero)) {
            let (votes, _) = self.vote_translations(&around, VOTE_REACH, blobs);
            self.push_shifted(&mut hyps, &around, &votes, DIFFERENT * s, blobs);
        }
        let (pick, tie) = self.decide(&hyps);
        let e = &hyps[pick].e;
        let whole_frame = e.missing as f64 <= 0.05 * e.kept as f64 + 2.0 && e.matched >= 3;
        self.confident_only = !whole_frame;
        let chosen = std::mem::take(&mut hyps[pick].motion);
        let offsets = tie
            .into_iter()
            .map(|k| mean_difference(&hyps[k].motion, &chosen))
            .collect();
        self.hyp.copy_from_slice(&chosen);
        offsets
    }

    /// The hypothesis to take among those ranked, with `self.global_confidence` set, and
    /// the rivals it could not be told from (empty when the choice is certain).
    fn decide(&mut self, hyps: &[Hypothesis]) -> (usize, Vec<usize>) {
        let s = self.spacing_px;
        let differs = self.differs();
        let (_, best, rivals) = rank(hyps, &differs);
        if rivals.is_empty() || hyps[best].e.matched < 3 {
            self.global_confidence = 1.0;
            return (best, Vec::new());
        }
        // The smallest motion decides, if it is clearly smaller than every clearly
        // different rival; rivals nearly as small stay as aliases of the frame.
        let mut sizes: Vec<(f64, usize)> = std::iter::once(best)
            .chain(rivals.iter().copied())
            .filter_map(|k| self.motion_size(&hyps[k].motion).map(|c| (c, k)))
            .collect();
        sizes.sort_by(|a, b| a.0.total_cmp(&b.0));
        let Some(&(c1, first)) = sizes.first() else {
            // Nothing measured to size the motions by: every rival is an alias.
            self.global_confidence = 0.0;
            return (best, rivals);
        };
        let tie: Vec<usize> = sizes
            .iter()
            .filter(|(c, k)| {
                *c - c1 < SMALLER_MARGIN * s && differs(&hyps[*k].motion, &hyps[first].motion)
            })
            .map(|&(_, k)| k)
            .collect();
        let c2 = sizes
            .iter()
            .find(|(_, k)| differs(&hyps[*k].motion, &hyps[first].motion))
            .map_or(f64::INFINITY, |&(c, _)| c);
        // Among the motions no different from the smallest, the frame's evidence picks
        // (a refined vote or a similarity fits better than standing still exactly).
        let first = sizes
            .iter()
            .filter(|(_, k)| !differs(&hyps[*k].motion, &hyps[first].motion))
            .map(|&(_, k)| k)
            .min_by(|&a, &b| {
                hyps[a]
                    .e
                    .against()
                    .cmp(&hyps[b].e.against())
                    .then(hyps[b].e.mean_fit().total_cmp(&hyps[a].e.mean_fit()))
            })
            .unwrap_or(first);
        self.global_confidence = if tie.is_empty() {
            ((c2 - c1) / (3.0 * SMALLER_MARGIN * s)).min(1.0)
        } else {
            0.0
        };
        (first, tie)
    }

    /// Whether a hypothesis not refuted, whose predictions land on their blobs (within a
    /// twentieth of a spacing on average), moves the markers by so little (under half a
    /// spacing less the margin) that every alias of it, a lattice step away, is clearly
    /// larger: then no alias left unvoted can win on size.
    fn has_small_candidate(&self, hyps: &[Hypothesis]) -> bool {
        let s = self.spacing_px;
        let (candidates, _, _) = rank(hyps, &self.differs());
        candidates.iter().any(|&k| {
            hyps[k].e.mean_fit() >= 0.8
                && self
                    .motion_size(&hyps[k].motion)
                    .is_some_and(|c| c <= (0.5 - SMALLER_MARGIN) * s)
        })
    }

    /// Whether two per-marker motions differ by more than [`DIFFERENT`] spacings on average.
    fn differs(&self) -> impl Fn(&[[f64; 2]], &[[f64; 2]]) -> bool + use<> {
        let (n, s) = (self.len().max(1) as f64, self.spacing_px);
        move |a: &[[f64; 2]], b: &[[f64; 2]]| {
            a.iter().zip(b).map(|(x, y)| dist(*x, *y)).sum::<f64>() / n > DIFFERENT * s
        }
    }

    /// Adds `base + v` for each vote `v` longer than `min_len`.
    fn push_shifted(
        &self,
        hyps: &mut Vec<Hypothesis>,
        base: &[[f64; 2]],
        votes: &[[f64; 2]],
        min_len: f64,
        blobs: &[Blob],
    ) {
        for v in votes {
            if norm(*v) > min_len {
                let motion = base.iter().map(|p| [p[0] + v[0], p[1] + v[1]]).collect();
                hyps.push(self.hypothesis(motion, blobs));
            }
        }
    }

    fn hypothesis(&self, motion: Vec<[f64; 2]>, blobs: &[Blob]) -> Hypothesis {
        let e = self.explain(&motion, blobs);
        Hypothesis { motion, e }
    }

    /// How far `motion` moves the markers: the mean length over the markers in view that
    /// were matched to a whole blob last frame, their identity certain or not (whose place
    /// is a measurement; a blob touching the border is biased inward); `None` with fewer
    /// than three such markers. After frames with no markers at all (a dark or covered
    /// camera) the markers measured before them count, at their last positions: nothing was
    /// seen to move.
    fn motion_size(&self, motion: &[[f64; 2]]) -> Option<f64> {
        let (mut sum, mut k) = (0.0, 0usize);
        for (i, m) in motion.iter().enumerate() {
            let known = self.prev_whole[i] || (self.after_blind && self.measured_before_blind[i]);
            if known && self.in_view(self.pos[i]) {
                sum += norm(*m);
                k += 1;
            }
        }
        (k >= 3).then(|| sum / k as f64)
    }

    /// Common translations of the markers away from the motion prior: the vectors from each
    /// prior prediction to the blobs within [`VOTE_REACH`] spacings, voted into bins of
    /// [`VOTE_BIN`]; the strongest bins (up to six, 0.3 spacing apart), each refined to the
    /// mean of its vectors. Also returns the (marker, blob) pairs voted.
    fn vote_translations(
        &self,
        prior: &[[f64; 2]],
        reach_spacings: f64,
        blobs: &[Blob],
    ) -> (Vec<[f64; 2]>, Vec<(u32, u32)>) {
        let s = self.spacing_px;
        let half = (reach_spacings / VOTE_BIN).round() as usize;
        let bins = 2 * half + 1;
        let bin = VOTE_BIN * s;
        let reach = reach_spacings * s;
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
        // Each bin's 3×3 neighbourhood sum, as a row pass then a column pass.
        let mut across = vec![0u32; bins * bins];
        for (src, dst) in hist.chunks_exact(bins).zip(across.chunks_exact_mut(bins)) {
            for x in 0..bins {
                dst[x] = src[x.saturating_sub(1)..=(x + 1).min(bins - 1)]
                    .iter()
                    .sum();
            }
        }
        let mut smooth = vec![0u32; bins * bins];
        for y in 0..bins {
            for yy in y.saturating_sub(1)..=(y + 1).min(bins - 1) {
                for (o, a) in smooth[y * bins..][..bins]
                    .iter_mut()
                    .zip(&across[yy * bins..][..bins])
                {
                    *o += a;
                }
            }
        }
        // The strongest neighbourhood first, at its strongest bin (its own count breaks a
        // tie, then raster order): the bins that could be one (a neighbourhood of at least
        // three) sorted once, then taken in turn while not cleared by a stronger one.
        let mut order: Vec<(u64, u32)> = smooth
            .iter()
            .zip(&hist)
            .enumerate()
            .filter(|(_, (v, _))| **v >= 3)
            .map(|(k, (&v, &c))| (((v as u64) << 32) | c as u64, k as u32))
            .collect();
        order.sort_unstable_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
        let clear = (DIFFERENT * s / bin).powi(2);
        let span = clear.sqrt().ceil() as usize;
        let mut modes: Vec<[f64; 2]> = Vec::new();
        for &(_, k) in &order {
            if modes.len() == 6 {
                break;
            }
            let k = k as usize;
            if smooth[k] == 0 {
                continue;
            }
            let at = (k % bins, k / bins);
            let centre = [
                (at.0 as f64 - half as f64) * bin,
                (at.1 as f64 - half as f64) * bin,
            ];
            let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
            let near = (1.5 * bin) * (1.5 * bin);
            for c in &cands {
                let (dx, dy) = (c[0] - centre[0], c[1] - centre[1]);
                if dx * dx + dy * dy < near {
                    sx += c[0];
                    sy += c[1];
                    n += 1.0;
                }
            }
            if n > 0.0 {
                modes.push([sx / n, sy / n]);
            }
            // Clear every bin within DIFFERENT spacings (the square around them only).
            for y in at.1.saturating_sub(span)..=(at.1 + span).min(bins - 1) {
                for x in at.0.saturating_sub(span)..=(at.0 + span).min(bins - 1) {
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
        for (i, (p, m)) in self.pos.iter().zip(motion).enumerate() {
            let q = [p[0] + m[0], p[1] + m[1]];
            if !self.in_view(q) {
                continue;
            }
            // A prediction whole in view must land on a blob; so must one near the border
            // of a marker whose blob was seen there last frame, half in view or more, and
            // that moves no further out (a sliver at the edge comes and goes).
            let counted = self.inside(q, self.radius_px)
                || (self.prev_matched[i]
                    && self.border_depth(q) >= self.border_depth(*p).max(0.5 * self.radius_px));
            let (mut nearest, mut at) = (tol, NONE);
            self.buckets.for_each_near(q, tol, |b| {
                let d = dist(q, [blobs[b as usize].x, blobs[b as usize].y]);
                if d < nearest {
                    (nearest, at) = (d, b);
                }
            });
            if at != NONE {
                fit[at as usize] = fit[at as usize].max(1.0 - nearest / tol);
            }
            if counted {
                e.kept += 1;
                if at == NONE {
                    e.missing += 1;
                } else {
                    e.matched += 1;
                }
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
            let mean = mean_of(motion);
            e.unexplained = unhit
                .into_iter()
                .filter(|&b| {
                    let p = [blobs[b].x, blobs[b].y];
                    surrounded(p, &predicted, &grid, 1.5 * s)
                        || !self.could_enter(p, motion, mean, &predicted, &grid)
                })
                .count();
        }
        e
    }

    /// Whether a blob at `p` that no prediction explains can be a marker entering the
    /// view under `motion`: moved back by the motion of the nearest prediction, it lay
    /// outside the view (or too near its border to be seen whole), or near a blob that no
    /// marker held last frame (a marker that entered earlier). A blob the motion brings
    /// from the open middle of the last frame, where nothing was, is not one.
    fn could_enter(
        &self,
        p: [f64; 2],
        motion: &[[f64; 2]],
        mean: [f64; 2],
        predicted: &[[f64; 2]],
        grid: &Buckets,
    ) -> bool {
        let reach = 1.5 * self.spacing_px;
        let (mut best, mut m) = (reach, mean);
        grid.for_each_near(p, reach, |k| {
            let d = dist(p, predicted[k as usize]);
            if d < best {
                (best, m) = (d, motion[k as usize]);
            }
        });
        let origin = [p[0] - m[0], p[1] - m[1]];
        !self.inside(origin, self.radius_px) || self.foreign_near(origin, 0.5 * self.spacing_px)
    }

    /// Distance from `p` to the nearest image border, px.
    fn border_depth(&self, p: [f64; 2]) -> f64 {
        (p[0] + 0.5)
            .min(p[1] + 0.5)
            .min(self.width - 0.5 - p[0])
            .min(self.height - 0.5 - p[1])
    }
}

/// The mean of a per-marker motion.
fn mean_of(motion: &[[f64; 2]]) -> [f64; 2] {
    let n = motion.len().max(1) as f64;
    motion
        .iter()
        .fold([0.0; 2], |a, m| [a[0] + m[0] / n, a[1] + m[1] / n])
}

/// The mean of `a − b` over the markers: the uniform offset between two placements.
pub(super) fn mean_difference(a: &[[f64; 2]], b: &[[f64; 2]]) -> [f64; 2] {
    let n = a.len().max(1) as f64;
    a.iter().zip(b).fold([0.0; 2], |acc, (x, y)| {
        [acc[0] + (x[0] - y[0]) / n, acc[1] + (x[1] - y[1]) / n]
    })
}

/// How much evidence against a hypothesis is still a clean explanation of the frame: a few
/// markers, or one in fifty (as [`rank`]'s slack).
fn clean(e: &Explanation) -> usize {
    3.max(e.kept / 50)
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
