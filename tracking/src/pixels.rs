//! The detector's per-pixel passes: darkness against the reference's background, and the
//! 3×3 binomial low-pass (the runs above the threshold are [`super::runs`]).
//!
//! They are most of a frame's cost, and on a 640×480 frame they were bound by memory more
//! than by arithmetic: the darkness went through a frame-sized buffer of per-channel products
//! (0.9 MB written, then read back) and the low-pass through a frame of 16-bit row sums
//! (0.6 MB). Both now work on blocks that stay in the first-level cache — 64 pixels of
//! products, three rows of sums — and both are compiled for the best instruction set the
//! CPU has ([`pulp::Arch`] chooses at run time; the loops are plain Rust, which the compiler
//! vectorises there). Their results are the definitions' to the bit (tests below).

/// Pixels per block of the darkness pass: 192 bytes of products, in the first-level cache.
const BLOCK_PX: usize = 64;

/// `dark[i] = 255 − min(255, max_c (rgb[3i+c]·inv_bg[3i+c]) >> 8)` for every pixel `i`
/// (`inv_bg` is 65280/B per channel, so the product is the brightness ratio in 1/255).
pub(crate) fn darkness(rgb: &[u8], inv_bg: &[u16], dark: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = pulp::x86::V3::try_new() {
        return simd.vectorize(|| darkness_v3::run(simd, rgb, inv_bg, dark));
    }
    pulp::Arch::new().dispatch(Darkness { rgb, inv_bg, dark });
}

/// `smooth` = ([1 2 1] ⊗ [1 2 1]) `src` / 16, rounded, edges replicated; `rows` holds three
/// rows of horizontal sums (resized here).
pub(crate) fn binomial_3x3(
    src: &[u8],
    width: usize,
    height: usize,
    rows: &mut Vec<u16>,
    smooth: &mut [u8],
) {
    if width < 2 || height == 0 || src.len() < width * height || smooth.len() < width * height {
        return;
    }
    rows.resize(3 * width, 0);
    pulp::Arch::new().dispatch(Binomial {
        src,
        width,
        height,
        rows,
        smooth,
    });
}

struct Darkness<'a> {
    rgb: &'a [u8],
    inv_bg: &'a [u16],
    dark: &'a mut [u8],
}

/// One channel's `I·inv >> 8` as the high half of a 16-bit multiply (`(I·256)·inv >> 16`),
/// saturated to a byte.
#[inline(always)]
fn ratio(c: u8, inv: u16) -> u8 {
    let p = ((((c as u16) << 8) as u32 * inv as u32) >> 16) as u16;
    p.min(255) as u8
}

/// One block: the products, then each pixel's maximum (which needs byte shuffles, so the two
/// loops stay apart; the products never leave the cache).
#[inline(always)]
fn darkness_block(rgb: &[u8], inv: &[u16], dark: &mut [u8], prod: &mut [u8]) {
    for ((o, &c), &i) in prod.iter_mut().zip(rgb).zip(inv) {
        *o = ratio(c, i);
    }
    for (d, p) in dark.iter_mut().zip(prod.chunks_exact(3)) {
        *d = 255 - p[0].max(p[1]).max(p[2]);
    }
}

impl pulp::WithSimd for Darkness<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let n = self
            .dark
            .len()
            .min(self.rgb.len() / 3)
            .min(self.inv_bg.len() / 3);
        let (dark, rgb, inv) = (
            &mut self.dark[..n],
            &self.rgb[..3 * n],
            &self.inv_bg[..3 * n],
        );
        let mut prod = [0u8; 3 * BLOCK_PX];
        let whole = n / BLOCK_PX * BLOCK_PX;
        // Whole blocks with their length known to the compiler, then the rest.
        for ((d, c), i) in dark[..whole]
            .chunks_exact_mut(BLOCK_PX)
            .zip(rgb.chunks_exact(3 * BLOCK_PX))
            .zip(inv.chunks_exact(3 * BLOCK_PX))
        {
            darkness_block(c, i, d, &mut prod);
        }
        let rest = n - whole;
        darkness_block(
            &rgb[3 * whole..],
            &inv[3 * whole..],
            &mut dark[whole..],
            &mut prod[..3 * rest],
        );
    }
}

/// The darkness pass written out in AVX2 and SSSE3 (x86-64-v3, most x86 CPUs since 2013):
/// the compiler's own vectorisation of the channel maximum spilled its shuffles through the
/// stack and ran at about 2.5 cycles a pixel.
#[cfg(target_arch = "x86_64")]
mod darkness_v3 {
    use core::arch::x86_64::{__m128i, __m256i};
    use pulp::x86::V3;

    /// How far ahead, in elements of the frame and of the background's inverse, each step
    /// asks for their next cache lines.
    ///
    /// A camera's or decoder's frame is not in the cache when the pass starts, and the
    /// hardware's own prefetcher did not keep ahead of it: on this project's 2-core machine
    /// a 640×480 frame's pass took 0.18 ms cold against 0.11 ms in cache. Asking for the
    /// frame's line 4 KiB ahead (from 2 KiB to 8 KiB, the same) brought it to 0.13 ms; the
    /// inverse's (1.8 MB, more than this machine's second-level cache holds beside the
    /// frame; 4096 elements are 8 KiB of it) 0.4–1.8 % more of detection, within the noise
    /// (docs/benchmarks/tracking.md, "Reading the frame ahead").
    const PREFETCH_AHEAD: usize = 4096;

    /// Sixteen pixels: 48 bytes of RGB against 48 of the background's inverse.
    #[inline(always)]
    fn sixteen(simd: V3, rgb: &[u8; 48], inv: &[u16; 48], out: &mut [u8; 16]) {
        let (avx2, sse2, ssse3) = (simd.avx2, simd.sse2, simd.ssse3);
        let cap: __m256i = pulp::cast([255u16; 16]);
        // Each channel's `(I·256)·inv >> 16`, capped at 255, back to bytes (in order).
        let product = |c: [u8; 16], i: [u16; 16]| -> __m128i {
            let wide = avx2._mm256_cvtepu8_epi16(pulp::cast(c));
            let p = avx2._mm256_min_epu16(
                avx2._mm256_mulhi_epu16(avx2._mm256_slli_epi16::<8>(wide), pulp::cast(i)),
                cap,
            );
            sse2._mm_packus_epi16(
                simd.avx._mm256_castsi256_si128(p),
                avx2._mm256_extracti128_si256::<1>(p),
            )
        };
        let (c, _) = rgb.as_chunks::<16>();
        let (i, _) = inv.as_chunks::<16>();
        let (p0, p1, p2) = (
            product(c[0], i[0]),
            product(c[1], i[1]),
            product(c[2], i[2]),
        );
        let zero: __m128i = pulp::cast([0u8; 16]);
        // Byte j of `m` is the maximum of bytes j, j+1, j+2 of the stream: at byte 3i, pixel
        // i's maximum over its three channels.
        let max3 = |a: __m128i, b: __m128i| {
            sse2._mm_max_epu8(
                a,
                sse2._mm_max_epu8(
                    ssse3._mm_alignr_epi8::<1>(b, a),
                    ssse3._mm_alignr_epi8::<2>(b, a),
                ),
            )
        };
        let (m0, m1, m2) = (max3(p0, p1), max3(p1, p2), max3(p2, zero));
        // Gather bytes 0, 3, …, 45 of the stream: pixels 0–5 from m0, 6–10 from m1 (stream
        // byte 18 is m1's byte 2), 11–15 from m2 (byte 33 is m2's byte 1). 0x80 clears.
        const Z: u8 = 0x80;
        let g0: __m128i = pulp::cast([0u8, 3, 6, 9, 12, 15, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z]);
        let g1: __m128i = pulp::cast([Z, Z, Z, Z, Z, Z, 2, 5, 8, 11, 14, Z, Z, Z, Z, Z]);
        let g2: __m128i = pulp::cast([Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, 1, 4, 7, 10, 13]);
        let max = sse2._mm_or_si128(
            ssse3._mm_shuffle_epi8(m0, g0),
            sse2._mm_or_si128(
                ssse3._mm_shuffle_epi8(m1, g1),
                ssse3._mm_shuffle_epi8(m2, g2),
            ),
        );
        // 255 − max.
        *out = pulp::cast(sse2._mm_xor_si128(max, pulp::cast([0xFFu8; 16])));
    }

    #[inline(always)]
    pub(super) fn run(simd: V3, rgb: &[u8], inv: &[u16], dark: &mut [u8]) {
        let n = dark.len().min(rgb.len() / 3).min(inv.len() / 3);
        let whole = n / 16 * 16;
        let (rgb_blocks, _) = rgb[..3 * whole].as_chunks::<48>();
        let (inv_blocks, _) = inv[..3 * whole].as_chunks::<48>();
        let (out_blocks, _) = dark[..whole].as_chunks_mut::<16>();
        for (k, ((o, c), i)) in out_blocks
            .iter_mut()
            .zip(rgb_blocks)
            .zip(inv_blocks)
            .enumerate()
        {
            if let Some(ahead) = inv.get(48 * k + PREFETCH_AHEAD) {
                simd.sse
                    ._mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(
                        core::ptr::from_ref(ahead).cast(),
                    );
            }
            if let Some(ahead) = rgb.get(48 * k + PREFETCH_AHEAD) {
                simd.sse
                    ._mm_prefetch::<{ core::arch::x86_64::_MM_HINT_T0 }>(
                        core::ptr::from_ref(ahead).cast(),
                    );
            }
            sixteen(simd, c, i, o);
        }
        let mut prod = [0u8; 48];
        super::darkness_block(
            &rgb[3 * whole..3 * n],
            &inv[3 * whole..3 * n],
            &mut dark[whole..n],
            &mut prod[..3 * (n - whole)],
        );
    }
}

/// Adds one row of pixels to per-block sums: for each block of `block` pixels, Σ R, G, B
/// over the pixels that are not marker (`dark ≤ mark`) into `sums`, and their number into
/// `counts` (the contact finder's block means, [`super::contact`]).
pub(crate) fn add_row_blocks(
    dark: &[u8],
    rgb: &[u8],
    block: usize,
    mark: u8,
    sums: &mut [[u32; 3]],
    counts: &mut [u32],
) {
    let blocks = sums
        .len()
        .min(counts.len())
        .min(dark.len() / block.max(1))
        .min(rgb.len() / (3 * block.max(1)));
    // The groups of four blocks done in SSSE3 (none without x86-64-v3), then the rest.
    #[cfg(target_arch = "x86_64")]
    let done = match (block, pulp::x86::V3::try_new()) {
        (4, Some(simd)) => simd.vectorize(|| {
            blocks4_v3::run(
                simd,
                dark,
                rgb,
                mark,
                &mut sums[..blocks],
                &mut counts[..blocks],
            )
        }),
        _ => 0,
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for k in done..blocks {
        let (d, p) = (
            &dark[k * block..][..block],
            &rgb[3 * k * block..][..3 * block],
        );
        let (mut acc, mut n) = ([0u32; 3], 0u32);
        for (&d, px) in d.iter().zip(p.chunks_exact(3)) {
            let keep = u32::from(d <= mark);
            acc[0] += px[0] as u32 * keep;
            acc[1] += px[1] as u32 * keep;
            acc[2] += px[2] as u32 * keep;
            n += keep;
        }
        for c in 0..3 {
            sums[k][c] += acc[c];
        }
        counts[k] += n;
    }
}

/// [`add_row_blocks`] for 4-px blocks, sixteen pixels (four blocks) at a time in SSSE3: the
/// keep mask widened to the RGB bytes, the kept bytes split by channel, and each group of
/// four summed by two multiply-adds against ones.
#[cfg(target_arch = "x86_64")]
mod blocks4_v3 {
    use core::arch::x86_64::__m128i;
    use pulp::x86::V3;

    const Z: u8 = 0x80;
    /// Byte k of the RGB stream takes the keep byte of pixel k / 3.
    const WIDEN: [[u8; 16]; 3] = [
        [0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4, 5],
        [5, 5, 6, 6, 6, 7, 7, 7, 8, 8, 8, 9, 9, 9, 10, 10],
        [
            10, 11, 11, 11, 12, 12, 12, 13, 13, 13, 14, 14, 14, 15, 15, 15,
        ],
    ];
    /// Per channel, which bytes of each of the three 16-byte parts are that channel's, in
    /// pixel order (0x80 clears).
    const SPLIT: [[[u8; 16]; 3]; 3] = [
        [
            [0, 3, 6, 9, 12, 15, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z],
            [Z, Z, Z, Z, Z, Z, 2, 5, 8, 11, 14, Z, Z, Z, Z, Z],
            [Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, 1, 4, 7, 10, 13],
        ],
        [
            [1, 4, 7, 10, 13, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z],
            [Z, Z, Z, Z, Z, 0, 3, 6, 9, 12, 15, Z, Z, Z, Z, Z],
            [Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, 2, 5, 8, 11, 14],
        ],
        [
            [2, 5, 8, 11, 14, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, Z],
            [Z, Z, Z, Z, Z, 1, 4, 7, 10, 13, Z, Z, Z, Z, Z, Z],
            [Z, Z, Z, Z, Z, Z, Z, Z, Z, Z, 0, 3, 6, 9, 12, 15],
        ],
    ];

    /// Adds whole groups of four blocks; returns how many blocks it added.
    #[inline(always)]
    pub(super) fn run(
        simd: V3,
        dark: &[u8],
        rgb: &[u8],
        mark: u8,
        sums: &mut [[u32; 3]],
        counts: &mut [u32],
    ) -> usize {
        let (sse2, ssse3) = (simd.sse2, simd.ssse3);
        let marks: __m128i = pulp::cast([mark; 16]);
        let zero: __m128i = pulp::cast([0u8; 16]);
        let ones8: __m128i = pulp::cast([1u8; 16]);
        let ones16: __m128i = pulp::cast([1i16; 8]);
        // Σ of each group of four bytes, as four u32.
        let quads = |v: __m128i| -> [u32; 4] {
            pulp::cast(sse2._mm_madd_epi16(ssse3._mm_maddubs_epi16(v, ones8), ones16))
        };
        let (dgroups, _) = dark.as_chunks::<16>();
        let (pgroups, _) = rgb.as_chunks::<48>();
        let (sgroups, _) = sums.as_chunks_mut::<4>();
        let (cgroups, _) = counts.as_chunks_mut::<4>();
        let mut done = 0;
        for (((d, p), s), n) in dgroups.iter().zip(pgroups).zip(sgroups).zip(cgroups) {
            // 0xFF where the pixel is not marker: `d − mark` saturates to 0 exactly there.
            let keep = sse2._mm_cmpeq_epi8(sse2._mm_subs_epu8(pulp::cast(*d), marks), zero);
            let (parts, _) = p.as_chunks::<16>();
            let kept: [__m128i; 3] = std::array::from_fn(|k| {
                sse2._mm_and_si128(
                    pulp::cast(parts[k]),
                    ssse3._mm_shuffle_epi8(keep, pulp::cast(WIDEN[k])),
                )
            });
            for (c, split) in SPLIT.iter().enumerate() {
                let channel = sse2._mm_or_si128(
                    ssse3._mm_shuffle_epi8(kept[0], pulp::cast(split[0])),
                    sse2._mm_or_si128(
                        ssse3._mm_shuffle_epi8(kept[1], pulp::cast(split[1])),
                        ssse3._mm_shuffle_epi8(kept[2], pulp::cast(split[2])),
                    ),
                );
                for (sum, q) in s.iter_mut().zip(quads(channel)) {
                    sum[c] += q;
                }
            }
            for (count, q) in n.iter_mut().zip(quads(sse2._mm_and_si128(keep, ones8))) {
                *count += q;
            }
            done += 4;
        }
        done
    }
}

struct Binomial<'a> {
    src: &'a [u8],
    width: usize,
    height: usize,
    rows: &'a mut [u16],
    smooth: &'a mut [u8],
}

/// Horizontal [1 2 1] of one row, edges replicated (`w ≥ 2`).
#[inline(always)]
fn horizontal(src: &[u8], dst: &mut [u16]) {
    let w = dst.len().min(src.len());
    dst[0] = 3 * src[0] as u16 + src[1] as u16;
    for ((d, s), n) in dst[1..w - 1].iter_mut().zip(src.windows(2)).zip(&src[2..w]) {
        *d = s[0] as u16 + 2 * s[1] as u16 + *n as u16;
    }
    dst[w - 1] = src[w - 2] as u16 + 3 * src[w - 1] as u16;
}

impl pulp::WithSimd for Binomial<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let (w, h) = (self.width, self.height);
        let row = |y: usize| &self.src[y * w..][..w];
        // Ring of three rows of horizontal sums: row y lives in slot y % 3.
        let (r0, rest) = self.rows.split_at_mut(w);
        let (r1, r2) = rest.split_at_mut(w);
        let ring = [r0, r1, r2];
        horizontal(row(0), ring[0]);
        if h > 1 {
            horizontal(row(1), ring[1]);
        }
        for y in 0..h {
            if y >= 1 && y + 1 < h {
                horizontal(row(y + 1), ring[(y + 1) % 3]);
            }
            let up = &*ring[y.saturating_sub(1) % 3];
            let mid = &*ring[y % 3];
            let down = &*ring[(y + 1).min(h - 1) % 3];
            let out = &mut self.smooth[y * w..][..w];
            for (((o, &u), &m), &d) in out.iter_mut().zip(up).zip(mid).zip(down) {
                *o = ((u + 2 * m + d + 8) >> 4) as u8;
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::{binomial_3x3, darkness};

    /// Bytes from a xorshift generator (Marsaglia 2003), the same for the same seed.
    pub(crate) fn noise(n: usize, seed: u64) -> Vec<u8> {
        let mut state = seed;
        (0..n)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect()
    }

    /// The blocked, dispatched darkness equals the definition on every kind of input,
    /// saturated products and a pixel count that is not a whole number of blocks included.
    #[test]
    fn the_vectorised_darkness_is_the_definition() {
        for n in [1, 63, 64, 65, 1001] {
            let mut rgb = noise(3 * n, 0x9E37_79B9_7F4A_7C15 + n as u64);
            let bytes = noise(6 * n, 0x2545_F491_4F6C_DD1D + n as u64);
            let mut inv: Vec<u16> = bytes
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect();
            if n >= 2 {
                rgb[..6].copy_from_slice(&[255, 255, 255, 0, 0, 0]);
                inv[..6].copy_from_slice(&[65535, 65535, 65535, 65535, 0, 1]);
            }
            let mut dark = vec![0u8; n];
            darkness(&rgb, &inv, &mut dark);
            for (k, d) in dark.iter().enumerate() {
                let m = (0..3)
                    .map(|c| rgb[3 * k + c] as u32 * inv[3 * k + c] as u32)
                    .max()
                    .unwrap_or(0);
                assert_eq!(*d as u32, 255 - (m >> 8).min(255), "n {n}, pixel {k}");
            }
        }
    }

    /// Block sums sixteen pixels at a time are the per-pixel definition's, for 4-px blocks
    /// (with a tail of blocks past the last group of four) and another block size.
    #[test]
    fn block_sums_are_the_kept_pixels_sums() {
        for (block, blocks) in [(4, 1), (4, 9), (4, 160), (3, 7)] {
            let dark = noise(block * blocks, 0x1234_5678 + blocks as u64);
            let rgb = noise(3 * block * blocks, 0x8765_4321 + blocks as u64);
            for mark in [0u8, 3, 128, 255] {
                let (mut sums, mut counts) = (vec![[7u32; 3]; blocks], vec![5u32; blocks]);
                super::add_row_blocks(&dark, &rgb, block, mark, &mut sums, &mut counts);
                for k in 0..blocks {
                    let kept: Vec<usize> = (k * block..(k + 1) * block)
                        .filter(|&i| dark[i] <= mark)
                        .collect();
                    for c in 0..3 {
                        let want = 7 + kept.iter().map(|&i| rgb[3 * i + c] as u32).sum::<u32>();
                        assert_eq!(
                            sums[k][c], want,
                            "block {block}, mark {mark}, #{k}, channel {c}"
                        );
                    }
                    assert_eq!(
                        counts[k],
                        5 + kept.len() as u32,
                        "block {block}, mark {mark}, #{k}"
                    );
                }
            }
        }
    }

    /// The rolling three-row low-pass equals the separable definition with replicated edges,
    /// on frames of one, two, three and many rows.
    #[test]
    fn the_rolling_low_pass_is_the_definition() {
        for (w, h) in [(2, 1), (5, 2), (7, 3), (640, 9), (33, 31)] {
            let src = noise(w * h, 0xD1B5_4A32_D192_ED03 + (w * h) as u64);
            let (mut rows, mut out) = (Vec::new(), vec![0u8; w * h]);
            binomial_3x3(&src, w, h, &mut rows, &mut out);
            let at = |x: isize, y: isize| {
                let x = x.clamp(0, w as isize - 1) as usize;
                let y = y.clamp(0, h as isize - 1) as usize;
                src[y * w + x] as u32
            };
            for y in 0..h as isize {
                for x in 0..w as isize {
                    let mut s = 0;
                    for (dy, ky) in [(-1, 1), (0, 2), (1, 1)] {
                        for (dx, kx) in [(-1, 1), (0, 2), (1, 1)] {
                            s += ky * kx * at(x + dx, y + dy);
                        }
                    }
                    let want = ((s + 8) >> 4) as u8;
                    assert_eq!(
                        out[y as usize * w + x as usize],
                        want,
                        "{w}×{h} at ({x}, {y})"
                    );
                }
            }
        }
    }
}
