//! `gelrig plan`: the arithmetic of steps, durations, frames and data volume.

use std::process::Command;

use experiments::plan::{FORCE_ROW_BYTES, JOURNAL_LINE_BYTES, STEP_ROW_BYTES, plan};

use crate::support::{gelrig, load_ok, protocol, shipped};

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-6 * b.abs().max(1.0)
}

#[test]
fn box_normal_flat_arithmetic() {
    let l = load_ok(&protocol("box-normal-flat"));
    let p = plan(&l.protocol, &l.compiled, &l.rig);
    assert_eq!(p.steps.len(), 20);
    let depth_mm: Vec<f64> = (1..=10)
        .map(|k| 0.084 * k as f64)
        .chain((0..10).rev().map(|k| 0.084 * k as f64))
        .collect();
    for (s, d) in p.steps.iter().zip(&depth_mm) {
        let shown: f64 = s.target.trim_end_matches(" mm").parse().unwrap();
        assert!(
            (shown - d).abs() < 1e-9,
            "step {}: {} vs {d}",
            s.step,
            s.target
        );
    }
    assert!(
        p.steps[..10].iter().all(|s| s.phase == "load")
            && p.steps[10..].iter().all(|s| s.phase == "unload")
    );
    // Hand count, seconds. Home: the stage may start anywhere in [0, 25] mm at 2 mm/s.
    // Tare 2. Rapid to 9 mm at 2 mm/s: 4.5. Creep 0–2 mm at 0.05 mm/s: 0–40. Reference
    // frame 1/25. Each step: 0.084 mm at 0.5 mm/s, 180 s settle, one frame at 25 Hz.
    // Retract: from the contact, somewhere in [9, 11] mm, to 0 at 2 mm/s.
    let step = 0.084 / 0.5 + 180.0 + 1.0 / 25.0;
    let min = 0.0 + 2.0 + 4.5 + 0.0 + 0.04 + 20.0 * step + 9.0 / 2.0;
    let max = 12.5 + 2.0 + 4.5 + 40.0 + 0.04 + 20.0 * step + 11.0 / 2.0;
    assert!(
        close(p.duration_s.min, min),
        "{} vs {min}",
        p.duration_s.min
    );
    assert!(
        close(p.duration_s.max, max),
        "{} vs {max}",
        p.duration_s.max
    );
    // Each step ends one step-duration after the previous one.
    for w in p.steps.windows(2) {
        assert!(close(w[1].ends_s.min - w[0].ends_s.min, step));
    }
    assert!(close(p.frames.min, 21.0) && close(p.frames.max, 21.0));
    // Force is recorded at 20 Hz for the whole run except the retract.
    let recorded = |d: f64, retract: f64| 20.0 * (d - retract);
    assert!(
        close(p.force_rows.min, recorded(min, 4.5)),
        "{:?}",
        p.force_rows
    );
    assert!(
        close(p.force_rows.max, recorded(max, 5.5)),
        "{:?}",
        p.force_rows
    );
    let frame_bytes = (640 * 480 * 3 + 1024) as f64;
    let fixed =
        (20 * STEP_ROW_BYTES + l.compiled.actions.len() as u64 * 2 * JOURNAL_LINE_BYTES) as f64;
    let bytes_min = p.force_rows.min * FORCE_ROW_BYTES as f64 + fixed + 21.0 * frame_bytes;
    assert!(
        close(p.bytes.min, bytes_min),
        "{} vs {bytes_min}",
        p.bytes.min
    );
}

#[test]
fn rate_settling_widens_the_eta_by_its_bounds() {
    let l = load_ok(&protocol("portable-normal"));
    let p = plan(&l.protocol, &l.compiled, &l.rig);
    assert_eq!(p.steps.len(), 12);
    // 12 steps settling 60–120 s; the approach creeps 0–2 mm at 0.02 mm/s (0–100 s);
    // homing 0–12.5 s; retract from [9, 11] mm: 4.5–5.5 s.
    let spread = p.duration_s.max - p.duration_s.min;
    assert!(close(spread, 12.0 * 60.0 + 100.0 + 12.5 + 1.0), "{spread}");
}

#[test]
fn grasp_trials_repeat_with_their_own_trial_numbers() {
    let l = load_ok(&protocol("lifting-can"));
    let p = plan(&l.protocol, &l.compiled, &l.rig);
    assert_eq!(p.steps.len(), 60);
    for (i, chunk) in p.steps.chunks(6).enumerate() {
        let labels: Vec<&str> = chunk.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(
            labels,
            ["lift", "hold", "twist", "swing", "lower", "release"]
        );
        assert!(chunk.iter().all(|s| s.trial == i as u32 + 1));
    }
    // Frames at 25 Hz and force at 50 Hz over the same recorded time.
    assert!(
        close(p.frames.min, 0.5 * p.force_rows.min) && close(p.frames.max, 0.5 * p.force_rows.max),
        "{:?} {:?}",
        p.frames,
        p.force_rows
    );
    // Axes at 10 Hz for two axes and force at 50 Hz, over the same recorded time.
    assert!(
        close(p.axes_rows.min, 0.4 * p.force_rows.min),
        "{:?} {:?}",
        p.axes_rows,
        p.force_rows
    );
    assert!(
        close(p.axes_rows.max, 0.4 * p.force_rows.max),
        "{:?} {:?}",
        p.axes_rows,
        p.force_rows
    );
    let hold = 5.0 + 2.0; // hold + disturb
    let lift = 20.0 / 10.0;
    assert!(p.force_rows.min >= 50.0 * 10.0 * (hold + 2.0 * lift));
}

#[test]
fn every_shipped_protocol_plans_consistently() {
    for name in shipped() {
        let l = load_ok(&protocol(&name));
        let p = plan(&l.protocol, &l.compiled, &l.rig);
        assert_eq!(p.steps.len() as u32, l.compiled.steps, "{name}");
        assert!(
            p.duration_s.min > 0.0 && p.duration_s.min <= p.duration_s.max,
            "{name}"
        );
        for w in p.steps.windows(2) {
            assert!(
                w[0].ends_s.min <= w[1].ends_s.min && w[0].ends_s.max <= w[1].ends_s.max,
                "{name}"
            );
        }
        let frames: u32 = p.steps.iter().map(|s| s.frames).sum::<u32>()
            + l.protocol
                .sequence
                .iter()
                .filter_map(|b| match b {
                    experiments::protocol::schema::Block::Approach(a) => Some(a.reference_frames),
                    _ => None,
                })
                .sum::<u32>();
        // Grasp trials add the camera's continuous frames to the captured ones.
        let streamed = name.starts_with("lifting-can");
        assert!(
            if streamed {
                p.frames.min > frames as f64
            } else {
                close(p.frames.min, frames as f64)
            },
            "{name}: {:?} vs {frames}",
            p.frames
        );
    }
}

#[test]
fn cli_prints_the_plan() {
    let out = Command::new(gelrig())
        .args(["plan"])
        .arg(protocol("box-normal-flat"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("steps        20"), "{text}");
    assert!(
        text.contains("duration     1 h 00 min 15 s – 1 h 01 min 09 s"),
        "{text}"
    );
    assert!(text.contains("frames       21"), "{text}");
    let json = Command::new(gelrig())
        .args(["plan", "--json"])
        .arg(protocol("box-normal-flat"))
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(v["steps"].as_array().map(|a| a.len()), Some(20));
}

/// `gelrig plan` says what the simulated bench solves and leaves out, at which fidelity and
/// what that level was measured to cost; `--fidelity` changes the level, a run records it in
/// its `rig.yaml`, and a rig without a simulated bench refuses it.
#[test]
fn the_plan_lists_the_simulated_models_and_the_fidelity() {
    let plan = |name: &str, extra: &[&str]| {
        let mut args = vec![std::ffi::OsString::from("plan"), protocol(name).into()];
        args.extend(extra.iter().map(std::ffi::OsString::from));
        crate::support::gelrig_ok(args)
    };
    let flat = plan("box-normal-flat", &[]);
    assert!(
        flat.contains("simulated bench, fidelity default (32 cells"),
        "{flat}"
    );
    assert!(
        flat.contains("solves     normal  flat punch, 32 cells"),
        "{flat}"
    );
    assert!(flat.contains("solves     fields  256×256 grid"), "{flat}");
    assert!(flat.contains("leaves out shear   no shear stage"), "{flat}");
    assert!(
        flat.contains("leaves out twist   no rotation stage"),
        "{flat}"
    );
    assert!(flat.contains("expected   step forces within"), "{flat}");
    let fast = plan("box-normal-sphere", &["--fidelity", "fast"]);
    assert!(
        fast.contains("simulated bench, fidelity fast (32 cells"),
        "{fast}"
    );
    assert!(
        fast.contains("8 cells across 1.2 contact diameters"),
        "{fast}"
    );
    let can = plan("lifting-can", &["--fidelity", "reference"]);
    assert!(
        can.contains("solves     shear   partial-slip backbone (the grasp"),
        "{can}"
    );
    assert!(can.contains("solves     twist"), "{can}");
    assert!(!can.contains("leaves out"), "{can}");
    // The JSON plan carries the same.
    let v: serde_json::Value =
        serde_json::from_str(&plan("box-shear-flat", &["--json", "--fidelity", "fast"])).unwrap();
    assert_eq!(v["sim"]["fidelity"], "fast");
    // A run records the level it ran at.
    let tmp = tempfile::tempdir().unwrap();
    crate::support::gelrig_ok([
        std::ffi::OsStr::new("run"),
        "--quiet".as_ref(),
        "--fidelity".as_ref(),
        "fast".as_ref(),
        "--out".as_ref(),
        tmp.path().as_os_str(),
        protocol("box-normal-flat").as_os_str(),
    ]);
    // Unless quiet, a run says what its bench solves and leaves out.
    let said = std::process::Command::new(gelrig())
        .args(["run", "--plain", "--fidelity", "fast", "--out"])
        .arg(tmp.path().join("said"))
        .arg(protocol("box-normal-flat"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&said.stderr);
    assert!(
        err.contains(
            "simulated bench at fidelity fast: solves normal, fields; leaves out shear (no shear \
             stage and no grasp), twist (no rotation stage and no grasp)"
        ),
        "{err}"
    );
    let dir = std::fs::read_dir(tmp.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .find(|e| e.path().join("rig.yaml").is_file())
        .unwrap()
        .path();
    let rig: rig::config::RigConfig = rig::config::RigConfig::from_yaml_str(
        &std::fs::read_to_string(dir.join("rig.yaml")).unwrap(),
    )
    .unwrap();
    assert_eq!(rig.fidelity(), rig::config::Fidelity::Fast);
    // A rig without a simulated bench has nothing to resolve.
    let real = tmp.path().join("manual.yaml");
    std::fs::write(
        &real,
        "name: manual\naxes:\n  normal: {driver: manual, travel: [0 mm, 25 mm], max_speed: 1 mm/s, resolution: 0.001 mm}\n",
    )
    .unwrap();
    let refused = Command::new(gelrig())
        .args(["plan", "--fidelity", "fast", "--rig"])
        .arg(&real)
        .arg(protocol("box-normal-flat"))
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("has no simulated bench"), "{err}");
    // An unknown level is refused by the command line, naming the three.
    let bad = Command::new(gelrig())
        .args(["plan", "--fidelity", "fastest"])
        .arg(protocol("box-normal-flat"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("fast, default or reference"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}
