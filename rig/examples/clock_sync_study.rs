//! Error against cost of the F/T counter clock model (`rig::clock_sync`): a 7 kHz counter
//! whose crystal runs 50 ppm slow, sent in packets of 7 samples every 1 ms with 2 ms of
//! latency and up to 10 ms more, for 60 s; the model's sample times against the truth after
//! the first window, for several bin sizes and windows, and what each observed sample costs.
//!
//! `cargo run --release -p rig --example clock_sync_study`

use rand::{Rng, SeedableRng};
use rig::clock_sync::CounterClock;

fn main() {
    println!("| bin | window | worst error | rms error | arrival-stamp rms | ns per sample |");
    println!("|---|---|---|---|---|---|");
    for (bin_s, window_s) in [
        (0.001, 20.0),
        (0.01, 5.0),
        (0.01, 20.0),
        (0.1, 20.0),
        (0.1, 5.0),
        (1.0, 20.0),
    ] {
        let (mut worst, mut sq, mut naive_sq, mut n) = (0.0f64, 0.0, 0.0, 0usize);
        let mut cost_ns = 0.0;
        let seeds = 3;
        for seed in 0..seeds {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let mut m = CounterClock::new(7000.0, bin_s, window_s).with_known_latency_ns(2e6);
            let period_true_ns = 1e9 / 7000.0 * (1.0 + 50e-6);
            let start = std::time::Instant::now();
            let mut errs = Vec::new();
            for packet in 0..60_000u64 {
                let last = packet * 7 + 6;
                let t_last = 5e9 + last as f64 * period_true_ns;
                let arrival = t_last + 2e6 + rng.random_range(0.0..10e6);
                for k in packet * 7..=last {
                    m.observe(k, arrival as u64);
                }
                if last > (window_s * 7000.0) as u64
                    && let Some(t) = m.time_of(last)
                {
                    errs.push((t as f64 - t_last, arrival - t_last));
                }
            }
            cost_ns += start.elapsed().as_nanos() as f64 / (60_000.0 * 7.0);
            for (e, a) in errs {
                worst = worst.max(e.abs());
                sq += e * e;
                naive_sq += a * a;
                n += 1;
            }
        }
        println!(
            "| {:.0} ms | {window_s:.0} s | {:.3} ms | {:.3} ms | {:.2} ms | {:.0} |",
            bin_s * 1e3,
            worst * 1e-6,
            (sq / n.max(1) as f64).sqrt() * 1e-6,
            (naive_sq / n.max(1) as f64).sqrt() * 1e-6,
            cost_ns / seeds as f64
        );
    }
}
