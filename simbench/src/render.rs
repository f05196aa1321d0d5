//! GelSight-like frames of the simulated elastomer.
//!
//! A GelSight camera looks at the back of a coated elastomer lit from the sides by coloured
//! lights, so a flat gel shows a smooth colour gradient and a deformed one shows colour
//! where its surface tilts; the printed markers ride on the surface. Each frame here is:
//!
//! 1. the lit background (a fixed gradient, computed once);
//! 2. shading from the surface slope: three lights (red, green, blue) at 120° azimuths,
//!    each adding gain·(∇u_z · l) — the coloured ring of a punch's edge, the bulge around it;
//! 3. the markers, at their displaced positions (the field sampled at each marker's
//!    reference point), with edges blurred analytically: coverage ½·erfc((d − r)/(√2σ)),
//!    σ = 0.6 px, from a lookup table — the camera's blur without a convolution pass;
//! 4. sensor noise, σ ≈ 1.5 grey levels, from a precomputed texture at a per-frame offset.
//!
//! The exact marker centres in pixels are returned as ground truth. Budget: a 640×480 frame
//! in ≤ 5 ms (BENCHMARKS.md).

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use mechanics::response::Field;

use super::plant::{MarkerLayout, PlantSpec};

/// The surface field the camera renders, placed in the view.
#[derive(Debug, Clone)]
pub struct SurfaceView {
    /// Field on a grid centred on the contact pattern.
    pub field: Field,
    /// Where the contact pattern's centre sits in view coordinates, mm.
    pub centre_mm: (f64, f64),
    /// How far the contact pattern has turned by slipping, rad.
    pub rotation_rad: f64,
}

/// Reference (undeformed) marker centres in mm relative to the view centre, x right, y down.
///
/// A grid is centred on the view. A random layout is a jittered lattice drawn once from a
/// fixed seed: the markers are printed on the elastomer, so every frame and every run of the
/// same sensor sees the same pattern.
pub fn marker_reference_positions_mm(
    layout: &MarkerLayout,
    view_w_mm: f64,
    view_h_mm: f64,
) -> Vec<(f64, f64)> {
    match *layout {
        MarkerLayout::Grid {
            columns,
            rows,
            spacing_mm,
            ..
        } => {
            let mut out = Vec::with_capacity((columns * rows) as usize);
            for j in 0..rows {
                for i in 0..columns {
                    out.push((
                        (i as f64 - (columns as f64 - 1.0) / 2.0) * spacing_mm,
                        (j as f64 - (rows as f64 - 1.0) / 2.0) * spacing_mm,
                    ));
                }
            }
            out
        }
        MarkerLayout::Random { spacing_mm, .. } => {
            let mut rng = StdRng::seed_from_u64(0x6E15_1647);
            let nx = (view_w_mm / spacing_mm).ceil() as i64 + 1;
            let ny = (view_h_mm / spacing_mm).ceil() as i64 + 1;
            let mut out = Vec::new();
            for j in -ny / 2..=ny / 2 {
                for i in -nx / 2..=nx / 2 {
                    let jx = (rng.random::<f64>() - 0.5) * 0.5 * spacing_mm;
                    let jy = (rng.random::<f64>() - 0.5) * 0.5 * spacing_mm;
                    let (x, y) = (i as f64 * spacing_mm + jx, j as f64 * spacing_mm + jy);
                    if x.abs() <= view_w_mm / 2.0 && y.abs() <= view_h_mm / 2.0 {
                        out.push((x, y));
                    }
                }
            }
            out
        }
    }
}

/// erfc by Abramowitz & Stegun 7.1.26 (|error| < 1.5e-7), enough for a coverage table.
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * z);
    let y = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let r = y * (-z * z).exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// `dst[i] = (src[i] + gain·noise[i] + 0.5) as u8`: float-to-integer casts saturate, so the
/// `+ 0.5` and the cast round and clamp at once. This is the last pass over every channel of
/// every frame (14 % of a grasp dry run's samples as a scalar loop, which the compiler does
/// not vectorise: the saturating cast). On x86-64-v3 eight channels at a time: the same two
/// additions in the same order, then max(·, 0) and min(·, 255) and a truncating conversion,
/// which is the saturating cast for every finite value and maps NaN to 0 as it does, so the
/// bytes are the scalar loop's (`the_vector_pass_is_the_scalar_cast_byte_for_byte`).
fn add_noise_and_round(dst: &mut [u8], src: &[f32], noise: &[i8], gain: f32) {
    let scalar = |dst: &mut [u8], src: &[f32], noise: &[i8]| {
        for ((o, v), n) in dst.iter_mut().zip(src).zip(noise) {
            *o = (v + gain * *n as f32 + 0.5) as u8;
        }
    };
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = pulp::x86::V3::try_new() {
        let lanes = src.len().min(dst.len()).min(noise.len()) / 8 * 8;
        simd.vectorize(|| {
            let chunks = dst[..lanes]
                .chunks_exact_mut(8)
                .zip(src[..lanes].chunks_exact(8))
                .zip(noise[..lanes].chunks_exact(8));
            for ((o, v), n) in chunks {
                round_8_v3(simd, o, v, n, gain);
            }
        });
        return scalar(&mut dst[lanes..], &src[lanes..], &noise[lanes..]);
    }
    scalar(dst, src, noise)
}

/// Eight channels of [`add_noise_and_round`] with AVX2.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn round_8_v3(simd: pulp::x86::V3, dst: &mut [u8], src: &[f32], noise: &[i8], gain: f32) {
    use core::arch::x86_64::{__m128i, __m256};
    let (Ok(v), Ok(n), Ok(out)) = (
        <[f32; 8]>::try_from(src),
        <[i8; 8]>::try_from(noise),
        <&mut [u8; 8]>::try_from(dst),
    ) else {
        return;
    };
    let (avx, avx2, sse2, sse41) = (simd.avx, simd.avx2, simd.sse2, simd.sse4_1);
    let mut n16 = [0i8; 16];
    n16[..8].copy_from_slice(&n);
    let n: __m256 = avx._mm256_cvtepi32_ps(avx2._mm256_cvtepi8_epi32(pulp::cast(n16)));
    let x = avx._mm256_add_ps(
        avx._mm256_add_ps(pulp::cast(v), avx._mm256_mul_ps(pulp::cast([gain; 8]), n)),
        pulp::cast([0.5f32; 8]),
    );
    // `max` returns its second operand when the first is NaN: NaN becomes 0, as in a cast.
    let x = avx._mm256_min_ps(
        avx._mm256_max_ps(x, pulp::cast([0.0f32; 8])),
        pulp::cast([255.0f32; 8]),
    );
    let i = avx._mm256_cvttps_epi32(x);
    let (lo, hi): (__m128i, __m128i) = (
        avx._mm256_castsi256_si128(i),
        avx2._mm256_extracti128_si256::<1>(i),
    );
    let words = sse41._mm_packus_epi32(lo, hi);
    let bytes: [u8; 16] = pulp::cast(sse2._mm_packus_epi16(words, words));
    out.copy_from_slice(&bytes[..8]);
}

/// Edge blur of the markers, px.
const BLUR_PX: f64 = 0.6;
/// Steps per pixel of the coverage table.
const LUT_STEPS: f64 = 64.0;
/// Shading gain: grey levels per unit of surface slope.
const SHADE_GAIN: f64 = 55.0;
/// Ink colour of the markers.
const INK: [f32; 3] = [30.0, 28.0, 36.0];

/// Renders frames of one sensor at one camera resolution (public for benchmarks).
pub struct Renderer {
    width: u32,
    height: u32,
    mm_per_px: f64,
    background: Vec<f32>,
    markers_mm: Vec<(f64, f64)>,
    /// Orientation of each printed triangle (fixed per sensor), rad.
    orientations: Vec<f64>,
    layout: MarkerLayout,
    /// Coverage against signed distance from the marker edge, d = −4σ−1 … +4σ+1 px.
    lut: Vec<f32>,
    lut_origin: f64,
    noise: Vec<i8>,
    noisy: bool,
    /// Unit light directions in the image plane (x right, y down) for R, G, B.
    lights: [(f64, f64); 3],
}

impl Renderer {
    /// Prepares the background, marker layout, blur table and noise texture.
    pub fn new(spec: &PlantSpec, width: u32, height: u32) -> Self {
        Self::for_view(
            &spec.markers,
            spec.view_width_mm,
            spec.view_height_mm,
            width,
            height,
        )
    }

    /// A renderer for a marker layout seen over `view_width_mm × view_height_mm`, without a
    /// contact model (tests and benchmarks of the tracker draw markers where they choose).
    pub fn for_view(
        markers: &MarkerLayout,
        view_width_mm: f64,
        view_height_mm: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let mm_per_px = (view_width_mm / width as f64).max(view_height_mm / height as f64);
        let mut background = Vec::with_capacity((width * height * 3) as usize);
        for y in 0..height {
            for x in 0..width {
                let u = x as f64 / width as f64 - 0.5;
                let v = y as f64 / height as f64 - 0.5;
                let vignette = 1.0 - 0.35 * (u * u + v * v);
                background.push(((150.0 + 50.0 * u) * vignette).clamp(0.0, 255.0) as f32);
                background.push(((145.0 - 40.0 * v) * vignette).clamp(0.0, 255.0) as f32);
                background
                    .push(((160.0 - 30.0 * u + 25.0 * v) * vignette).clamp(0.0, 255.0) as f32);
            }
        }
        let lut_origin = -(4.0 * BLUR_PX + 1.0);
        let lut_len = (2.0 * -lut_origin * LUT_STEPS) as usize + 2;
        let lut = (0..lut_len)
            .map(|i| {
                let d = lut_origin + i as f64 / LUT_STEPS;
                (0.5 * erfc(d / (std::f64::consts::SQRT_2 * BLUR_PX))) as f32
            })
            .collect();
        let mut rng = StdRng::seed_from_u64(0x5EED_0FC0_FFEE);
        let noise = (0..1 << 20)
            .map(|_| {
                let z: f64 = rng.sample(StandardNormal);
                (1.5 * z).round().clamp(-127.0, 127.0) as i8
            })
            .collect();
        let lights = [0.0_f64, 120.0, 240.0].map(|deg: f64| {
            let a = deg.to_radians();
            (a.cos(), a.sin())
        });
        let markers_mm = marker_reference_positions_mm(markers, view_width_mm, view_height_mm);
        let mut orient_rng = StdRng::seed_from_u64(0x07A1_A6E5);
        let orientations = markers_mm
            .iter()
            .map(|_| orient_rng.random::<f64>() * 2.0 * std::f64::consts::PI / 3.0)
            .collect();
        Self {
            width,
            height,
            mm_per_px,
            background,
            orientations,
            markers_mm,
            layout: markers.clone(),
            lut,
            lut_origin,
            noise,
            noisy: true,
            lights,
        }
    }

    fn coverage(&self, signed_distance_px: f64) -> f32 {
        let i = ((signed_distance_px - self.lut_origin) * LUT_STEPS) as isize;
        if i < 0 {
            1.0
        } else if i as usize >= self.lut.len() {
            0.0
        } else {
            self.lut[i as usize]
        }
    }

    /// Without sensor noise (clean frames for sub-pixel accuracy tests).
    pub fn without_noise(mut self) -> Self {
        self.noisy = false;
        self
    }

    /// Millimetres per pixel of the view.
    pub fn mm_per_px(&self) -> f64 {
        self.mm_per_px
    }

    /// The surface's normal displacement (mm, into the gel) at each pixel's centre, row-major:
    /// the truth the shading was drawn from, mapped to pixels as [`Self::render`] maps it
    /// (bilinear between field cells; zero beyond the field).
    pub fn surface_depth_mm(&self, s: &SurfaceView) -> Vec<f32> {
        let g = &s.field.grid;
        let n = g.n;
        let (w, h) = (self.width as usize, self.height as usize);
        let cell = |mm: f64| -> Option<(usize, f64)> {
            let f = mm / g.dx + (n / 2) as f64 - 0.5;
            (f >= 0.0 && f <= (n - 1) as f64).then(|| {
                let i = (f.floor() as usize).min(n - 2);
                (i, f - i as f64)
            })
        };
        let mut out = vec![0.0f32; w * h];
        for py in 0..h {
            let Some((cj, ty)) =
                cell((py as f64 + 0.5 - h as f64 / 2.0) * self.mm_per_px - s.centre_mm.1)
            else {
                continue;
            };
            for px in 0..w {
                let Some((ci, tx)) =
                    cell((px as f64 + 0.5 - w as f64 / 2.0) * self.mm_per_px - s.centre_mm.0)
                else {
                    continue;
                };
                let at = |i: usize, j: usize| s.field.uz[j * n + i];
                let v = (1.0 - ty) * ((1.0 - tx) * at(ci, cj) + tx * at(ci + 1, cj))
                    + ty * ((1.0 - tx) * at(ci, cj + 1) + tx * at(ci + 1, cj + 1));
                out[py * w + px] = v as f32;
            }
        }
        out
    }

    /// Undeformed marker centres, px, with pixel (i, j) centred at (i, j).
    pub fn reference_px(&self) -> Vec<[f64; 2]> {
        self.markers_mm
            .iter()
            .map(|&(x, y)| self.to_px(x, y))
            .collect()
    }

    /// View millimetres (centred) to pixels, pixel (i, j) centred at (i, j).
    pub(crate) fn to_px(&self, x_mm: f64, y_mm: f64) -> [f64; 2] {
        [
            self.width as f64 / 2.0 - 0.5 + x_mm / self.mm_per_px,
            self.height as f64 / 2.0 - 0.5 + y_mm / self.mm_per_px,
        ]
    }

    /// Renders one frame; returns RGB pixels and the exact marker centres in pixels (pixel
    /// (i, j) centred at (i, j), the tracker's convention).
    pub fn render(&self, surface: Option<&SurfaceView>, seq: u64) -> (Vec<u8>, Vec<[f64; 2]>) {
        // Markers at their displaced positions.
        let (c, sn) = surface
            .map(|s| (s.rotation_rad.cos(), s.rotation_rad.sin()))
            .unwrap_or((1.0, 0.0));
        let truth: Vec<[f64; 2]> = self
            .markers_mm
            .iter()
            .map(|&(x, y)| {
                let (ux, uy) = match surface {
                    Some(s) => {
                        // Reference point in the contact pattern's frame, then back.
                        let (dx, dy) = (x - s.centre_mm.0, y - s.centre_mm.1);
                        let (px, py) = (c * dx + sn * dy, -sn * dx + c * dy);
                        let g = &s.field.grid;
                        let (fx, fy) =
                            (g.sample(&s.field.ux, px, py), g.sample(&s.field.uy, px, py));
                        (c * fx - sn * fy, sn * fx + c * fy)
                    }
                    None => (0.0, 0.0),
                };
                self.to_px(x + ux, y + uy)
            })
            .collect();
        let turn = surface.map(|s| s.rotation_rad).unwrap_or(0.0);
        let rgb = self.render_at(surface, &truth, turn, seq);
        (rgb, truth)
    }

    /// Renders the markers at `centres_px` (one per reference marker, in order; pixel (i, j)
    /// centred at (i, j)), triangles turned by `turn_rad`, over the shading of `surface`.
    pub fn render_at(
        &self,
        surface: Option<&SurfaceView>,
        centres_px: &[[f64; 2]],
        turn_rad: f64,
        seq: u64,
    ) -> Vec<u8> {
        let mut img = self.background_layer(surface);
        self.draw_markers(&mut img, centres_px, |_| turn_rad);
        self.finish(&img, seq)
    }

    /// The lit background with the shading of `surface`, before markers and noise, as
    /// linear grey levels (RGB, row-major).
    pub fn background_layer(&self, surface: Option<&SurfaceView>) -> Vec<f32> {
        let mut img: Vec<f32> = self.background.clone();
        if let Some(s) = surface {
            self.shade(&mut img, s);
        }
        img
    }

    /// Draws markers at `centres_px` onto a layer; `turn_rad(m)` turns marker `m`'s
    /// triangle (printed triangles turn with the surface they are printed on). Markers
    /// beyond the sensor's own layout get orientations from their index.
    pub fn draw_markers(
        &self,
        img: &mut [f32],
        centres_px: &[[f64; 2]],
        turn_rad: impl Fn(usize) -> f64,
    ) {
        for (m, &[x, y]) in centres_px.iter().enumerate() {
            // The drawing code puts pixel centres at +0.5.
            let (cx, cy) = (x + 0.5, y + 0.5);
            match self.layout {
                MarkerLayout::Grid { diameter_mm, .. } => {
                    self.dot(img, cx, cy, diameter_mm / 2.0 / self.mm_per_px)
                }
                MarkerLayout::Random { size_mm, .. } => {
                    let own = self.orientations.get(m).copied().unwrap_or_else(|| {
                        // SplitMix64 of the index: a fixed, well-spread orientation.
                        let mut z = (m as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
                        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
                        z ^= z >> 31;
                        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 * std::f64::consts::PI / 3.0
                    });
                    self.triangle(img, cx, cy, size_mm / self.mm_per_px, own + turn_rad(m))
                }
            }
        }
    }

    /// Sensor noise (unless [`Self::without_noise`]) at a per-frame offset, then bytes.
    pub fn finish(&self, img: &[f32], seq: u64) -> Vec<u8> {
        let offset = (seq.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 44) as usize;
        let mask = self.noise.len() - 1;
        let gain = if self.noisy { 1.0 } else { 0.0 };
        let mut out = vec![0u8; img.len()];
        // Pixel i takes the texture's value at (i + offset) mod its length: walked as runs
        // of contiguous slices (one or two per frame) rather than an index masked and
        // bounds-checked per pixel (BENCHMARKS.md, "Grasp trials that feel slip").
        let mut at = 0;
        while at < img.len() {
            let k = (at + offset) & mask;
            let run = (img.len() - at).min(self.noise.len() - k);
            let (src, dst) = (&img[at..at + run], &mut out[at..at + run]);
            add_noise_and_round(dst, src, &self.noise[k..k + run], gain);
            at += run;
        }
        out
    }

    /// Frame size, px.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Ink darkness of a marker's centre against the background at the view's centre,
    /// `1 − max_c(ink_c / background_c)` (the tracker's darkness measure).
    pub fn ink_darkness(&self) -> f64 {
        let i = (((self.height / 2) * self.width + self.width / 2) * 3) as usize;
        let ratio = (0..3)
            .map(|c| INK[c] as f64 / self.background[i + c].max(1.0) as f64)
            .fold(0.0, f64::max);
        1.0 - ratio
    }

    /// Adds the lights' response to the surface slope.
    ///
    /// The colour change of each field cell is computed once; per pixel row the two cell
    /// rows around it are blended once, leaving one interpolation per pixel. Slopes below
    /// 0.01 (under half a grey level) are skipped, and so are the cells no pixel reads: the
    /// field's period adds twelve layer thicknesses to the view, so most of its cells lie
    /// outside the picture.
    fn shade(&self, img: &mut [f32], s: &SurfaceView) {
        let g = &s.field.grid;
        let n = g.n;
        let uz = &s.field.uz;
        let gain = SHADE_GAIN;
        let (w, h) = (self.width as usize, self.height as usize);
        if w == 0 || h == 0 || n < 3 {
            return;
        }
        let cell_of = |mm: f64| -> (usize, f32) {
            let f = (mm / g.dx + (n / 2) as f64 - 0.5).clamp(0.0, (n - 2) as f64);
            (f.floor() as usize, (f - f.floor()) as f32)
        };
        let col_cell = |px: usize| {
            cell_of((px as f64 + 0.5 - w as f64 / 2.0) * self.mm_per_px - s.centre_mm.0)
        };
        let row_cell = |py: usize| {
            cell_of((py as f64 + 0.5 - h as f64 / 2.0) * self.mm_per_px - s.centre_mm.1)
        };
        // The cells any pixel reads (its cell and the next, along each axis), inside the
        // border where the central difference is defined.
        let (rx0, rx1) = (col_cell(0).0.max(1), (col_cell(w - 1).0 + 1).min(n - 2));
        let (ry0, ry1) = (row_cell(0).0.max(1), (row_cell(h - 1).0 + 1).min(n - 2));
        if rx0 > rx1 || ry0 > ry1 {
            return;
        }
        let rw = rx1 - rx0 + 1;
        let at = |i: usize, j: usize| (j - ry0) * rw + (i - rx0);
        let mut delta = vec![[0.0f32; 3]; rw * (ry1 - ry0 + 1)];
        let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (usize::MAX, 0, usize::MAX, 0);
        for j in ry0..=ry1 {
            for i in rx0..=rx1 {
                let k = j * n + i;
                let sx = (uz[k + 1] - uz[k - 1]) / (2.0 * g.dx);
                let sy = (uz[k + n] - uz[k - n]) / (2.0 * g.dx);
                if sx.abs() + sy.abs() > 1e-2 {
                    lo_x = lo_x.min(i - 1);
                    hi_x = hi_x.max(i + 1);
                    lo_y = lo_y.min(j - 1);
                    hi_y = hi_y.max(j + 1);
                    for (ch, (lx, ly)) in self.lights.iter().enumerate() {
                        delta[at(i, j)][ch] = (gain * (sx * lx + sy * ly)) as f32;
                    }
                }
            }
        }
        if lo_x > hi_x {
            return;
        }
        // A cell outside the range has no colour change here (as one whose slope is small).
        let delta_at = |i: usize, j: usize| -> [f32; 3] {
            if (rx0..=rx1).contains(&i) && (ry0..=ry1).contains(&j) {
                delta[at(i, j)]
            } else {
                [0.0; 3]
            }
        };
        let to_px = |cell: usize, centre: f64, half: f64| {
            (half + (g.coord(cell) + centre) / self.mm_per_px) as isize
        };
        let x0 = to_px(lo_x, s.centre_mm.0, w as f64 / 2.0).clamp(0, w as isize - 1) as usize;
        let x1 = to_px(hi_x, s.centre_mm.0, w as f64 / 2.0).clamp(0, w as isize - 1) as usize;
        let y0 = to_px(lo_y, s.centre_mm.1, h as f64 / 2.0).clamp(0, h as isize - 1) as usize;
        let y1 = to_px(hi_y, s.centre_mm.1, h as f64 / 2.0).clamp(0, h as isize - 1) as usize;
        let cols: Vec<(usize, f32)> = (x0..=x1).map(col_cell).collect();
        let (c_lo, c_hi) = (
            cols.first().map(|c| c.0).unwrap_or(0),
            cols.last().map(|c| c.0 + 1).unwrap_or(0),
        );
        let mut row = vec![[0.0f32; 3]; n];
        for py in y0..=y1 {
            let (cj, ty) = row_cell(py);
            for (ci, cell) in row.iter_mut().enumerate().take(c_hi + 1).skip(c_lo) {
                let (a, b) = (delta_at(ci, cj), delta_at(ci, cj + 1));
                *cell = [
                    a[0] + ty * (b[0] - a[0]),
                    a[1] + ty * (b[1] - a[1]),
                    a[2] + ty * (b[2] - a[2]),
                ];
            }
            let base = (py * w + x0) * 3;
            for (k, &(ci, tx)) in cols.iter().enumerate() {
                let (a, b) = (row[ci], row[ci + 1]);
                let p = base + 3 * k;
                img[p] += a[0] + tx * (b[0] - a[0]);
                img[p + 1] += a[1] + tx * (b[1] - a[1]);
                img[p + 2] += a[2] + tx * (b[2] - a[2]);
            }
        }
    }

    fn ink(&self, img: &mut [f32], x: i64, y: i64, coverage: f32) {
        if coverage <= 0.0 || x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = ((y as u32 * self.width + x as u32) * 3) as usize;
        for (c, ink) in img[i..i + 3].iter_mut().zip(INK) {
            *c += (ink - *c) * coverage;
        }
    }

    /// A round marker: coverage from the distance of each pixel centre to the edge.
    fn dot(&self, img: &mut [f32], cx: f64, cy: f64, r: f64) {
        let m = r + 4.0 * BLUR_PX + 1.0;
        let (x0, x1) = ((cx - m).floor() as i64, (cx + m).ceil() as i64);
        let (y0, y1) = ((cy - m).floor() as i64, (cy + m).ceil() as i64);
        for y in y0..=y1 {
            let dy = y as f64 + 0.5 - cy;
            for x in x0..=x1 {
                let d = (x as f64 + 0.5 - cx).hypot(dy);
                self.ink(img, x, y, self.coverage(d - r));
            }
        }
    }

    /// An equilateral triangle of side `side`, centroid at (cx, cy), turned by `turn` rad:
    /// coverage from the signed distance to its nearest edge.
    fn triangle(&self, img: &mut [f32], cx: f64, cy: f64, side: f64, turn: f64) {
        let rc = side / 3f64.sqrt();
        let ri = rc / 2.0;
        // Outward edge normals, 120° apart.
        let normals: [(f64, f64); 3] = [30.0_f64, 150.0, 270.0].map(|deg: f64| {
            let a = deg.to_radians() + turn;
            (a.cos(), a.sin())
        });
        let m = rc + 4.0 * BLUR_PX + 1.0;
        let (x0, x1) = ((cx - m).floor() as i64, (cx + m).ceil() as i64);
        let (y0, y1) = ((cy - m).floor() as i64, (cy + m).ceil() as i64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                let d = normals
                    .iter()
                    .map(|(nx, ny)| px * nx + py * ny - ri)
                    .fold(f64::MIN, f64::max);
                self.ink(img, x, y, self.coverage(d));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shading as first written: every cell of the field's grid differenced, the
    /// bounding box of the steep cells mapped to pixels and clamped to the picture.
    fn shade_every_cell(r: &Renderer, img: &mut [f32], s: &SurfaceView) {
        let (g, n, uz) = (&s.field.grid, s.field.grid.n, &s.field.uz);
        let mut delta = vec![[0.0f32; 3]; n * n];
        let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (usize::MAX, 0, usize::MAX, 0);
        for j in 1..n - 1 {
            for i in 1..n - 1 {
                let k = j * n + i;
                let sx = (uz[k + 1] - uz[k - 1]) / (2.0 * g.dx);
                let sy = (uz[k + n] - uz[k - n]) / (2.0 * g.dx);
                if sx.abs() + sy.abs() > 1e-2 {
                    (lo_x, hi_x) = (lo_x.min(i - 1), hi_x.max(i + 1));
                    (lo_y, hi_y) = (lo_y.min(j - 1), hi_y.max(j + 1));
                    for (ch, (lx, ly)) in r.lights.iter().enumerate() {
                        delta[k][ch] = (SHADE_GAIN * (sx * lx + sy * ly)) as f32;
                    }
                }
            }
        }
        if lo_x > hi_x {
            return;
        }
        let (w, h) = (r.width as usize, r.height as usize);
        let to_px = |cell: usize, centre: f64, half: f64, len: usize| {
            ((half + (g.coord(cell) + centre) / r.mm_per_px) as isize).clamp(0, len as isize - 1)
                as usize
        };
        let cell_of = |mm: f64| -> (usize, f32) {
            let f = (mm / g.dx + (n / 2) as f64 - 0.5).clamp(0.0, (n - 2) as f64);
            (f.floor() as usize, (f - f.floor()) as f32)
        };
        let (cx, cy) = s.centre_mm;
        let (x0, x1) = (
            to_px(lo_x, cx, w as f64 / 2.0, w),
            to_px(hi_x, cx, w as f64 / 2.0, w),
        );
        let (y0, y1) = (
            to_px(lo_y, cy, h as f64 / 2.0, h),
            to_px(hi_y, cy, h as f64 / 2.0, h),
        );
        for py in y0..=y1 {
            let (cj, ty) = cell_of((py as f64 + 0.5 - h as f64 / 2.0) * r.mm_per_px - cy);
            for px in x0..=x1 {
                let (ci, tx) = cell_of((px as f64 + 0.5 - w as f64 / 2.0) * r.mm_per_px - cx);
                let blend = |ci: usize| -> [f32; 3] {
                    let (a, b) = (delta[cj * n + ci], delta[(cj + 1) * n + ci]);
                    [0, 1, 2].map(|c| a[c] + ty * (b[c] - a[c]))
                };
                let (a, b) = (blend(ci), blend(ci + 1));
                for c in 0..3 {
                    img[(py * w + px) * 3 + c] += a[c] + tx * (b[c] - a[c]);
                }
            }
        }
    }

    /// Shading only the cells some pixel reads gives the picture shading every cell gave,
    /// bit for bit: a dimple wider than the view, one in a corner, one beyond the view, on
    /// field grids finer and coarser than the pixels.
    #[test]
    fn shading_the_cells_the_picture_reads_is_shading_every_cell() {
        let layout = MarkerLayout::Grid {
            columns: 3,
            rows: 2,
            spacing_mm: 4.0,
            diameter_mm: 1.0,
        };
        let r = Renderer::for_view(&layout, 16.0, 12.0, 160, 120);
        for (n, dx) in [(128, 0.3), (64, 0.11)] {
            let grid = mechanics::operator::Grid { n, dx };
            for (centre_mm, radius_mm) in
                [((0.5, -0.3), 14.0), ((7.0, 5.5), 3.0), ((30.0, 0.0), 2.0)]
            {
                let uz: Vec<f64> = (0..grid.len())
                    .map(|k| {
                        let (x, y) = grid.xy(k);
                        let r2 = (x * x + y * y) / (radius_mm * radius_mm);
                        0.4 * (1.0 - r2).max(0.0).powi(2)
                    })
                    .collect();
                let z = vec![0.0; grid.len()];
                let view = SurfaceView {
                    field: Field {
                        grid,
                        ux: z.clone(),
                        uy: z,
                        uz,
                    },
                    centre_mm,
                    rotation_rad: 0.0,
                };
                let got = r.background_layer(Some(&view));
                let mut want = r.background.clone();
                shade_every_cell(&r, &mut want, &view);
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                let tag = format!("{n} cells of {dx} mm, centre {centre_mm:?}");
                assert!(bits(&got) == bits(&want), "{tag}");
                let shaded = got
                    .iter()
                    .zip(&r.background)
                    .filter(|(a, b)| a != b)
                    .count();
                assert_eq!(
                    shaded > 0,
                    centre_mm.0 < 20.0,
                    "{tag}: {shaded} channels shaded"
                );
            }
        }
    }

    #[test]
    fn the_vector_pass_is_the_scalar_cast_byte_for_byte() {
        // Values across and beyond the byte range, halves that round either way, NaN and
        // infinities, with noise of both signs, at lengths that leave a scalar tail.
        let mut src: Vec<f32> = (0..4000).map(|i| i as f32 * 0.0731 - 20.0).collect();
        src.extend([
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            254.5,
            255.49,
            -0.5,
            0.49,
        ]);
        src.extend((0..300).map(|i| 250.0 + i as f32 * 0.5));
        let noise: Vec<i8> = (0..src.len())
            .map(|i| ((i * 37 % 255) as i32 - 127) as i8)
            .collect();
        for gain in [1.0f32, 0.0] {
            for len in [src.len(), src.len() - 3, 7, 8, 9, 0] {
                let mut fast = vec![0u8; len];
                add_noise_and_round(&mut fast, &src[..len], &noise[..len], gain);
                let slow: Vec<u8> = src[..len]
                    .iter()
                    .zip(&noise)
                    .map(|(v, n)| (v + gain * *n as f32 + 0.5) as u8)
                    .collect();
                assert_eq!(fast, slow, "gain {gain}, {len} channels");
            }
        }
    }

    #[test]
    fn erfc_is_accurate_enough_for_coverage() {
        assert!((erfc(0.0) - 1.0).abs() < 1e-7);
        assert!((erfc(1.0) - 0.157_299_207).abs() < 2e-7);
        assert!((erfc(-1.0) - 1.842_700_793).abs() < 2e-7);
    }
}
