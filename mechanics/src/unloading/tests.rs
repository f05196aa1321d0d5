use super::*;
use crate::viscoelastic::PronyTerm;

fn gel() -> Prony {
    Prony::new(crate::geometry::presets::portable_material().prony).expect("prony")
}

/// Hertz's law at unit contact modulus for a sphere of radius 1 (N, mm).
fn hertz(d: f64) -> f64 {
    4.0 / 3.0 * d.max(0.0).powf(1.5)
}

/// While the contact grows the foundation is Lee–Radok on F_e: the same hereditary integral
/// as the plant's [`crate::PronyState`], step for step.
#[test]
fn loading_is_lee_radok() {
    let prony = gel();
    let mut ting = TingContact::new(hertz, 0.05, &prony).expect("foundation");
    let mut lee = prony.state();
    let dt = 0.01;
    for k in 1..=300 {
        let d = 0.05 * k as f64 / 300.0;
        let f = ting.step(d, dt);
        lee.advance_linear(&prony, dt, hertz(d));
        assert!(
            (f - lee.value()).abs() < 1e-3 * hertz(0.05),
            "step {k}: {f} vs {}",
            lee.value()
        );
    }
    // Held: both relax alike.
    for _ in 0..200 {
        let f = ting.step(0.05, 0.1);
        lee.advance_linear(&prony, 0.1, hertz(0.05));
        assert!((f - lee.value()).abs() < 1e-3 * hertz(0.05));
    }
}

/// An elastic gel (no relaxation) follows its force law up and down.
#[test]
fn an_elastic_gel_follows_its_law_both_ways() {
    let prony = Prony::new(vec![]).expect("elastic");
    let mut ting = TingContact::new(hertz, 0.05, &prony).expect("foundation");
    for k in (0..=100).chain((0..=100).rev()) {
        let d = 0.05 * k as f64 / 100.0;
        let f = ting.step(d, 0.01);
        assert!((f - hertz(d)).abs() < 1e-3 * hertz(0.05), "{d}: {f}");
    }
}

/// A fast unload: Lee–Radok's integral dips below zero (the indenter would pull a gel it
/// no longer touches); the foundation's force never does, stays at or above Lee–Radok's,
/// and its contact shrinks before the indenter leaves — and after the indenter has left, the
/// gel creeps back at zero force and is touched again only when pressed past where it is.
#[test]
fn a_fast_unload_pushes_and_the_contact_shrinks() {
    let prony = Prony::new(vec![PronyTerm {
        weight: 1.0,
        tau_s: 1.0,
    }])
    .expect("sls");
    let mut ting = TingContact::new(hertz, 0.05, &prony).expect("foundation");
    let mut lee = prony.state();
    let dt = 0.002;
    let n = 250; // 0.5 s up, 0.5 s down
    let mut lee_min = f64::INFINITY;
    let mut touched = Vec::new();
    for k in (1..=n).chain((0..n).rev()) {
        let d = 0.05 * k as f64 / n as f64;
        let f = ting.step(d, dt);
        lee.advance_linear(&prony, dt, hertz(d));
        lee_min = lee_min.min(lee.value());
        assert!(f >= 0.0);
        assert!(
            f >= lee.value() - 2e-3 * hertz(0.05),
            "{d}: {f} below Lee–Radok {}",
            lee.value()
        );
        touched.push(ting.touching_elements());
    }
    assert!(lee_min < -0.01 * hertz(0.05), "Lee–Radok went to {lee_min}");
    // The contact shrinks on the way down faster than an elastic gel's (a ∝ √δ: the gel's
    // surface lags behind the rising indenter), and is gone before the depth is zero.
    let peak = touched.iter().copied().max().unwrap_or(0);
    assert_eq!(touched[n - 1], peak);
    let elastic_half = (0.5f64).sqrt() * peak as f64;
    assert!(
        (touched[n + n / 2] as f64) < elastic_half,
        "{} vs {elastic_half}",
        touched[n + n / 2]
    );
    let gone = touched[n..].iter().position(|t| *t == 0).expect("lets go");
    assert!(
        gone < n - n / 10,
        "let go {} steps before the end",
        n - gone
    );
    assert_eq!(*touched.last().expect("steps"), 0);
    // Pressed again right away, barely: the gel has not recovered, nothing is touched.
    assert_eq!(ting.step(0.002, dt), 0.0);
}

/// Laws that are not increasing, or a depth that is not positive, are refused.
#[test]
fn bad_laws_are_refused() {
    let prony = gel();
    assert!(TingContact::new(hertz, 0.0, &prony).is_none());
    assert!(TingContact::new(|_| 0.0, 0.05, &prony).is_none());
    assert!(TingContact::new(|_| f64::NAN, 0.05, &prony).is_none());
    assert!(TingContact::new(|d| -d, 0.05, &prony).is_none());
}

/// A law that rises from zero with a finite slope (a line contact's): no element is pressed
/// at or above the surface, before or after a load.
#[test]
fn nothing_is_pressed_out_of_contact() {
    let prony = gel();
    let mut ting = TingContact::new(|d| 3.0 * d + 10.0 * d * d, 0.5, &prony).expect("foundation");
    assert_eq!(ting.step(0.0, 0.1), 0.0);
    assert_eq!(ting.step(-0.1, 0.1), 0.0);
    for k in (0..=50).chain((0..=50).rev()) {
        ting.step(0.5 * k as f64 / 50.0, 0.05);
    }
    assert_eq!(ting.step(0.0, 0.1), 0.0);
    assert_eq!(ting.touching_elements(), 0);
}

/// Let go and left alone, the gel creeps back whether the time passes in one step or in many:
/// the recovery does not depend on how often the plant is sampled.
#[test]
fn recovery_does_not_depend_on_the_step() {
    let prony = gel();
    let run = |idle_steps: usize| {
        let mut ting = TingContact::new(hertz, 0.05, &prony).expect("foundation");
        for k in 1..=100 {
            ting.step(0.05 * k as f64 / 100.0, 0.01);
        }
        for k in (0..100).rev() {
            ting.step(0.05 * k as f64 / 100.0, 0.001);
        }
        for _ in 0..idle_steps {
            ting.step(0.0, 5.0 / idle_steps as f64);
        }
        // Pressed again: how far the gel has come back decides the force.
        ting.step(0.02, 0.01)
    };
    let (one, many) = (run(1), run(500));
    assert!((one - many).abs() < 0.01 * many, "{one} vs {many}");
}
