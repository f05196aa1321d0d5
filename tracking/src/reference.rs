//! The no-contact reference: marker-free background, marker statistics, lattice spacing.
//!
//! Darkness is measured against what the gel would look like *without* its markers at the
//! same place, so the background is estimated from the reference frame with the markers
//! removed: a coarse box-filter background finds the markers, they are masked (dilated by
//! 2 px for their blurred rims), and each channel is filled by normalised convolution
//! (Knutsson & Westin 1993) — the masked mean of the neighbourhood. The MIT 2014 code used a
//! Gaussian of the whole frame instead, which darkens the background near every marker and
//! so biases both threshold and weights.
//!
//! A reference that shows a contact imprint would make every later displacement relative to
//! a deformed gel. The imprint shows as *chromatic* structure at the scale of the contact
//! (the lights are coloured, so surface slope changes hue), while the illumination of an
//! untouched gel varies smoothly in hue across the whole view. The check: high-pass the
//! chromaticity of the marker-free background at twice the coarse scale and take the 99th
//! percentile of its magnitude. On the real GelSight Mini sequence (`../shared/data`),
//! untouched frames score 0.049–0.055 and frames with a visible imprint 0.10–0.43; the limit
//! is 0.09. A light touch without a visible imprint cannot be told from a single frame.

use super::detect::{Detector, Thresholds};
use super::{RgbView, TrackError, TrackParams, median};

/// One marker found on the reference frame; its index is its identity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceMarker {
    /// Darkness-weighted centroid, px.
    pub x: f64,
    /// Darkness-weighted centroid, px.
    pub y: f64,
    /// Area above the low threshold, px².
    pub area_px: u32,
    /// Touches the image border: present, but its centroid is biased.
    pub border: bool,
}

/// Everything measured once on the no-contact frame.
#[derive(Clone)]
pub struct Reference {
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// 255·256 / background, per pixel and channel, interleaved like the frame.
    pub(crate) inv_bg: Vec<u16>,
    pub(crate) thresholds: Thresholds,
    pub(crate) markers: Vec<ReferenceMarker>,
    /// Smoothed darkness of the reference frame (LK templates).
    pub(crate) darkness: Vec<u8>,
    spacing_px: f64,
    radius_px: f64,
    area_px: f64,
    contrast: f64,
    contact_score: f64,
    pub(crate) params: TrackParams,
}

impl std::fmt::Debug for Reference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reference")
            .field("size", &(self.width, self.height))
            .field("markers", &self.markers.len())
            .field("spacing_px", &self.spacing_px)
            .field("radius_px", &self.radius_px)
            .field("contrast", &self.contrast)
            .field("contact_score", &self.contact_score)
            .finish_non_exhaustive()
    }
}

/// Detection against a reference lives beside the reference, so the detector itself knows
/// nothing of how a reference is measured (and the two files do not import each other).
impl Detector {
    /// Detects the markers of `frame`, measured against `reference`.
    pub fn detect(
        &mut self,
        frame: RgbView<'_>,
        reference: &Reference,
    ) -> Result<&[super::Blob], TrackError> {
        reference.check_size(&frame)?;
        Ok(self.detect_with(frame, &reference.inv_bg, &reference.thresholds))
    }
}

impl Reference {
    /// Measures the reference; refuses a frame that is saturated, holds too few markers or
    /// shows a contact imprint.
    pub fn new(frame: RgbView<'_>, params: &TrackParams) -> Result<Self, TrackError> {
        Self::measure(frame, params, true)
    }

    /// Measures a frame that may show contact: its own background, thresholds and markers
    /// (the detections of a single frame, for `--detect-only` and the reference-free start).
    /// Displacements measured against it are not from the untouched gel.
    pub fn of_any_frame(frame: RgbView<'_>, params: &TrackParams) -> Result<Self, TrackError> {
        Self::measure(frame, params, false)
    }

    /// The same background and thresholds with other markers (the undeformed lattice of a
    /// reference-free start), in reading order, with the given spacing.
    pub(crate) fn with_markers(
        mut self,
        mut markers: Vec<ReferenceMarker>,
        spacing_px: f64,
    ) -> Self {
        sort_raster(&mut markers, spacing_px);
        self.markers = markers;
        self.spacing_px = spacing_px;
        self
    }

    fn measure(
        frame: RgbView<'_>,
        params: &TrackParams,
        imprint_check: bool,
    ) -> Result<Self, TrackError> {
        let (w, h) = (frame.width(), frame.height());
        let data = frame.data();
        let saturated = data
            .chunks_exact(3)
            .filter(|p| p.iter().all(|&c| c >= 250))
            .count();
        if saturated * 2 > w * h {
            return Err(TrackError::ReferenceSaturated {
                percent: 100.0 * saturated as f64 / (w * h) as f64,
            });
        }
        let r0 = coarse_radius(w, h);
        let bg = marker_free_background(data, w, h, r0);
        // The imprint check fills at a finer scale, which keeps the imprint's structure.
        let contact_score = chromatic_residual(&marker_free_background(data, w, h, r0 / 2), w, h);
        let inv_bg: Vec<u16> = bg
            .iter()
            .map(|&b| (65280.0 / b.max(1.0)).round().min(65535.0) as u16)
            .collect();

        // Bootstrap: Otsu on the darkness gives provisional thresholds; the blobs found
        // with them give the marker contrast and area, which set the final ones.
        let mut detector = Detector::new(w, h);
        detector.darkness_into(data, &inv_bg);
        // Thresholds no lower than four times the background's noise (its robust spread,
        // 1.4826·MAD), so faint markers (contrast down to 5 %) are found and noise is not.
        let floor = (4.0 * noise_level(detector.smoothed())).clamp(5.0, 20.0) as u8;
        let otsu = otsu_u8(detector.smoothed()).max(floor);
        let provisional = Thresholds {
            low: (otsu / 2).max(floor / 2).max(3),
            high: otsu,
            min_area: 4,
            max_area: (w * h / 16) as u32,
            split_area: 0,
            marker_area: 1.0,
            fragment_radius: 0.0,
        };
        detector.label(&provisional);
        let interior: Vec<&super::Blob> = detector.blobs().iter().filter(|b| !b.border).collect();
        let mut areas: Vec<f64> = interior.iter().map(|b| b.area_px as f64).collect();
        let Some(area_med) = median(&mut areas) else {
            return Err(TrackError::NoMarkers { found: 0 });
        };
        let mut peaks: Vec<f64> = interior
            .iter()
            .filter(|b| {
                let a = b.area_px as f64;
                a > 0.5 * area_med && a < 2.0 * area_med
            })
            .map(|b| b.peak as f64)
            .collect();
        let contrast = median(&mut peaks).unwrap_or(otsu as f64);
        let thresholds = Thresholds {
            low: (params.low_fraction * contrast).round().clamp(4.0, 250.0) as u8,
            high: (params.high_fraction * contrast).round().clamp(6.0, 252.0) as u8,
            min_area: 1,
            max_area: u32::MAX,
            split_area: 0,
            marker_area: 1.0,
            fragment_radius: 0.0,
        };
        detector.label(&thresholds);
        let mut areas: Vec<f64> = detector
            .blobs()
            .iter()
            .filter(|b| !b.border && b.area_px >= 4)
            .map(|b| b.area_px as f64)
            .collect();
        let area_px = median(&mut areas).unwrap_or(area_med);
        let thresholds = Thresholds {
            min_area: ((params.min_area_fraction * area_px).round() as u32).max(3),
            max_area: (params.max_area_factor * area_px).round() as u32,
            split_area: (1.5 * area_px).round() as u32,
            marker_area: area_px,
            fragment_radius: 2.0 * (area_px / std::f64::consts::PI).sqrt(),
            ..thresholds
        };
        detector.label(&thresholds);
        let single = |b: &&super::Blob| (b.area_px as f64) < 2.0 * area_px;
        let mut markers: Vec<ReferenceMarker> = detector
            .blobs()
            .iter()
            .filter(single)
            .map(|b| ReferenceMarker {
                x: b.x,
                y: b.y,
                area_px: b.area_px,
                border: b.border,
            })
            .collect();
        if markers.len() < 3 {
            return Err(TrackError::NoMarkers {
                found: markers.len(),
            });
        }
        if imprint_check && contact_score > params.contact_imprint_limit {
            return Err(TrackError::ReferenceInContact {
                score: contact_score,
                limit: params.contact_imprint_limit,
            });
        }
        let spacing_px = median_nearest_distance(&markers);
        sort_raster(&mut markers, spacing_px);
        Ok(Self {
            width: w,
            height: h,
            inv_bg,
            thresholds,
            markers,
            darkness: detector.smoothed().to_vec(),
            spacing_px,
            radius_px: (area_px / std::f64::consts::PI).sqrt(),
            area_px,
            contrast,
            contact_score,
            params: params.clone(),
        })
    }

    /// Frame width, px.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Frame height, px.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The markers; index = identity.
    pub fn markers(&self) -> &[ReferenceMarker] {
        &self.markers
    }

    /// Median distance between nearest markers, px.
    pub fn spacing_px(&self) -> f64 {
        self.spacing_px
    }

    /// Radius of a disc with the median marker area, px.
    pub fn radius_px(&self) -> f64 {
        self.radius_px
    }

    /// Median marker area above the low threshold, px².
    pub fn area_px(&self) -> f64 {
        self.area_px
    }

    /// Median peak darkness of the markers, in 1/255 of the background.
    pub fn contrast(&self) -> f64 {
        self.contrast
    }

    /// Chromatic residual of the background (see the module doc).
    pub fn contact_score(&self) -> f64 {
        self.contact_score
    }

    /// Smoothed darkness of the reference frame, 1/255 of the background, row-major.
    pub fn darkness(&self) -> &[u8] {
        &self.darkness
    }

    /// The parameters the reference was measured with.
    pub fn params(&self) -> &TrackParams {
        &self.params
    }

    pub(crate) fn check_size(&self, frame: &RgbView<'_>) -> Result<(), TrackError> {
        if frame.width() != self.width || frame.height() != self.height {
            return Err(TrackError::SizeMismatch {
                ref_w: self.width,
                ref_h: self.height,
                got_w: frame.width(),
                got_h: frame.height(),
            });
        }
        Ok(())
    }
}

/// Sorts markers into reading order: rows of markers closer than half a spacing in y, then x.
fn sort_raster(markers: &mut [ReferenceMarker], spacing_px: f64) {
    markers.sort_by(|a, b| a.y.total_cmp(&b.y));
    let mut row = 0usize;
    let mut rows = Vec::with_capacity(markers.len());
    let mut row_start_y = f64::NEG_INFINITY;
    for m in markers.iter() {
        if m.y - row_start_y > 0.5 * spacing_px {
            row += 1;
            row_start_y = m.y;
        }
        rows.push(row);
    }
    let mut keyed: Vec<(usize, ReferenceMarker)> =
        rows.into_iter().zip(markers.iter().copied()).collect();
    keyed.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.x.total_cmp(&b.1.x)));
    for (dst, (_, m)) in markers.iter_mut().zip(keyed) {
        *dst = m;
    }
}

/// Median over markers of the distance to the nearest other marker.
fn median_nearest_distance(markers: &[ReferenceMarker]) -> f64 {
    let mut d: Vec<f64> = markers
        .iter()
        .enumerate()
        .map(|(i, a)| {
            markers
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, b)| (a.x - b.x).hypot(a.y - b.y))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    median(&mut d).unwrap_or(1.0)
}

/// Otsu's threshold (Otsu 1979) of a u8 image: maximises the between-class variance.
/// Robust standard deviation of a darkness image's background: 1.4826 × the median
/// absolute deviation from the median (markers are a minority of pixels).
fn noise_level(img: &[u8]) -> f64 {
    let mut hist = [0u32; 256];
    for &v in img.iter().step_by(3) {
        hist[v as usize] += 1;
    }
    let n: u32 = hist.iter().sum();
    let quantile = |h: &[u32], q: u32| {
        let mut acc = 0;
        h.iter()
            .position(|&c| {
                acc += c;
                2 * acc >= q
            })
            .unwrap_or(0)
    };
    let med = quantile(&hist, n);
    let mut dev = [0u32; 256];
    for (v, &c) in hist.iter().enumerate() {
        dev[v.abs_diff(med)] += c;
    }
    1.4826 * quantile(&dev, n).max(1) as f64
}

fn otsu_u8(img: &[u8]) -> u8 {
    let mut hist = [0u64; 256];
    for &v in img {
        hist[v as usize] += 1;
    }
    let total = img.len() as f64;
    let sum_all: f64 = hist
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * c as f64)
        .sum();
    let (mut w0, mut sum0, mut best, mut best_t) = (0.0, 0.0, -1.0, 0u8);
    for (t, &c) in hist.iter().enumerate() {
        w0 += c as f64;
        sum0 += t as f64 * c as f64;
        let w1 = total - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let (m0, m1) = (sum0 / w0, (sum_all - sum0) / w1);
        let between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if between > best {
            best = between;
            best_t = t as u8;
        }
    }
    best_t.saturating_add(1)
}

/// Mean over the window of radius `r` clipped to the image, separable running sums, with
/// its buffers kept between calls (a reference's background takes a dozen such means of
/// the whole frame; fresh buffers each time were pages the kernel had to clear, a tenth of
/// a 300-frame `gelrig track`).
#[derive(Debug, Default)]
pub(crate) struct BoxMean {
    rows: Vec<f32>,
    prefix: Vec<f64>,
    columns: Vec<f64>,
}

impl BoxMean {
    /// `out` = the mean of `src` (`w` × `h`) over each pixel's window of radius `r`.
    ///
    /// Both passes run along rows (the column pass keeps a row of prefix sums per image
    /// row), so memory is read in order: a column-by-column pass strode the image by its
    /// width and was most of a 640×480 reference's cost. The sums are the same to the bit.
    pub(crate) fn mean(&mut self, src: &[f32], w: usize, h: usize, r: usize, out: &mut [f32]) {
        let (tmp, prefix, columns) = (&mut self.rows, &mut self.prefix, &mut self.columns);
        tmp.resize(w * h, 0.0);
        prefix.resize(w + 1, 0.0);
        for (row, dst) in src.chunks_exact(w).zip(tmp.chunks_exact_mut(w)).take(h) {
            for x in 0..w {
                prefix[x + 1] = prefix[x] + row[x] as f64;
            }
            for (x, d) in dst.iter_mut().enumerate() {
                let (a, b) = (x.saturating_sub(r), (x + r + 1).min(w));
                *d = ((prefix[b] - prefix[a]) / (b - a) as f64) as f32;
            }
        }
        // Row y + 1 of `columns` holds, per column, the sum of `tmp` over rows 0..=y.
        columns.resize(w * (h + 1), 0.0);
        columns[..w].fill(0.0);
        for y in 0..h {
            let (done, next) = columns.split_at_mut((y + 1) * w);
            for ((n, p), t) in next[..w]
                .iter_mut()
                .zip(&done[y * w..])
                .zip(&tmp[y * w..][..w])
            {
                *n = p + *t as f64;
            }
        }
        for (y, dst) in out.chunks_exact_mut(w).enumerate().take(h) {
            let (a, b) = (y.saturating_sub(r), (y + r + 1).min(h));
            let n = (b - a) as f64;
            for ((d, hi), lo) in dst.iter_mut().zip(&columns[b * w..]).zip(&columns[a * w..]) {
                *d = ((hi - lo) / n) as f32;
            }
        }
    }
}

/// Coarse scale of the background model, px: a sixteenth of the short side (15 px at
/// 320×240), several marker diameters on every GelSight camera we know.
fn coarse_radius(w: usize, h: usize) -> usize {
    (w.min(h) / 16).max(7)
}

/// Per-channel background without markers, interleaved RGB f32.
fn marker_free_background(data: &[u8], w: usize, h: usize, r_fill: usize) -> Vec<f32> {
    let n = w * h;
    let mut boxes = BoxMean::default();
    let r0 = coarse_radius(w, h);
    let planes: Vec<Vec<f32>> = (0..3)
        .map(|c| data.iter().skip(c).step_by(3).map(|&v| v as f32).collect())
        .collect();
    let mut coarse: Vec<Vec<f32>> = vec![vec![0.0; n]; 3];
    for (p, out) in planes.iter().zip(coarse.iter_mut()) {
        boxes.mean(p, w, h, r0, out);
    }
    // Pixels darker than the coarse background in every channel by > 8 % are marker.
    let mut mask = vec![0.0f32; n];
    for (i, m) in mask.iter_mut().enumerate() {
        let d = (0..3)
            .map(|c| 1.0 - planes[c][i] / coarse[c][i].max(1.0))
            .fold(f32::INFINITY, f32::min);
        if d > 0.08 {
            *m = 1.0;
        }
    }
    // Dilate by 2 px: a window mean above zero means a marker pixel is near.
    let mut grown = vec![0.0f32; n];
    boxes.mean(&mask, w, h, 2, &mut grown);
    let keep: Vec<f32> = grown
        .iter()
        .map(|&g| if g > 0.0 { 0.0 } else { 1.0 })
        .collect();
    let mut den = vec![0.0f32; n];
    let mut num = vec![0.0f32; n];
    let mut out = vec![0.0f32; 3 * n];
    for (c, plane) in planes.iter().enumerate() {
        let masked: Vec<f32> = plane.iter().zip(&keep).map(|(v, k)| v * k).collect();
        let mut r = r_fill;
        let mut filled = vec![false; n];
        loop {
            boxes.mean(&keep, w, h, r, &mut den);
            boxes.mean(&masked, w, h, r, &mut num);
            let mut missing = false;
            for i in 0..n {
                if filled[i] {
                    continue;
                }
                if den[i] > 1e-3 {
                    out[3 * i + c] = num[i] / den[i];
                    filled[i] = true;
                } else {
                    missing = true;
                }
            }
            if !missing || r > w.max(h) {
                break;
            }
            r *= 2;
        }
        // Nothing unmasked anywhere (a frame that is all marker): keep the coarse mean.
        for i in 0..n {
            if !filled[i] {
                out[3 * i + c] = coarse[c][i];
            }
        }
    }
    out
}

/// 99th percentile of the chromatic high-pass of the background (see the module doc).
fn chromatic_residual(bg: &[f32], w: usize, h: usize) -> f64 {
    let n = w * h;
    let r0 = coarse_radius(w, h);
    let mut chroma: Vec<Vec<f32>> = vec![vec![0.0; n]; 3];
    for i in 0..n {
        let mean = (bg[3 * i] + bg[3 * i + 1] + bg[3 * i + 2]) / 3.0 + 1.0;
        for (c, plane) in chroma.iter_mut().enumerate() {
            plane[i] = bg[3 * i + c] / mean;
        }
    }
    let mut worst = vec![0.0f32; n];
    let mut smooth = vec![0.0f32; n];
    let mut boxes = BoxMean::default();
    for plane in &chroma {
        boxes.mean(plane, w, h, 2 * r0, &mut smooth);
        for i in 0..n {
            worst[i] = worst[i].max((plane[i] - smooth[i]).abs());
        }
    }
    let margin = r0.min(w / 4).min(h / 4);
    let mut inner: Vec<f64> = (margin..h - margin)
        .flat_map(|y| (margin..w - margin).map(move |x| (x, y)))
        .map(|(x, y)| worst[y * w + x] as f64)
        .collect();
    if inner.is_empty() {
        return 0.0;
    }
    let k = ((inner.len() as f64 * 0.99) as usize).min(inner.len() - 1);
    let (_, p, _) = inner.select_nth_unstable_by(k, f64::total_cmp);
    *p
}

#[cfg(test)]
mod tests {
    use super::BoxMean;

    /// The running sums give each pixel the mean of its window clipped to the image.
    #[test]
    fn box_means_are_the_clipped_window_means() {
        let mut boxes = BoxMean::default();
        // One set of buffers over frames of two sizes, as a reader reused.
        for (w, h) in [(37, 23), (5, 9), (37, 23)] {
            let src: Vec<f32> = (0..w * h)
                .map(|i| ((i * 7919) % 251) as f32 * 0.37)
                .collect();
            for r in [0, 1, 3, 30] {
                let mut out = vec![0.0f32; w * h];
                boxes.mean(&src, w, h, r, &mut out);
                for y in 0..h {
                    for x in 0..w {
                        let (xs, ys) = (
                            x.saturating_sub(r)..(x + r + 1).min(w),
                            y.saturating_sub(r)..(y + r + 1).min(h),
                        );
                        let n = (xs.len() * ys.len()) as f64;
                        let sum: f64 = ys
                            .flat_map(|yy| xs.clone().map(move |xx| (xx, yy)))
                            .map(|(xx, yy)| src[yy * w + xx] as f64)
                            .sum();
                        let want = sum / n;
                        assert!(
                            (out[y * w + x] as f64 - want).abs() <= 1e-4 * want.abs().max(1.0),
                            "r {r} at ({x}, {y}): {} against {want}",
                            out[y * w + x]
                        );
                    }
                }
            }
        }
    }
}
