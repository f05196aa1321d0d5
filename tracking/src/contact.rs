//! The contact region, from the image alone (thesis §5.1 measured contact diameters on the
//! camera's frames).
//!
//! A GelSight's lights are coloured and come from the sides, so where the gel surface tilts
//! the colour changes; markers aside, an untouched gel looks like the reference. Per frame:
//!
//! 1. **Change map.** Per block of `block_px`², the mean of `I_c / B_c` over the pixels that
//!    are not marker (darkness below a quarter of the low threshold; every other row), against the reference's
//!    marker-free background `B`. A global change of exposure is divided out (the median
//!    over blocks, per channel); the change of a block is the length of its colour vector
//!    from that median. Blocks wholly under a marker take their neighbours' mean; a 3×3
//!    binomial smooths the map.
//! 2. **Is there contact?** Only if the largest change exceeds the noise floor
//!    (`noise_factor` times half the reference's median pixel noise, at least `min_change`)
//!    and the blocks above that floor connected to it cover at least two markers: noise
//!    lifts single blocks, a contact tilts a region.
//! 3. **Seed.** The blocks connected to the peak with more than `seed_fraction` of it, with
//!    every other part above that level as large as two markers (a strip's other side),
//!    what lies between them along each row and column, and holes filled: a sphere's centre
//!    does not tilt, a flat punch's face does not either, and a can's flat top between the
//!    strip's two tilting sides runs to the view's edges.
//!    The reference's own residual (its background model's error, per block) is subtracted
//!    from every frame's change, and refreshed slowly from frames without contact.
//! 4. **Edge.** Along `rays` rays from the seed's centroid, the change rises to the ring
//!    where the surface tilts most and falls outside it. For a sphere the slope is steepest
//!    at the edge of contact (inside, the surface follows the sphere, slope r/R; outside, it
//!    relaxes), for a flat punch the slope is singular there; so the edge is where the
//!    change, going outward past the ray's maximum, drops below `edge_fraction` of it
//!    (interpolated between samples). The outline is star-shaped about the centroid: one
//!    contact, as in indentation and grasping; two separate contacts are not told apart.
//!
//! Area (shoelace), centroid and equivalent radius √(A/π) come from the outline. On the
//! simulated box sensor's sphere runs the equivalent radius is within −3.9 … +1.9 % of the
//! simulator's contact radius from 0.3 mm depth on (BENCHMARKS.md).

use super::{Reference, RgbView, TrackError};

/// Tuning of the contact region. Defaults fit the simulated box sensor's sphere runs.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactParams {
    /// Side of the blocks the change is averaged over, px (1–8).
    pub block_px: usize,
    /// Outward from a ray's maximum, the edge is where the change falls below this share.
    pub edge_fraction: f64,
    /// Blocks above this share of the peak change seed the region.
    pub seed_fraction: f64,
    /// The peak change must exceed this multiple of half the reference's median pixel noise.
    pub noise_factor: f64,
    /// Rays cast from the centroid to find the edge.
    pub rays: usize,
    /// The smallest peak colour change that can be contact (relative intensity).
    pub min_change: f64,
    /// After a frame without contact, the reference's per-block colours move this share of
    /// the way to that frame's (lighting and exposure drift slowly; an untouched gel must
    /// not drift into a contact).
    pub refresh: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            block_px: 4,
            edge_fraction: 0.85,
            seed_fraction: 0.25,
            noise_factor: 4.0,
            rays: 72,
            min_change: 0.015,
            refresh: 0.1,
        }
    }
}

/// The contact region of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactRegion {
    /// Area inside the outline, px².
    pub area_px2: f64,
    /// Centroid of the outline, px.
    pub centroid_px: [f64; 2],
    /// Radius of the circle of the same area, px.
    pub radius_px: f64,
    /// Central second moments of the outline's area per unit area, [σxx, σyy, σxy], px²:
    /// the region's moment-equivalent ellipse (a disc of radius a: a²/4, a²/4, 0). A
    /// traction map's support follows it, so an elongated contact is not cut to a disc.
    pub second_moments_px2: [f64; 3],
    /// Closed outline (the last point joins the first), px.
    pub outline_px: Vec<[f64; 2]>,
    /// Largest colour change against the reference (relative intensity units).
    pub peak_change: f64,
}

/// Finds the contact region frame after frame; its buffers are reused.
#[derive(Debug, Clone)]
pub struct ContactFinder {
    params: ContactParams,
    block: usize,
    bw: usize,
    bh: usize,
    sums: Vec<[u32; 3]>,
    counts: Vec<u32>,
    map: Vec<f32>,
    tmp: Vec<f32>,
    /// Scratch of [`fill_nan`]: the blocks still missing, and a ring's new values.
    holes: (Vec<usize>, Vec<(usize, f32)>),
    marks: Vec<u8>,
    stack: Vec<usize>,
    samples: Vec<(f64, f32, bool)>,
    /// Largest distance of a seed block from the seed's centroid, blocks (+1.5).
    reach: f64,
    /// Mean of `65280 / B_c` over each block and channel (the background is smooth, so a
    /// block's mean ratio is its mean intensity times this).
    block_inv: Vec<[f32; 3]>,
    /// The reference's own change per block and channel (its background model's error,
    /// the vignetted corners above all), subtracted from every frame's.
    base: [Vec<f32>; 3],
    /// Per block, the typical pixel noise over that block's own (≥ 1): the change of a
    /// noisier block (the dark, vignetted corners of a real camera) is divided by it.
    noisiness: Vec<f32>,
    /// The smallest peak change that is contact.
    min_peak: f32,
    floor: f32,
    /// The last frame's exposure (for the refresh).
    exposure: [f32; 3],
}

/// Rows of each block sampled: one in `ROW_STEP`.
const ROW_STEP: usize = 2;

const UNSEEN: u8 = 0;
const SEED: u8 = 1;
const OUTSIDE: u8 = 2;
/// A part above the seed's level being measured.
const PART: u8 = 3;
/// A part too small to be contact.
const SPECK: u8 = 4;

impl ContactFinder {
    /// Measures the noise floor of the change on the reference frame itself.
    pub fn new(
        reference_frame: RgbView<'_>,
        reference: &Reference,
        params: ContactParams,
    ) -> Result<Self, TrackError> {
        reference.check_size(&reference_frame)?;
        let block = params.block_px.clamp(1, 8);
        let (w, h) = (reference.width(), reference.height());
        let (bw, bh) = ((w / block).max(1), (h / block).max(1));
        let n = bw * bh;
        let mut finder = Self {
            params,
            block,
            bw,
            bh,
            sums: vec![[0; 3]; n],
            counts: vec![0; n],
            map: vec![0.0; n],
            tmp: vec![0.0; n],
            holes: (Vec::new(), Vec::new()),
            marks: vec![0; n],
            stack: Vec::new(),
            samples: Vec::new(),
            reach: 0.0,
            block_inv: vec![[0.0; 3]; n],
            base: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            noisiness: vec![1.0; n],
            min_peak: 0.0,
            floor: 0.0,
            exposure: [0.0; 3],
        };
        finder.measure_block_inv(reference);
        let exposure = finder.block_means(reference_frame, reference, reference.darkness());
        let mut base = std::mem::take(&mut finder.base);
        for (c, channel) in base.iter_mut().enumerate() {
            for (k, v) in channel.iter_mut().enumerate() {
                *v = finder.block_change(k, c, exposure[c]);
            }
            fill_nan(channel, &mut finder.holes, bw, bh);
        }
        finder.base = base;
        finder.measure_noise(reference_frame, reference, exposure);
        Ok(finder)
    }

    /// The change below which nothing counted as contact in the last frame.
    pub fn noise_floor(&self) -> f64 {
        self.floor as f64
    }

    /// The smoothed change map of the last frame: `(blocks, columns, rows, block side px)`.
    pub fn map(&self) -> (&[f32], usize, usize, usize) {
        (&self.map, self.bw, self.bh, self.block)
    }

    /// The contact region of `frame`, or `None` when nothing touches the gel. `darkness`
    /// is the frame's smoothed darkness from the [`super::Detector`] (it masks the markers).
    pub fn find(
        &mut self,
        frame: RgbView<'_>,
        reference: &Reference,
        darkness: &[u8],
    ) -> Result<Option<ContactRegion>, TrackError> {
        reference.check_size(&frame)?;
        let pixels = reference.width() * reference.height();
        if darkness.len() != pixels {
            return Err(TrackError::BufferLength {
                expected: pixels,
                got: darkness.len(),
            });
        }
        self.change_map(frame, reference, darkness);
        let Some((peak_at, peak)) = self
            .map
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            return Ok(None);
        };
        if peak < self.floor {
            self.refresh_base();
            return Ok(None);
        }
        // A contact tilts the gel over a region; the camera's noise lifts single blocks. On
        // the simulated portable sensor (1.1 % pixel noise) an untouched gel's peak reaches
        // 0.025–0.031 against a floor of 0.022, but only 4–7 blocks around it stand above
        // the floor, while a lifting can's gentle contact (peak 0.044–0.05) lifts 800–2 300:
        // fewer than two markers' worth of blocks above the floor is noise.
        self.marks.fill(UNSEEN);
        let floor = self.floor;
        let above = self.flood(&[peak_at], SEED, |v, m| m == UNSEEN && v >= floor) as f64;
        let marker_blocks =
            std::f64::consts::PI * reference.radius_px().powi(2) / (self.block * self.block) as f64;
        // The base is not refreshed from such a frame: a contact that is only beginning
        // looks the same, and must not be taken into the untouched gel's colours.
        if above < 2.0 * marker_blocks {
            return Ok(None);
        }
        self.seed(
            peak_at,
            peak * self.params.seed_fraction as f32,
            2.0 * marker_blocks,
        );
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for (i, _) in self.marks.iter().enumerate().filter(|(_, m)| **m == SEED) {
            sx += (i % self.bw) as f64;
            sy += (i / self.bw) as f64;
            n += 1.0;
        }
        let centre = [sx / n, sy / n];
        // How far the seed reaches from its centroid: rays need not look for the maximum
        // beyond it.
        self.reach = self
            .marks
            .iter()
            .enumerate()
            .filter(|(_, m)| **m == SEED)
            .map(|(i, _)| {
                let (x, y) = (
                    (i % self.bw) as f64 - centre[0],
                    (i / self.bw) as f64 - centre[1],
                );
                x * x + y * y
            })
            .fold(0.0, f64::max)
            .sqrt()
            + 1.5;
        let rays = self.params.rays.max(8);
        let angle = |k: usize| std::f64::consts::TAU * k as f64 / rays as f64;
        let radii: Vec<f64> = (0..rays)
            .map(|k| self.edge_along(centre, [angle(k).cos(), angle(k).sin()], peak))
            .collect();
        // An outline is smooth: each radius is the median of its ray and two on each side,
        // so a ray that runs along a fingerprint ridge or stops at a speck does not spike it
        // (a circle is unchanged).
        let outline: Vec<[f64; 2]> = (0..rays)
            .map(|k| {
                let mut near: [f64; 5] = std::array::from_fn(|d| radii[(k + rays + d - 2) % rays]);
                near.sort_by(f64::total_cmp);
                let (r, a) = (near[2], angle(k));
                self.to_px(centre[0] + r * a.cos(), centre[1] + r * a.sin())
            })
            .collect();
        let (area, centroid) = super::outline::area_centroid(&outline);
        // A change smaller than a marker is noise or a speck: no contact that small can be
        // told from the markers' own rims.
        if area < std::f64::consts::PI * reference.radius_px().powi(2) {
            return Ok(None);
        }
        let radius_px = (area / std::f64::consts::PI).sqrt();
        let disc = [
            radius_px * radius_px / 4.0,
            radius_px * radius_px / 4.0,
            0.0,
        ];
        Ok(Some(ContactRegion {
            area_px2: area,
            centroid_px: centroid,
            radius_px,
            second_moments_px2: super::outline::second_moments(&outline).unwrap_or(disc),
            outline_px: outline,
            peak_change: peak as f64,
        }))
    }

    /// Moves the base towards the last frame (no contact in it), block by measured block.
    fn refresh_base(&mut self) {
        let a = self.params.refresh.clamp(0.0, 1.0) as f32;
        if a == 0.0 {
            return;
        }
        for k in 0..self.map.len() {
            for c in 0..3 {
                let v = self.block_change(k, c, self.exposure[c]);
                if !v.is_nan() {
                    self.base[c][k] += a * (v - self.base[c][k]);
                }
            }
        }
    }

    /// Block coordinates to pixels (a block's centre).
    fn to_px(&self, bx: f64, by: f64) -> [f64; 2] {
        let half = (self.block as f64 - 1.0) / 2.0;
        [bx * self.block as f64 + half, by * self.block as f64 + half]
    }

    /// Step 1: the smoothed change map.
    fn change_map(&mut self, frame: RgbView<'_>, reference: &Reference, darkness: &[u8]) {
        let exposure = self.block_means(frame, reference, darkness);
        self.exposure = exposure;
        for k in 0..self.map.len() {
            let d = |c: usize| self.block_change(k, c, exposure[c]) - self.base[c][k];
            self.map[k] = (d(0) * d(0) + d(1) * d(1) + d(2) * d(2)).sqrt() / self.noisiness[k];
        }
        fill_nan(&mut self.map, &mut self.holes, self.bw, self.bh);
        smooth_121(&mut self.map, &mut self.tmp, self.bw, self.bh);
        self.floor = self.min_peak;
    }

    /// Sums of `I_c / B_c` (×65280) per block over the pixels that are not marker, and the
    /// exposure: per channel, the median block mean.
    fn block_means(
        &mut self,
        frame: RgbView<'_>,
        reference: &Reference,
        darkness: &[u8],
    ) -> [f32; 3] {
        let (w, b, bw, bh) = (reference.width(), self.block, self.bw, self.bh);
        let data = frame.data();
        let mark = (reference.thresholds.low / 4).max(2);
        self.sums.fill([0; 3]);
        self.counts.fill(0);
        // Row by row and block by block, no division and no branch per pixel: the sums are
        // of raw intensity (the block's mean background ratio is applied per block). Every
        // other row: the shading is smooth over a block, and this pass is half the cost.
        for y in (0..bh * b).step_by(ROW_STEP) {
            let (p0, p1) = (y * w, y * w + bw * b);
            let (Some(drow), Some(prow)) = (darkness.get(p0..p1), data.get(3 * p0..3 * p1)) else {
                return [0.0; 3];
            };
            let row = (y / b) * bw;
            let (sums, counts) = (
                &mut self.sums[row..row + bw],
                &mut self.counts[row..row + bw],
            );
            super::pixels::add_row_blocks(drow, prow, b, mark, sums, counts);
        }
        let mut exposure = [0.0f32; 3];
        for (c, e) in exposure.iter_mut().enumerate() {
            self.tmp.clear();
            self.tmp.extend(
                self.sums
                    .iter()
                    .zip(&self.counts)
                    .filter(|(_, n)| **n > 0)
                    .zip(&self.block_inv)
                    .map(|((s, n), inv)| s[c] as f32 / *n as f32 * inv[c]),
            );
            if !self.tmp.is_empty() {
                let mid = self.tmp.len() / 2;
                let (_, m, _) = self.tmp.select_nth_unstable_by(mid, f32::total_cmp);
                *e = *m;
            }
        }
        self.tmp.resize(bw * bh, 0.0);
        exposure
    }

    /// The mean of `65280 / B_c` over every pixel of each block.
    fn measure_block_inv(&mut self, reference: &Reference) {
        let (w, b, bw, bh) = (reference.width(), self.block, self.bw, self.bh);
        let inv = &reference.inv_bg;
        let mut sums = vec![[0u64; 3]; bw * bh];
        for y in 0..bh * b {
            for x in 0..bw * b {
                let (k, p) = ((y / b) * bw + x / b, y * w + x);
                for c in 0..3 {
                    sums[k][c] += inv[3 * p + c] as u64;
                }
            }
        }
        let n = (b * b) as f32;
        for (out, s) in self.block_inv.iter_mut().zip(&sums) {
            *out = [s[0] as f32 / n, s[1] as f32 / n, s[2] as f32 / n];
        }
    }

    /// Per-block pixel noise of the reference: the spread of `I_c / B_c` about the block's
    /// mean, over its non-marker pixels, averaged over channels. The contact needs a peak
    /// of `noise_factor` times half the median spread (a block mean of 16 pixels differs
    /// between two frames by about σ/3 per channel; the peak of ~20 000 smoothed blocks of
    /// noise stays below 2σ), and never below a 1.5 % change.
    fn measure_noise(&mut self, frame: RgbView<'_>, reference: &Reference, exposure: [f32; 3]) {
        let (w, b, bw, bh) = (reference.width(), self.block, self.bw, self.bh);
        let (data, inv, dark) = (frame.data(), &reference.inv_bg, reference.darkness());
        let mark = (reference.thresholds.low / 4).max(2);
        let mut sq = vec![0.0f32; bw * bh];
        for y in (0..bh * b).step_by(ROW_STEP) {
            for x in 0..bw * b {
                let p = y * w + x;
                if dark.get(p).is_none_or(|&d| d > mark) {
                    continue;
                }
                let k = (y / b) * bw + x / b;
                for c in 0..3 {
                    let r = (data[3 * p + c] as u32 * inv[3 * p + c] as u32) as f32 / 65280.0;
                    let mean = self.block_change(k, c, exposure[c]) + exposure[c] / 65280.0;
                    sq[k] += (r - mean) * (r - mean);
                }
            }
        }
        let mut sigma: Vec<f32> = sq
            .iter()
            .zip(&self.counts)
            .map(|(s, &n)| match n {
                0 | 1 => f32::NAN,
                n => (s / (3 * (n - 1)) as f32).sqrt(),
            })
            .collect();
        fill_nan(&mut sigma, &mut self.holes, bw, bh);
        self.tmp.copy_from_slice(&sigma);
        let mid = self.tmp.len() / 2;
        let (_, median, _) = self.tmp.select_nth_unstable_by(mid, f32::total_cmp);
        let median = median.max(1e-4);
        self.noisiness = sigma.iter().map(|s| (s / median).max(1.0)).collect();
        self.min_peak =
            (self.params.noise_factor as f32 * 0.5 * median).max(self.params.min_change as f32);
    }

    /// Block `k`'s mean relative intensity in channel `c` minus the exposure (NaN when the
    /// block is all marker).
    fn block_change(&self, k: usize, c: usize, exposure: f32) -> f32 {
        const UNIT: f32 = 65280.0;
        match self.counts[k] {
            0 => f32::NAN,
            n => (self.sums[k][c] as f32 / n as f32 * self.block_inv[k][c] - exposure) / UNIT,
        }
    }

    /// Step 3: the blocks above `level` connected to the peak, holes filled (`SEED`).
    fn seed(&mut self, peak_at: usize, level: f32, min_blocks: f64) {
        let (bw, bh) = (self.bw, self.bh);
        self.marks.fill(UNSEEN);
        self.flood(&[peak_at], SEED, |v, m| m == UNSEEN && v >= level);
        // The other edge of the same contact. A can lying across the pad tilts the gel along
        // the strip's two sides and not on its flat top, which runs to the view's sides: two
        // bands above the level that neither the flood from the peak nor the hole fill below
        // joins (pressed with friction, the surface under the can follows it and its top is
        // flatter: the region caught one band, 4–9 mm² of a 100 mm² strip). Every part above
        // the level as large as the noise test's two markers joins the seed; specks do not.
        for k in 0..self.map.len() {
            if self.marks[k] != UNSEEN || self.map[k] < level {
                continue;
            }
            let size = self.flood(&[k], PART, |v, m| m == UNSEEN && v >= level);
            let to = if size as f64 >= min_blocks {
                SEED
            } else {
                SPECK
            };
            self.flood(&[k], to, |_, m| m == PART);
        }
        // Between the parts: along each column and each row, what lies between its first
        // and last seed block is the contact (a strip's top between its two sides).
        for i in 0..bw {
            let seeded = |j: &usize| self.marks[j * bw + i] == SEED;
            if let (Some(a), Some(b)) = ((0..bh).find(seeded), (0..bh).rfind(seeded)) {
                (a..=b).for_each(|j| self.marks[j * bw + i] = SEED);
            }
        }
        for j in 0..bh {
            let row = &mut self.marks[j * bw..(j + 1) * bw];
            if let (Some(a), Some(b)) = (
                row.iter().position(|m| *m == SEED),
                row.iter().rposition(|m| *m == SEED),
            ) {
                row[a..=b].iter_mut().for_each(|m| *m = SEED);
            }
        }
        self.marks
            .iter_mut()
            .filter(|m| **m == SPECK)
            .for_each(|m| *m = UNSEEN);
        let border: Vec<usize> = (0..bw)
            .flat_map(|i| [i, (bh - 1) * bw + i])
            .chain((0..bh).flat_map(|j| [j * bw, j * bw + bw - 1]))
            .collect();
        self.flood(&border, OUTSIDE, |_, m| m == UNSEEN);
        self.marks
            .iter_mut()
            .filter(|m| **m == UNSEEN)
            .for_each(|m| *m = SEED);
    }

    /// 4-connected flood fill from `starts` over blocks accepted by `take(value, mark)`.
    /// Returns how many blocks it marked.
    fn flood(&mut self, starts: &[usize], to: u8, take: impl Fn(f32, u8) -> bool) -> usize {
        let (bw, bh) = (self.bw, self.bh);
        self.stack.clear();
        let mut marked = 0;
        for &s in starts {
            if take(self.map[s], self.marks[s]) {
                self.marks[s] = to;
                self.stack.push(s);
                marked += 1;
            }
        }
        let n = bw * bh;
        while let Some(k) = self.stack.pop() {
            // The first and last rows are told apart by the index alone: one remainder a block.
            let i = k % bw;
            let near = [
                (i > 0).then(|| k - 1),
                (i + 1 < bw).then(|| k + 1),
                (k >= bw).then(|| k - bw),
                (k + bw < n).then(|| k + bw),
            ];
            for q in near.into_iter().flatten() {
                if take(self.map[q], self.marks[q]) {
                    self.marks[q] = to;
                    self.stack.push(q);
                    marked += 1;
                }
            }
        }
        marked
    }

    /// Step 4: distance in blocks from `centre` along `dir` to the edge.
    fn edge_along(&mut self, centre: [f64; 2], dir: [f64; 2], peak: f32) -> f64 {
        const STEP: f64 = 0.5;
        let (bw, bh) = (self.bw as f64 - 1.0, self.bh as f64 - 1.0);
        let mut samples = std::mem::take(&mut self.samples);
        samples.clear();
        let r = self.edge_on(&mut samples, centre, dir, peak, STEP, bw, bh);
        self.samples = samples;
        r
    }

    #[allow(clippy::too_many_arguments)]
    fn edge_on(
        &self,
        samples: &mut Vec<(f64, f32, bool)>,
        centre: [f64; 2],
        dir: [f64; 2],
        peak: f32,
        step: f64,
        bw: f64,
        bh: f64,
    ) -> f64 {
        // Samples along the ray up to `t_max` (or the frame's edge): value and whether the
        // sample is in the seed.
        let walk = |samples: &mut Vec<(f64, f32, bool)>, t_max: f64| {
            let mut t = samples.last().map_or(0.0, |s| s.0 + step);
            while t <= t_max {
                let (x, y) = (centre[0] + t * dir[0], centre[1] + t * dir[1]);
                if !(0.0..=bw).contains(&x) || !(0.0..=bh).contains(&y) {
                    return false;
                }
                // Coordinates are ≥ 0 here, so +0.5 and truncation round.
                let k = (y + 0.5) as usize * self.bw + (x + 0.5) as usize;
                samples.push((t, self.sample(x, y), self.marks[k] == SEED));
                t += step;
            }
            true
        };
        let mut open = walk(samples, self.reach);
        let Some(last_seed) = samples.iter().rposition(|s| s.2) else {
            return 0.0;
        };
        // The ray's maximum lies in the seed (which holds everything above a quarter of the
        // peak).
        let reach = (last_seed + 2).min(samples.len());
        let (top, vmax) = samples[..reach]
            .iter()
            .enumerate()
            .map(|(i, s)| (i, s.1))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((0, peak));
        let level = (self.params.edge_fraction as f32 * vmax).max(self.floor);
        let mut i = top;
        loop {
            if i + 1 >= samples.len() {
                if !open {
                    break;
                }
                // Past the seed: a few more samples at a time, until the change drops.
                let further = samples.last().map_or(0.0, |s| s.0) + 8.0 * step;
                open = walk(samples, further);
                if i + 1 >= samples.len() {
                    break;
                }
            }
            if samples[i + 1].1 < level {
                break;
            }
            i += 1;
        }
        match samples.get(i + 1) {
            Some(&(t1, v1, _)) => {
                let (t0, v0, _) = samples[i];
                let f = if v0 > v1 {
                    ((v0 - level) / (v0 - v1)) as f64
                } else {
                    0.0
                };
                t0 + f.clamp(0.0, 1.0) * (t1 - t0)
            }
            None => samples[i].0,
        }
    }

    /// Bilinear sample of the map at block coordinates (inside the grid).
    fn sample(&self, x: f64, y: f64) -> f32 {
        // x, y ≥ 0: truncation is the floor (and no library call on the x86-64 baseline).
        let (i, j) = (x as usize, y as usize);
        let (i1, j1) = ((i + 1).min(self.bw - 1), (j + 1).min(self.bh - 1));
        let (fx, fy) = ((x - i as f64) as f32, (y - j as f64) as f32);
        let m = |i: usize, j: usize| self.map[j * self.bw + i];
        let top = m(i, j) + fx * (m(i1, j) - m(i, j));
        let bottom = m(i, j1) + fx * (m(i1, j1) - m(i, j1));
        top + fy * (bottom - top)
    }
}

/// Blocks wholly under markers (NaN) take the mean of their measured neighbours, ring by
/// ring; a map with nothing measured becomes zero.
///
/// Only the blocks still missing are visited (about a tenth of the map on a marker gel),
/// each ring reading the map as the ring before left it.
fn fill_nan(map: &mut [f32], scratch: &mut (Vec<usize>, Vec<(usize, f32)>), bw: usize, bh: usize) {
    let (missing, filled) = scratch;
    missing.clear();
    missing.extend((0..map.len()).filter(|&k| map[k].is_nan()));
    for _ in 0..bw.max(bh) {
        if missing.is_empty() {
            return;
        }
        filled.clear();
        missing.retain(|&k| {
            let (i, j) = (k % bw, k / bw);
            let (mut s, mut n) = (0.0, 0.0);
            for y in j.saturating_sub(1)..(j + 2).min(bh) {
                for x in i.saturating_sub(1)..(i + 2).min(bw) {
                    let v = map[y * bw + x];
                    if !v.is_nan() {
                        s += v;
                        n += 1.0;
                    }
                }
            }
            if n > 0.0 {
                filled.push((k, s / n));
            }
            n == 0.0
        });
        if filled.is_empty() {
            break;
        }
        for &(k, v) in filled.iter() {
            map[k] = v;
        }
    }
    for &k in missing.iter() {
        map[k] = 0.0;
    }
}

/// Separable [1 2 1]/4 smoothing, edges replicated.
fn smooth_121(map: &mut [f32], tmp: &mut [f32], w: usize, h: usize) {
    for j in 0..h {
        for i in 0..w {
            let m = |x: usize| map[j * w + x];
            tmp[j * w + i] = 0.25 * (m(i.saturating_sub(1)) + 2.0 * m(i) + m((i + 1).min(w - 1)));
        }
    }
    for j in 0..h {
        for i in 0..w {
            let m = |y: usize| tmp[y * w + i];
            map[j * w + i] = 0.25 * (m(j.saturating_sub(1)) + 2.0 * m(j) + m((j + 1).min(h - 1)));
        }
    }
}

#[cfg(test)]
#[path = "contact_tests.rs"]
mod tests;
