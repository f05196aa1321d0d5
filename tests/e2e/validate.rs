//! `gelrig validate`: every class of error names file, line, column and the fix; nothing
//! panics on bad input.

use std::process::Command;

use experiments::Diagnostic;

use crate::support::{gelrig, load_ok, load_text, protocol, root, shipped, shipped_text};

/// Replaces `from` (which must occur) in `text`.
fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture lacks {from:?}");
    text.replacen(from, to, 1)
}

/// 1-based line of the first line containing `token`.
fn line_of(text: &str, token: &str) -> usize {
    text.lines()
        .position(|l| l.contains(token))
        .map(|i| i + 1)
        .unwrap_or_else(|| panic!("no {token:?}"))
}

/// Loads `text` and returns the error whose message contains `needle`.
fn error_with(text: &str, needle: &str) -> Diagnostic {
    let dir = tempfile::tempdir().unwrap();
    let diags = match load_text(dir.path(), text) {
        Ok(_) => panic!("expected an error containing {needle:?}, but the protocol loads"),
        Err(d) => d,
    };
    let d = diags
        .iter()
        .find(|d| d.is_error() && d.message.contains(needle))
        .unwrap_or_else(|| panic!("no error containing {needle:?} in {diags:#?}"))
        .clone();
    assert!(d.line >= 1 && d.column >= 1, "{d:?} has no location");
    assert!(!d.fix.is_empty(), "{d:?} has no fix");
    assert!(d.file.ends_with("protocol.yaml"), "{d:?}");
    d
}

#[test]
fn every_shipped_protocol_validates() {
    for name in shipped() {
        let loaded = load_ok(&protocol(&name));
        assert!(loaded.compiled.steps > 0, "{name}");
        assert!(loaded.warnings.is_empty(), "{name}: {:?}", loaded.warnings);
    }
}

#[test]
fn yaml_syntax_error_is_located() {
    let text = edit(
        &shipped_text("box-normal-flat"),
        "  - home: {axes: [normal]}",
        "  - home: {axes: [normal]",
    );
    let dir = tempfile::tempdir().unwrap();
    let diags = load_text(dir.path(), &text).unwrap_err();
    assert_eq!(diags.len(), 1, "{diags:#?}");
    let d = &diags[0];
    let broken = line_of(&text, "  - home: {axes: [normal]");
    assert!(d.line >= broken && d.line <= broken + 1, "{d}");
    assert!(d.fix.contains("YAML"), "{d}");
}

#[test]
fn unknown_key_suggests_the_right_one() {
    let text = edit(
        &shipped_text("box-normal-flat"),
        "      speed: 0.5 mm/s",
        "      sped: 0.5 mm/s",
    );
    let d = error_with(&text, "unknown field `sped`");
    assert_eq!(d.line, line_of(&text, "sped:"), "{d}");
    assert_eq!(d.fix, "did you mean `speed`?");
    // Inside an internally tagged section the error moves to the key too.
    let text = edit(
        &shipped_text("box-normal-flat"),
        "diameter: 9.5 mm",
        "diamter: 9.5 mm",
    );
    let d = error_with(&text, "unknown field `diamter`");
    assert_eq!(d.line, line_of(&text, "diamter"), "{d}");
    assert_eq!(d.fix, "did you mean `diameter`?");
    // An unknown block keyword.
    let text = edit(
        &shipped_text("box-normal-flat"),
        "  - tare: {duration: 2 s}",
        "  - taer: {duration: 2 s}",
    );
    let d = error_with(&text, "unknown variant `taer`");
    assert_eq!(d.line, line_of(&text, "taer"), "{d}");
    assert_eq!(d.fix, "did you mean `tare`?");
}

#[test]
fn missing_key_names_the_key() {
    let text = edit(
        &shipped_text("box-normal-flat"),
        "      settle: {fixed: 180 s}\n",
        "",
    );
    let d = error_with(&text, "missing field `settle`");
    let block = line_of(&text, "- stepped:");
    assert!(d.line >= block && d.line <= block + 2, "{d}");
    assert!(d.fix.contains("add `settle:`"), "{d}");
}

#[test]
fn bad_units_are_named_with_the_accepted_ones() {
    let base = shipped_text("box-normal-flat");
    let text = edit(&base, "      step: 2 %", "      step: 2 kg");
    let d = error_with(&text, "`2 kg` is a mass");
    assert_eq!(
        (d.line, d.column),
        (line_of(&text, "step: 2 kg"), 13),
        "{d}"
    );
    assert!(d.message.contains("mm") && d.message.contains("deg"), "{d}");
    let text = edit(&base, "      step: 2 %", "      step: 2 mmm");
    let d = error_with(&text, "unknown unit `mmm`");
    assert_eq!(d.fix, "did you mean `mm`?");
    let text = edit(&base, "      step: 2 %", "      step: 2");
    let d = error_with(&text, "has no unit");
    assert!(d.fix.contains("`2 mm`"), "{d}");
    // A unit of the right kind of thing but the wrong axis: degrees on the normal axis.
    let text = edit(&base, "      step: 2 %", "      step: 2 deg");
    let d = error_with(&text, "does not fit the normal axis");
    assert_eq!(d.line, line_of(&text, "step: 2 deg"), "{d}");
    // A speed written as a length.
    let text = edit(&base, "      speed: 0.5 mm/s", "      speed: 0.5 mm");
    let d = error_with(&text, "`0.5 mm` is a length");
    assert!(d.fix.contains("mm/s"), "{d}");
}

#[test]
fn depth_at_or_beyond_thickness_is_refused() {
    let text = edit(
        &shipped_text("box-normal-flat"),
        "      to: 20 %",
        "      to: 100 %",
    );
    let d = error_with(&text, "reaches the elastomer thickness 4.2 mm");
    assert_eq!((d.line, d.column), (line_of(&text, "to: 100 %"), 11), "{d}");
    let text = edit(
        &shipped_text("box-normal-sphere"),
        "      to: 2.0 mm",
        "      to: 4.5 mm",
    );
    let d = error_with(&text, "depth 4.5 mm reaches the elastomer thickness");
    assert_eq!(d.line, line_of(&text, "to: 4.5 mm"), "{d}");
}

#[test]
fn target_beyond_travel_is_refused() {
    let text = edit(
        &shipped_text("box-shear-flat"),
        "      to: 1 mm",
        "      to: 14 mm",
    );
    let d = error_with(&text, "beyond its travel [-12.5, 12.5] mm");
    assert_eq!(d.line, line_of(&text, "to: 14 mm"), "{d}");
    // The contact point is unknown before the run: an approach that may end at 24 mm leaves
    // no room for a 2 mm move.
    let text = edit(
        &shipped_text("box-normal-flat"),
        "from: 9 mm",
        "from: 22.5 mm",
    );
    let d = error_with(&text, "beyond its travel [0, 25] mm");
    assert_eq!(d.line, line_of(&text, "to: 20 %"), "{d}");
}

#[test]
fn step_below_stage_resolution_is_refused() {
    let text = edit(
        &shipped_text("box-normal-flat"),
        "      step: 2 %",
        "      step: 0.001 mm",
    );
    let d = error_with(&text, "below the normal stage's resolution 0.002 mm");
    assert_eq!(d.line, line_of(&text, "step: 0.001 mm"), "{d}");
    assert!(d.fix.contains("0.002 mm"), "{d}");
}

#[test]
fn limits_above_the_nano17_range_are_refused() {
    let base = shipped_text("box-normal-flat");
    for (from, to, needle) in [
        (
            "max_fz: 40 N",
            "max_fz: 80 N",
            "above the ATI Nano17's axial range 70 N",
        ),
        (
            "max_fxy: 10 N",
            "max_fxy: 55 N",
            "above the ATI Nano17's tangential range 50 N",
        ),
        (
            "max_tz: 100 N·mm",
            "max_tz: 0.6 N·m",
            "above the ATI Nano17's torque range 500 N·mm",
        ),
    ] {
        let text = edit(&base, from, to);
        let d = error_with(&text, needle);
        assert_eq!(d.line, line_of(&text, to), "{d}");
    }
}

#[test]
fn a_role_missing_from_the_rig_is_named_with_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let rig_text = std::fs::read_to_string(root().join("protocols/rigs/sim.yaml")).unwrap();
    let rig_text: String = rig_text
        .lines()
        .filter(|l| !l.trim_start().starts_with("shear:"))
        .map(|l| format!("{l}\n"))
        .collect();
    let rig_path = dir.path().join("no-shear.yaml");
    std::fs::write(&rig_path, rig_text).unwrap();
    let text = shipped_text("box-shear-flat");
    let p = dir.path().join("protocol.yaml");
    std::fs::write(&p, &text).unwrap();
    let diags = experiments::load::load(&p, Some(&rig_path)).unwrap_err();
    let d = diags
        .iter()
        .find(|d| d.message.contains("binds no `shear` axis"))
        .unwrap_or_else(|| panic!("{diags:#?}"));
    assert_eq!(d.line, line_of(&text, "axes: [normal, shear]"), "{d}");
    assert!(d.fix.contains("add `axes.shear` to the rig file"), "{d}");
    // Reported once, not for every block that uses the axis.
    assert_eq!(
        diags
            .iter()
            .filter(|d| d.message.contains("`shear` axis"))
            .count(),
        1
    );
    // Frames with a rig that has no camera.
    let rig_text = std::fs::read_to_string(root().join("protocols/rigs/sim.yaml")).unwrap();
    let rig_text: String = rig_text
        .lines()
        .filter(|l| !l.starts_with("camera:"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&rig_path, rig_text).unwrap();
    let p = protocol("box-normal-flat");
    let diags = experiments::load::load(&p, Some(&rig_path)).unwrap_err();
    assert!(
        diags.iter().any(|d| d.message.contains("needs a camera")),
        "{diags:#?}"
    );
}

#[test]
fn semantic_checks_catch_common_mistakes() {
    let base = shipped_text("box-normal-flat");
    // Moving before homing.
    let text = edit(&base, "  - home: {axes: [normal]}\n", "");
    error_with(&text, "before any `home` block homes it");
    // A force window longer than the settle.
    let text = edit(&base, "force_window: 10 s", "force_window: 200 s");
    error_with(&text, "shorter than the capture's force window");
    // A zero window (or `-0 s`) would make one sample a step's quasistatic value.
    for zero in ["0 s", "-0 s", "0 ms"] {
        let text = edit(
            &base,
            "force_window: 10 s",
            &format!("force_window: {zero}"),
        );
        let d = error_with(&text, "makes a single sample the step's quasistatic value");
        assert!(d.fix.contains("force_window: 10 s"), "{d}");
    }
    // A move's capture may ask for the latest reading.
    let dir = tempfile::tempdir().unwrap();
    let latest = format!(
        "{}  - move: {{axis: normal, to: 0 mm, speed: 1 mm/s, capture: {{force_window: 0 s, frames: 1}}}}\n",
        base.trim_end_matches('\n').to_owned() + "\n"
    );
    if let Err(d) = load_text(dir.path(), &latest) {
        panic!("a move capturing the latest reading is refused: {d:?}");
    }
    // A span that is not a whole number of steps.
    let text = edit(&base, "      step: 2 %", "      step: 3 %");
    let d = error_with(&text, "not a whole number of steps");
    // The two nearest whole numbers of steps, in the unit `to` was written in.
    assert!(d.fix.contains("choose `to` = 18 % or 21 %"), "{d}");
    // A pressing axis without a retract position.
    let text = edit(&base, "  retract: {normal: 0 mm}\n", "");
    error_with(&text, "has no retract position");
    // Speed above the stage's maximum.
    let text = edit(&base, "speed: 0.5 mm/s", "speed: 5 mm/s");
    error_with(&text, "above the normal axis's maximum 2 mm/s");
}

#[test]
fn malformed_input_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        "",
        "\u{0}\u{1}\u{2}",
        "name: [",
        "sequence: 5",
        "- just\n- a list",
        "name: x\nsensor: {kind: box}\nindenter: {shape: sphere}\nsafety: {}\nsequence: []",
        "name: x\n\tsensor: tab",
        "name: x\nsensor: {kind: box, elastomer: {width: -1 mm, length: 1 mm, thickness: 0 mm}}\nindenter: {shape: sphere, diameter: 1e308 mm}\nsafety: {max_fz: 1 N, max_fxy: 1 N, max_tz: 1 N·mm}\nsequence: [{repeat: {times: 0, blocks: []}}]",
        &"a: ".repeat(2000),
        &format!("{}1{}", "[".repeat(300), "]".repeat(300)),
    ];
    for text in cases {
        let result = load_text(dir.path(), text);
        let diags = result
            .err()
            .unwrap_or_else(|| panic!("{text:?} should not load"));
        assert!(diags.iter().any(|d| d.is_error()), "{text:?}");
    }
    let missing = experiments::load::load(&dir.path().join("nope.yaml"), None).unwrap_err();
    assert!(
        missing[0].message.contains("cannot read the protocol"),
        "{missing:?}"
    );
}

#[test]
fn cli_reports_file_line_column_and_fix_with_exit_code_2() {
    let dir = tempfile::tempdir().unwrap();
    let text = edit(
        &shipped_text("box-normal-flat"),
        "      to: 20 %",
        "      to: 100 %",
    );
    let p = dir.path().join("bad.yaml");
    std::fs::write(&p, &text).unwrap();
    let out = Command::new(gelrig())
        .args(["validate"])
        .arg(&p)
        .arg("--rig")
        .arg(root().join("protocols/rigs/sim.yaml"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    let expected = format!(
        "{}:{}:11: error: depth 4.2 mm",
        p.display(),
        line_of(&text, "to: 100 %")
    );
    assert!(err.contains(&expected), "{err}");
    assert!(err.contains("fix: keep the depth below 4.2 mm"), "{err}");
    assert!(
        err.contains("to: 100 %") && err.contains('^'),
        "shows the line: {err}"
    );
    let ok = Command::new(gelrig())
        .args(["validate"])
        .arg(protocol("box-normal-flat"))
        .output()
        .unwrap();
    assert_eq!(
        ok.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
}

#[test]
fn schema_is_generated_from_the_parser_types() {
    let out = Command::new(gelrig()).arg("schema").output().unwrap();
    assert!(out.status.success());
    let schema: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let text = schema.to_string();
    for key in [
        "sequence",
        "stepped",
        "approach",
        "settle",
        "force_window",
        "max_fz",
        "retract",
        "flat_ellipse",
        "repeat",
    ] {
        assert!(text.contains(key), "schema lacks {key}");
    }
    assert_eq!(
        schema["additionalProperties"],
        serde_json::Value::Bool(false)
    );
    let out = Command::new(gelrig())
        .args(["schema", "--rig"])
        .output()
        .unwrap();
    let rig: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(rig.to_string().contains("normal_contact"));
}

/// Errors inside `indenter:` point at the value, not at the file's first line.
#[test]
fn errors_inside_the_indenter_point_at_the_value() {
    // With its opening comment block (the shipped file) and without it: the comments once
    // moved these errors to the document's first line.
    let shipped = shipped_text("portable-normal");
    assert!(shipped.starts_with('#'));
    let bare: String = shipped
        .lines()
        .skip_while(|l| l.starts_with('#'))
        .map(|l| format!("{l}\n"))
        .collect();
    for base in [shipped, bare] {
        let text = edit(&base, "diameter: 12.5 mm}", "diameter: 12.5}");
        let d = error_with(&text, "has no unit");
        let line = line_of(&text, "indenter:");
        assert_eq!(
            (d.line, d.column),
            (
                line,
                text.lines().nth(line - 1).unwrap().find("12.5").unwrap() + 1
            ),
            "{d}"
        );
        let text = edit(
            &base,
            "{shape: flat_circle, diameter: 12.5 mm}",
            "{shape: flat_circle}",
        );
        let d = error_with(&text, "missing field `diameter`");
        assert_eq!(d.line, line, "{d}");
        assert!(d.column > 1, "{d}");
    }
}

/// A copied protocol whose `rig:` no longer resolves: the resolved path, at the `rig:` line,
/// with the simulated rig to pass instead; shipped protocols run and list by name.
#[test]
fn a_rig_that_does_not_resolve_and_protocols_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("mine.yaml");
    std::fs::write(&copy, shipped_text("box-normal-flat")).unwrap();
    let o = Command::new(gelrig())
        .arg("validate")
        .arg(&copy)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    let resolved = dir.path().join("rigs/sim.yaml");
    assert!(
        e.contains(&format!(
            "mine.yaml:{}:6",
            line_of(&shipped_text("box-normal-flat"), "rig:")
        )),
        "{e}"
    );
    assert!(
        e.contains(&resolved.display().to_string()) && e.contains("does not exist"),
        "{e}"
    );
    assert!(e.contains("--rig") && e.contains("rigs/sim.yaml"), "{e}");
    // By name from a folder without such a file.
    let o = Command::new(gelrig())
        .current_dir(dir.path())
        .args(["validate", "box-normal-flat"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("using the shipped protocol"));
    // Listed.
    let o = Command::new(gelrig()).arg("protocols").output().unwrap();
    assert!(o.status.success());
    let list = String::from_utf8_lossy(&o.stdout);
    for name in shipped() {
        assert!(list.contains(&name), "{name} not in {list}");
    }
    assert!(
        list.contains("Normal indentation of the box sensor with a 9.5 mm flat circular punch"),
        "{list}"
    );
}

#[test]
fn an_adaptive_settle_is_checked_where_it_is_written() {
    let base = shipped_text("box-normal-flat");
    let with = |rule: &str| {
        edit(
            &base,
            "settle: {fixed: 180 s}",
            &format!("settle: {{{rule}}}"),
        )
    };
    let line = line_of(&base, "settle: {fixed");
    let d = error_with(
        &with("adaptive: {tolerance: 0 %, min: 20 s, max: 300 s}"),
        "cannot be met",
    );
    assert_eq!(d.line, line);
    let d = error_with(
        &with("adaptive: {tolerance: 1, min: 20 s, max: 300 s}"),
        "not a percentage",
    );
    assert_eq!(d.line, line);
    error_with(
        &with("adaptive: {tolerance: 1 %, min: 5 s, max: 300 s}"),
        "shorter than the capture's force window",
    );
    error_with(
        &with("adaptive: {tolerance: 1 %, min: 60 s, max: 30 s}"),
        "is below min",
    );
    // A good one loads, and the plan says what it waits for.
    let dir = tempfile::tempdir().unwrap();
    let loaded = load_text(
        dir.path(),
        &with("adaptive: {tolerance: 1 %, min: 20 s, max: 300 s}"),
    )
    .unwrap();
    let plan = loaded.plan.clone();
    let text = format!("{plan:?}");
    assert!(plan.duration_s.max > plan.duration_s.min, "{text}");
}

/// Every shipped protocol states, where it is read, the values the thesis does not give
/// and a dry run assumes — the gel's modulus, Poisson's ratio, friction and relaxation
/// exactly as the simulated bench uses them, and the preloads chosen to meet the thesis's
/// slip points — so the comment cannot drift from what runs.
#[test]
fn every_shipped_protocol_states_the_values_it_assumes() {
    for name in shipped() {
        let text = shipped_text(&name);
        assert!(
            text.starts_with("# Assumed values"),
            "{name}: no \"# Assumed values\" block at the top"
        );
        let loaded = load_ok(&protocol(&name));
        let spec = experiments::protocol::plant_spec(&loaded.protocol, &loaded.compiled).unwrap();
        let m = &spec.contact.material;
        let terms: Vec<String> = m
            .prony
            .iter()
            .map(|t| format!("{}·e^(−t/{} s)", t.weight, t.tau_s))
            .collect();
        let gel = format!(
            "E∞ {} MPa, ν {}, μ {} static / {:.2} sliding, relaxation g(t) = 1 + {}",
            m.youngs_modulus_mpa,
            m.poisson_ratio,
            m.friction,
            spec.kinetic_friction,
            terms.join(" + ")
        );
        assert!(
            text.contains(&gel),
            "{name}: the gel is not stated as run: {gel}"
        );
        // A preload the thesis does not give is stated with why it was chosen.
        for assumed in ["box-shear-flat", "box-rotation", "portable-rotation"] {
            if name == assumed {
                assert!(
                    text.contains("# - the preload"),
                    "{name}: its preload is not stated"
                );
            }
        }
        if name.starts_with("lifting-can") {
            assert!(
                text.contains("# - the jig"),
                "{name}: the jig is not stated"
            );
        }
    }
}

/// The README says how many protocols ship; the folder decides.
#[test]
fn the_readme_counts_the_shipped_protocols() {
    const WORDS: [&str; 21] = [
        "Zero",
        "One",
        "Two",
        "Three",
        "Four",
        "Five",
        "Six",
        "Seven",
        "Eight",
        "Nine",
        "Ten",
        "Eleven",
        "Twelve",
        "Thirteen",
        "Fourteen",
        "Fifteen",
        "Sixteen",
        "Seventeen",
        "Eighteen",
        "Nineteen",
        "Twenty",
    ];
    let n = shipped().len();
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let word = WORDS.get(n).copied().unwrap_or("Many");
    assert!(
        readme.contains(&format!("{word} protocols ship")),
        "protocols/ holds {n} protocols; the README should say \"{word} protocols ship\""
    );
}
