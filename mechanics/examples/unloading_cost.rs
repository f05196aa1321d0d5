//! Cost of a step of the sphere's unloading foundation (`mechanics::unloading`) against the
//! Lee–Radok state it replaces for curved indenters, on the simulated gel's three terms:
//! `cargo run --release -p mechanics --example unloading_cost`.

use std::time::Instant;

use mechanics::Prony;
use mechanics::unloading::TingContact;

fn main() {
    let prony = Prony::new(mechanics::geometry::presets::portable_material().prony).expect("prony");
    let hertz = |d: f64| 4.0 / 3.0 * 6.34f64.sqrt() * 0.3 * d.max(0.0).powf(1.5);
    let built = Instant::now();
    let mut ting = TingContact::new(hertz, 2.5, &prony).expect("foundation");
    let build_us = built.elapsed().as_secs_f64() * 1e6;
    let mut lee = prony.state();
    let n = 200_000;
    let depth = |k: usize| 2.0 * (1.0 - ((k as f64 / n as f64) * 2.0 - 1.0).abs());
    let t = Instant::now();
    let mut sink = 0.0;
    for k in 0..n {
        sink += ting.step(depth(k), 0.005);
    }
    let ting_ns = t.elapsed().as_secs_f64() * 1e9 / n as f64;
    let t = Instant::now();
    for k in 0..n {
        lee.advance_linear(&prony, 0.005, hertz(depth(k)));
        sink += lee.value();
    }
    let lee_ns = t.elapsed().as_secs_f64() * 1e9 / n as f64;
    println!(
        "foundation built in {build_us:.0} µs; a step: Ting {ting_ns:.0} ns, Lee–Radok {lee_ns:.0} ns \
         (a load–unload to 2 mm in {n} steps; checksum {sink:.3})"
    );
}
