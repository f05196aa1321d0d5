//! Hostile input, through the real binary (issue "Safety first", findings 7–11): values that
//! used to panic, allocate until killed or run away, duplicate keys, untrusted text reaching
//! HTML and the file system, and the small things (a closed stderr, a BOM, a long name).
//! Every command runs under a 4 GB address-space limit and a time limit, so a regression
//! fails the test instead of taking the machine down.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::{gelrig, protocol, root, sim_rig};

/// Runs gelrig with `args` under `prlimit --as=4G` and a 30 s limit; (exit code, stderr).
fn gelrig_limited(args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new("prlimit")
        .arg("--as=4000000000")
        .arg(gelrig())
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        use std::io::Read;
        let mut s = String::new();
        let _ = std::io::BufReader::new(stderr)
            .take(1 << 20)
            .read_to_string(&mut s);
        s
    });
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("gelrig {args:?} ran for 30 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (status.code(), reader.join().unwrap())
}

/// A copy of box-normal-flat with `edits` applied, and the rig path absolute.
fn variant(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(protocol("box-normal-flat")).unwrap();
    text = text.replace(
        "rig: rigs/sim.yaml",
        &format!("rig: {}", sim_rig().display()),
    );
    for (from, to) in edits {
        assert!(text.contains(from), "{from} not in the protocol");
        text = text.replace(from, to);
    }
    let p = dir.join(format!("{name}.yaml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// A copy of the simulated rig with `edits` applied.
fn rig_variant(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(sim_rig()).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from} not in the rig");
        text = text.replace(from, to);
    }
    let p = dir.join(format!("{name}.rig.yaml"));
    std::fs::write(&p, text).unwrap();
    p
}

/// The protocols (and rigs) of [`impossible_values_are_refused_before_anything_runs`],
/// written into `d`, each with the words its refusal must contain.
fn impossible_cases(d: &Path) -> Vec<(PathBuf, Option<PathBuf>, &'static str)> {
    let nested_repeats = "sequence:\n  - home: {axes: [normal]}\n  - repeat:\n      times: 1000\n      blocks:\n        - repeat:\n            times: 1000\n            blocks:\n              - hold: {duration: 1 s}\n";
    let base = std::fs::read_to_string(variant(d, "base", &[])).unwrap();
    let head = base.split("sequence:").next().unwrap().to_string();
    std::fs::write(d.join("repeats.yaml"), format!("{head}{nested_repeats}")).unwrap();
    std::fs::write(
        d.join("deep.yaml"),
        format!(
            "{head}sequence:\n{}{}\n",
            "[".repeat(100_000),
            "]".repeat(100_000)
        ),
    )
    .unwrap();
    vec![
        (
            variant(d, "to", &[("to: 20 %", "to: 1e12 %")]),
            None,
            "over the budget",
        ),
        (
            variant(d, "from", &[("from: 0 %", "from: 1e18 mm")]),
            None,
            "over the budget",
        ),
        (
            d.join("repeats.yaml"),
            None,
            "1000000 steps, over the budget",
        ),
        (d.join("deep.yaml"), None, "nests more than"),
        (
            variant(d, "settle", &[("{fixed: 180 s}", "{fixed: 4294967296 s}")]),
            None,
            "plausible range [0, 86400] s",
        ),
        (
            variant(d, "frames", &[("frames: 1}", "frames: 1000000000}")]),
            None,
            "plausible range [0, 10000]",
        ),
        (
            variant(d, "slow", &[("speed: 0.5 mm/s", "speed: 1e-7 mm/s")]),
            None,
            "speed 1e-7 mm/s is outside",
        ),
        (
            variant(
                d,
                "rate",
                &[("record: {force: 20 Hz}", "record: {force: 1e-320 Hz}")],
            ),
            None,
            "force rate 1e-320 Hz is outside",
        ),
        (
            variant(
                d,
                "window",
                &[
                    ("{fixed: 180 s}", "{fixed: 0.1 ms}"),
                    ("force_window: 10 s", "force_window: 0.1 ms"),
                ],
            ),
            None,
            "holds 0 force samples",
        ),
        (
            variant(
                d,
                "sphere",
                &[(
                    "{shape: flat_circle, diameter: 9.5 mm}",
                    "{shape: sphere, diameter: 0.03 mm}",
                )],
            ),
            None,
            "indenter diameter 0.03 mm is outside",
        ),
        (
            variant(
                d,
                "huge",
                &[(
                    "{shape: flat_circle, diameter: 9.5 mm}",
                    "{shape: flat_circle, diameter: 4294967295 mm}",
                )],
            ),
            None,
            "indenter diameter 4294967295 mm is outside",
        ),
        (
            variant(
                d,
                "kinetic",
                &[(
                    "sensor: {kind: box}",
                    "sensor: {kind: box, material: {youngs_modulus: 0.25 MPa, poisson_ratio: 0.49, friction: 0.6, kinetic_friction: 0.9}}",
                )],
            ),
            None,
            "kinetic friction 0.9 is above the static friction 0.6",
        ),
        (
            variant(d, "base2", &[]),
            Some(rig_variant(
                d,
                "reversed",
                &[("travel: [0 mm, 25 mm]", "travel: [25 mm, 0 mm]")],
            )),
            "travel [25, 0] is empty",
        ),
        (
            variant(d, "base3", &[]),
            Some(rig_variant(d, "fps", &[("fps: 25 Hz", "fps: 1e12 Hz")])),
            "fps 1000000000000 Hz is outside",
        ),
        (
            variant(d, "base4", &[]),
            Some(rig_variant(
                d,
                "camera",
                &[("width: 640, height: 480", "width: 100000, height: 65535")],
            )),
            "width 100000 px is outside",
        ),
        (
            variant(d, "base5", &[]),
            Some({
                let p = d.join("twins.rig.yaml");
                let text = std::fs::read_to_string(sim_rig()).unwrap();
                std::fs::write(&p, format!("{text}twins: {{time_scale: 1e-300}}\n")).unwrap();
                p
            }),
            "time_scale 1e-300 is outside",
        ),
    ]
}

/// Findings 7 and 8: every value that validated and then panicked, allocated until killed or
/// ran away is now a validation error (exit 2) naming the value and its range — fast.
#[test]
fn impossible_values_are_refused_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = impossible_cases(tmp.path());
    for (p, rig, expect) in cases {
        let mut args = vec!["validate".to_string(), p.display().to_string()];
        if let Some(r) = &rig {
            args.push("--rig".into());
            args.push(r.display().to_string());
        }
        for verb in ["validate", "plan"] {
            args[0] = verb.into();
            let argv: Vec<&str> = args.iter().map(String::as_str).collect();
            let t0 = Instant::now();
            let (code, err) = gelrig_limited(&argv);
            assert_eq!(code, Some(2), "{verb} {}: {err}", p.display());
            assert!(
                err.contains(expect),
                "{verb} {}: want {expect:?} in:\n{err}",
                p.display()
            );
            assert!(
                t0.elapsed() < Duration::from_secs(10),
                "{verb} {} took {:?}",
                p.display(),
                t0.elapsed()
            );
        }
    }
}

/// The budget is a budget, not a wall: a big-but-real protocol passes with the flag.
#[test]
fn the_step_budget_can_be_raised() {
    let tmp = tempfile::tempdir().unwrap();
    let p = variant(tmp.path(), "fine", &[("step: 2 %", "step: 0.1 %")]);
    let p = p.display().to_string();
    let (code, err) = gelrig_limited(&["validate", &p, "--max-steps", "20"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("400 steps, over the budget of 20"), "{err}");
    let (code, err) = gelrig_limited(&["validate", &p]);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = gelrig_limited(&["plan", &p, "--max-data", "1MB"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("over the data budget of 1.0 MB"), "{err}");
}

/// Finding 9: a key twice in a mapping is an error at the second one (it used to retract to
/// 9.5 mm, the last value).
#[test]
fn duplicate_keys_are_errors_at_the_second() {
    let tmp = tempfile::tempdir().unwrap();
    let p = variant(
        tmp.path(),
        "dup",
        &[(
            "retract: {normal: 0 mm}",
            "retract: {normal: 0 mm, normal: 9.5 mm}",
        )],
    );
    let (code, err) = gelrig_limited(&["validate", &p.display().to_string()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("a key appears twice") && err.contains("\"normal\""),
        "{err}"
    );
    let line = std::fs::read_to_string(&p)
        .unwrap()
        .lines()
        .position(|l| l.contains("normal: 9.5 mm"))
        .unwrap()
        + 1;
    assert!(err.contains(&format!("dup.yaml:{line}:")), "{err}");
    // In a rig file too.
    let r = rig_variant(
        tmp.path(),
        "duprig",
        &[(
            "disturber: {driver: sim}",
            "disturber: {driver: sim}\ndisturber: {driver: sim}",
        )],
    );
    let base = variant(tmp.path(), "base", &[]);
    let (code, err) = gelrig_limited(&[
        "validate",
        &base.display().to_string(),
        "--rig",
        &r.display().to_string(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("a key appears twice"), "{err}");
}

/// Finding 10: paths from files point where they should. A rig that is not a rig file is not
/// quoted back; a device or an endless file is refused unread.
#[test]
fn paths_from_files_are_confined_and_never_quoted_or_read_endlessly() {
    let tmp = tempfile::tempdir().unwrap();
    let secret = tmp.path().join("shadow");
    std::fs::write(&secret, "root:$6$SECRETHASH:20228:0:99999:7:::\n").unwrap();
    for (rig, expect) in [
        (secret.display().to_string(), "this is not a rig file"),
        ("/dev/urandom".to_string(), "not a regular file"),
        ("/dev/zero".to_string(), "not a regular file"),
    ] {
        let p = variant(tmp.path(), "p", &[]);
        let text = std::fs::read_to_string(&p).unwrap().replace(
            &format!("rig: {}", sim_rig().display()),
            &format!("rig: {rig}"),
        );
        std::fs::write(&p, text).unwrap();
        let (code, err) = gelrig_limited(&["validate", &p.display().to_string()]);
        assert_eq!(code, Some(2), "{rig}: {err}");
        assert!(err.contains(expect), "{rig}: {err}");
        assert!(!err.contains("SECRETHASH"), "{err}");
    }
    let (code, err) = gelrig_limited(&["track", "--reference", "/dev/zero", "/dev/zero"]);
    assert_ne!(code, Some(0), "{err}");
    assert!(err.contains("not a regular file"), "{err}");
}

/// Finding 10: a protocol's name is text, not markup, in report.html; rows of frames.csv that
/// point outside the run are refused by `report` and `track`, which never open them.
#[test]
fn untrusted_text_is_escaped_and_run_files_stay_inside_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("xss.yaml");
    std::fs::write(
        &p,
        format!(
            "name: '</title><script>alert(1)</script>'\n\
             rig: {}\n\
             sensor: {{kind: box}}\n\
             indenter: {{shape: flat_circle, diameter: 9.5 mm}}\n\
             safety: {{max_fz: 40 N, max_fxy: 10 N, max_tz: 100 N·mm, retract: {{normal: 0 mm}}}}\n\
             record: {{force: 20 Hz}}\n\
             sequence:\n\
             \x20 - home: {{axes: [normal]}}\n\
             \x20 - tare: {{duration: 1 s}}\n\
             \x20 - approach: {{axis: normal, from: 9 mm, speed: 0.05 mm/s, until: 0.1 N, max_travel: 2 mm, reference_frames: 1}}\n\
             \x20 - stepped: {{axis: normal, from: 0 %, to: 4 %, step: 2 %, speed: 0.5 mm/s, settle: {{fixed: 20 s}}, capture: {{force_window: 5 s, frames: 1}}}}\n",
            sim_rig().display()
        ),
    )
    .unwrap();
    let out = Command::new(gelrig())
        .arg("run")
        .arg(&p)
        .args(["--quiet", "--out"])
        .arg(tmp.path().join("runs"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
    let (code, err) = gelrig_limited(&["report", &dir.display().to_string()]);
    assert_eq!(code, Some(0), "{err}");
    let html = std::fs::read_to_string(dir.join("report/report.html")).unwrap();
    assert!(
        !html.contains("<script>"),
        "a script tag reached report.html"
    );
    assert!(
        html.contains("&lt;script&gt;alert(1)"),
        "the name is not shown escaped"
    );
    // frames.csv rows pointing outside the run.
    let frames = std::fs::read_to_string(dir.join("frames.csv")).unwrap();
    for evil in [
        "/etc/passwd",
        "../../../../../../etc/passwd",
        "frames/../../run.yaml",
    ] {
        let mut lines: Vec<String> = frames.lines().map(str::to_string).collect();
        lines[1] = lines[1].replacen("frames/000000.png", evil, 1);
        std::fs::write(dir.join("frames.csv"), lines.join("\n") + "\n").unwrap();
        let _ = std::fs::remove_file(dir.join("markers.csv"));
        let (code, err) = gelrig_limited(&[
            "track",
            &dir.display().to_string(),
            "--out",
            &tmp.path().join("m.csv").display().to_string(),
        ]);
        assert_ne!(code, Some(0), "{evil}: {err}");
        assert!(
            err.contains("is not a path inside the run directory")
                || err.contains("leads outside the run directory"),
            "{evil}: {err}"
        );
        let (code, err) = gelrig_limited(&["report", &dir.display().to_string()]);
        assert_ne!(code, Some(0), "{evil}: {err}");
        assert!(!err.contains("root:"), "{err}");
    }
}

/// Finding 11: a closed stderr is not a crash (it used to exit 101), a UTF-8 byte-order mark
/// is accepted, and a name too long for a directory is refused at validation.
#[test]
fn closed_stderr_bom_and_long_names() {
    let tmp = tempfile::tempdir().unwrap();
    let bad = variant(tmp.path(), "bad", &[("to: 20 %", "to: 1e12 %")]);
    let mut child = Command::new(gelrig())
        .arg("validate")
        .arg(&bad)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(2), "exit code with stderr closed");

    let text = std::fs::read_to_string(variant(tmp.path(), "plain", &[])).unwrap();
    let bom = tmp.path().join("bom.yaml");
    std::fs::write(&bom, format!("\u{feff}{text}")).unwrap();
    let (code, err) = gelrig_limited(&["validate", &bom.display().to_string()]);
    assert_eq!(code, Some(0), "{err}");

    let long = variant(
        tmp.path(),
        "long",
        &[(
            "name: box-normal-flat",
            &format!("name: {}", "x".repeat(300)),
        )],
    );
    let (code, err) = gelrig_limited(&["validate", &long.display().to_string()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("300 characters"), "{err}");
    let _ = root();
}
