//! Grid oracles of spec §5 for the FFT operators and contact solvers (O7, O8, O10, O12,
//! O14, O15, O16, O18), at the spec's tolerances and resolutions.

use std::f64::consts::PI;

use crate::operator::{Compliance, Grid, HalfSpaceOperator, LayerOperator};
use crate::solve::{Tangential, Tolerance, normal_known_area, normal_unknown_area, tangential};

fn disk(g: Grid, a: f64) -> Vec<bool> {
    (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            x * x + y * y <= a * a
        })
        .collect()
}

fn tight() -> Tolerance {
    Tolerance {
        rel: 1e-9,
        max_iter: 5000,
    }
}

/// Flat punch force on the half-space with `cells` across the diameter, E* = a = d = 1.
fn o7_force(cells: usize, extent: f64) -> (f64, Vec<f64>, Grid) {
    let dx = 2.0 / cells as f64;
    let g = Grid {
        n: crate::operator::fast_size((2.0 * extent / dx).ceil() as usize),
        dx,
    };
    let nu = 0.5;
    let op = HalfSpaceOperator::new(g, 1.0 - nu * nu, nu);
    let s = normal_known_area(&op, &disk(g, 1.0), &vec![1.0; g.len()], tight());
    let mut uz = vec![0.0; g.len()];
    op.normal(&s.p, &mut uz);
    (s.force_n, uz, g)
}

#[test]
fn flat_punch_half_space_o7() {
    let (p58, uz, g) = o7_force(58, 2.2);
    assert!((p58 / 2.0 - 1.0).abs() <= 0.004, "58 cells: {p58}");
    // u_z(2a) = (2/π) asin(1/2) = 1/3, outside the punch.
    let u2 = g.sample(&uz, 2.0, 0.0);
    assert!((u2 - 1.0 / 3.0).abs() < 0.004, "{u2}");
    let (p116, _, _) = o7_force(116, 1.1);
    let (p232, _, _) = o7_force(232, 1.05);
    assert!((p232 / 2.0 - 1.0).abs() <= 0.0012, "232 cells: {p232}");
    // First order in the cell size.
    let order = ((2.0 - p58) / (2.0 - p116)).log2();
    assert!(order > 0.7 && order < 1.6, "order {order}");
    assert!(p58 < p116 && p116 < p232 && p232 < 2.0);
}

#[test]
fn elliptic_punch_o8() {
    let cells = 244;
    let dx = 2.0 / cells as f64;
    let g = Grid {
        n: crate::operator::fast_size(cells + 6),
        dx,
    };
    let nu = 0.5;
    let op = HalfSpaceOperator::new(g, 1.0 - nu * nu, nu);
    let mask: Vec<bool> = (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            x * x + (y / 0.5).powi(2) <= 1.0
        })
        .collect();
    let s = normal_known_area(&op, &mask, &vec![1.0; g.len()], tight());
    assert!(
        (s.force_n / 1.456791 - 1.0).abs() <= 0.0015,
        "{}",
        s.force_n
    );
}

#[test]
fn hertz_o10() {
    // E* = R = 1, d = 0.01: P = 4/3·10⁻³, a = 0.1, p₀ = 0.063662; 27 cells across 2a.
    let dx: f64 = 0.2 / 27.0;
    let g = Grid {
        n: crate::operator::fast_size((0.3 / dx).ceil() as usize),
        dx,
    };
    let op = HalfSpaceOperator::new(g, 0.75, 0.5);
    let profile: Vec<f64> = (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            (x * x + y * y) / 2.0
        })
        .collect();
    let s = normal_unknown_area(
        &op,
        &profile,
        0.01,
        None,
        Tolerance {
            rel: 1e-10,
            max_iter: 3000,
        },
    );
    assert!(s.converged);
    assert!(
        (s.force_n / (4.0e-3 / 3.0) - 1.0).abs() <= 2e-4,
        "{}",
        s.force_n
    );
    let a = (s.area_mm2 / PI).sqrt();
    assert!((a - 0.1).abs() <= 1.5 * dx, "{a}");
    let p0 = s.p.iter().cloned().fold(0.0, f64::max);
    assert!((p0 / 0.063662 - 1.0).abs() < 2e-3, "{p0}");
}

#[test]
fn cattaneo_mindlin_grid_o12() {
    // ν = ½ half-space, Hertz pressure with a = 1, μ = 1, 61 cells across 2a.
    let dx = 2.0 / 61.0;
    let g = Grid { n: 64, dx };
    let (nu, gmod) = (0.5, 1.0);
    let op = HalfSpaceOperator::new(g, 2.0 * gmod * (1.0 + nu), nu);
    let p: Vec<f64> = (0..g.len())
        .map(|i| {
            let (x, y) = g.xy(i);
            (1.0 - x * x - y * y).max(0.0).sqrt()
        })
        .collect();
    let p_total = 2.0 * PI / 3.0;
    let dstar = crate::friction::cm_full_slip_displacement(1.0, p_total, nu, gmod, 1.0);
    for (frac, c_expect, q_expect) in [
        (0.25, 0.866, 0.3505),
        (0.5, 0.707, 0.6464),
        (0.75, 0.5, 0.875),
    ] {
        let tx = vec![frac * dstar; g.len()];
        let ty = vec![0.0; g.len()];
        let s = tangential(&Tangential {
            op: &op,
            p: &p,
            mu: 1.0,
            target: (&tx, &ty),
            source: None,
            x_only: true,
            initial: None,
            tol: Tolerance {
                rel: 1e-9,
                max_iter: 5000,
            },
        });
        assert!(s.converged);
        let p_grid = p.iter().sum::<f64>() * g.area();
        assert!(
            (s.fx_n / p_grid - q_expect).abs() < 1e-3,
            "δ/δ* {frac}: {}",
            s.fx_n / p_grid
        );
        let c = (s.stick.iter().filter(|v| **v).count() as f64 * g.area() / PI).sqrt();
        assert!((c - c_expect).abs() <= dx, "δ/δ* {frac}: c/a {c}");
    }
}

#[test]
fn torsion_of_a_stuck_and_a_slipping_punch_o14() {
    // Half-space, G = a = 1, ν = ½: full-stick twist β gives T = (16/3)Ga³β; with Sneddon
    // pressure and μ = 1 the contact slips fully at T = (π/4)μPa.
    let dx = 2.0 / 64.0;
    let g = Grid { n: 72, dx };
    let op = HalfSpaceOperator::new(g, 3.0, 0.5);
    let inside = disk(g, 1.0);
    // Cell averages of the Sneddon pressure 1/(2π√(1−r²)) (P = 1) by 16×16 sub-samples:
    // the edge singularity is integrable and carries the torque's largest lever arm.
    let p_sneddon: Vec<f64> = (0..g.len())
        .map(|i| {
            if !inside[i] {
                return 0.0;
            }
            let (x, y) = g.xy(i);
            let mut sum = 0.0;
            for sj in 0..16 {
                for si in 0..16 {
                    let xs = x + (si as f64 + 0.5) / 16.0 * dx - dx / 2.0;
                    let ys = y + (sj as f64 + 0.5) / 16.0 * dx - dx / 2.0;
                    let r2 = xs * xs + ys * ys;
                    if r2 < 1.0 {
                        sum += 1.0 / (2.0 * PI * (1.0 - r2).sqrt());
                    }
                }
            }
            sum / 256.0
        })
        .collect();
    let p_total: f64 = p_sneddon.iter().sum::<f64>() * g.area();
    let beta = 1e-3;
    let tx: Vec<f64> = (0..g.len()).map(|i| -beta * g.xy(i).1).collect();
    let ty: Vec<f64> = (0..g.len()).map(|i| beta * g.xy(i).0).collect();
    let stuck = tangential(&Tangential {
        op: &op,
        p: &p_sneddon,
        mu: 1e9,
        target: (&tx, &ty),
        source: None,
        x_only: false,
        initial: None,
        tol: tight(),
    });
    let t = stuck.torque_nmm(g) / beta;
    assert!((t / (16.0 / 3.0) - 1.0).abs() < 0.01, "stick stiffness {t}");
    let (tx, ty): (Vec<f64>, Vec<f64>) = (
        tx.iter().map(|v| v * 1e3).collect(),
        ty.iter().map(|v| v * 1e3).collect(),
    );
    let slipping = tangential(&Tangential {
        op: &op,
        p: &p_sneddon,
        mu: 1.0,
        target: (&tx, &ty),
        source: None,
        x_only: false,
        initial: None,
        tol: tight(),
    });
    assert_eq!(slipping.stick_fraction(&p_sneddon), 0.0);
    let t_slip = slipping.torque_nmm(g);
    // The solver: at full slip every cell carries μp along the twist, exactly.
    let discrete: f64 = (0..g.len())
        .map(|i| p_sneddon[i] * g.xy(i).0.hypot(g.xy(i).1))
        .sum::<f64>()
        * g.area();
    assert!(
        (t_slip / discrete - 1.0).abs() < 1e-6,
        "{t_slip} vs {discrete}"
    );
    // The discretised pressure against the continuum (π/4)μPa: first order in dx.
    assert!(
        (discrete / (PI / 4.0 * p_total) - 1.0).abs() < 0.015,
        "{discrete} vs {}",
        PI / 4.0 * p_total
    );
}

fn layer_punch(ah: f64, cells: usize) -> (f64, Vec<f64>, Grid, LayerOperator) {
    let (h, a, mu, nu) = (1.0, ah, 1.0, 0.5);
    let dx = 2.0 * a / cells as f64;
    let g = Grid {
        n: LayerOperator::period_for(2.0 * a, h, dx),
        dx,
    };
    let op = LayerOperator::new(g, h, mu, nu);
    let s = normal_known_area(&op, &disk(g, a), &vec![1.0; g.len()], tight());
    let estar = 2.0 * mu / (1.0 - nu);
    (s.force_n / (2.0 * estar * a), s.p, g, op)
}

#[test]
fn layer_stiffness_on_the_grid_o15() {
    for (ah, kappa) in [(1.131, 4.1749), (1.51, 6.0581)] {
        let (k, ..) = layer_punch(ah, 64);
        assert!((k / kappa - 1.0).abs() <= 0.006, "a/h {ah}: {k} vs {kappa}");
    }
}

#[test]
fn layer_radial_field_points_outward_o16() {
    let ah = 1.131;
    let (_, p, g, op) = layer_punch(ah, 64);
    let zero = vec![0.0; g.len()];
    let [ux, _, _] = op.full(&zero, &zero, &p);
    let ur = |s: f64| g.sample(&ux, s * ah, 0.0);
    for (s, expect) in [(0.5, 0.320), (1.5, 0.453), (2.0, 0.312)] {
        assert!(
            (ur(s) - expect).abs() <= 0.003,
            "u_r/d at {s}a = {} (expect {expect})",
            ur(s)
        );
    }
    let (peak_at, peak) = (0..300)
        .map(|i| {
            let s = 0.8 + i as f64 * 0.002;
            (s, ur(s))
        })
        .fold((0.0, 0.0), |best, v| if v.1 > best.1 { v } else { best });
    assert!((peak - 0.499).abs() < 0.005, "peak {peak}");
    assert!((peak_at - 1.14).abs() < 0.05, "peak at {peak_at}a");
    assert!(
        (0..200).all(|i| ur(0.05 + i as f64 * 0.02) > 0.0),
        "outward everywhere"
    );
}

#[test]
fn sphere_on_the_layer_o18() {
    // R/h = 1.51, ν = ½, frictionless, paraboloid: P/P_Hertz = 1.249 at d/h = 2 %, 2.360 at
    // 20 %; a power law over 2–20 % has exponent 1.78.
    let (r, h, mu, nu) = (6.34_f64, 4.2_f64, 1.0, 0.5);
    let estar = 2.0 * mu / (1.0 - nu);
    let mut pts = Vec::new();
    for frac in [0.02, 0.05, 0.1, 0.2] {
        let d = frac * h;
        let a_h = (r * d).sqrt();
        let dx = 2.4 * a_h / 27.0;
        let g = Grid {
            n: LayerOperator::period_for(2.4 * a_h, h, dx),
            dx,
        };
        let op = LayerOperator::new(g, h, mu, nu);
        let profile: Vec<f64> = (0..g.len())
            .map(|i| {
                let (x, y) = g.xy(i);
                (x * x + y * y) / (2.0 * r)
            })
            .collect();
        let s = normal_unknown_area(
            &op,
            &profile,
            d,
            None,
            Tolerance {
                rel: 1e-8,
                max_iter: 3000,
            },
        );
        assert!(s.converged);
        let ratio = s.force_n / (4.0 / 3.0 * estar * r.sqrt() * d.powf(1.5));
        match frac {
            0.02 => assert!((ratio / 1.249 - 1.0).abs() < 0.01, "{ratio}"),
            0.2 => assert!((ratio / 2.360 - 1.0).abs() < 0.01, "{ratio}"),
            _ => {}
        }
        pts.push((d.ln(), s.force_n.ln()));
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    assert!((slope / 1.78 - 1.0).abs() < 0.01, "exponent {slope}");
}

#[test]
fn flat_punch_on_the_layer_slips_from_the_edge_inward() {
    // The thesis saw partial slip under a flat punch (§4.4, Fig. 4-13). An ideal flat punch
    // on a half-space has none (q/p uniform). On the bonded layer the normal–tangential
    // coupling makes the pressed surface push outward against friction, so the side where
    // that traction adds to the shear slips first: partial slip grows from the edge.
    let (a, h, nu) = (6.34, 4.2, 0.49);
    let mu_mod = 0.25 / (2.0 * (1.0 + nu));
    let dx = 2.0 * a / 32.0;
    let g = Grid {
        n: LayerOperator::period_for(2.0 * a, h, dx),
        dx,
    };
    let op = LayerOperator::new(g, h, mu_mod, nu);
    let s = normal_known_area(&op, &disk(g, a), &vec![0.21; g.len()], tight());
    let (mut cx, mut cy) = (vec![0.0; g.len()], vec![0.0; g.len()]);
    op.tangential_from_normal(&s.p, &mut cx, &mut cy);
    let mut fractions = Vec::new();
    let mut forces = Vec::new();
    for delta in [0.2, 0.4, 0.6, 0.7, 1.0] {
        let tx: Vec<f64> = cx.iter().map(|v| v + delta).collect();
        let sol = tangential(&Tangential {
            op: &op,
            p: &s.p,
            mu: 0.6,
            target: (&tx, &cy),
            source: Some((&cx, &cy)),
            x_only: false,
            initial: None,
            tol: Tolerance {
                rel: 1e-7,
                max_iter: 5000,
            },
        });
        assert!(sol.converged, "δ = {delta}");
        fractions.push(sol.stick_fraction(&s.p));
        forces.push(sol.fx_n);
        // Slip cells lie at larger radius than stick cells.
        let mean_r = |stick: bool| {
            let rs: Vec<f64> = (0..g.len())
                .filter(|i| s.p[*i] > 0.0 && sol.stick[*i] == stick)
                .map(|i| g.xy(i).0.hypot(g.xy(i).1))
                .collect();
            rs.iter().sum::<f64>() / rs.len().max(1) as f64
        };
        if fractions.last().is_some_and(|f| *f > 0.05 && *f < 0.95) {
            assert!(
                mean_r(false) > mean_r(true),
                "slip zone outside the stick zone"
            );
        }
    }
    assert!(fractions[0] > 0.95 && fractions[4] == 0.0, "{fractions:?}");
    assert!(fractions.windows(2).all(|w| w[1] <= w[0]), "{fractions:?}");
    assert!(
        fractions.iter().any(|f| *f > 0.1 && *f < 0.9),
        "a partial-slip stage: {fractions:?}"
    );
    assert!(
        (forces[4] / (0.6 * s.force_n) - 1.0).abs() < 1e-3,
        "full slip at μP"
    );
}

#[test]
fn torsional_slip_thresholds_o14() {
    // Spec §1.6 with G = a = 1, P = 1, μ = 1. Full stick: τ_θz = 3Tr/(4πa³√(a²−r²)) against
    // the Sneddon pressure P/(2πa√(a²−r²)): the ratio 3Tr/(2Pa²) is largest at the edge, so
    // slip starts at T = (2/3)μPa.
    let (a, p_n, mu) = (1.0_f64, 1.0_f64, 1.0_f64);
    let t_onset = crate::friction::torsion_slip_onset_nmm(mu, p_n, a);
    let r = a * (1.0 - 1e-12);
    let tau = 3.0 * t_onset * r / (4.0 * PI * a.powi(3) * (a * a - r * r).sqrt());
    let press = p_n / (2.0 * PI * a * (a * a - r * r).sqrt());
    assert!((tau / press - mu).abs() < 1e-8, "{}", tau / press);
    assert!((t_onset - 2.0 / 3.0).abs() < 1e-15);
    // Full slip: every point carries μp, so T = μ∫p r dA = (π/4)μPa (Gauss–Legendre in
    // θ = asin(r/a), which removes the edge singularity).
    let (x, w) = crate::punch::gauss_legendre(40);
    let integral: f64 = x
        .iter()
        .zip(&w)
        .map(|(xi, wi)| {
            let th = (xi + 1.0) * PI / 4.0;
            // r = a sin θ, dr = a cos θ dθ, p r 2πr dr = P sin²θ dθ · a
            wi * PI / 4.0 * p_n * a * th.sin().powi(2)
        })
        .sum();
    let t_full = crate::friction::torsion_full_slip_nmm(mu, p_n, a);
    assert!((mu * integral - t_full).abs() < 1e-8, "{integral}");
    assert!((t_full - PI / 4.0).abs() < 1e-15);
    // Stuck stiffness T = (16/3)Ga³β and the field (O14) are checked above and in `field`.
}

#[test]
fn extreme_inputs_stay_finite() {
    use crate::contact::Contact;
    use crate::response::{ContactModel, ModelSpec, Quality, State};
    use crate::{Indenter, Layer, Material};
    // ν = 0.49999: the layer tensor, the Nyström κ and the grid solve all stay close to ½.
    let k1 = crate::punch::layer_kappa(1.131, 0.49999, 48);
    let k2 = crate::punch::layer_kappa(1.131, 0.5, 48);
    assert!((k1 / k2 - 1.0).abs() < 1e-3, "{k1} vs {k2}");
    let mut m = ContactModel::build(ModelSpec {
        contact: Contact::new(
            Layer {
                width_mm: 50.0,
                length_mm: 50.0,
                thickness_mm: 2.0,
            },
            Material {
                youngs_modulus_mpa: 0.2,
                poisson_ratio: 0.49999,
                prony: vec![],
                friction: 0.6,
            },
            Indenter::FlatCircle { diameter_mm: 6.0 },
        )
        .expect("valid"),
        max_depth_mm: 1.9,
        shear: true,
        twist: false,
        field_view_mm: Some((20.0, 15.0)),
        pressing_friction: false,
        quality: Quality::default(),
    })
    .expect("builds");
    // Zero load: zero force, zero field.
    assert_eq!(m.normal_force_n(0.0), 0.0);
    let f0 = m
        .field(State {
            depth_mm: 0.0,
            shear_n: 0.0,
            torque_nmm: 0.0,
        })
        .expect("field");
    assert!(f0.ux.iter().chain(&f0.uz).all(|v| *v == 0.0));
    // Depth near the thickness: finite and growing.
    let (a, b) = (m.normal_force_n(1.0), m.normal_force_n(1.9));
    assert!(a.is_finite() && b.is_finite() && b > a);
    // Shear far beyond the slip limit: the backbone saturates, the field stays finite.
    let t = m.shear_table(1.0).expect("shear");
    let far = t.backbone.force(1e3);
    assert!((far - t.backbone.limit()).abs() < 1e-12);
    let f = m
        .field(State {
            depth_mm: 1.0,
            shear_n: 10.0 * t.backbone.limit(),
            torque_nmm: 0.0,
        })
        .expect("field");
    assert!(f.ux.iter().chain(&f.uy).chain(&f.uz).all(|v| v.is_finite()));
}

#[test]
fn normal_and_shear_fields_superpose_while_stuck() {
    // Thesis Fig. 4-4: the field under normal + shear load is the sum of the separate
    // fields. In stick the shear tractions are linear in the displacement, so
    // field(δ₁+δ₂) − field(0) = [field(δ₁) − field(0)] + [field(δ₂) − field(0)].
    use crate::Indenter;
    use crate::contact::Contact;
    use crate::response::{ContactModel, ModelSpec, Quality, State};
    let mut m = ContactModel::build(ModelSpec {
        contact: Contact::new(
            crate::geometry::presets::BOX_LAYER,
            crate::geometry::presets::box_material(),
            Indenter::FlatCircle { diameter_mm: 12.68 },
        )
        .expect("valid"),
        max_depth_mm: 0.5,
        shear: true,
        twist: false,
        field_view_mm: Some((45.36, 40.32)),
        pressing_friction: false,
        quality: Quality::default(),
    })
    .expect("builds");
    let d = 0.21;
    let limit = m.shear_table(d).expect("table").backbone.limit();
    let field = |m: &mut ContactModel, q: f64| {
        m.field(State {
            depth_mm: d,
            shear_n: q,
            torque_nmm: 0.0,
        })
        .expect("field")
    };
    let (q1, q2) = (0.05 * limit, 0.1 * limit);
    let f0 = field(&mut m, 1e-12);
    let f1 = field(&mut m, q1);
    let f2 = field(&mut m, q2);
    let f12 = field(&mut m, q1 + q2);
    let g = f0.grid;
    let mut worst: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for (x, y) in [
        (0.0, 0.0),
        (8.0, 0.0),
        (0.0, 8.0),
        (-7.0, 5.0),
        (12.0, -9.0),
    ] {
        let at = |f: &crate::response::Field| g.sample(&f.ux, x, y);
        let sum = (at(&f1) - at(&f0)) + (at(&f2) - at(&f0));
        worst = worst.max((at(&f12) - at(&f0) - sum).abs());
        scale = scale.max(sum.abs());
    }
    assert!(
        worst < 0.01 * scale,
        "superposition error {worst} of {scale}"
    );
}
