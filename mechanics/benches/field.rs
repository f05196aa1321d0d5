//! Time of the layer field solver (issue 3; errors against resolution are printed by
//! `cargo run --release -p mechanics --example error_vs_cost`).
//!
//! - `field/<n>`: the surface field (u_x, u_y, u_z) of the box sensor's 9.5 mm punch at
//!   20 % depth on an n×n field grid, from precomputed tractions: what every simulated
//!   frame costs. Target: 256² in ≤ 10 ms.
//! - `solve/normal_256`, `solve/friction_256`: one flat-punch normal solve (CG) and one
//!   partial-slip shear solve (spectral projected gradient) on a 256² layer grid.

use criterion::{Criterion, criterion_group, criterion_main};
use mechanics::Indenter;
use mechanics::contact::Contact;
use mechanics::operator::{Compliance, Grid, LayerOperator};
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::solve::{Tangential, Tolerance, normal_known_area, tangential};

fn contact() -> Contact {
    Contact::new(
        mechanics::geometry::presets::BOX_LAYER,
        mechanics::geometry::presets::box_material(),
        Indenter::FlatCircle { diameter_mm: 9.5 },
    )
    .expect("valid contact")
}

fn field(c: &mut Criterion) {
    let mut group = c.benchmark_group("field");
    group.sample_size(20);
    for n in [128, 256, 512] {
        let mut model = ContactModel::build(ModelSpec {
            contact: contact(),
            max_depth_mm: 0.84,
            shear: false,
            twist: false,
            field_view_mm: Some((45.36, 40.32)),
            pressing_friction: false,
            quality: Quality {
                field_cells: n,
                ..Quality::default()
            },
        })
        .expect("model");
        let state = State {
            depth_mm: 0.84,
            shear_n: 0.0,
            torque_nmm: 0.0,
        };
        let _ = model.field(state);
        group.bench_function(format!("{n}"), |b| b.iter(|| model.field(state)));
    }
    group.finish();
}

fn solve(c: &mut Criterion) {
    let mut group = c.benchmark_group("solve");
    group.sample_size(10);
    let g = Grid { n: 256, dx: 0.25 };
    let op = LayerOperator::new(g, 4.2, 0.25 / 2.98, 0.49);
    let mask: Vec<bool> = (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            x * x + y * y <= 6.34 * 6.34
        })
        .collect();
    let tol = Tolerance {
        rel: 1e-7,
        max_iter: 4000,
    };
    group.bench_function("normal_256", |b| {
        b.iter(|| normal_known_area(&op, &mask, &vec![0.21; g.len()], tol))
    });
    let p = normal_known_area(&op, &mask, &vec![0.21; g.len()], tol).p;
    let (mut sx, mut sy) = (vec![0.0; g.len()], vec![0.0; g.len()]);
    op.tangential_from_normal(&p, &mut sx, &mut sy);
    let tx: Vec<f64> = sx.iter().map(|v| v + 0.6).collect();
    group.bench_function("friction_256", |b| {
        b.iter(|| {
            tangential(&Tangential {
                op: &op,
                p: &p,
                mu: 0.6,
                target: (&tx, &sy),
                source: Some((&sx, &sy)),
                x_only: false,
                initial: None,
                tol,
            })
        })
    });
    group.finish();
}

criterion_group!(benches, field, solve);
criterion_main!(benches);
