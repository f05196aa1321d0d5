//! The far field's datum: a quadratic fitted to the height where the gel is untouched and
//! taken away, so the undeformed surface reads 0 and a slow drift of the slope estimate
//! over the frame (the lights' vignetting is not all in the calibration) does not tilt or
//! bow the map. It halved the largest spurious height beyond the contact on the ball presses
//! (0.37 → 0.18 of the cap height, docs/explanation/shape.md).

use nalgebra::{Matrix6, Vector6};

const STRIDE: usize = 4;

/// Subtracts from `z` the quadratic in (x, y) fitted to it where `far` holds, on every
/// `STRIDE`th pixel in each direction (a smooth surface over tens of thousands of pixels:
/// the subsample fits it as well, 16 times cheaper); where the untouched gel is a small part
/// of the frame, a plane or its mean only (below).
pub(crate) fn level(z: &mut [f32], far: &[bool], w: usize, h: usize) {
    let (sx, sy) = (2.0 / w as f64, 2.0 / h as f64);
    let terms = |x: usize, y: usize| {
        let (u, v) = (x as f64 * sx - 1.0, y as f64 * sy - 1.0);
        Vector6::new(1.0, u, v, u * u, u * v, v * v)
    };
    let (mut ata, mut atz) = (Matrix6::<f64>::zeros(), Vector6::<f64>::zeros());
    let mut count = 0usize;
    let mut sum = 0.0f64;
    for y in (0..h).step_by(STRIDE) {
        for x in (0..w).step_by(STRIDE) {
            if far[y * w + x] {
                let t = terms(x, y);
                let v = z[y * w + x] as f64;
                ata += t * t.transpose();
                atz += t * v;
                sum += v;
                count += 1;
            }
        }
    }
    if count == 0 {
        return;
    }
    // As much of a surface as the untouched gel can carry: a quadratic where it is at least
    // 30 % of the frame; a plane from 15 %; else its mean. A large contact leaves only the
    // corners, where a fitted bowl bends the whole map (a 12.5 mm punch on the simulated
    // portable sensor read 83 % of its depth off with the quadratic).
    let share = count as f64 / (w.div_ceil(STRIDE) * h.div_ceil(STRIDE)) as f64;
    let terms_used = if count < 50 {
        1
    } else if share >= 0.3 {
        6
    } else if share >= 0.15 {
        3
    } else {
        1
    };
    let coef = (terms_used > 1)
        .then(|| {
            let a = nalgebra::DMatrix::from_fn(terms_used, terms_used, |i, j| ata[(i, j)])
                + nalgebra::DMatrix::identity(terms_used, terms_used) * 1e-9 * count as f64;
            let b = nalgebra::DVector::from_fn(terms_used, |i, _| atz[i]);
            a.cholesky().map(|c| {
                let x = c.solve(&b);
                let mut full = Vector6::zeros();
                full.rows_mut(0, terms_used).copy_from(&x);
                full
            })
        })
        .flatten();
    for y in 0..h {
        let v = y as f64 * sy - 1.0;
        // The quadratic along this row: a + b·u + c·u².
        let (a, b, c) = match &coef {
            Some(k) => (k[0] + k[2] * v + k[5] * v * v, k[1] + k[4] * v, k[3]),
            None => (sum / count as f64, 0.0, 0.0),
        };
        for x in 0..w {
            let u = x as f64 * sx - 1.0;
            z[y * w + x] -= (a + u * (b + c * u)) as f32;
        }
    }
}
