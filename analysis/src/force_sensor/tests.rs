use mechanics::operator::{Compliance, Grid, LayerOperator};

use super::ridge::LinearModel;
use super::*;

/// Markers on every other cell of the middle of `grid` (a 2 mm layer, 0.25 mm cells), with
/// the displacement of the layer under tractions (qx, qy, p) in MPa per cell.
fn layer_field(grid: Grid, qx: &[f64], qy: &[f64], p: &[f64]) -> (Layout, Vec<[f64; 2]>) {
    let op = LayerOperator::new(grid, 2.0, 0.1, 0.5);
    let [ux, uy, _] = op.full(qx, qy, p);
    let (mut refs, mut u) = (Vec::new(), Vec::new());
    let n = grid.n;
    for j in (n / 8..7 * n / 8).step_by(2) {
        for i in (n / 8..7 * n / 8).step_by(2) {
            let (x, y) = grid.xy(j * n + i);
            // 0.1 mm per px: markers every 5 px.
            refs.push([x * 10.0, y * 10.0]);
            u.push([ux[j * n + i], uy[j * n + i]]);
        }
    }
    (Layout::new(refs, 0.1, [0.0, 0.0]), u)
}

/// The moments read the wrench of an irregular, off-centre load through the layer's
/// constants: ∫u = (h/μ)F∥, ∫r·u = (h²/μ)Fz + (h/μ)∫r·t∥, ∫r×u = (h/μ)Tz (ν = ½).
#[test]
fn field_moments_are_the_wrench_times_the_layers_constants() {
    let grid = Grid { n: 192, dx: 0.25 };
    let len = grid.len();
    let (mut qx, mut qy, mut p) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
    let (mut f, mut tz, mut rq) = ([0.0; 3], 0.0, 0.0);
    for idx in 0..len {
        let (x, y) = grid.xy(idx);
        // An ellipse 6 × 3.5 mm off the centre, with uneven pressure and a twisting shear.
        let (ex, ey) = ((x - 1.5) / 3.0, (y + 1.0) / 1.75);
        if ex * ex + ey * ey < 1.0 {
            p[idx] = 0.05 * (1.0 + 0.5 * ex);
            qx[idx] = 0.01 - 0.004 * (y + 1.0);
            qy[idx] = 0.004 * (x - 1.5) - 0.005;
            let a = grid.area();
            f[0] += qx[idx] * a;
            f[1] += qy[idx] * a;
            f[2] += p[idx] * a;
            tz += (x * qy[idx] - y * qx[idx]) * a;
            rq += (x * qx[idx] + y * qy[idx]) * a;
        }
    }
    let (layout, u) = layer_field(grid, &qx, &qy, &p);
    let m = layout.features(&u);
    let c = 2.0 / 0.1; // h/μ, mm/MPa
    let close = |got: f64, want: f64, what: &str| {
        assert!(
            (got - want).abs() <= 0.03 * want.abs().max(1e-12),
            "{what}: {got} vs {want}"
        );
    };
    close(m[0], c * f[0], "∫ux");
    close(m[1], c * f[1], "∫uy");
    close(m[2], 2.0 * 2.0 / 0.1 * f[2] + c * rq, "∫r·u");
    close(m[3], c * tz, "∫r×u");
}

#[test]
fn ridge_recovers_a_linear_map_and_widens_away_from_its_data() {
    // y = 2 x0 − 3 x1 + 0.5 + noise; x2 a near-copy of x0 (collinear: the ridge's job).
    let mut x = Vec::new();
    let mut y = Vec::new();
    let mut state = 12345u64;
    let mut noise = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02
    };
    for i in 0..60 {
        let a = (i as f64 * 0.37).sin();
        let b = (i as f64 * 0.11).cos();
        x.push(vec![a, b, a + 1e-6 * noise()]);
        y.push(vec![2.0 * a - 3.0 * b + 0.5 + noise()]);
    }
    let m = LinearModel::fit(&x, &y).expect("fit");
    let (v, sd) = m.predict(&[0.3, -0.2, 0.3]);
    assert!((v[0] - (0.6 + 0.6 + 0.5)).abs() < 0.02, "{v:?}");
    assert!(sd[0] > 0.003 && sd[0] < 0.02, "{sd:?}");
    let (_, far) = m.predict(&[30.0, -20.0, -30.0]);
    assert!(far[0] > 10.0 * sd[0], "{far:?} vs {sd:?}");
    assert_eq!(
        LinearModel::fit(&x[..3], &y[..3]),
        Err(SensorError::TooFewSamples {
            samples: 3,
            features: 3
        })
    );
}

#[test]
fn another_layout_is_refused_and_unmeasured_markers_are_filled() {
    let refs: Vec<[f64; 2]> = (0..100)
        .map(|k| [(k % 10) as f64 * 8.0, (k / 10) as f64 * 8.0])
        .collect();
    let layout = Layout::new(refs.clone(), 0.05, [36.0, 36.0]);
    // The same pattern detected in another order, a little jittered: all match.
    let mut shuffled: Vec<[f64; 2]> = refs
        .iter()
        .rev()
        .map(|p| [p[0] + 0.7, p[1] - 0.5])
        .collect();
    let map = layout.match_markers(&shuffled).expect("same layout");
    assert_eq!(map[0], Some(99));
    // A pattern at half the spacing is another gel.
    shuffled = refs
        .iter()
        .map(|p| [p[0] * 0.5 + 3.0, p[1] * 0.5 + 3.0])
        .collect();
    let e = layout.match_markers(&shuffled).expect_err("other layout");
    assert!(
        e.to_string().contains("calibrate one for this setup"),
        "{e}"
    );
    // A uniform 1 px shift with marker 55 unmeasured: filled as 1 px too.
    let field = MarkerField {
        reference_px: refs.clone(),
        displacement_px: vec![[1.0, 0.0]; 100],
        measured: (0..100).map(|i| i != 55).collect(),
    };
    let map = layout.match_markers(&refs).expect("match");
    let (u, share) = layout.displacements_mm(&field, &map);
    assert!((u[55][0] - 0.05).abs() < 1e-12, "{:?}", u[55]);
    assert!((share - 0.99).abs() < 1e-12);
}

/// Tractions on `grid` of a region (`inside(x, y)`) pressed with `p` MPa, sheared with
/// (`qx`, `qy`) MPa and twisted with `tw` MPa/mm about the origin; the wrench they carry.
fn loaded(
    grid: Grid,
    inside: impl Fn(f64, f64) -> bool,
    [p, qx, qy, tw]: [f64; 4],
) -> ([Vec<f64>; 3], [f64; 4]) {
    let a = grid.area();
    let mut w = [0.0; 4];
    let cells: Vec<[f64; 3]> = (0..grid.len())
        .map(|idx| {
            let (x, y) = grid.xy(idx);
            if !inside(x, y) {
                return [0.0; 3];
            }
            let (tx, ty) = (qx - tw * y, qy + tw * x);
            w[0] += tx * a;
            w[1] += ty * a;
            w[2] += p * a;
            w[3] += (x * ty - y * tx) * a;
            [tx, ty, p]
        })
        .collect();
    let t = [0, 1, 2].map(|k| cells.iter().map(|c| c[k]).collect());
    (t, w)
}

/// Fitted on what a calibration sees — a centred disc pressed, sheared, and twisted at a
/// preload — each channel on the features that turn as it does reads a pressed strip's Fz
/// the same whether or not the strip is twisted; fitted on every feature, the twist moves
/// Fz (the pure-shear moment of a twisted strip is what the disc never showed).
#[test]
fn a_twist_does_not_leak_into_the_normal_force() {
    let grid = Grid { n: 128, dx: 0.25 };
    let disc = |x: f64, y: f64| x * x + y * y < 9.0;
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    let mut state = 777u64;
    let mut rnd = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for k in 0..40 {
        // Half the samples pressed deeper and deeper; half twisted at a fixed preload (the
        // twist rising with the sample, as a rotation protocol's steps do).
        let load = if k % 2 == 0 {
            [
                0.01 + 0.04 * rnd(),
                0.004 * (rnd() - 0.5),
                0.004 * (rnd() - 0.5),
                0.0,
            ]
        } else {
            [0.02 + 0.001 * rnd(), 0.0, 0.0, 0.0002 * k as f64]
        };
        let (t, w) = loaded(grid, disc, load);
        let (layout, u) = layer_field(grid, &t[0], &t[1], &t[2]);
        let noisy: Vec<[f64; 2]> = u
            .iter()
            .map(|d| [d[0] + 1e-5 * (rnd() - 0.5), d[1] + 1e-5 * (rnd() - 0.5)])
            .collect();
        xs.push(layout.features(&noisy).to_vec());
        ys.push(w.to_vec());
    }
    let masks = channel_features(&FEATURES);
    let fz_mask = &masks[2];
    assert_eq!(
        fz_mask,
        &vec![false, false, true, false, false, false, true, false],
        "Fz sees ∫r·u and ∫r²r·u"
    );
    let strip = |x: f64, y: f64| x.abs() < 6.0 && y.abs() < 1.2;
    let read = |model: &LinearModel, tw: f64| {
        let (t, w) = loaded(grid, strip, [0.03, 0.0, 0.0, tw]);
        let (layout, u) = layer_field(grid, &t[0], &t[1], &t[2]);
        (model.predict(&layout.features(&u)).0[2], w[2])
    };
    let by_kind = LinearModel::fit_masked(&xs, &ys, Some(&masks)).expect("fit");
    let (pressed, fz) = read(&by_kind, 0.0);
    let (twisted, _) = read(&by_kind, 0.01);
    assert!(
        (twisted - pressed).abs() < 0.01 * fz,
        "twisted {twisted} N, pressed {pressed} N (Fz {fz} N)"
    );
    // The same fit on every feature: the twist moves the reading.
    let all = LinearModel::fit(&xs, &ys).expect("fit");
    let (p_all, _) = read(&all, 0.0);
    let (t_all, _) = read(&all, 0.01);
    assert!(
        (t_all - p_all).abs() > 0.05 * fz,
        "every feature: twisted {t_all} N, pressed {p_all} N — the scenario no longer shows the leak"
    );
    // A channel fitted on its mask has no weight elsewhere, and is the fit of those
    // features alone.
    for (c, m) in masks.iter().enumerate() {
        for (j, keep) in m.iter().enumerate() {
            if !keep {
                assert_eq!(by_kind.channels[c].weights[j], 0.0, "{c} {j}");
            }
        }
    }
    let cols: Vec<usize> = (0..8).filter(|&j| fz_mask[j]).collect();
    let sub: Vec<Vec<f64>> = xs
        .iter()
        .map(|r| cols.iter().map(|&j| r[j]).collect())
        .collect();
    let alone = LinearModel::fit(&sub, &ys).expect("fit");
    let f: Vec<f64> = cols.iter().map(|&j| xs[3][j]).collect();
    let (a, sa) = alone.predict(&f);
    let (b, sb) = by_kind.predict(&xs[3]);
    assert!(
        (a[2] - b[2]).abs() < 1e-9 * a[2].abs().max(1.0),
        "{a:?} vs {b:?}"
    );
    assert!(
        (sa[2] - sb[2]).abs() < 1e-9 * sa[2].abs().max(1.0),
        "{sa:?} vs {sb:?}"
    );
}
