//! The contact model against exact results and its own invariants.

use super::*;
use crate::{Layer, Material, PronyTerm};

fn contact(indenter: Indenter, h: f64) -> Contact {
    Contact::new(
        Layer {
            width_mm: 125.0,
            length_mm: 70.0,
            thickness_mm: h,
        },
        Material {
            youngs_modulus_mpa: 0.25,
            poisson_ratio: 0.49,
            prony: vec![PronyTerm {
                weight: 0.2,
                tau_s: 10.0,
            }],
            friction: 0.6,
        },
        indenter,
    )
    .expect("valid")
}

#[test]
fn flat_punch_force_is_the_exact_layer_stiffness_raised_by_friction() {
    let build = |mu: f64, shear: bool| {
        let mut c = contact(Indenter::FlatCircle { diameter_mm: 9.5 }, 4.2);
        c.material.friction = mu;
        ContactModel::build(ModelSpec {
            contact: c,
            max_depth_mm: 1.0,
            shear,
            twist: false,
            field_view_mm: None,
            pressing_friction: true,
            quality: Quality::default(),
        })
        .expect("builds")
    };
    let e_star = contact(Indenter::FlatCircle { diameter_mm: 9.5 }, 4.2)
        .material
        .contact_modulus_mpa();
    let kappa = punch::layer_kappa(4.75 / 4.2, 0.49, 48);
    let exact = 2.0 * e_star * 4.75 * 0.084 * kappa;
    // Frictionless: the exact (Nyström) layer stiffness.
    let free = build(0.0, false);
    assert!((free.normal_force_n(0.084) / exact - 1.0).abs() < 1e-12);
    assert_eq!(free.normal_force_n(-0.1), 0.0);
    // μ = 0.6 sticks: the face holds the outward flow and presses ~9 % harder
    // (`crate::pressing`; the independent check is in tests/peers).
    let mut stuck = build(0.6, true);
    let ratio = stuck.normal_force_n(0.084) / exact;
    assert!(ratio > 1.07 && ratio < 1.11, "{ratio}");
    // The slip limit is μ times the model's own Fz.
    let (b, _) = stuck.shear_curve(0.084).expect("shear");
    let limit = b.f.last().copied().unwrap_or(0.0);
    assert!(
        (limit / stuck.normal_force_n(0.084) - 0.6).abs() < 1e-9,
        "{limit}"
    );
}

#[test]
fn sphere_table_is_stiffer_than_hertz_and_grows_its_contact() {
    let c = contact(Indenter::Sphere { diameter_mm: 12.68 }, 4.2);
    let e_star = c.material.contact_modulus_mpa();
    let m = ContactModel::build(ModelSpec {
        contact: c,
        max_depth_mm: 2.0,
        shear: false,
        twist: false,
        field_view_mm: None,
        pressing_friction: false,
        quality: Quality::default(),
    })
    .expect("builds");
    let mut last_a = 0.0;
    for frac in [0.02, 0.05, 0.1, 0.2, 0.4] {
        let d: f64 = frac * 4.2;
        let hertz = 4.0 / 3.0 * e_star * 6.34_f64.sqrt() * d.powf(1.5);
        let ratio = m.normal_force_n(d) / hertz;
        assert!(ratio > 1.0, "{frac}: {ratio}");
        let a = m.contact_radius_mm(d);
        assert!(a > last_a);
        last_a = a;
    }
    // Fitted exponent over 2–20 % of thickness: stiffer than Hertz's 1.5 (spec O18 ≈
    // 1.78 for a paraboloid; the exact sphere is a little softer).
    let e = (m.normal_force_n(0.84) / m.normal_force_n(0.084)).ln() / 10f64.ln();
    assert!(e > 1.6 && e < 1.85, "exponent {e}");
}

#[test]
fn flat_shear_backbone_saturates_at_mu_p_with_partial_slip_on_the_way() {
    let c = contact(Indenter::FlatCircle { diameter_mm: 12.68 }, 4.2);
    let mut m = ContactModel::build(ModelSpec {
        contact: c,
        max_depth_mm: 0.5,
        shear: true,
        twist: true,
        field_view_mm: None,
        pressing_friction: false,
        quality: Quality::default(),
    })
    .expect("builds");
    let d = 0.21;
    let t = m.shear_table(d).expect("shear table");
    let limit = 0.6 * m.normal_force_n(d);
    // The grid's force differs from the exact κ by the discretisation error (≈1 %).
    assert!(
        (t.backbone.limit() / limit - 1.0).abs() < 0.03,
        "{} vs {limit}",
        t.backbone.limit()
    );
    assert!(
        t.stick_fraction.iter().any(|s| *s > 0.1 && *s < 0.9),
        "{:?}",
        t.stick_fraction
    );
    assert_eq!(t.stick_fraction.last().copied(), Some(0.0));
    let tw = m.twist_table(d).expect("twist table");
    assert!(tw.backbone.limit() > 0.0 && tw.stick_fraction.last().copied() == Some(0.0));
    // Scaling with depth is exact for a flat punch.
    let t2 = m.shear_table(2.0 * d).expect("shear table");
    assert!((t2.backbone.limit() / t.backbone.limit() - 2.0).abs() < 1e-12);
}

#[test]
fn a_sheared_flat_punch_tilts_its_pressure_forward() {
    // The stuck punch pulls the surface along +x; through the layer's coupling the leading
    // side is pressed harder, so the tractions on the gel have My = −arm·Fx (z into the gel)
    // and, by symmetry, Mx = +arm·Fy. The arm of the 12.68 mm punch on the 4.2 mm box gel is
    // 0.91 mm (0.93 at 16 cells, 0.91 at 32: the `pressing_friction` example).
    let build = |shear: bool| {
        ContactModel::build(ModelSpec {
            contact: contact(Indenter::FlatCircle { diameter_mm: 12.68 }, 4.2),
            max_depth_mm: 1.0,
            shear,
            twist: false,
            field_view_mm: None,
            pressing_friction: false,
            quality: Quality::default(),
        })
        .expect("builds")
    };
    let m = build(true);
    let (tx, ty) = m.tilting_moments_nmm(1.0, 0.0);
    assert_eq!(tx, 0.0);
    assert!(ty < -0.85 && ty > -0.97, "My per N of Fx: {ty}");
    let (tx, ty) = m.tilting_moments_nmm(0.0, 1.0);
    assert_eq!(ty, 0.0);
    assert!(tx > 0.85 && tx < 0.97, "Mx per N of Fy: {tx}");
    // No shear built: nothing asks for it, nothing is solved.
    assert_eq!(build(false).tilting_moments_nmm(1.0, 1.0), (0.0, 0.0));
}

#[test]
fn a_non_circular_punchs_force_is_extrapolated_across_grids_to_within_a_percent() {
    let force = |indenter: Indenter, cells_flat: usize, extrapolate_flat: bool| {
        let c = contact(indenter, 4.2);
        ContactModel::build(ModelSpec {
            contact: c,
            max_depth_mm: 0.84,
            shear: false,
            twist: false,
            field_view_mm: None,
            pressing_friction: false,
            quality: Quality {
                cells_flat,
                extrapolate_flat,
                ..Quality::default()
            },
        })
        .expect("builds")
        .normal_force_n(1.0)
    };
    // A circle taken through the grid path (an ellipse with equal axes) against the exact
    // κ: the 32-cell grid alone is 1.8 % low, extrapolated with 64 cells 0.1 %.
    let c = contact(Indenter::FlatCircle { diameter_mm: 9.5 }, 4.2);
    let a = 4.75;
    let exact = 2.0
        * c.material.contact_modulus_mpa()
        * a
        * crate::punch::layer_kappa(a / 4.2, c.material.poisson_ratio, 48);
    let round = Indenter::FlatEllipse {
        major_mm: 9.5,
        minor_mm: 9.5,
    };
    let (grid, extrapolated) = (force(round, 32, false), force(round, 32, true));
    assert!(grid < 0.99 * exact, "grid {grid} vs exact {exact}");
    assert!(
        (extrapolated / exact - 1.0).abs() < 0.005,
        "extrapolated {extrapolated} vs exact {exact}"
    );
    // The rectangle (corners converge slowest): at 32 cells within 1 % of the same
    // extrapolation from grids twice as fine; the 32-cell grid alone is 3.8 % low.
    let rectangle = Indenter::FlatRectangle {
        width_mm: 12.0,
        length_mm: 6.0,
    };
    let (grid, at_32, at_64) = (
        force(rectangle, 32, false),
        force(rectangle, 32, true),
        force(rectangle, 64, true),
    );
    assert!(grid < 0.97 * at_64, "grid {grid} vs {at_64}");
    assert!((at_32 / at_64 - 1.0).abs() < 0.01, "{at_32} vs {at_64}");
}

#[test]
fn a_curved_indenter_pressed_with_friction_follows_its_loading_path() {
    // The can across the portable pad (h = 2 mm): its strip is wide against the layer, so
    // the coupling friction holds is strong (+36 % at 0.4 mm, BENCHMARKS.md).
    let build = |mu: f64, friction: bool| {
        let mut c = contact(
            Indenter::Cylinder {
                diameter_mm: 57.2,
                length_mm: 100.0,
            },
            2.0,
        );
        c.layer.width_mm = 22.6;
        c.layer.length_mm = 23.4;
        c.material.youngs_modulus_mpa = 0.15;
        c.material.friction = mu;
        ContactModel::build(ModelSpec {
            contact: c,
            max_depth_mm: 0.4,
            shear: true,
            twist: false,
            field_view_mm: Some((18.0, 18.0)),
            pressing_friction: friction,
            quality: Quality::default(),
        })
        .expect("builds")
    };
    let d = 0.3;
    let mut free = build(0.6, false);
    let mut held = build(0.6, true);
    // μ = 0 is the frictionless table exactly; μ = 0.6 presses harder, and more so deeper
    // (the strip widens against h).
    let none = build(0.0, true);
    assert_eq!(none.normal_force_n(d), free.normal_force_n(d));
    let ratio = |m: &ContactModel, d: f64| m.normal_force_n(d) / free.normal_force_n(d);
    let (shallow, deep) = (ratio(&held, 0.05), ratio(&held, d));
    // 1.338 measured here at 0.3 mm (27 Nov); the path example on finer grids gives
    // 1.3617 at 0.4 mm and 1.1820 at 0.1 mm (32 cells, 16 increments), 1.31 between them
    // by interpolation in √δ.
    assert!(deep > 1.3 && deep < 1.37, "{deep}");
    assert!(shallow > 1.0 && shallow < deep, "{shallow} vs {deep}");
    // The slip limit starts from the pressed state's own pressure: against the model's Fz
    // it stands where the frictionless one does (both are the table grid's pressure, 6 %
    // under the adapted grids' force on this strip).
    let slip_ratio = |m: &mut ContactModel| {
        m.shear_table(d).expect("shear").backbone.limit() / (0.6 * m.normal_force_n(d))
    };
    let (r0, r1) = (slip_ratio(&mut free), slip_ratio(&mut held));
    assert!((r1 / r0 - 1.0).abs() < 0.01, "{r1} vs {r0}");
    // The field carries the path's pressure and tractions, and its surface under the
    // strip follows the can (u_z = δ at the centre, within the table grid's 1.2 mm cells).
    // Printed for BENCHMARKS.md, not required (the default's gap is not a property to
    // keep): the one-way (Goodman) field's centre (0.186 for 0.3 mm, 27 Nov) and its
    // in-plane field beside the strip (a third of the path's).
    let pressed = State {
        depth_mm: d,
        shear_n: 0.0,
        torque_nmm: 0.0,
    };
    let (f0, f1) = (
        free.field(pressed).expect("field"),
        held.field(pressed).expect("field"),
    );
    let g = f1.grid;
    let centre = |f: &Field| g.sample(&f.uz, 0.0, 0.0);
    assert!((centre(&f1) / d - 1.0).abs() < 0.03, "{}", centre(&f1));
    let beside = |f: &Field| g.sample(&f.uy, 0.0, 4.0);
    assert!(
        beside(&f1) > 0.0,
        "the caught surface flows outward: {}",
        beside(&f1)
    );
    eprintln!(
        "u_z at the centre: path {:.4}, one-way {:.4} (δ {d}); u_y 4 mm beside: path {:.4}, one-way {:.4}",
        centre(&f1),
        centre(&f0),
        beside(&f1),
        beside(&f0)
    );
}
