//! The real drivers against the twins over real transports: `gelrig sim serve` with
//! `protocols/rigs/sim-wire.yaml`, `gelrig probe` on the bound rig, then a shortened
//! `box-normal-flat` run through the Zaber (pty) and Net F/T (UDP) drivers in real time.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::{csv_rows, gelrig, load_text, root, run_virtual, shipped_text};

/// `box-normal-flat` cut to two load and two unload steps with 2 s settles, no frames, a
/// fast approach from just above contact: the wire run takes about 20 s of real time.
fn short_protocol() -> String {
    shipped_text("box-normal-flat")
        .replace(
            "from: 9 mm, speed: 0.05 mm/s",
            "from: 9.9 mm, speed: 0.5 mm/s",
        )
        .replace("reference_frames: 1", "reference_frames: 0")
        .replace("to: 20 %", "to: 4 %")
        .replace("settle: {fixed: 180 s}", "settle: {fixed: 2 s}")
        .replace(
            "capture: {force_window: 10 s, frames: 1}",
            "capture: {force_window: 1 s, frames: 0}",
        )
}

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

#[test]
fn sim_serve_probe_and_a_run_through_the_real_drivers() {
    let tmp = tempfile::tempdir().unwrap();
    let bound = tmp.path().join("bound.yaml");
    let child = Command::new(gelrig())
        .args(["sim", "serve", "--rig"])
        .arg(root().join("protocols/rigs/sim-wire.yaml"))
        .arg("--write")
        .arg(&bound)
        .stdout(Stdio::piped())
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
        text.contains("/dev/pts/") && text.contains("127.0.0.1:"),
        "{text}"
    );

    let (ok, out) = probe(&bound);
    assert!(ok, "{out}");
    assert!(
        out.contains("Zaber device id") && out.contains("not referenced"),
        "{out}"
    );
    assert!(
        out.contains("counts/force"),
        "calibration read from the box: {out}"
    );

    // The shortened protocol through the real drivers, in real time.
    let protocol = tmp.path().join("wire-short.yaml");
    std::fs::write(&protocol, short_protocol()).unwrap();
    let o = Command::new(gelrig())
        .arg("run")
        .arg(&protocol)
        .arg("--rig")
        .arg(&bound)
        .arg("--out")
        .arg(tmp.path().join("runs"))
        .arg("--plain")
        .output()
        .unwrap();
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{log}");
    let dir = std::fs::read_dir(tmp.path().join("runs"))
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    let wire_steps = csv_rows(&dir.join("steps.csv"));
    let fz: Vec<f64> = wire_steps
        .iter()
        .map(|r| r["fz_n"].parse().unwrap())
        .collect();
    assert!(
        fz[1] > fz[0] && fz[0] > 0.5 && fz[3] < fz[2],
        "the twin's spring loads the sensor: {fz:?}"
    );
    let manifest = std::fs::read_to_string(dir.join("run.yaml")).unwrap();
    assert!(
        manifest.contains("Zaber device id") && manifest.contains("Net F/T"),
        "{manifest}"
    );

    // The same protocol in-process on the simulated bench has the same steps.
    let loaded = load_text(tmp.path(), &short_protocol()).unwrap_or_else(|d| panic!("{d:?}"));
    let (outcome, _) = run_virtual(&loaded, &tmp.path().join("dry"), 1, None);
    let dry_steps = csv_rows(&outcome.dir.join("steps.csv"));
    assert_eq!(wire_steps.len(), dry_steps.len());
    assert_eq!(wire_steps.len(), 4);

    // Stopping the twins: the probe names every device that no longer answers.
    let _ = Command::new("kill")
        .arg("-TERM")
        .arg(serve.0.id().to_string())
        .status();
    let status = serve.0.wait().unwrap();
    assert!(status.success(), "sim serve exits cleanly on SIGTERM");
    let (ok, out) = probe(&bound);
    assert!(
        !ok && out.contains("no answer from: normal, shear, force"),
        "{out}"
    );
}
