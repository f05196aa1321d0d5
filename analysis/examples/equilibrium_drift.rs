//! The adaptive rule's drift test on synthetic relaxations (BENCHMARKS.md, "Settle rules"):
//! the box gel's three terms (1.5, 15, 60 s) with and without a 600 s term beside them,
//! records of 30–300 s at 20 Hz with 3 mN noise (the simulated Nano17's resolution). Per
//! record: F∞'s error, the reported 2σ, the drift statistic (how much one slower term lowers
//! the residual, in noise variances), the verdict, and the fit's cost (median of 5).
//!
//! ```text
//! cargo run --release -p analysis --example equilibrium_drift
//! ```

use analysis::equilibrium::estimate;
use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::StandardNormal;

fn main() {
    let f_inf = 1.1;
    let gels: [(&str, &[f64], &[f64]); 2] = [
        (
            "box gel (1.5, 15, 60 s)",
            &[1.5, 15.0, 60.0],
            &[0.625, 0.5, 0.375],
        ),
        (
            "with a 600 s term",
            &[1.5, 15.0, 60.0, 600.0],
            &[1.0, 0.8, 0.6, 0.6],
        ),
    ];
    println!("| gel | record | F∞ error | 2σ | drift statistic | drifting | ms per fit |");
    println!("|---|---|---|---|---|---|---|");
    for (name, taus, amps) in gels {
        for t_end in [30.0, 60.0, 150.0, 300.0] {
            let mut rng = StdRng::seed_from_u64(1);
            let n = (t_end * 20.0) as usize;
            let t: Vec<f64> = (0..n).map(|i| i as f64 / 20.0).collect();
            let y: Vec<f64> = t
                .iter()
                .map(|ti| {
                    f_inf
                        + taus
                            .iter()
                            .zip(amps)
                            .map(|(tau, a)| f_inf * a * (-ti / tau).exp())
                            .sum::<f64>()
                        + 0.003 * rng.sample::<f64, _>(StandardNormal)
                })
                .collect();
            let mut ms: Vec<f64> = (0..5)
                .map(|_| {
                    let start = std::time::Instant::now();
                    std::hint::black_box(estimate(&t, &y, 10.0));
                    start.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            ms.sort_by(f64::total_cmp);
            let Some(e) = estimate(&t, &y, 10.0) else {
                println!("| {name} | {t_end} s | — | — | — | too short | |");
                continue;
            };
            println!(
                "| {name} | {t_end:.0} s | {:+.2} % | {:.2} % | {:.1} | {} | {:.1} |",
                100.0 * (e.f_inf - f_inf) / f_inf,
                200.0 * e.sigma / f_inf,
                e.slower_term_chi2,
                e.drifting,
                ms[2]
            );
        }
    }
}
