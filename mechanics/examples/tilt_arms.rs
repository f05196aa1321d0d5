//! The tilting-moment arms of the shipped curved indenters (the box sphere, the lifting can
//! across the portable pad) by depth and by the cells across the contact's footprint
//! (`Quality::cells_flat`), with the cost of solving a depth, beside the flat punches' arms.
//! The arm is My = −arm·Fx: how far ahead of the contact's centre a stuck contact's shear
//! moves its pressure through the layer's coupling.
//!
//! Then, under partial slip, the full-slip arm each contact's arm moves toward, and how far
//! it has gone at each point of the shear backbone (`ContactModel::shear_slip_tilt`), pressed
//! with friction as the rigs are by default; and the curved contacts' full-slip arms on two
//! grids, with the time `shear_slip_tilt` takes once the shear table exists.
//!
//! `cargo run --release -p mechanics --example tilt_arms`

use std::time::Instant;

use mechanics::contact::Contact;
use mechanics::response::{ContactModel, ModelSpec, Quality};
use mechanics::{Indenter, Layer, Material};

fn contact(indenter: Indenter, h: f64, e: f64, width_mm: f64, length_mm: f64) -> Contact {
    Contact::new(
        Layer {
            width_mm,
            length_mm,
            thickness_mm: h,
        },
        Material {
            youngs_modulus_mpa: e,
            poisson_ratio: 0.49,
            prony: vec![],
            friction: 0.6,
        },
        indenter,
    )
    .expect("a valid contact")
}

fn model(c: Contact, max_depth_mm: f64, cells_flat: usize) -> ContactModel {
    model_pressed(c, max_depth_mm, cells_flat, 16, false)
}

fn model_pressed(
    c: Contact,
    max_depth_mm: f64,
    cells_flat: usize,
    cells_curved: usize,
    pressing_friction: bool,
) -> ContactModel {
    ContactModel::build(ModelSpec {
        contact: c,
        max_depth_mm,
        shear: true,
        twist: false,
        field_view_mm: None,
        pressing_friction,
        quality: Quality {
            cells_flat,
            cells_curved,
            ..Quality::default()
        },
    })
    .expect("builds")
}

fn main() {
    let sphere = || {
        contact(
            Indenter::Sphere { diameter_mm: 12.68 },
            4.2,
            0.25,
            125.0,
            70.0,
        )
    };
    let can = || {
        contact(
            Indenter::Cylinder {
                diameter_mm: 57.2,
                length_mm: 100.0,
            },
            2.0,
            0.15,
            22.6,
            23.4,
        )
    };
    println!("indenter               depth_mm  cells  a_mm   arm_x_mm  arm_y_mm  ms (2 buckets)");
    for (name, c, depths) in [
        (
            "box sphere 12.68 mm",
            sphere as fn() -> Contact,
            vec![0.5, 1.0, 2.0],
        ),
        ("can across the pad", can as fn() -> Contact, vec![0.1, 0.3]),
    ] {
        for cells in [8usize, 16, 32, 64] {
            let mut m = model(c(), 2.0, cells);
            for &d in &depths {
                let t0 = Instant::now();
                // The two depth buckets around `d`, solved and blended.
                let (ax, ay) = m.tilt_arms_mm(d);
                let ms = t0.elapsed().as_secs_f64() * 1e3;
                println!(
                    "{name:<22} {d:>8.2}  {cells:>5}  {:>5.2}  {ax:>8.4}  {ay:>8.4}  {ms:>13.0}",
                    m.contact_radius_mm(d)
                );
            }
        }
    }
    println!();
    println!("flat punch (model, 32 cells)   arm_mm");
    for (name, d, h, e) in [
        ("box 9.5 mm (h 4.2)", 9.5, 4.2, 0.25),
        ("box 12.68 mm (h 4.2)", 12.68, 4.2, 0.25),
        ("portable 12.5 (h 2.0)", 12.5, 2.0, 0.15),
    ] {
        let mut m = model(
            contact(Indenter::FlatCircle { diameter_mm: d }, h, e, 125.0, 70.0),
            1.0,
            32,
        );
        println!("{name:<30} {:>7.4}", m.tilt_arms_mm(0.5).0);
    }
    println!();
    println!(
        "under partial slip (pressed with friction): stuck arm (mm) → full-slip arm (mm), \
         then per backbone point F/limit / stick fraction / progress to full slip"
    );
    for (name, c, d) in [
        (
            "box 9.5 mm at 0.4 mm",
            contact(
                Indenter::FlatCircle { diameter_mm: 9.5 },
                4.2,
                0.25,
                125.0,
                70.0,
            ),
            0.4,
        ),
        (
            "box 12.68 mm at 0.4 mm",
            contact(
                Indenter::FlatCircle { diameter_mm: 12.68 },
                4.2,
                0.25,
                125.0,
                70.0,
            ),
            0.4,
        ),
        (
            "portable 12.5 mm at 0.3 mm",
            contact(
                Indenter::FlatCircle { diameter_mm: 12.5 },
                2.0,
                0.15,
                22.6,
                23.4,
            ),
            0.3,
        ),
        ("box sphere at 1 mm", sphere(), 1.0),
        ("box sphere at 2 mm", sphere(), 2.0),
        ("can across the pad at 0.3 mm", can(), 0.3),
    ] {
        let t0 = Instant::now();
        let mut m = model_pressed(c, 2.0, 32, 16, true);
        let Some((b, stick)) = m.shear_curve(d) else {
            continue;
        };
        let t1 = Instant::now();
        let Some(slip) = m.shear_slip_tilt(d) else {
            continue;
        };
        let (table_ms, ms) = (
            (t1 - t0).as_secs_f64() * 1e3,
            t1.elapsed().as_secs_f64() * 1e3,
        );
        let stuck = m.tilt_arms_mm(d).0;
        let limit = b.limit();
        let row: Vec<String> = (0..b.f.len())
            .map(|k| {
                format!(
                    "{:.2}/{:.2}/{:.2}",
                    b.f[k] / limit,
                    stick[k],
                    slip.progress[k]
                )
            })
            .collect();
        println!(
            "{name:<30} {stuck:.4} → {:.4} ({:+.1} %), {ms:.0} ms (model and table \
             {table_ms:.0} ms): {}",
            slip.full_slip_arm_mm,
            (slip.full_slip_arm_mm / stuck - 1.0) * 100.0,
            row.join(" ")
        );
    }
    println!();
    println!(
        "full-slip arm (mm) of the curved contacts by the tables' grid (cells across 1.2 \
         contact diameters, `Quality::cells_curved`)"
    );
    for (name, c, d) in [
        ("box sphere at 1 mm", sphere as fn() -> Contact, 1.0),
        ("box sphere at 2 mm", sphere, 2.0),
        ("can across the pad at 0.3 mm", can, 0.3),
    ] {
        for cells in [16usize, 24] {
            let mut m = model_pressed(c(), 2.0, 32, cells, true);
            let _ = m.shear_curve(d);
            let t0 = Instant::now();
            let full = m
                .shear_slip_tilt(d)
                .map_or(f64::NAN, |s| s.full_slip_arm_mm);
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            println!("{name:<30} {cells:>3} cells  {full:.4}  {ms:.0} ms");
        }
    }
}
