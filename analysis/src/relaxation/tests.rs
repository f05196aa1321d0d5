//! Tests of the relaxation fits.

use super::*;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

fn record(t_end: f64, hz: f64, noise: f64, rng: Option<&mut StdRng>) -> (Vec<f64>, Vec<f64>) {
    let n = (t_end * hz).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|i| i as f64 / hz).collect();
    let mut y: Vec<f64> = t
        .iter()
        .map(|t| 1.0 + 0.2 * (-t / 3.0).exp() + 0.15 * (-t / 40.0).exp())
        .collect();
    if let Some(rng) = rng {
        let d = Normal::new(0.0, noise).expect("σ > 0");
        for v in &mut y {
            *v += d.sample(rng);
        }
    }
    (t, y)
}

#[test]
fn noise_free_two_exponentials_o21() {
    let (t, y) = record(300.0, 10.0, 0.0, None);
    let fit = fit_exponentials(&t, &y, 2).expect("fits");
    assert!((fit.f_inf - 1.0).abs() < 1e-9, "{}", fit.f_inf);
    assert!(
        (fit.taus_s[0] - 3.0).abs() < 1e-9 && (fit.taus_s[1] - 40.0).abs() < 1e-9,
        "{:?}",
        fit.taus_s
    );
    assert!((fit.amplitudes[0] - 0.2).abs() < 1e-9 && (fit.amplitudes[1] - 0.15).abs() < 1e-9);
}

#[test]
fn aitken_o22() {
    let f = |t: f64| 1.0 + 0.3 * (-t / 7.0).exp();
    let est = aitken(f(5.0), f(9.0), f(13.0)).expect("curvature");
    assert!((est - 1.0).abs() < 1e-12, "{est}");
    assert!(aitken(2.0, 2.0, 2.0).is_none());
}

#[test]
fn settle_calibration_monte_carlo_o23() {
    // Spec §4: noise 1e-3, 10 Hz, 200 runs. At T = 2τ_slow and 4τ_slow the median
    // Jacobian σ̂ is ≈ 3.8e-4 and 7.2e-5, and the actual RMSE is within 1.3× of it.
    for (t_end, sigma_expect) in [(80.0, 3.8e-4), (160.0, 7.2e-5)] {
        let mut rng = StdRng::seed_from_u64(23);
        let mut errs = Vec::new();
        let mut sigmas = Vec::new();
        for _ in 0..200 {
            let (t, y) = record(t_end, 10.0, 1e-3, Some(&mut rng));
            let fit = fit_exponentials(&t, &y, 2).expect("fits");
            errs.push(fit.f_inf - 1.0);
            sigmas.push(fit.sigma_f_inf);
        }
        sigmas.sort_by(|a, b| a.total_cmp(b));
        let median = sigmas[100];
        let rmse = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        assert!(
            (median / sigma_expect - 1.0).abs() < 0.25,
            "T {t_end}: median σ̂ {median:.2e}"
        );
        assert!(
            rmse / median < 1.3 && median / rmse < 1.3,
            "T {t_end}: RMSE {rmse:.2e} vs σ̂ {median:.2e}"
        );
    }
}

fn three_terms(t_end: f64, hz: f64, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let d = Normal::new(0.0, noise).expect("σ > 0");
    let n = (t_end * hz).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|i| i as f64 / hz).collect();
    let y = t
        .iter()
        .map(|t| {
            2.0 + 0.5 * (-t / 1.5).exp()
                + 0.4 * (-t / 15.0).exp()
                + 0.3 * (-t / 60.0).exp()
                + d.sample(&mut rng)
        })
        .collect();
    (t, y)
}

#[test]
fn the_information_criterion_picks_the_terms_the_data_hold() {
    // Three well-separated terms over 4τ_slow at 20 Hz: three terms, confident.
    let (t, y) = three_terms(240.0, 20.0, 0.005, 1);
    let s = analyse_step(&t, &y, 10.0, 3);
    assert_eq!(s.terms, 3, "{s:?}");
    assert!(s.confident(), "{:?}", s.issues);
    for (got, want) in s.taus_s.iter().zip([1.5, 15.0, 60.0]) {
        assert!((got / want - 1.0).abs() < 0.1, "τ {got} vs {want}");
    }
    assert!(
        (s.f_inf - 2.0).abs() < 3.0 * s.sigma_f_inf.max(1e-3),
        "{}",
        s.f_inf
    );
    // The last-window mean still carries e^{-4}·0.3 of the slow term.
    assert!(s.window_mean > 2.0);
}

#[test]
fn noise_only_is_no_relaxation_and_short_records_are_flagged() {
    let mut rng = StdRng::seed_from_u64(2);
    let d = Normal::new(0.0, 0.01).expect("σ > 0");
    let t: Vec<f64> = (0..2000).map(|i| i as f64 * 0.05).collect();
    let y: Vec<f64> = t.iter().map(|_| 3.0 + d.sample(&mut rng)).collect();
    let s = analyse_step(&t, &y, 10.0, 3);
    assert_eq!(s.terms, 0, "noise only: {s:?}");
    assert!((s.f_inf - 3.0).abs() < 0.002);
    // 30 s of a 60 s relaxation: the slow term cannot be pinned down.
    let (t, y) = three_terms(30.0, 20.0, 0.002, 3);
    let s = analyse_step(&t, &y, 10.0, 3);
    assert!(!s.confident(), "{s:?}");
    assert!(
        s.issues.iter().any(|i| i.contains("shorter than 2τ_slow")),
        "{:?}",
        s.issues
    );
    // Two nearly equal time constants are reported as not separable, or merged.
    let t: Vec<f64> = (0..4000).map(|i| i as f64 * 0.05).collect();
    let y: Vec<f64> = t
        .iter()
        .map(|t| 1.0 + 0.3 * (-t / 10.0).exp() + 0.3 * (-t / 12.0).exp())
        .collect();
    let s = analyse_step(&t, &y, 10.0, 3);
    assert!(
        s.terms == 1 || s.issues.iter().any(|i| i.contains("not separable")),
        "{s:?}"
    );
    // Too few samples.
    let s = analyse_step(&[0.0, 1.0, 2.0], &[1.0, 1.0, 1.0], 1.0, 3);
    assert!(!s.confident());
}

#[test]
fn shared_time_constants_from_several_short_steps() {
    // Twenty 180 s steps (as box-normal-flat) with different F∞, same τ, noise like a
    // Nano17's.
    let mut rng = StdRng::seed_from_u64(5);
    let d = Normal::new(0.0, 0.0125).expect("σ > 0");
    let t: Vec<f64> = (0..3600).map(|i| i as f64 * 0.05).collect();
    let ys: Vec<Vec<f64>> = (1..=20)
        .map(|k| {
            let a = k as f64;
            t.iter()
                .map(|t| {
                    a + 0.25 * (-t / 1.5).exp()
                        + 0.2 * (-t / 15.0).exp()
                        + 0.15 * (-t / 60.0).exp()
                        + d.sample(&mut rng)
                })
                .collect()
        })
        .collect();
    let recs: Vec<(&[f64], &[f64])> = ys.iter().map(|y| (&t[..], &y[..])).collect();
    let fit = fit_shared(&recs, &[1.0, 10.0, 40.0]).expect("fits");
    for (got, want) in fit.taus_s.iter().zip([1.5, 15.0, 60.0]) {
        assert!((got / want - 1.0).abs() < 0.05, "τ {got} vs {want}");
    }
    for (k, lin) in fit.linear.iter().enumerate() {
        assert!((lin[0] - (k + 1) as f64).abs() < 0.01, "F∞ {}", lin[0]);
    }
}

#[test]
fn settle_error_shrinks_with_the_wait() {
    let t: Vec<f64> = (0..=3600).map(|i| i as f64 * 0.05).collect();
    let y: Vec<f64> = t.iter().map(|t| 1.0 + 0.2 * (-t / 30.0).exp()).collect();
    let e = settle_error(&t, &y, 10.0, &[20.0, 60.0, 180.0, 400.0], 1.0);
    assert!(e[0] > e[1] && e[1] > e[2] && e[2] > 0.0, "{e:?}");
    assert!(e[3].is_nan());
    // Mean of e^{-t/30} over (170, 180] ≈ 0.2·e^{-175/30}.
    assert!(
        (e[2] - 0.2 * (-175.0f64 / 30.0).exp()).abs() < 1e-4,
        "{}",
        e[2]
    );
}

/// The starting grid's residuals as first written: each combination's normal equations
/// summed from its columns, every residual summed to the end.
fn grid_start_by_each_combination(t: &[f64], y: &[f64], terms: usize) -> Option<Vec<f64>> {
    let n = t.len();
    let (grid, columns) = start_grid(t);
    let step = [1, 2, 4][terms.min(3) - 1];
    let mut best = (f64::INFINITY, vec![0.0; terms]);
    for_each_combination(terms, step, grid.len(), |idx| {
        let m = terms + 1;
        let col = |k: usize, i: usize| if k == 0 { 1.0 } else { columns[idx[k - 1]][i] };
        let mut ata = DMatrix::<f64>::zeros(m, m);
        let mut aty = DVector::<f64>::zeros(m);
        for (i, yi) in y.iter().enumerate() {
            for a in 0..m {
                aty[a] += col(a, i) * yi;
                for b in a..m {
                    ata[(a, b)] += col(a, i) * col(b, i);
                }
            }
        }
        for a in 0..m {
            for b in 0..a {
                ata[(a, b)] = ata[(b, a)];
            }
        }
        let rss = bounded_svd_solve(ata, &aty).map_or(f64::INFINITY, |c| {
            (0..n)
                .map(|i| (y[i] - (0..m).map(|k| c[k] * col(k, i)).sum::<f64>()).powi(2))
                .sum()
        });
        if rss < best.0 {
            best = (rss, idx.iter().map(|i| grid[*i]).collect());
        }
    });
    best.0.is_finite().then_some(best.1)
}

/// The grid start read from one Gram matrix, with residuals cut short once they pass the
/// best, chooses the very combination (the same bits) the per-combination sums choose: on
/// clean and noisy records, one to three terms, short and long.
#[test]
fn the_grid_start_from_one_gram_matrix_is_the_per_combination_start() {
    let mut rng = StdRng::seed_from_u64(49);
    for (t_end, hz, noise) in [(5.0, 20.0, 0.0), (60.0, 10.0, 0.002), (200.0, 50.0, 0.01)] {
        let (t, y) = match noise > 0.0 {
            true => record(t_end, hz, noise, Some(&mut rng)),
            false => record(t_end, hz, noise, None),
        };
        for terms in 1..=3 {
            let got = grid_start(&t, &y, terms).expect("a start");
            let want = grid_start_by_each_combination(&t, &y, terms).expect("a start");
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&got),
                bits(&want),
                "{t_end} s at {hz} Hz, {terms} terms"
            );
        }
    }
}

/// The kept columns give the projection computed afresh, bit for bit, through a sequence of
/// time constants as Levenberg–Marquardt asks for them (a base point, each constant moved
/// alone, a new point, the base again after it was evicted).
#[test]
fn kept_decay_columns_give_the_fresh_projection() {
    let (t, y) = record(30.0, 20.0, 0.0, None);
    let decays = Decays::new(&t, 2);
    let asks: [[f64; 2]; 8] = [
        [2.0, 30.0],
        [2.000002, 30.0],
        [2.0, 30.00003],
        [2.5, 41.0],
        [2.500002, 41.0],
        [2.5, 41.000041],
        [3.0, 50.0],
        [2.0, 30.0],
    ];
    for taus in asks {
        let (kept_c, kept_r) = decays.linear_part(&y, &taus).expect("solves");
        let (c, r) = linear_part(&t, &y, &taus).expect("solves");
        let bits = |v: &DVector<f64>| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&kept_c), bits(&c), "{taus:?}");
        assert_eq!(bits(&kept_r), bits(&r), "{taus:?}");
    }
    assert!(decays.kept.borrow().len() <= 6);
}
