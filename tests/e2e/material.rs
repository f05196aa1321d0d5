//! The user's own gel: `gelrig fit-material` on dry runs of a gel whose values it is not
//! told, the fitted file taken by a protocol (`material: {from: …}`) so the dry run
//! reproduces the source bench, the shipped example, and the refusals.

use std::path::{Path, PathBuf};

use sensing::material::MaterialFile;

use crate::support::{
    csv_rows, dry_text as dry, gelrig, load_text, root, shared_dry_run, shipped_text,
};

/// The source gel: none of the presets' values.
const SOURCE: &str = "material: {youngs_modulus: 0.18 MPa, poisson_ratio: 0.49, friction: 0.35, \
                      kinetic_friction: 0.3, prony: [{weight: 0.25, tau: 2 s}, {weight: 0.15, \
                      tau: 20 s}]}";

fn with_sensor(name: &str, sensor: &str) -> String {
    let text = shipped_text(name);
    let edited = text.replace("sensor: {kind: portable}", sensor);
    assert_ne!(edited, text, "{name}'s sensor line changed");
    edited
}

fn within(got: f64, want: f64, rel: f64, what: &str) {
    assert!(
        (got / want - 1.0).abs() <= rel,
        "{what}: fitted {got}, source {want} ({:+.2} %, allowed {:.0} %)",
        100.0 * (got / want - 1.0),
        100.0 * rel
    );
}

#[test]
fn fit_material_recovers_a_gel_it_was_not_told_and_its_dry_run_reproduces_the_bench() {
    let tmp = tempfile::tempdir().unwrap();
    let sensor = format!("sensor: {{kind: portable, {SOURCE}}}");
    let normal = dry(
        &tmp.path().join("normal"),
        &with_sensor("portable-normal", &sensor),
        7,
    );
    // Sheared to 1 mm, past the shipped run's 0.6 mm: pressed with friction this gel's
    // 0.1 mm preload holds 6.7 N, so its 0.35 slides at 2.4 N, beyond the 2.1 N that 0.6 mm
    // reaches (frictionless pressing held 4.9 N and slid within 0.6 mm). The friction fit
    // needs a run that reaches gross slip.
    let shear_text = with_sensor("portable-shear", &sensor);
    let longer = shear_text.replace("      to: 0.6 mm\n", "      to: 1.0 mm\n");
    assert_ne!(longer, shear_text, "portable-shear's end changed");
    let shear = dry(&tmp.path().join("shear"), &longer, 7);
    let out = tmp.path().join("material.yaml");
    let o = std::process::Command::new(gelrig())
        .arg("fit-material")
        .args([&normal, &shear])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("E∞ ="), "{stdout}");
    let fitted = MaterialFile::read(&out).unwrap();
    let m = &fitted.material;
    // The targets: E∞ and the Prony weights within 2 %, the time constants within 5 %.
    within(m.youngs_modulus.mpa(), 0.18, 0.02, "E∞");
    assert_eq!(m.prony.len(), 2, "{m:?}");
    for (t, (w, tau)) in m.prony.iter().zip([(0.25, 2.0), (0.15, 20.0)]) {
        within(t.weight, w, 0.02, "a Prony weight");
        within(t.tau.s(), tau, 0.05, "a time constant");
    }
    // ν from the marker field around the punch (the runs record frames), with its ±.
    assert!(
        (m.poisson_ratio - 0.49).abs() < 0.001,
        "ν {} (source 0.49)",
        m.poisson_ratio
    );
    assert!(fitted.uncertainty.poisson_ratio.is_some_and(|sd| sd > 0.0));
    assert!(stdout.contains("from the marker field"), "{stdout}");
    // Friction: the source's within the bracket the steps give, the sliding one within 5 %.
    let sd = fitted.uncertainty.friction.expect("the shear run slipped");
    assert!(
        (m.friction - 0.35).abs() <= sd + 0.005,
        "μ {} ± {sd}, source 0.35",
        m.friction
    );
    within(m.kinetic_friction.unwrap(), 0.3, 0.05, "sliding μ");
    // Every fitted value carries an uncertainty, and the fit says how well it follows.
    assert!(fitted.uncertainty.youngs_modulus_mpa > 0.0);
    let pressing: Vec<_> = fitted
        .fitted_on
        .iter()
        .filter(|r| r.used_for == "pressing")
        .collect();
    assert_eq!(pressing.len(), 2, "{:?}", fitted.fitted_on);
    for r in &pressing {
        assert!(r.residual_rms_n.unwrap() < 0.05, "{r:?}");
        // The approach stops at 0.1 N: the surface lies a little before the origin.
        let d0 = r.contact_offset_mm.unwrap();
        assert!(d0 < 0.0 && d0 > -0.01, "{r:?}");
    }
    // The fitted gel, taken by a protocol, reproduces the source run's quasistatic steps
    // within the force sensor's noise (same seed: same noise draws).
    let refit_dir = tmp.path().join("refit");
    std::fs::create_dir_all(&refit_dir).unwrap();
    std::fs::copy(&out, refit_dir.join("gel.yaml")).unwrap();
    let refit = dry(
        &refit_dir,
        &with_sensor(
            "portable-normal",
            "sensor: {kind: portable, material: {from: gel.yaml}}",
        ),
        7,
    );
    let (src, again) = (
        csv_rows(&normal.join("steps.csv")),
        csv_rows(&refit.join("steps.csv")),
    );
    assert_eq!(src.len(), again.len());
    for (a, b) in src.iter().zip(&again) {
        let num = |r: &std::collections::BTreeMap<String, String>, k: &str| -> f64 {
            r[k].parse().unwrap()
        };
        let noise = num(a, "window_std");
        assert!(
            (num(a, "fz_n") - num(b, "fz_n")).abs() < noise,
            "step {}: {} N from the source gel, {} N from the fitted one (noise {noise} N)",
            a["step"],
            a["fz_n"],
            b["fz_n"]
        );
    }
    // The run records the values, not the path: its protocol.yaml reads back alone.
    let kept = std::fs::read_to_string(refit.join("protocol.yaml")).unwrap();
    assert!(
        !kept.contains("gel.yaml") && kept.contains("youngs_modulus"),
        "{kept}"
    );
}

#[test]
fn the_shipped_fitted_material_recovers_the_gel_it_came_from() {
    let path = root().join("protocols/materials/portable-fitted.yaml");
    let fitted = MaterialFile::read(&path).unwrap();
    let m = &fitted.material;
    // Fitted (docs/explanation/material-fit.md) on dry runs of the SOURCE gel above.
    within(m.youngs_modulus.mpa(), 0.18, 0.02, "E∞");
    for (t, (w, tau)) in m.prony.iter().zip([(0.25, 2.0), (0.15, 20.0)]) {
        within(t.weight, w, 0.02, "a Prony weight");
        within(t.tau.s(), tau, 0.05, "a time constant");
    }
    // And a protocol takes it.
    let tmp = tempfile::tempdir().unwrap();
    let text = with_sensor(
        "portable-normal",
        &format!(
            "sensor: {{kind: portable, material: {{from: {}}}}}",
            path.display()
        ),
    );
    let loaded = load_text(tmp.path(), &text).unwrap_or_else(|d| panic!("{}", d[0]));
    let spec = experiments::protocol::plant_spec(&loaded.protocol, &loaded.compiled).unwrap();
    assert_eq!(
        spec.contact.material.youngs_modulus_mpa,
        m.youngs_modulus.mpa()
    );
}

#[test]
fn a_material_from_a_file_that_is_not_one_is_refused_at_its_line() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("notes.yaml"), "just: notes\n").unwrap();
    for (from, says) in [
        ("missing.yaml", "No such file"),
        ("notes.yaml", "not a material file"),
    ] {
        let text = with_sensor(
            "portable-normal",
            &format!("sensor: {{kind: portable, material: {{from: {from}}}}}"),
        );
        let e = load_text(tmp.path(), &text).unwrap_err();
        let shown = e[0].to_string();
        assert!(
            shown.contains(says) && shown.contains("fit-material"),
            "{shown}"
        );
    }
    // `from:` stands alone.
    let text = with_sensor(
        "portable-normal",
        "sensor: {kind: portable, material: {from: gel.yaml, friction: 0.3}}",
    );
    let e = load_text(tmp.path(), &text).unwrap_err();
    assert!(
        e[0].to_string().contains("unknown field `friction`"),
        "{}",
        e[0]
    );
    // One gel per fit; and a grasp's grip position is not the gel's depth (the sponge is in
    // series), so a grasp run gives nothing to fit.
    for (runs, says) in [
        (
            vec![
                shared_dry_run("portable-normal"),
                shared_dry_run("box-normal-flat"),
            ],
            "one gel per fit",
        ),
        (
            vec![shared_dry_run("lifting-can-slip")],
            "none of the runs presses the gel",
        ),
    ] {
        let o = std::process::Command::new(gelrig())
            .arg("fit-material")
            .args(&runs)
            .arg("--out")
            .arg(tmp.path().join("m.yaml"))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says) && err.contains("fix:"), "{err}");
    }
    // No run to fit: a clear refusal.
    let o = std::process::Command::new(gelrig())
        .args(["fit-material", "/nonexistent/run", "--out"])
        .arg(tmp.path().join("m.yaml"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("fix:"), "{err}");
}

/// Poisson's ratio from two flat punch sizes on one gel, recorded without a camera: the box's
/// 9.5 mm punch pressed in steps and its 12.68 mm punch's preload, on a gel of ν 0.47 whose
/// run directories claim 0.49
/// (their `protocol.yaml` edited after the runs), so the fit cannot take ν from them. One
/// punch size alone holds ν at what the runs claim, and says why; so does a punch with a
/// sphere, whose law changes its shape with ν (counted, it told 0.483 for a gel of 0.49).
#[test]
fn two_flat_punch_sizes_tell_poissons_ratio_and_one_does_not() {
    let tmp = tempfile::tempdir().unwrap();
    let gel = "sensor: {kind: box, material: {youngs_modulus: 0.3 MPa, poisson_ratio: 0.47, \
               friction: 0.6, prony: [{weight: 0.3, tau: 3 s}]}}";
    // Shorter holds and fewer shear steps than the shipped runs: the fit needs the presses.
    // Recorded without a camera, so the forces alone tell ν (with frames the field around
    // the punch would: `a_flat_punchs_marker_field_tells_poissons_ratio_from_one_run`).
    let edit = |name: &str| {
        let text = shipped_text(name)
            .replace("sensor: {kind: box}", gel)
            .replace("settle: {fixed: 180 s}", "settle: {fixed: 40 s}")
            .replace("to: 1 mm", "to: 0.2 mm")
            .replace(", frames: 1}", "}")
            .replace(", reference_frames: 1}", "}");
        assert!(!text.contains("frames"), "{name}");
        assert!(text.contains("poisson_ratio: 0.47"), "{name}");
        text
    };
    let runs: Vec<PathBuf> = ["box-normal-flat", "box-shear-flat", "box-normal-sphere"]
        .iter()
        .map(|n| dry(&tmp.path().join(n), &edit(n), 5))
        .collect();
    for r in &runs {
        let p = r.join("protocol.yaml");
        let text = std::fs::read_to_string(&p).unwrap();
        std::fs::write(
            &p,
            text.replace("poisson_ratio: 0.47", "poisson_ratio: 0.49"),
        )
        .unwrap();
    }
    let fit = fit_material;
    let (both, stdout) = fit(&runs[..2], &tmp.path().join("both.yaml"));
    eprintln!("{stdout}");
    let m = &both.material;
    assert!(
        (m.poisson_ratio - 0.47).abs() < 0.005,
        "ν {} (source 0.47, the runs claim 0.49)",
        m.poisson_ratio
    );
    let sd = both
        .uncertainty
        .poisson_ratio
        .expect("ν fitted, with its uncertainty");
    assert!(sd > 0.0 && sd < 0.02, "ν ± {sd}");
    within(m.youngs_modulus.mpa(), 0.3, 0.02, "E∞");
    assert!(stdout.contains("ν = 0.4"), "{stdout}");
    assert!(
        both.provenance.iter().any(|p| p.contains("flat punches")),
        "{:?}",
        both.provenance
    );
    // One punch size: ν held at the claimed 0.49, and E∞ then reads the gel's E∞·κ(0.47)/κ(0.49)
    // — what a force record of one indenter can say.
    let (one, stdout) = fit(&runs[..1], &tmp.path().join("one.yaml"));
    assert_eq!(one.material.poisson_ratio, 0.49, "{stdout}");
    assert!(one.uncertainty.poisson_ratio.is_none());
    assert!(stdout.contains("ν held at 0.49"), "{stdout}");
    assert!(
        one.provenance
            .iter()
            .any(|p| p.contains("two flat punch sizes")),
        "{:?}",
        one.provenance
    );
    // The fitted ν's uncertainty reaches E∞'s: wider than a fit at a held ν.
    assert!(
        both.uncertainty.youngs_modulus_mpa > 10.0 * one.uncertainty.youngs_modulus_mpa,
        "E∞ ± {} (ν fitted) against ± {} (held)",
        both.uncertainty.youngs_modulus_mpa,
        one.uncertainty.youngs_modulus_mpa
    );
    // A file with nothing of version 2 in it is written as version 1.
    assert_eq!((both.version, one.version), (2, 1));
    // A flat punch with a sphere: ν held, and why.
    let (curved, stdout) = fit(
        &[runs[0].clone(), runs[2].clone()],
        &tmp.path().join("c.yaml"),
    );
    assert_eq!(curved.material.poisson_ratio, 0.49, "{stdout}");
    assert!(
        curved
            .provenance
            .iter()
            .any(|p| p.contains("only flat circular punches")),
        "{:?}",
        curved.provenance
    );
}

/// Poisson's ratio from the marker field around one flat punch: the field is set by the
/// depth, not the modulus, so one `box-normal-flat` run with frames tells ν where its force
/// record cannot — on a gel of ν 0.47 whose run directory claims 0.49. With the 12.68 mm
/// punch's run beside it the two sizes' forces tell ν too, and the file gives theirs as the
/// field's check.
#[test]
fn a_flat_punchs_marker_field_tells_poissons_ratio_from_one_run() {
    let tmp = tempfile::tempdir().unwrap();
    let gel = "sensor: {kind: box, material: {youngs_modulus: 0.3 MPa, poisson_ratio: 0.47, \
               friction: 0.6, prony: [{weight: 0.3, tau: 3 s}]}}";
    let runs: Vec<PathBuf> = ["box-normal-flat", "box-shear-flat"]
        .iter()
        .map(|n| {
            let text = shipped_text(n)
                .replace("sensor: {kind: box}", gel)
                .replace("settle: {fixed: 180 s}", "settle: {fixed: 40 s}")
                .replace("to: 1 mm", "to: 0.2 mm");
            assert!(text.contains("frames: 1"), "{n}");
            let dir = dry(&tmp.path().join(n), &text, 6);
            let p = dir.join("protocol.yaml");
            let claimed = std::fs::read_to_string(&p)
                .unwrap()
                .replace("poisson_ratio: 0.47", "poisson_ratio: 0.49");
            std::fs::write(&p, claimed).unwrap();
            dir
        })
        .collect();
    let fit = fit_material;
    let (one, stdout) = fit(&runs[..1], &tmp.path().join("one.yaml"));
    eprintln!("{stdout}");
    let m = &one.material;
    assert!(
        (m.poisson_ratio - 0.47).abs() < 5e-4,
        "ν {} (source 0.47, the run claims 0.49)",
        m.poisson_ratio
    );
    // The markers' noise and the fit's own floor (2e-4) in quadrature.
    let sd = one.uncertainty.poisson_ratio.expect("ν fitted, with its ±");
    assert!((2e-4..5e-4).contains(&sd), "ν ± {sd}");
    // E∞ no longer absorbs the ν the force record cannot see (held at 0.49 it reads
    // E∞·κ(0.47)/κ(0.49), about 10 % low).
    within(m.youngs_modulus.mpa(), 0.3, 0.005, "E∞");
    assert!(stdout.contains("from the marker field"), "{stdout}");
    assert!(
        one.provenance.iter().any(|p| p.contains("marker field")),
        "{:?}",
        one.provenance
    );
    assert_eq!(one.version, 2);
    // Both punch sizes: still the field's ν, the forces' beside it as a check.
    let (both, stdout) = fit(&runs, &tmp.path().join("both.yaml"));
    let nu = both.material.poisson_ratio;
    assert!((nu - 0.47).abs() < 5e-4, "{stdout}");
    let check = both
        .provenance
        .iter()
        .find(|p| p.starts_with("poisson_ratio check"))
        .unwrap_or_else(|| panic!("{:?}", both.provenance));
    let forces: f64 = check
        .split("agree at ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{check}"));
    assert!((forces - 0.47).abs() < 0.005 && forces != nu, "{check}");
    // Frames that show no marker: ν held, and the field's reason given (one punch size's
    // forces cannot tell it either).
    let blind = tmp.path().join("blind");
    crate::support::copy_run_dir(&runs[0], &blind);
    let markers = std::fs::read_to_string(blind.join("markers.csv")).unwrap();
    let header = markers.lines().next().unwrap().to_string() + "\n";
    std::fs::write(blind.join("markers.csv"), header).unwrap();
    let (held, stdout) = fit(&[blind], &tmp.path().join("held.yaml"));
    assert_eq!(held.material.poisson_ratio, 0.49, "{stdout}");
    assert!(
        held.provenance
            .iter()
            .any(|p| p.contains("the field:") && p.contains("tracked frame")),
        "{:?}",
        held.provenance
    );
}

/// A bench states its contact model in its rig file's `contact:` section, and
/// `fit-material` fits with it: the same stuck run, its rig file saying the faces slide
/// (`contact: {pressing_friction: false}`), reads E∞ high — the stuck face's extra force taken
/// for a stiffer gel (BENCHMARKS.md: +2.8 % on a gel of 0.3 MPa, ν 0.47) — and the file's
/// provenance names each model. A
/// model stated twice, differently, is refused where it is written.
#[test]
fn fit_material_fits_with_the_contact_model_the_rig_file_states() {
    let tmp = tempfile::tempdir().unwrap();
    let src = shared_dry_run("box-normal-flat");
    let copy = |name: &str, edit: &dyn Fn(String) -> String| {
        let dir = tmp.path().join(name);
        crate::support::copy_run_dir(&src, &dir);
        let rig = dir.join("rig.yaml");
        let text = std::fs::read_to_string(&rig).unwrap();
        let edited = edit(text.clone());
        assert_ne!(edited, text, "{name}: the rig file was not edited");
        std::fs::write(&rig, edited).unwrap();
        dir
    };
    let stuck = copy("stuck", &|t| t + "contact: {pressing_friction: true}\n");
    let sliding = copy("sliding", &|t| t + "contact: {pressing_friction: false}\n");
    let (a, _) = fit_material(&[stuck], &tmp.path().join("stuck.yaml"));
    let (b, _) = fit_material(&[sliding], &tmp.path().join("sliding.yaml"));
    let (ea, eb) = (
        a.material.youngs_modulus.mpa(),
        b.material.youngs_modulus.mpa(),
    );
    within(
        ea,
        0.25,
        0.005,
        "E∞ fitted with the bench's own (stuck) model",
    );
    assert!(
        (1.01..1.06).contains(&(eb / ea)),
        "fitted as sliding E∞ {eb} MPa, as stuck {ea} MPa"
    );
    let says = |m: &MaterialFile, what: &str| m.provenance.iter().any(|p| p.contains(what));
    assert!(says(&a, "stuck"), "{:?}", a.provenance);
    assert!(says(&b, "frictionless"), "{:?}", b.provenance);
    // Stated in `sim:` and `contact:`, differently: the run's rig does not load.
    let clash = copy("clash", &|t| {
        assert!(
            t.contains("sim:\n"),
            "the run's rig file has no `sim:` line to edit"
        );
        t.replace("sim:\n", "sim:\n  pressing_friction: true\n")
            + "contact: {pressing_friction: false}\n"
    });
    let o = std::process::Command::new(gelrig())
        .arg("fit-material")
        .arg(&clash)
        .arg("--out")
        .arg(tmp.path().join("clash.yaml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a contradicting rig file was fitted");
    assert!(
        err.contains("rig.yaml:")
            && err.contains("contradicts")
            && err.contains("once, under `contact:`"),
        "{err}"
    );
}

/// `gelrig fit-material RUNS --out OUT`, which must succeed: the file and the command's output.
fn fit_material(runs: &[PathBuf], out: &Path) -> (MaterialFile, String) {
    let o = std::process::Command::new(gelrig())
        .arg("fit-material")
        .args(runs)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (
        MaterialFile::read(out).unwrap(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
    )
}
