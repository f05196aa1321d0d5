//! The lookup table: the slope as a function of the colour change alone, binned over
//! (ΔR, ΔG, ΔB) in steps of 8 grey levels, each bin the mean slope of the calibration pixels
//! that fell in it, empty bins filled from the nearest occupied one. It is the classic
//! GelSight calibration (Johnson & Adelson, CVPR 2009; gs_sdk) and the baseline the
//! local-linear model is measured against: it cannot know that the same colour means another
//! slope where the lights are dim.

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

use crate::ball::{self, Circle};
use crate::frame::{Rgb, colour_change};

/// Bins per channel, over a change of ±1.5 (±96 grey levels): 8 grey levels a bin.
pub const BINS: usize = 24;
const LIMIT: f32 = 1.5;

/// One occupied bin: its index per channel and the mean slope of its pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bin {
    /// Bin index per channel (R, G, B).
    pub at: [u8; 3],
    /// Mean slope (∂d/∂x, ∂d/∂y).
    pub slope: [f32; 2],
    /// Pixels that fell in it.
    pub pixels: u32,
}

/// The fitted table: only its occupied bins.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Lut {
    /// The occupied bins.
    pub bins: Vec<Bin>,
}

fn bin_of(v: f32) -> usize {
    (((v + LIMIT) / (2.0 * LIMIT) * BINS as f32).floor().max(0.0) as usize).min(BINS - 1)
}

/// Accumulates a press's pixels into `sums` (per bin: Σgx, Σgy, count): those inside the
/// circle with the ball's slope, and every 7th pixel beyond 2.5 radii with zero slope (the
/// background's noise must read flat).
pub fn accumulate(
    frame: &Rgb<'_>,
    background: &Rgb<'_>,
    circle: &Circle,
    ball_px: f64,
    sums: &mut [[f64; 3]],
) {
    let mut change = Vec::new();
    colour_change(frame, background, &mut change);
    let w = frame.width;
    for (i, d) in change.chunks_exact(3).enumerate() {
        let (x, y) = ((i % w) as f64, (i / w) as f64);
        let r2 = (x - circle.x_px).powi(2) + (y - circle.y_px).powi(2);
        let a2 = circle.radius_px * circle.radius_px;
        let g = if r2 < a2 {
            ball::slope(circle, ball_px, x, y)
        } else if r2 > 6.25 * a2 && i % 7 == 0 {
            [0.0, 0.0]
        } else {
            continue;
        };
        let k = (bin_of(d[0]) * BINS + bin_of(d[1])) * BINS + bin_of(d[2]);
        sums[k][0] += g[0];
        sums[k][1] += g[1];
        sums[k][2] += 1.0;
    }
}

impl Lut {
    /// The table of accumulated `sums` (`BINS³` entries).
    pub fn from_sums(sums: &[[f64; 3]]) -> Self {
        let mut bins = Vec::new();
        for (k, s) in sums.iter().enumerate() {
            if s[2] > 0.0 {
                bins.push(Bin {
                    at: [
                        (k / (BINS * BINS)) as u8,
                        ((k / BINS) % BINS) as u8,
                        (k % BINS) as u8,
                    ],
                    slope: [(s[0] / s[2]) as f32, (s[1] / s[2]) as f32],
                    pixels: s[2] as u32,
                });
            }
        }
        Self { bins }
    }

    /// The whole table, empty bins filled from the nearest occupied one (breadth first over
    /// neighbouring bins); `None` when no bin is occupied.
    pub(crate) fn filled(&self) -> Option<Vec<[f32; 2]>> {
        let n = BINS * BINS * BINS;
        let mut table = vec![[0f32; 2]; n];
        let mut set = vec![false; n];
        let mut queue = VecDeque::new();
        for b in &self.bins {
            let at = b.at.map(|v| (v as usize).min(BINS - 1));
            let k = (at[0] * BINS + at[1]) * BINS + at[2];
            table[k] = b.slope;
            if !set[k] {
                set[k] = true;
                queue.push_back(k);
            }
        }
        if queue.is_empty() {
            return None;
        }
        while let Some(k) = queue.pop_front() {
            let at = [k / (BINS * BINS), (k / BINS) % BINS, k % BINS];
            for axis in 0..3 {
                for step in [-1i64, 1] {
                    let v = at[axis] as i64 + step;
                    if v < 0 || v >= BINS as i64 {
                        continue;
                    }
                    let mut nb = at;
                    nb[axis] = v as usize;
                    let j = (nb[0] * BINS + nb[1]) * BINS + nb[2];
                    if !set[j] {
                        set[j] = true;
                        table[j] = table[k];
                        queue.push_back(j);
                    }
                }
            }
        }
        Some(table)
    }
}

/// Slopes of `change` (3 per pixel) from a filled `table` where `touched`, zero elsewhere.
pub(crate) fn slopes(
    table: &[[f32; 2]],
    change: &[f32],
    touched: &[bool],
    gx: &mut [f32],
    gy: &mut [f32],
) {
    for (i, d) in change.chunks_exact(3).enumerate() {
        if !touched[i] {
            gx[i] = 0.0;
            gy[i] = 0.0;
            continue;
        }
        let g = table[(bin_of(d[0]) * BINS + bin_of(d[1])) * BINS + bin_of(d[2])];
        gx[i] = g[0];
        gy[i] = g[1];
    }
}
