//! The tilting-moment arms of the shipped curved indenters (the box sphere, the lifting can
//! across the portable pad) by depth and by the cells across the contact's footprint
//! (`Quality::cells_flat`), with the cost of solving a depth, beside the flat punches' arms.
//! The arm is My = −arm·Fx: how far ahead of the contact's centre a stuck contact's shear
//! moves its pressure through the layer's coupling.
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
    ContactModel::build(ModelSpec {
        contact: c,
        max_depth_mm,
        shear: true,
        twist: false,
        field_view_mm: None,
        pressing_friction: false,
        quality: Quality {
            cells_flat,
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
}
