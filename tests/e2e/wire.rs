//! The real drivers against the twins over real transports: `gelrig sim serve` with
//! `protocols/rigs/sim-wire.yaml` and the elastomer of `box-normal-flat`, `gelrig probe`
//! on the bound rig, then the whole shipped `box-normal-flat` through the Zaber (pty) and
//! Net F/T (UDP) drivers, 100× faster than the wall (about 40 s), compared with the
//! in-process dry run.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::{col, csv_rows, gelrig, protocol, root, shared_dry_run};

struct Serve(Child);

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn probe(bound: &Path) -> (bool, String) {
    let o = Command::new(gelrig())
        .arg("probe")
        .arg(bound)
        .output()
        .unwrap();
    (
        o.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
    )
}

/// Least-squares slope and intercept of `y` against `x`.
fn line(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let slope = sxy / sxx;
    (slope, my - slope * mx)
}

/// Normal stiffness (N/mm) and intercept over the loading half of a run's steps.
fn loading_line(dir: &Path) -> (f64, f64) {
    let rows: Vec<_> = csv_rows(&dir.join("steps.csv"))
        .into_iter()
        .filter(|r| r["phase"] == "load")
        .collect();
    line(&col(&rows, "target"), &col(&rows, "fz_n"))
}

/// Mean absolute grey-level difference between two frames of a run.
fn frame_change(dir: &Path, a: usize, b: usize) -> f64 {
    let files: Vec<String> = csv_rows(&dir.join("frames.csv"))
        .into_iter()
        .map(|r| r["file"].clone())
        .collect();
    let read = |k: usize| image::open(dir.join(&files[k])).unwrap().to_luma8();
    let (fa, fb) = (read(a), read(b));
    let sum: f64 = fa
        .pixels()
        .zip(fb.pixels())
        .map(|(p, q)| (f64::from(p.0[0]) - f64::from(q.0[0])).abs())
        .sum();
    sum / f64::from(fa.width() * fa.height())
}

#[test]
fn sim_serve_probe_and_box_normal_flat_through_the_real_drivers() {
    // The dry run first, so the wire run does not share the two cores with it.
    let dry = shared_dry_run("box-normal-flat");
    let tmp = tempfile::tempdir().unwrap();
    let bound = tmp.path().join("bound.yaml");
    let child = Command::new(gelrig())
        .args(["sim", "serve", "--rig"])
        .arg(root().join("protocols/rigs/sim-wire.yaml"))
        .arg("--protocol")
        .arg(protocol("box-normal-flat"))
        .args(["--time-scale", "100", "--seed", "1", "--write"])
        .arg(&bound)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut serve = Serve(child);
    let t0 = Instant::now();
    while !bound.is_file() {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "sim serve wrote no rig file"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let text = std::fs::read_to_string(&bound).unwrap();
    assert!(
        text.contains("/dev/pts/")
            && text.contains("127.0.0.1:")
            && text.contains("time_scale: 100"),
        "{text}"
    );

    let (ok, out) = probe(&bound);
    assert!(ok, "{out}");
    for identity in [
        "Zaber device id",
        "SMC100CC",
        "(RTU) unit 1",
        "counts per N,",
    ] {
        assert!(out.contains(identity), "{identity}: {out}");
    }
    assert!(out.contains("not referenced (home it)"), "{out}");

    // The shipped protocol, unchanged, through the production drivers.
    let o = Command::new(gelrig())
        .arg("run")
        .arg(protocol("box-normal-flat"))
        .arg("--rig")
        .arg(&bound)
        .args(["--seed", "1", "--quiet", "--out"])
        .arg(tmp.path().join("runs"))
        .output()
        .unwrap();
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{log}");
    let wire = std::fs::read_dir(tmp.path().join("runs"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let manifest = std::fs::read_to_string(wire.join("run.yaml")).unwrap();
    assert!(
        manifest.contains("Zaber device id") && manifest.contains("Net F/T"),
        "{manifest}"
    );

    // Same steps and frames as the in-process dry run, and the same elastomer: the twins'
    // plant gives the dry run's stiffness. The intercept differs by the contact detected
    // a little deeper: at 100× a wall millisecond of loop latency (pty and UDP round trips
    // of a debug build) is 0.1 s of protocol, 0.005 mm of the 0.05 mm/s approach.
    let (wire_steps, dry_steps) = (
        csv_rows(&wire.join("steps.csv")),
        csv_rows(&dry.join("steps.csv")),
    );
    assert_eq!(wire_steps.len(), 20);
    assert_eq!(wire_steps.len(), dry_steps.len());
    let frames = |d: &Path| csv_rows(&d.join("frames.csv")).len();
    assert_eq!(frames(&wire), frames(&dry));
    let ((k_wire, b_wire), (k_dry, b_dry)) = (loading_line(&wire), loading_line(&dry));
    assert!(
        (k_wire / k_dry - 1.0).abs() < 0.01,
        "stiffness over the wire {k_wire:.3} N/mm vs dry run {k_dry:.3}"
    );
    assert!(
        (b_wire - b_dry).abs() < 1.0,
        "intercepts {b_wire:.3} vs {b_dry:.3} N"
    );
    // The rendered camera follows the real stages: the deepest frame differs from the
    // reference as much as in the dry run.
    let (c_wire, c_dry) = (frame_change(&wire, 0, 10), frame_change(&dry, 0, 10));
    assert!(
        c_dry > 0.5 && (c_wire / c_dry - 1.0).abs() < 0.2,
        "frame change at the deepest step: wire {c_wire:.3}, dry {c_dry:.3}"
    );

    // Stopping the twins: the probe names every device that no longer answers.
    let _ = Command::new("kill")
        .arg("-TERM")
        .arg(serve.0.id().to_string())
        .status();
    let status = serve.0.wait().unwrap();
    assert!(status.success(), "sim serve exits cleanly on SIGTERM");
    let (ok, out) = probe(&bound);
    assert!(
        !ok && out.contains("no answer from: normal, shear, rotation, force"),
        "{out}"
    );
}

/// A bound rig fixes the run's clock to its twins' time scale; real devices run in real
/// time; `sim serve` refuses a scale that is not a positive number.
#[test]
fn the_time_scale_follows_the_twins() {
    let tmp = tempfile::tempdir().unwrap();
    let wire = std::fs::read_to_string(root().join("protocols/rigs/sim-wire.yaml")).unwrap();
    let run = |rig_text: &str, scale: &str| {
        let rig = tmp.path().join("rig.yaml");
        std::fs::write(&rig, rig_text).unwrap();
        let o = Command::new(gelrig())
            .arg("run")
            .arg(protocol("box-normal-flat"))
            .arg("--rig")
            .arg(&rig)
            .args(["--quiet", "--time-scale", scale, "--out"])
            .arg(tmp.path().join("runs"))
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let (ok, err) = run(&format!("{wire}twins: {{time_scale: 100}}\n"), "5");
    assert!(!ok && err.contains("twins run at 100×"), "{err}");
    let real = wire.replace("camera: {driver: sim", "camera: {driver: v4l2");
    let (ok, err) = run(&real, "5");
    assert!(
        !ok && err.contains("drives real devices (normal, force, camera)")
            && err.contains("which run in real time"),
        "{err}"
    );
    assert!(!tmp.path().join("runs").exists(), "nothing was recorded");

    let o = Command::new(gelrig())
        .args(["sim", "serve", "--time-scale", "0", "--write"])
        .arg(tmp.path().join("b.yaml"))
        .arg("--rig")
        .arg(root().join("protocols/rigs/sim-wire.yaml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("must be a positive number"),
        "{err}"
    );
    assert!(!tmp.path().join("b.yaml").exists());
}

/// The shipped `portable-rotation` over the wire against twins that behave like drives —
/// motion shown 200 ms after each command, a one-step overshoot — with `sim-wire.yaml`'s
/// AZ-true map on the Modbus RTU rotation drive: every step lands within the resolution of
/// its axis (the approach and the preload on the Zaber, the rotation on the AZ).
#[test]
fn late_drives_over_the_wire_still_land_every_step() {
    let tmp = tempfile::tempdir().unwrap();
    let bound = tmp.path().join("bound.yaml");
    let child = Command::new(gelrig())
        .args(["sim", "serve", "--rig"])
        .arg(root().join("protocols/rigs/sim-wire.yaml"))
        .arg("--protocol")
        .arg(protocol("portable-rotation"))
        .args([
            "--time-scale",
            "100",
            "--drive-latency-ms",
            "200",
            "--overshoot-steps",
            "1",
            "--write",
        ])
        .arg(&bound)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(tmp.path().join("serve.log")).unwrap())
        .spawn()
        .unwrap();
    let mut serve = Serve(child);
    let t0 = Instant::now();
    while !bound.is_file() {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "sim serve wrote no rig file"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let o = Command::new(gelrig())
        .arg("run")
        .arg(protocol("portable-rotation"))
        .arg("--rig")
        .arg(&bound)
        .args(["--quiet", "--out"])
        .arg(tmp.path().join("runs"))
        .output()
        .unwrap();
    if !o.status.success() {
        // Whether the twins were still there, and what `sim serve` said, tell a stalled
        // twin from one that died.
        let alive = matches!(serve.0.try_wait(), Ok(None));
        let log = std::fs::read_to_string(tmp.path().join("serve.log")).unwrap_or_default();
        panic!(
            "run failed: {}\nsim serve still running: {alive}; its stderr:\n{log}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let dir = std::path::PathBuf::from(String::from_utf8_lossy(&o.stdout).trim());
    let rows = csv_rows(&dir.join("steps.csv"));
    assert_eq!(rows.len(), 11);
    for r in &rows {
        let (t, p): (f64, f64) = (r["target"].parse().unwrap(), r["position"].parse().unwrap());
        let window = if r["axis"] == "rotation" { 0.01 } else { 0.002 };
        assert!((t - p).abs() <= window + 1e-9, "{r:?}");
    }
}
