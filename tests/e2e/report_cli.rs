//! Reports a researcher can put in a paper and a CLI that meets newcomers halfway: how a run
//! ended, the thesis's field pictures, relaxation against time with honest trust flags, plot
//! hygiene, comparing runs, overrides from the command line, `runs`, `track` refusals and the
//! progress line's trials.

use std::path::{Path, PathBuf};
use std::process::Command;

use sha2::{Digest, Sha256};

use crate::support::{csv_rows, gelrig, shared_dry_run};

fn run_ok(args: &[&str], dir: &Path) -> (String, String) {
    let o = Command::new(gelrig())
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    );
    assert!(o.status.success(), "gelrig {args:?}: {err}");
    (out, err)
}

fn summary(report_dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(report_dir.join("summary.json")).unwrap())
        .unwrap()
}

/// A copy of a shared dry run, for tests that edit it.
fn copy_run(name: &str, to: &Path) -> PathBuf {
    let src = shared_dry_run(name);
    let dst = to.join(src.file_name().unwrap());
    let o = Command::new("cp")
        .arg("-r")
        .arg(&src)
        .arg(&dst)
        .status()
        .unwrap();
    assert!(o.success());
    let _ = std::fs::remove_dir_all(dst.join("report"));
    dst
}

/// Every text of an SVG: what `<text>` elements say.
fn svg_texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = t.split_once('>')?.1;
            Some(body.split("</text>").next()?.to_string())
        })
        .collect()
}

#[test]
fn the_report_says_how_the_run_ended() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = copy_run("box-normal-flat", tmp.path());
    let (out, _) = run_ok(&["report", dir.to_str().unwrap()], tmp.path());
    // The headline numbers on the terminal, not only section names.
    assert!(
        out.contains("run: completed, 20 of 20 steps, simulated"),
        "{out}"
    );
    assert!(
        out.contains("stiffness ") && out.contains("N/mm (R² "),
        "{out}"
    );
    assert!(out.contains("force from field: "), "{out}");
    let s = summary(&dir.join("report"));
    let run = &s["run"];
    assert_eq!(run["status"], "completed");
    assert_eq!(run["steps_planned"], 20);
    assert_eq!(run["simulated"], true);
    assert!(run["reason"].is_null());
    let hash = Sha256::digest(std::fs::read(dir.join("protocol.yaml")).unwrap());
    let hex: String = hash.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(run["protocol_sha256"], hex.as_str());
    let md = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    assert!(md.contains("## Run") && md.contains("**completed**") && md.contains(&hex[..12]));
    // Aborted with a reason, on real devices; and killed (running, no lock held).
    let manifest = std::fs::read_to_string(dir.join("run.yaml")).unwrap();
    let aborted = manifest
        .replace(
            "status: completed",
            "status: aborted\nreason: safety trip fz 41 N > 40 N",
        )
        .replace("identity: simulated", "identity: Zaber X-LSM");
    std::fs::write(dir.join("run.yaml"), aborted).unwrap();
    run_ok(&["report", dir.to_str().unwrap()], tmp.path());
    let run = summary(&dir.join("report"))["run"].clone();
    assert_eq!(run["status"], "aborted");
    assert_eq!(run["reason"], "safety trip fz 41 N > 40 N");
    assert_eq!(run["simulated"], false);
    std::fs::write(
        dir.join("run.yaml"),
        manifest.replace("status: completed", "status: running"),
    )
    .unwrap();
    run_ok(&["report", dir.to_str().unwrap()], tmp.path());
    assert_eq!(summary(&dir.join("report"))["run"]["status"], "interrupted");
}

#[test]
fn the_thesis_pictures_and_relaxation_are_in_the_report() {
    let tmp = tempfile::tempdir().unwrap();
    // Normal: field figures of chosen steps with labelled scales; relaxation per step.
    let dir = copy_run("box-normal-flat", tmp.path());
    run_ok(&["report", dir.to_str().unwrap()], tmp.path());
    let report = dir.join("report");
    let figures: Vec<PathBuf> = std::fs::read_dir(&report)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("field_normal_step"))
        })
        .collect();
    assert!((2..=3).contains(&figures.len()), "{figures:?}");
    for f in &figures {
        let texts = svg_texts(&std::fs::read_to_string(f).unwrap());
        let all = texts.join("\n");
        assert!(
            all.contains("step ") && all.contains("depth ") && all.contains("Fz "),
            "{all}"
        );
        assert!(all.contains("arrows ×"), "{all}");
        assert!(
            all.contains(" px = ") && all.contains(" mm"),
            "scale in px and mm: {all}"
        );
    }
    assert!(report.join("relaxation_normal.svg").is_file());
    let s = summary(&report);
    assert_eq!(s["relaxation"]["tau_identified"]["normal"], true);
    // Rotation: the twist field has a section of its own.
    let dir = copy_run("portable-rotation", tmp.path());
    run_ok(&["report", dir.to_str().unwrap()], tmp.path());
    let s = summary(&dir.join("report"));
    let sections: Vec<&str> = s["sections"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(
        sections
            .iter()
            .any(|t| t.starts_with("Displacement field — rotation")),
        "{sections:?}"
    );
    let twist = std::fs::read_dir(dir.join("report"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("field_rotation_step"))
        })
        .expect("a twist figure");
    let all = svg_texts(&std::fs::read_to_string(twist).unwrap()).join("\n");
    assert!(
        all.contains("twist field") && all.contains("angle ") && all.contains("Tz "),
        "{all}"
    );
    // Shear: per-step time constants that scatter are flagged, not called confident.
    let dir = copy_run("box-shear-flat", tmp.path());
    run_ok(&["report", dir.to_str().unwrap()], tmp.path());
    let s = summary(&dir.join("report"));
    assert_eq!(
        s["relaxation"]["tau_identified"]["shear"], false,
        "{}",
        s["relaxation"]
    );
    let shear_steps: Vec<&serde_json::Value> = s["relaxation"]["steps"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|v| v["kind"] == "shear")
        .collect();
    assert!(shear_steps.iter().all(|v| v["confident"] == false));
    let md = std::fs::read_to_string(dir.join("report/report.md")).unwrap();
    assert!(md.contains("τ not identified"));
    // Plot hygiene: no float noise in any label, the lab's axis names.
    for e in std::fs::read_dir(dir.join("report")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "svg") {
            for t in svg_texts(&std::fs::read_to_string(&p).unwrap()) {
                let noisy = t
                    .split(|c: char| !(c.is_ascii_digit() || c == '.'))
                    .any(|w| w.split_once('.').is_some_and(|(_, d)| d.len() >= 8));
                assert!(!noisy, "{}: {t}", p.display());
            }
        }
    }
    let force_load =
        std::fs::read_to_string(dir.join("report/block2_shear_force_load.svg")).unwrap();
    let texts = svg_texts(&force_load).join("\n");
    assert!(
        texts.contains("shear offset (mm)") && !texts.contains("load (mm)"),
        "{texts}"
    );
}

#[test]
fn runs_are_compared_side_by_side() {
    let tmp = tempfile::tempdir().unwrap();
    let a = copy_run("box-normal-flat", tmp.path());
    let out = tmp.path().join("compare");
    // A second run of another seed.
    run_ok(
        &[
            "run",
            "box-normal-flat",
            "--seed",
            "2",
            "--quiet",
            "--out",
            "b",
        ],
        tmp.path(),
    );
    let b = std::fs::read_dir(tmp.path().join("b"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let o = Command::new(gelrig())
        .args(["report", a.to_str().unwrap(), b.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "no --out");
    assert!(String::from_utf8_lossy(&o.stderr).contains("--out DIR"));
    run_ok(
        &[
            "report",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        tmp.path(),
    );
    let s = summary(&out);
    assert_eq!(s["runs"].as_array().unwrap().len(), 2);
    let stiff = &s["metrics"]["stiffness (N/mm)"];
    let v: Vec<f64> = stiff["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let d = stiff["difference_pct_from_first"][0].as_f64().unwrap();
    assert!((d - 100.0 * (v[1] - v[0]) / v[0]).abs() < 1e-9);
    assert!(out.join("compare_force_load.svg").is_file());
    assert!(out.join("report.html").is_file() && b.join("report/report.html").is_file());
}

#[test]
fn overrides_runs_and_progress_meet_the_user_halfway() {
    let tmp = tempfile::tempdir().unwrap();
    // --set edits the protocol as run and names the variant; --name names it.
    let (_, err) = run_ok(
        &[
            "run",
            "box-normal-flat",
            "--set",
            "indenter.diameter=10mm",
            "--quiet",
            "--out",
            "runs",
        ],
        tmp.path(),
    );
    assert!(err.contains("using the shipped protocol"), "{err}");
    let dirs: Vec<PathBuf> = std::fs::read_dir(tmp.path().join("runs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let name = dirs[0].file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        name.contains("box-normal-flat-") && name.len() > "box-normal-flat-".len() + 16,
        "{name}"
    );
    let recorded = std::fs::read_to_string(dirs[0].join("protocol.yaml")).unwrap();
    assert!(recorded.contains("diameter: 10 mm"), "{recorded}");
    run_ok(
        &[
            "run",
            "box-normal-flat",
            "--set",
            "indenter.diameter=10mm",
            "--name",
            "ten",
            "--quiet",
            "--out",
            "runs",
        ],
        tmp.path(),
    );
    // A bad --set says what and how.
    let o = Command::new(gelrig())
        .current_dir(tmp.path())
        .args(["validate", "box-normal-flat", "--set", "sequence.99.home=x"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no item 99"));
    // `runs`: duration, seed and rig; no runs is not an error.
    let (out, _) = run_ok(&["runs", "runs"], tmp.path());
    assert!(
        out.contains("duration") && out.contains("sim (simulated)") && out.contains("ten"),
        "{out}"
    );
    let (out, _) = run_ok(&["runs", "nowhere"], tmp.path());
    assert!(out.starts_with("no runs"), "{out}");
    // The plan speaks units.
    let (out, _) = run_ok(&["plan", "portable-normal"], tmp.path());
    assert!(out.contains("|dFz/dt| < 0.005 N/s for 60–120 s"), "{out}");
    let (json, _) = run_ok(&["plan", "portable-normal", "--json"], tmp.path());
    let plan: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(plan["steps"][0]["target_value"], 0.1);
    assert_eq!(plan["steps"][0]["target_unit"], "mm");
    // The progress line names the trial and never restarts.
    let text = crate::support::shipped_text("lifting-can").replace("times: 10", "times: 2");
    std::fs::write(tmp.path().join("can.yaml"), text).unwrap();
    let rig = crate::support::root().join("protocols/rigs/sim.yaml");
    let (_, err) = run_ok(
        &[
            "run",
            "can.yaml",
            "--rig",
            rig.to_str().unwrap(),
            "--plain",
            "--out",
            "runs",
        ],
        tmp.path(),
    );
    assert!(err.contains("trial 2/2 begins"), "{err}");
    assert!(err.contains("trial 2/2 · step 7/12: "), "{err}");
}

#[test]
fn track_warns_and_refuses_what_a_newcomer_gets_wrong() {
    let tmp = tempfile::tempdir().unwrap();
    let bx = shared_dry_run("box-normal-flat");
    let portable = shared_dry_run("portable-normal");
    let reference = bx.join("frames/000000.png");
    let out = tmp.path().join("m.csv");
    // The reference among the frames: a warning; every row names its file.
    let o = Command::new(gelrig())
        .arg("track")
        .arg("--reference")
        .arg(&reference)
        .arg(&reference)
        .arg(bx.join("frames/000003.png"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("is also frame 1"));
    let rows = csv_rows(&out);
    assert!(
        rows.iter()
            .any(|r| r["frame"] == "2" && r["file"].ends_with("000003.png"))
    );
    // A frame of another sensor: refused, exit 2, naming the frame and the fix.
    let o = Command::new(gelrig())
        .arg("track")
        .arg("--reference")
        .arg(&reference)
        .arg(portable.join("frames/000005.png"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("000005.png") && e.contains("does not show the gel") && e.contains("fix:"),
        "{e}"
    );
}
