//! The detector's runs: each row's stretches of smoothed darkness above the low threshold,
//! with the darkness-weighted sums the blobs' centroids and moments are built from
//! ([`super::detect`]).

/// A row's run of pixels above a threshold, with its darkness-weighted sums (weight
/// `v − low`, see [`super::detect`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RowRun {
    pub(crate) y: u32,
    pub(crate) x0: u32,
    /// Exclusive.
    pub(crate) x1: u32,
    pub(crate) sw: u64,
    pub(crate) swx: u64,
    pub(crate) swx2: u64,
    pub(crate) peak: u8,
}

/// Every run of pixels above `low` in `src` (`width` × `height`), in raster order, to `emit`.
///
/// Most of a frame is background, so finding where the next run starts is the cost: on
/// x86-64-v3 32 pixels are compared at once and the first above the threshold is read off
/// the comparison's bit mask; elsewhere 16 pixels are skipped while their maximum is not above it.
pub(crate) fn runs_above(
    src: &[u8],
    width: usize,
    height: usize,
    low: u8,
    emit: &mut dyn FnMut(RowRun),
) {
    let rows = src.chunks_exact(width.max(1)).take(height);
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = pulp::x86::V3::try_new() {
        return simd.vectorize(|| {
            for (y, row) in rows.enumerate() {
                row_runs(
                    row,
                    y,
                    emit,
                    |row, x| next_v3::<true>(simd, row, x, low),
                    |row, x| next_v3::<false>(simd, row, x, low),
                    |row, x0, x1| {
                        let window = row
                            .get(x0..x0 + 32)
                            .and_then(|w| <&[u8; 32]>::try_from(w).ok());
                        match window {
                            Some(window) if x1 - x0 <= 32 => {
                                short_run_sums_v3(simd, window, x1 - x0, x0, low)
                            }
                            _ => run_sums(&row[x0..x1], x0, low),
                        }
                    },
                );
            }
        });
    }
    for (y, row) in rows.enumerate() {
        row_runs(
            row,
            y,
            emit,
            |row, x| next_above(row, x, low),
            |row, x| next_at_or_below(row, x, low),
            |row, x0, x1| run_sums(&row[x0..x1], x0, low),
        );
    }
}

/// The runs of one row; `next(row, x)` is the first index ≥ `x` above the threshold (or the
/// length), `end(row, x)` the first index ≥ `x` at or below it (or the length), and
/// `sums(row, x0, x1)` the run's [`run_sums`].
#[inline(always)]
fn row_runs(
    row: &[u8],
    y: usize,
    emit: &mut dyn FnMut(RowRun),
    next: impl Fn(&[u8], usize) -> usize,
    end: impl Fn(&[u8], usize) -> usize,
    sums: impl Fn(&[u8], usize, usize) -> (u64, u64, u64, u8),
) {
    let w = row.len();
    let mut x = 0usize;
    loop {
        x = next(row, x);
        if x >= w {
            return;
        }
        let x0 = x;
        x = end(row, x0);
        let (sw, swx, swx2, peak) = sums(row, x0, x);
        emit(RowRun {
            y: y as u32,
            x0: x0 as u32,
            x1: x as u32,
            sw,
            swx,
            swx2,
            peak,
        });
    }
}

/// A run's `Σ (v − low)`, `Σ (v − low)·x`, `Σ (v − low)·x²` and maximum, its first pixel at
/// column `x0` (every pixel of `run` is above `low`).
///
/// With the run's end known beforehand the loop has no exit that depends on the pixels, so
/// the compiler vectorises it; each product fits 32 bits while `x` < 4096 (255 · 4095² <
/// 2³²), and the sums are kept in 64.
#[inline(always)]
fn run_sums(run: &[u8], x0: usize, low: u8) -> (u64, u64, u64, u8) {
    let (mut sw, mut swx, mut swx2, mut peak) = (0u64, 0u64, 0u64, 0u8);
    if x0 + run.len() <= 4096 {
        for (k, &v) in run.iter().enumerate() {
            let x = (x0 + k) as u32;
            let wgt = v.saturating_sub(low) as u32;
            sw += wgt as u64;
            swx += (wgt * x) as u64;
            swx2 += (wgt * x * x) as u64;
            peak = peak.max(v);
        }
    } else {
        for (k, &v) in run.iter().enumerate() {
            let x = (x0 + k) as u64;
            let wgt = v.saturating_sub(low) as u64;
            sw += wgt;
            swx += wgt * x;
            swx2 += wgt * x * x;
            peak = peak.max(v);
        }
    }
    (sw, swx, swx2, peak)
}

/// [`run_sums`] of a run of `len` ≤ 32 pixels at the start of `window`, in AVX2 with no
/// branch on the pixels: a frame's runs are mostly a marker's width (about 17 pixels at
/// 640×480), and the loop over each, however vectorised, paid for its variable length.
/// Offsets `k` from `x0` keep every product small — `Σ w·k` by pairs of bytes, `Σ w·k²` by
/// pairs of 16-bit lanes — and the column sums follow exactly:
/// `Σ w·x = x0·Σ w + Σ w·k`, `Σ w·x² = x0²·Σ w + 2·x0·Σ w·k + Σ w·k²`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn short_run_sums_v3(
    simd: pulp::x86::V3,
    window: &[u8; 32],
    len: usize,
    x0: usize,
    low: u8,
) -> (u64, u64, u64, u8) {
    use core::arch::x86_64::{__m128i, __m256i};
    let avx2 = simd.avx2;
    const K: [u8; 32] = {
        let mut k = [0u8; 32];
        let mut i = 0;
        while i < 32 {
            k[i] = i as u8;
            i += 1;
        }
        k
    };
    const K2: [[i16; 16]; 2] = {
        let mut k2 = [[0i16; 16]; 2];
        let mut i = 0;
        while i < 32 {
            k2[i / 16][i % 16] = (i * i) as i16;
            i += 1;
        }
        k2
    };
    let lanes: __m256i = pulp::cast(K);
    // Lanes below `len` (both under 128, so the signed comparison is the unsigned one).
    let inside = avx2._mm256_cmpgt_epi8(pulp::cast([len as u8; 32]), lanes);
    let w = avx2._mm256_and_si256(
        avx2._mm256_subs_epu8(pulp::cast(*window), pulp::cast([low; 32])),
        inside,
    );
    let sw: [u64; 4] = pulp::cast(avx2._mm256_sad_epu8(w, pulp::cast([0u8; 32])));
    // Σ w·k: bytes times offsets summed in pairs (≤ 255·61, a 16-bit lane), then in fours.
    let wk: [i32; 8] = pulp::cast(
        avx2._mm256_madd_epi16(avx2._mm256_maddubs_epi16(w, lanes), pulp::cast([1i16; 16])),
    );
    // Σ w·k²: 16-bit weights times squared offsets, summed in pairs (≤ 255·1861).
    let (lo, hi): (__m128i, __m128i) = (
        simd.avx._mm256_castsi256_si128(w),
        avx2._mm256_extracti128_si256::<1>(w),
    );
    let wk2: [i32; 8] = pulp::cast(avx2._mm256_add_epi32(
        avx2._mm256_madd_epi16(avx2._mm256_cvtepu8_epi16(lo), pulp::cast(K2[0])),
        avx2._mm256_madd_epi16(avx2._mm256_cvtepu8_epi16(hi), pulp::cast(K2[1])),
    ));
    let top = pulp::cast::<_, [u8; 32]>(w).into_iter().fold(0u8, u8::max);
    let sw: u64 = sw.iter().sum();
    let swk: u64 = wk.iter().map(|&v| v as u64).sum();
    let swk2: u64 = wk2.iter().map(|&v| v as u64).sum();
    let x0 = x0 as u64;
    (
        sw,
        x0 * sw + swk,
        x0 * x0 * sw + 2 * x0 * swk + swk2,
        // Every pixel of a run is above `low`, so its peak is `low` plus the largest weight.
        low + top,
    )
}

/// The first index ≥ `x` whose value is at or below `low`, or the row's length.
#[inline(always)]
fn next_at_or_below(row: &[u8], mut x: usize, low: u8) -> usize {
    while x < row.len() && row[x] > low {
        x += 1;
    }
    x
}

/// The first index ≥ `x` whose value is above `low`, or the row's length.
#[inline(always)]
fn next_above(row: &[u8], mut x: usize, low: u8) -> usize {
    let w = row.len();
    while x + 16 <= w && row[x..x + 16].iter().fold(0u8, |m, &v| m.max(v)) <= low {
        x += 16;
    }
    while x < w && row[x] <= low {
        x += 1;
    }
    x
}

/// [`next_above`] (`ABOVE`) or [`next_at_or_below`] 32 pixels at a time: `v − low`
/// saturated is zero exactly where `v ≤ low`, and the first wanted pixel is read off the
/// comparison's bit mask.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn next_v3<const ABOVE: bool>(simd: pulp::x86::V3, row: &[u8], mut x: usize, low: u8) -> usize {
    use core::arch::x86_64::__m256i;
    let avx2 = simd.avx2;
    let (lows, zero): (__m256i, __m256i) = (pulp::cast([low; 32]), pulp::cast([0u8; 32]));
    while let Some(chunk) = row.get(x..x + 32) {
        let Ok(bytes) = <[u8; 32]>::try_from(chunk) else {
            break;
        };
        let over = avx2._mm256_subs_epu8(pulp::cast(bytes), lows);
        let at_or_below = avx2._mm256_movemask_epi8(avx2._mm256_cmpeq_epi8(over, zero)) as u32;
        let wanted = if ABOVE { !at_or_below } else { at_or_below };
        if wanted != 0 {
            return x + wanted.trailing_zeros() as usize;
        }
        x += 32;
    }
    if ABOVE {
        next_above(row, x, low)
    } else {
        next_at_or_below(row, x, low)
    }
}

#[cfg(test)]
mod tests {
    use super::super::pixels::tests::noise;

    /// The runs found 32 pixels at a time are the runs of the definition, thresholds at the
    /// extremes included.
    #[test]
    fn runs_are_the_pixels_above_the_threshold() {
        for (w, h) in [(1, 3), (31, 4), (32, 2), (33, 5), (640, 7), (4100, 2)] {
            // Sparse dark blobs on a background, as a marker frame is, and on odd rows long
            // runs (whole rows at the lower thresholds; past column 4096 on the widest).
            let mut src: Vec<u8> = noise(w * h, 0xA076_1D64_78BD_642F + w as u64)
                .iter()
                .enumerate()
                .map(|(k, &v)| match (k / w) % 2 {
                    0 if v > 200 => v,
                    0 => v / 8,
                    _ => v.max(40),
                })
                .collect();
            // On the 640-wide frame's last row, runs of every length from 1 to 40 pixels,
            // one background pixel apart (those near the end too short to read 32 ahead).
            if w == 640 {
                let last = &mut src[(h - 1) * w..];
                let (mut x, mut len) = (0, 1);
                while x < w {
                    for v in last.iter_mut().skip(x).take(len) {
                        *v = (*v).max(210);
                    }
                    if let Some(v) = last.get_mut(x + len) {
                        *v = 0;
                    }
                    (x, len) = (x + len + 1, len % 40 + 1);
                }
            }
            for low in [0u8, 30, 201, 254, 255] {
                let mut got = Vec::new();
                super::runs_above(&src, w, h, low, &mut |r| got.push(r));
                let mut want = Vec::new();
                for y in 0..h {
                    let mut x = 0;
                    while x < w {
                        if src[y * w + x] <= low {
                            x += 1;
                            continue;
                        }
                        let x0 = x;
                        let (mut sw, mut swx, mut swx2, mut peak) = (0u64, 0u64, 0u64, 0u8);
                        while x < w && src[y * w + x] > low {
                            let v = src[y * w + x];
                            let k = (v - low) as u64;
                            (sw, swx, swx2) =
                                (sw + k, swx + k * x as u64, swx2 + k * (x * x) as u64);
                            peak = peak.max(v);
                            x += 1;
                        }
                        want.push((y as u32, x0 as u32, x as u32, sw, swx, swx2, peak));
                    }
                }
                let got: Vec<_> = got
                    .iter()
                    .map(|r| (r.y, r.x0, r.x1, r.sw, r.swx, r.swx2, r.peak))
                    .collect();
                assert_eq!(got, want, "{w}×{h}, low {low}");
            }
        }
    }
}
