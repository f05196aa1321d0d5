//! Cost per frame of reading the wrench from the marker field (issue 15: the feature model
//! ≤ 1 ms per 640×480 frame): matching is done once per recording; per frame, the filled
//! displacements, the eight field moments and the four channels with their uncertainty.
//! Markers: the box sensor's 18 × 16 grid and a 30 × 22 grid (a denser pattern), with a
//! tenth unmeasured.
//!
//! Run: `cargo bench -p analysis --bench force_sensor`

use std::hint::black_box;

use analysis::force_sensor::Layout;
use analysis::force_sensor::ridge::LinearModel;
use criterion::{Criterion, criterion_group, criterion_main};
use tracking::field::MarkerField;

fn grid(nx: usize, ny: usize) -> Vec<[f64; 2]> {
    let (sx, sy) = (600.0 / nx as f64, 440.0 / ny as f64);
    (0..nx * ny)
        .map(|k| [20.0 + (k % nx) as f64 * sx, 20.0 + (k / nx) as f64 * sy])
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("force_from_field");
    for (nx, ny) in [(18, 16), (30, 22)] {
        let refs = grid(nx, ny);
        let layout = Layout::new(refs.clone(), 0.05, [319.5, 239.5]);
        let field = |k: usize| MarkerField {
            reference_px: refs.clone(),
            displacement_px: refs
                .iter()
                .map(|p| {
                    let (x, y) = (p[0] - 320.0, p[1] - 240.0);
                    let r2 = (x * x + y * y) / 4000.0;
                    let a = k as f64 * 0.1 * (-r2).exp();
                    [a * x / 60.0 + 0.3 * a, a * y / 60.0]
                })
                .collect(),
            measured: (0..refs.len()).map(|i| i % 10 != 3).collect(),
        };
        let map = layout.match_markers(&refs).expect("layout");
        let (x, y): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (1..40)
            .map(|k| {
                let (u, _) = layout.displacements_mm(&field(k), &map);
                let f = layout.features(&u).to_vec();
                let w = vec![f[0] * 3.0, f[1], f[2] * 0.5, f[3]];
                (f, w)
            })
            .unzip();
        let model = LinearModel::fit(&x, &y).expect("fit");
        let f = field(17);
        g.bench_function(format!("{}_markers", nx * ny), |b| {
            b.iter(|| {
                let (u, _) = layout.displacements_mm(black_box(&f), &map);
                black_box(model.predict(&layout.features(&u)))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
