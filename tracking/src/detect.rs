//! Marker detection: darkness, low-pass, hysteresis threshold, run-based components.
//!
//! The per-pixel passes dominate the cost (the connected components touch only the ~10 %
//! of pixels that are marker), so they work on bytes with integer arithmetic, in AVX2 where
//! the CPU has it ([`super::pixels`]), and reuse their buffers: no allocation per frame once
//! warm.
//!
//! Components are found in one pass over runs of above-threshold pixels (Rosenfeld & Pfaltz
//! 1966, run-based with union–find, 8-connected). Each run carries its darkness-weighted
//! moments with weight `w = d − t_low`: zero at the threshold, so a pixel crossing it
//! neither jumps in nor out of the centroid, which keeps the centroid free of the
//! threshold-dependent bias of an unweighted blob centre (thesis §3.4 used the darkness
//! centroid for the same reason). The high threshold (hysteresis) keeps only components
//! whose darkest pixel is clearly a marker, so faint shading never starts a blob.

use super::RgbView;

/// Thresholds in smoothed-darkness levels (1/255 of the background) and area limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Thresholds {
    pub(crate) low: u8,
    pub(crate) high: u8,
    pub(crate) min_area: u32,
    pub(crate) max_area: u32,
    /// Blobs larger than this and elongated are split into markers (0: never).
    pub(crate) split_area: u32,
    /// Area of one marker, px², to count the markers in a merged blob.
    pub(crate) marker_area: f64,
    /// Components closer than this are fragments of one marker (0: never joined).
    pub(crate) fragment_radius: f64,
}

/// A dark blob: one marker, part of one at the border, or several merged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blob {
    /// Darkness-weighted centroid, px.
    pub x: f64,
    /// Darkness-weighted centroid, px.
    pub y: f64,
    /// Pixels above the low threshold.
    pub area_px: u32,
    /// Σ weight (darkness above the low threshold).
    pub mass: f64,
    /// Darkest smoothed pixel, 1/255 of the background.
    pub peak: u8,
    /// Weighted second central moments, px²: xx, yy, xy.
    pub moments: [f64; 3],
    /// Bounding box, inclusive: x0, y0, x1, y1.
    pub bbox: [u32; 4],
    /// Touches the image border, so part of the marker may be cut off.
    pub border: bool,
    /// Split from a blob of several merged markers: position less certain.
    pub merged: bool,
}

impl Blob {
    /// Ratio of the principal axes of the weighted second moments (1 for a disc).
    pub fn elongation(&self) -> f64 {
        let [xx, yy, xy] = self.moments;
        let tr = xx + yy;
        let disc = ((xx - yy) * (xx - yy) + 4.0 * xy * xy).sqrt();
        let (l1, l2) = ((tr + disc) / 2.0, ((tr - disc) / 2.0).max(1e-9));
        (l1 / l2).sqrt()
    }
}

#[derive(Debug, Clone, Copy)]
struct Run {
    y: u32,
    x0: u32,
    /// Exclusive.
    x1: u32,
    sw: u64,
    swx: u64,
    swx2: u64,
    peak: u8,
    root: u32,
}

#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    n: u64,
    sw: u64,
    swx: u64,
    swy: u64,
    swx2: u64,
    swy2: u64,
    swxy: u64,
    peak: u8,
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    /// Holds fragments of other components.
    joined: bool,
}

impl Acc {
    fn centroid(&self) -> [f64; 2] {
        let sw = self.sw.max(1) as f64;
        [self.swx as f64 / sw, self.swy as f64 / sw]
    }

    fn absorb(&mut self, o: &Acc) {
        self.n += o.n;
        self.sw += o.sw;
        self.swx += o.swx;
        self.swy += o.swy;
        self.swx2 += o.swx2;
        self.swy2 += o.swy2;
        self.swxy += o.swxy;
        self.peak = self.peak.max(o.peak);
        self.x0 = self.x0.min(o.x0);
        self.y0 = self.y0.min(o.y0);
        self.x1 = self.x1.max(o.x1);
        self.y1 = self.y1.max(o.y1);
        self.joined = true;
    }
}

/// Finds marker blobs in frames; holds its buffers so a warm detector does not allocate.
#[derive(Debug, Clone)]
pub struct Detector {
    width: usize,
    height: usize,
    dark: Vec<u8>,
    rows: Vec<u16>,
    smooth: Vec<u8>,
    runs: Vec<Run>,
    parent: Vec<u32>,
    acc_of_root: Vec<u32>,
    accs: Vec<Acc>,
    blobs: Vec<Blob>,
    low: u8,
    /// Background darkness per 32-px block of the last frame.
    block_bg: Vec<f32>,
}

impl Detector {
    /// A detector for frames of this size.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            dark: vec![0; n],
            rows: Vec::new(),
            smooth: vec![0; n],
            runs: Vec::new(),
            parent: Vec::new(),
            acc_of_root: Vec::new(),
            accs: Vec::new(),
            blobs: Vec::new(),
            low: 0,
            block_bg: Vec::new(),
        }
    }

    /// Detects the markers of `frame` given the reference's background (`inv_bg`, 65280/B
    /// per channel) and thresholds; [`super::Reference`] wraps it as `Detector::detect`.
    pub(crate) fn detect_with(
        &mut self,
        frame: RgbView<'_>,
        inv_bg: &[u16],
        thresholds: &Thresholds,
    ) -> &[Blob] {
        if self.width != frame.width() || self.height != frame.height() {
            *self = Self::new(frame.width(), frame.height());
        }
        self.darkness_into(frame.data(), inv_bg);
        self.label(thresholds);
        &self.blobs
    }

    /// The blobs of the last frame.
    pub fn blobs(&self) -> &[Blob] {
        &self.blobs
    }

    /// Smoothed darkness of the last frame, 1/255 of the background, row-major.
    pub fn smoothed(&self) -> &[u8] {
        &self.smooth
    }

    /// Frame width, px.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Frame height, px.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Darkness `255·(1 − max_c I_c/B_c)`, clamped at 0, then a 3×3 binomial low-pass
    /// ([`super::pixels`]).
    pub(crate) fn darkness_into(&mut self, rgb: &[u8], inv_bg: &[u16]) {
        super::pixels::darkness(rgb, inv_bg, &mut self.dark);
        self.normalise_exposure();
        super::pixels::binomial_3x3(
            &self.dark,
            self.width,
            self.height,
            &mut self.rows,
            &mut self.smooth,
        );
    }

    /// Divides out a change of exposure or illumination since the reference.
    ///
    /// Darkness is measured against the reference's background, so a frame 40 % darker
    /// overall would read as 40 % dark everywhere and drown the markers. In blocks of 32 px
    /// (larger than a marker, smaller than a vignetting gradient), the 10th percentile of the
    /// darkness on an eighth of the pixels (every fourth row, every other column) is the
    /// background's (even defocused markers leave a tenth of any block as background). When the median block's is above 2 %,
    /// every pixel's brightness ratio is divided by its background's, bilinearly between
    /// block centres. A frame lit as the reference costs one count of sampled pixels per
    /// block ([`Self::block_at_most`]) and no rescaling; a changed one the tenth percentiles
    /// ([`tenth_level`]) and the rescaling.
    fn normalise_exposure(&mut self) {
        const BLOCK: usize = EXPOSURE_BLOCK;
        let (w, h) = (self.width, self.height);
        let (bx, by) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
        // Rescale only when the frame as a whole changed (the median block is 2 % darker):
        // a few blocks full of defocused ink are not an exposure change. Whether a block's
        // level is above 2 % is one count (`block_at_most`), not the level's eight: a frame lit as
        // the reference needs no level at all (the median, the middle of the sorted levels,
        // is at most 5 exactly when more than half of the blocks are).
        let blocks = bx * by;
        let low = (0..by)
            .flat_map(|j| (0..bx).map(move |i| (i, j)))
            .filter(|&(i, j)| self.block_at_most(i, j, EXPOSURE_UNCHANGED))
            .count();
        if blocks == 0 || low > blocks / 2 {
            return;
        }
        self.block_bg.clear();
        for j in 0..by {
            for i in 0..bx {
                let (samples, n) = self.block_samples(i, j);
                // Keep a tenth of the ratio range at least: a block that is all marker or
                // all shadow is not a background.
                self.block_bg.push(tenth_level(&samples, n).min(230) as f32);
            }
        }
        let centre = |k: usize, n: usize, len: usize| {
            ((k * BLOCK) as f32 + (((k + 1) * BLOCK).min(len) - k * BLOCK) as f32 / 2.0 - 0.5)
                .min(len as f32 - 1.0)
                .max(0.0)
                .min(n as f32 * BLOCK as f32)
        };
        let cx: Vec<f32> = (0..bx).map(|i| centre(i, bx, w)).collect();
        let cy: Vec<f32> = (0..by).map(|j| centre(j, by, h)).collect();
        let locate = |c: &[f32], v: f32| -> (usize, usize, f32) {
            if v <= c[0] || c.len() == 1 {
                return (0, 0, 0.0);
            }
            let last = c.len() - 1;
            if v >= c[last] {
                return (last, last, 0.0);
            }
            let k = c.partition_point(|&q| q <= v) - 1;
            (k, k + 1, (v - c[k]) / (c[k + 1] - c[k]))
        };
        let columns: Vec<(usize, usize, f32)> = (0..w).map(|x| locate(&cx, x as f32)).collect();
        let mut row_bg = vec![0f32; bx];
        for y in 0..h {
            let (j0, j1, ty) = locate(&cy, y as f32);
            for (i, v) in row_bg.iter_mut().enumerate() {
                let (a, b) = (self.block_bg[j0 * bx + i], self.block_bg[j1 * bx + i]);
                *v = a + ty * (b - a);
            }
            for (d, &(i0, i1, tx)) in self.dark[y * w..][..w].iter_mut().zip(&columns) {
                let bg = row_bg[i0] + tx * (row_bg[i1] - row_bg[i0]);
                let ratio = (255 - *d) as f32 * 255.0 / (255.0 - bg);
                *d = (255.5 - ratio.min(255.0)) as u8;
            }
        }
    }

    /// Whether block `(i, j)`'s tenth-percentile darkness is at most `level`: one step of
    /// [`tenth_level`]'s bisection on [`Self::block_samples`], counted in place (a whole row of the block is 32 bytes,
    /// whose even ones are compared at once; gathering them first cost more than the count).
    fn block_at_most(&self, i: usize, j: usize, level: u8) -> bool {
        const BLOCK: usize = EXPOSURE_BLOCK;
        let (w, h) = (self.width, self.height);
        let (mut below, mut n) = (0usize, 0usize);
        for y in (j * BLOCK..((j + 1) * BLOCK).min(h)).step_by(4) {
            let row = &self.dark[y * w..][i * BLOCK..((i + 1) * BLOCK).min(w)];
            if let Ok(whole) = <&[u8; BLOCK]>::try_from(row) {
                below += whole
                    .iter()
                    .enumerate()
                    .map(|(k, &v)| u8::from(v <= level) & u8::from(k % 2 == 0))
                    .sum::<u8>() as usize;
                n += BLOCK / 2;
            } else {
                below += row.iter().step_by(2).filter(|&&v| v <= level).count();
                n += row.len().div_ceil(2);
            }
        }
        below >= n.div_ceil(10)
    }

    /// Block `(i, j)`'s samples of darkness for the exposure check, every fourth row and
    /// every other column, in one array (at most 8 rows of 16) padded with 255, which
    /// [`tenth_level`] never counts; and how many there are.
    fn block_samples(&self, i: usize, j: usize) -> ([u8; SAMPLES], usize) {
        const BLOCK: usize = EXPOSURE_BLOCK;
        let (w, h) = (self.width, self.height);
        let mut samples = [255u8; SAMPLES];
        let mut n = 0usize;
        for y in (j * BLOCK..((j + 1) * BLOCK).min(h)).step_by(4) {
            let row = &self.dark[y * w..][i * BLOCK..((i + 1) * BLOCK).min(w)];
            if let Ok(whole) = <&[u8; BLOCK]>::try_from(row) {
                // A whole block's row: every other byte, which the compiler packs.
                let even: [u8; BLOCK / 2] = std::array::from_fn(|k| whole[2 * k]);
                samples[n..n + BLOCK / 2].copy_from_slice(&even);
                n += BLOCK / 2;
            } else {
                for &v in row.iter().step_by(2) {
                    samples[n] = v;
                    n += 1;
                }
            }
        }
        (samples, n)
    }

    /// Labels runs above the low threshold and keeps components that pass the filters.
    pub(crate) fn label(&mut self, t: &Thresholds) {
        let (w, h) = (self.width, self.height);
        self.low = t.low;
        self.runs.clear();
        self.parent.clear();
        self.blobs.clear();
        let low = t.low;
        let (runs, parent) = (&mut self.runs, &mut self.parent);
        super::runs::runs_above(&self.smooth, w, h, low, &mut |r| {
            let id = runs.len() as u32;
            runs.push(Run {
                y: r.y,
                x0: r.x0,
                x1: r.x1,
                sw: r.sw,
                swx: r.swx,
                swx2: r.swx2,
                peak: r.peak,
                root: id,
            });
            parent.push(id);
        });
        // Union each run with the 8-connected runs of the row above (two pointers).
        let (mut prev_start, mut row_start) = (0usize, 0usize);
        while row_start < self.runs.len() {
            let y = self.runs[row_start].y;
            let row_end = row_start
                + self.runs[row_start..]
                    .iter()
                    .take_while(|r| r.y == y)
                    .count();
            let above = prev_start < row_start && self.runs[prev_start].y + 1 == y;
            if above {
                let mut p = prev_start;
                for r in row_start..row_end {
                    let (a0, a1) = (self.runs[r].x0, self.runs[r].x1);
                    while p < row_start && self.runs[p].x1 < a0 {
                        p += 1;
                    }
                    let mut q = p;
                    while q < row_start && self.runs[q].x0 <= a1 {
                        union(&mut self.parent, q as u32, r as u32);
                        q += 1;
                    }
                }
            }
            (prev_start, row_start) = (row_start, row_end);
        }
        // Accumulate per root.
        self.acc_of_root.clear();
        self.acc_of_root.resize(self.runs.len(), u32::MAX);
        self.accs.clear();
        for i in 0..self.runs.len() {
            let root = find(&mut self.parent, i as u32) as usize;
            self.runs[i].root = root as u32;
            let slot = if self.acc_of_root[root] == u32::MAX {
                self.acc_of_root[root] = self.accs.len() as u32;
                let r = &self.runs[i];
                self.accs.push(Acc {
                    x0: r.x0,
                    y0: r.y,
                    x1: r.x1 - 1,
                    y1: r.y,
                    ..Acc::default()
                });
                self.accs.len() - 1
            } else {
                self.acc_of_root[root] as usize
            };
            let r = self.runs[i];
            let a = &mut self.accs[slot];
            let y = r.y as u64;
            a.n += (r.x1 - r.x0) as u64;
            a.sw += r.sw;
            a.swx += r.swx;
            a.swy += r.sw * y;
            a.swx2 += r.swx2;
            a.swy2 += r.sw * y * y;
            a.swxy += r.swx * y;
            a.peak = a.peak.max(r.peak);
            a.x0 = a.x0.min(r.x0);
            a.x1 = a.x1.max(r.x1 - 1);
            a.y0 = a.y0.min(r.y);
            a.y1 = a.y1.max(r.y);
        }
        if t.fragment_radius > 0.0 {
            self.merge_fragments(t);
        }
        for root in 0..self.acc_of_root.len() {
            let slot = self.acc_of_root[root];
            if slot == u32::MAX {
                continue;
            }
            let a = self.accs[slot as usize];
            if a.peak < t.high || a.n < t.min_area as u64 || a.n > t.max_area as u64 || a.sw == 0 {
                continue;
            }
            let sw = a.sw as f64;
            let (x, y) = (a.swx as f64 / sw, a.swy as f64 / sw);
            let xx = a.swx2 as f64 / sw - x * x;
            let yy = a.swy2 as f64 / sw - y * y;
            let xy = a.swxy as f64 / sw - x * y;
            self.blobs.push(Blob {
                x,
                y,
                area_px: a.n as u32,
                mass: sw,
                peak: a.peak,
                moments: [xx, yy, xy],
                bbox: [a.x0, a.y0, a.x1, a.y1],
                border: a.x0 == 0 || a.y0 == 0 || a.x1 as usize == w - 1 || a.y1 as usize == h - 1,
                merged: false,
            });
            if t.split_area > 0 && a.n > t.split_area as u64 && !a.joined {
                let last = self.blobs.len() - 1;
                if self.blobs[last].elongation() > 1.5 {
                    let k = (a.n as f64 / t.marker_area).round().clamp(2.0, 4.0) as usize;
                    let merged = self.blobs[last];
                    self.blobs.truncate(last);
                    self.split(&merged, root as u32, k);
                }
            }
        }
    }

    /// Joins components closer than a marker diameter whose joint area is still one marker's.
    ///
    /// Real markers can image as rings (a bright specular centre) whose rim drops below the
    /// threshold in places; the pieces are one marker, and their joint darkness-weighted
    /// centroid is its centre. Two distinct markers that close would overlap and so already
    /// be one component.
    fn merge_fragments(&mut self, t: &Thresholds) {
        let mut order: Vec<(f64, u32)> = self
            .accs
            .iter()
            .enumerate()
            .filter(|(_, a)| a.sw > 0)
            .map(|(i, a)| (a.centroid()[1], i as u32))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let r = t.fragment_radius;
        let max_n = (1.5 * t.marker_area) as u64;
        for k in 0..order.len() {
            let i = order[k].1 as usize;
            for &(y, j) in &order[k + 1..] {
                if y - order[k].0 > r {
                    break;
                }
                let (ai, aj) = (self.accs[i], self.accs[j as usize]);
                if ai.sw == 0 || aj.sw == 0 || ai.n + aj.n > max_n {
                    continue;
                }
                let (ci, cj) = (ai.centroid(), aj.centroid());
                let (dx, dy) = (ci[0] - cj[0], ci[1] - cj[1]);
                if dx * dx + dy * dy < r * r {
                    self.accs[i].absorb(&aj);
                    self.accs[j as usize] = Acc::default();
                }
            }
        }
    }

    /// Splits a blob of `k` merged markers by weighted k-means (Lloyd 1982) over its pixels,
    /// started from points spread along its major axis.
    fn split(&mut self, blob: &Blob, root: u32, k: usize) {
        let [xx, yy, xy] = blob.moments;
        let angle = 0.5 * (2.0 * xy).atan2(xx - yy);
        let (ax, ay) = (angle.cos(), angle.sin());
        let major = (0.5 * (xx + yy) + (0.25 * (xx - yy).powi(2) + xy * xy).sqrt()).sqrt();
        // A uniform bar of standard deviation σ is 2√3·σ long.
        let len = 2.0 * 3f64.sqrt() * major;
        let mut centres: Vec<[f64; 2]> = (0..k)
            .map(|j| {
                let t = -0.5 * len + len * (j as f64 + 0.5) / k as f64;
                [blob.x + t * ax, blob.y + t * ay]
            })
            .collect();
        let mut acc = vec![Acc::default(); k];
        let nearest = |c: &[[f64; 2]], x: f64, y: f64| {
            let mut best = (0, f64::INFINITY);
            for (j, cj) in c.iter().enumerate() {
                let d = (x - cj[0]).powi(2) + (y - cj[1]).powi(2);
                if d < best.1 {
                    best = (j, d);
                }
            }
            best.0
        };
        for iteration in 0..8 {
            acc.iter_mut().for_each(|a| {
                *a = Acc {
                    x0: u32::MAX,
                    y0: u32::MAX,
                    ..Acc::default()
                }
            });
            let (w, low) = (self.width, self.low);
            for r in self.runs.iter().filter(|r| r.root == root) {
                let row = &self.smooth[r.y as usize * w..];
                for x in r.x0..r.x1 {
                    let j = nearest(&centres, x as f64, r.y as f64);
                    let wgt = (row[x as usize] - low) as u64;
                    let (xu, yu) = (x as u64, r.y as u64);
                    let a = &mut acc[j];
                    a.n += 1;
                    a.sw += wgt;
                    a.swx += wgt * xu;
                    a.swy += wgt * yu;
                    a.swx2 += wgt * xu * xu;
                    a.swy2 += wgt * yu * yu;
                    a.swxy += wgt * xu * yu;
                    a.peak = a.peak.max(row[x as usize]);
                    a.x0 = a.x0.min(x);
                    a.x1 = a.x1.max(x);
                    a.y0 = a.y0.min(r.y);
                    a.y1 = a.y1.max(r.y);
                }
            }
            let moved = centres.iter_mut().zip(&acc).fold(0.0f64, |m, (c, a)| {
                if a.sw == 0 {
                    return m;
                }
                let n = [a.swx as f64 / a.sw as f64, a.swy as f64 / a.sw as f64];
                let d = (n[0] - c[0]).hypot(n[1] - c[1]);
                *c = n;
                m.max(d)
            });
            if moved < 1e-3 && iteration > 0 {
                break;
            }
        }
        for a in acc.iter().filter(|a| a.sw > 0) {
            let sw = a.sw as f64;
            let (x, y) = (a.swx as f64 / sw, a.swy as f64 / sw);
            self.blobs.push(Blob {
                x,
                y,
                area_px: a.n as u32,
                mass: sw,
                peak: a.peak,
                moments: [
                    a.swx2 as f64 / sw - x * x,
                    a.swy2 as f64 / sw - y * y,
                    a.swxy as f64 / sw - x * y,
                ],
                bbox: [a.x0, a.y0, a.x1, a.y1],
                border: blob.border,
                merged: true,
            });
        }
    }
}

/// Side of [`Detector::normalise_exposure`]'s blocks, px.
const EXPOSURE_BLOCK: usize = 32;

/// Samples of one such block: every fourth row and every other column.
const SAMPLES: usize = EXPOSURE_BLOCK.div_ceil(4) * EXPOSURE_BLOCK.div_ceil(2);

/// The tenth percentile of `samples[..n]`: the lowest level at or below which a tenth of them
/// lie (10·count ≥ n), found by bisection on the count, each count a byte sum over the whole
/// array the compiler vectorises. The entries from `n` on must be 255, which is never
/// counted (the bisection asks about levels up to 254 only). A histogram per block cost
/// more than the rest of the pass: four of them cleared and summed, 256 bins each.
fn tenth_level(samples: &[u8; SAMPLES], n: usize) -> u8 {
    let need = n.div_ceil(10);
    let (mut lo, mut hi) = (0u8, 255u8);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        // At most 128 samples: the count fits a byte.
        const _: () = assert!(SAMPLES <= 255);
        let below = samples
            .iter()
            .fold(0u8, |c, &v| c.wrapping_add(u8::from(v <= mid)));
        if usize::from(below) >= need {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// A block's tenth-percentile darkness at or below which the frame counts as lit as the
/// reference (2 % of the background).
const EXPOSURE_UNCHANGED: u8 = 5;

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        // Keep the earlier run as the root, so roots are stable in raster order.
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether [`tenth_level`]`(samples, n)` is at most `level` (< 255): one step of its
    /// bisection.
    fn at_most(samples: &[u8; SAMPLES], n: usize, level: u8) -> bool {
        let below = samples
            .iter()
            .fold(0u8, |c, &v| c.wrapping_add(u8::from(v <= level)));
        usize::from(below) >= n.div_ceil(10)
    }

    /// The definition: the lowest level whose running count reaches a tenth (a histogram).
    fn by_histogram(samples: &[u8]) -> u8 {
        let mut hist = [0u32; 256];
        samples.iter().for_each(|&v| hist[v as usize] += 1);
        let (mut acc, mut level) = (0u32, 0usize);
        while level < 255 {
            acc += hist[level];
            if 10 * acc >= samples.len() as u32 {
                break;
            }
            level += 1;
        }
        level as u8
    }

    /// The exposure check's count in place is the count of the gathered samples, on frames
    /// whose size is and is not a whole number of blocks.
    #[test]
    fn a_blocks_count_in_place_is_its_samples() {
        let mut state = 0x853C_49E6_748F_EA9Bu64;
        for (w, h) in [(640, 480), (100, 70), (33, 5), (7, 40)] {
            let mut d = Detector::new(w, h);
            for v in &mut d.dark {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                // Mostly background near the level, some marker.
                *v = if state.is_multiple_of(7) {
                    200
                } else {
                    (state % 12) as u8
                };
            }
            for j in 0..h.div_ceil(EXPOSURE_BLOCK) {
                for i in 0..w.div_ceil(EXPOSURE_BLOCK) {
                    let (samples, n) = d.block_samples(i, j);
                    for level in [0u8, 3, 5, 11, 254] {
                        assert_eq!(
                            d.block_at_most(i, j, level),
                            at_most(&samples, n, level),
                            "{w}×{h}, block ({i}, {j}), level {level}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_tenth_level_is_the_histograms() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for n in 0..=SAMPLES {
            // Flat, narrow, wide, saturated and two-level (marker and background) blocks.
            for spread in [0u64, 3, 40, 256] {
                for base in [0u8, 7, 200, 255] {
                    let mut samples = [255u8; SAMPLES];
                    for v in &mut samples[..n] {
                        let r = if spread == 0 { 0 } else { next() % spread };
                        *v = base.saturating_add(r as u8);
                    }
                    if base == 7 {
                        samples[..n / 3].fill(230);
                    }
                    let level = by_histogram(&samples[..n]);
                    assert_eq!(
                        tenth_level(&samples, n),
                        level,
                        "n {n}, spread {spread}, base {base}"
                    );
                    for at in [0u8, 5, 6, 7, 200, 229, 254] {
                        assert_eq!(at_most(&samples, n, at), level <= at, "n {n}, at {at}");
                    }
                }
            }
        }
    }
}
