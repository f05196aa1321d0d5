//! How a non-circular flat punch's force converges with the contact grid, and what
//! extrapolating across grids buys: the box sensor's shipped punches (ellipse 12 × 6 mm,
//! rectangle 12 × 6 mm, triangle of side 12 mm) and, as a control with an exact answer, a
//! circle of 9.5 mm taken through the same grid path (an ellipse with equal axes) against
//! the exact κ of the bonded layer. Frictionless pressing, Fz per mm of depth: the grid's
//! own force, and the model's (extrapolated from `cells` and twice as many), against the
//! reference — the model at 128 cells (128 and 256 extrapolated; for the circle, exact).
//!
//! `cargo run --release -p mechanics --example flat_shape_convergence`

use std::time::Instant;

use mechanics::contact::Contact;
use mechanics::geometry::presets;
use mechanics::response::{ContactModel, ModelSpec, Quality};
use mechanics::{Indenter, punch};

fn force_per_mm(indenter: Indenter, cells: usize, extrapolate: bool) -> Option<(f64, f64)> {
    let spec = ModelSpec {
        contact: Contact {
            layer: presets::BOX_LAYER,
            material: presets::box_material(),
            indenter,
        },
        max_depth_mm: 0.2 * presets::BOX_LAYER.thickness_mm,
        shear: false,
        twist: false,
        field_view_mm: None,
        pressing_friction: false,
        quality: Quality {
            cells_flat: cells,
            extrapolate_flat: extrapolate,
            ..Quality::default()
        },
    };
    let t0 = Instant::now();
    let m = ContactModel::build(spec).ok()?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    Some((m.normal_force_n(1.0), ms))
}

fn main() {
    let h = presets::BOX_LAYER.thickness_mm;
    let material = presets::box_material();
    let a = 9.5 / 2.0;
    let exact_circle = 2.0
        * material.contact_modulus_mpa()
        * a
        * punch::layer_kappa(a / h, material.poisson_ratio, 48);
    let shapes = [
        (
            "circle 9.5 mm (control)",
            Indenter::FlatEllipse {
                major_mm: 9.5,
                minor_mm: 9.5,
            },
        ),
        (
            "ellipse 12 x 6 mm",
            Indenter::FlatEllipse {
                major_mm: 12.0,
                minor_mm: 6.0,
            },
        ),
        (
            "rectangle 12 x 6 mm",
            Indenter::FlatRectangle {
                width_mm: 12.0,
                length_mm: 6.0,
            },
        ),
        ("triangle 12 mm", Indenter::FlatTriangle { side_mm: 12.0 }),
    ];
    let cells = [16, 24, 32, 48, 64];
    println!("exact circle: {exact_circle:.4} N/mm");
    println!(
        "| shape | cells | grid Fz/mm (N) | error | build ms | extrapolated Fz/mm (N) | error | build ms |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (k, (name, ind)) in shapes.into_iter().enumerate() {
        let reference = if k == 0 {
            exact_circle
        } else {
            match force_per_mm(ind, 128, true) {
                Some((f, _)) => f,
                None => {
                    println!("{name}: the reference failed");
                    continue;
                }
            }
        };
        println!("| {name} | reference | {reference:.4} | | | | | |");
        for &n in &cells {
            let (Some((raw, raw_ms)), Some((ext, ext_ms))) =
                (force_per_mm(ind, n, false), force_per_mm(ind, n, true))
            else {
                println!("| {name} | {n} | failed | | | | | |");
                continue;
            };
            let pct = |f: f64| 100.0 * (f / reference - 1.0);
            println!(
                "| {name} | {n} | {raw:.4} | {:+.2} % | {raw_ms:.0} | {ext:.4} | {:+.2} % | {ext_ms:.0} |",
                pct(raw),
                pct(ext)
            );
        }
    }
}
