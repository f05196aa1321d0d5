//! `gelrig shape` on the real GelSight Mini's ball presses: a calibration that states each
//! model's held-out error and cost and leaves out a press whose label was copied, height
//! maps that NumPy reads as float32 H×W in mm, a depth picture and `shape.csv` per frame,
//! and refusals that name the file and the fix.

use std::process::Command;

use crate::support::{gelrig, gelrig_ok, python_peer};

fn ball_dir(what: &str) -> Option<std::path::PathBuf> {
    testkit::shared_data(env!("CARGO_MANIFEST_DIR"), "gelsight-mini-ball", what)
}

#[test]
fn shape_calibrates_on_ball_presses_and_writes_height_maps() {
    let Some(dir) = ball_dir("gelrig shape on the real ball presses") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("shape.yaml");
    let out = gelrig_ok([
        "shape".as_ref(),
        "calibrate".as_ref(),
        dir.as_os_str(),
        "--ball-diameter".as_ref(),
        "9.47mm".as_ref(),
        "--mm-per-px".as_ref(),
        "0.0634".as_ref(),
        "--out".as_ref(),
        model.as_os_str(),
    ]);
    assert!(out.contains("calibrated on 39 ball presses"), "{out}");
    assert!(out.contains("left out press_50.png"), "{out}");
    assert!(out.contains("chosen: local-linear"), "{out}");
    assert!(out.contains("ms a frame"), "{out}");
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(text.contains("format: gelrig-shape") && text.contains("ms_per_frame"));
    // Version 2: the local-linear responses are of the flat-fielded change, and say so. The
    // same file called version 1 (whose responses were of the raw change) is refused.
    assert!(text.contains("version: 2") && text.contains("flat_field: true"));
    let old = tmp.path().join("v1.yaml");
    std::fs::write(&old, text.replace("version: 2", "version: 1")).unwrap();
    let refused = std::process::Command::new(crate::support::gelrig())
        .args(["shape".as_ref(), dir.join("press_02.png").as_os_str()])
        .args(["--model".as_ref(), old.as_os_str()])
        .args([
            "--background".as_ref(),
            dir.join("background.png").as_os_str(),
        ])
        .args(["--out".as_ref(), tmp.path().join("v1-maps").as_os_str()])
        .output()
        .unwrap();
    assert!(!refused.status.success());
    let said = String::from_utf8_lossy(&refused.stderr);
    assert!(
        said.contains("v1.yaml") && said.contains("predates the flat field"),
        "{said}"
    );
    // A version 1 file as it was written (no `flat_field`: responses of the raw change) is
    // still read.
    let raw: String = text
        .replace("version: 2", "version: 1")
        .lines()
        .filter(|l| !l.contains("flat_field"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&old, raw).unwrap();
    let out = gelrig_ok([
        "shape".as_ref(),
        dir.join("press_02.png").as_os_str(),
        "--model".as_ref(),
        old.as_os_str(),
        "--background".as_ref(),
        dir.join("background.png").as_os_str(),
        "--out".as_ref(),
        tmp.path().join("v1-maps").as_os_str(),
    ]);
    assert!(out.contains("1 height map in"), "{out}");

    // Two presses and the bead (against its own session's background).
    let maps = tmp.path().join("maps");
    let out = gelrig_ok([
        "shape".as_ref(),
        dir.join("press_02.png").as_os_str(),
        dir.join("press_06.png").as_os_str(),
        "--model".as_ref(),
        model.as_os_str(),
        "--background".as_ref(),
        dir.join("background.png").as_os_str(),
        "--out".as_ref(),
        maps.as_os_str(),
        "--ply".as_ref(),
    ]);
    assert!(out.contains("2 height maps"), "{out}");
    for stem in ["press_02", "press_06"] {
        for ext in ["height.npy", "height.png", "ply"] {
            assert!(maps.join(format!("{stem}.{ext}")).is_file(), "{stem}.{ext}");
        }
    }
    let rows = crate::support::csv_rows(&maps.join("shape.csv"));
    assert_eq!(rows.len(), 2);
    // press_02: a 31 px contact of the 9.47 mm ball: its cap is 0.43 mm deep below the
    // circle's edge, and the gel beyond the edge sinks too.
    let deepest: f64 = rows[0]["max_depth_mm"].parse().unwrap();
    assert!(
        (0.35..1.0).contains(&deepest),
        "press_02 deepest {deepest} mm"
    );
    let cx: f64 = rows[0]["centroid_x_px"].parse().unwrap();
    let cy: f64 = rows[0]["centroid_y_px"].parse().unwrap();
    assert!(
        (cx - 88.0).abs() < 6.0 && (cy - 111.1).abs() < 6.0,
        "centroid {cx}, {cy}"
    );

    // An independent reader of the .npy: NumPy.
    if python_peer(
        "import numpy",
        "reading gelrig's .npy height maps with NumPy",
        "pip install numpy",
    ) {
        let check = Command::new("python3")
            .arg("-c")
            .arg(
                "import numpy, sys; a = numpy.load(sys.argv[1]); \
                 assert a.dtype == numpy.float32 and a.shape == (240, 320), (a.dtype, a.shape); \
                 assert a.min() < -0.35 and abs(numpy.median(a)) < 0.02, (a.min(), numpy.median(a)); \
                 print(a.min())",
            )
            .arg(maps.join("press_02.height.npy"))
            .output()
            .unwrap();
        assert!(
            check.status.success(),
            "{}",
            String::from_utf8_lossy(&check.stderr)
        );
    }

    // Refusals: a background of another session's size, a model file that is not one, a
    // directory without labels.
    let small = tmp.path().join("small.png");
    image::RgbImage::new(64, 48).save(&small).unwrap();
    let refused = |model: &std::path::Path| {
        let e = Command::new(gelrig())
            .args(["shape".as_ref(), dir.join("press_02.png").as_os_str()])
            .args(["--model".as_ref(), model.as_os_str()])
            .args(["--background".as_ref(), small.as_os_str()])
            .args(["--out".as_ref(), maps.as_os_str()])
            .output()
            .unwrap();
        let msg = String::from_utf8_lossy(&e.stderr).into_owned();
        assert_eq!(e.status.code(), Some(2), "{msg}");
        msg
    };
    let msg = refused(&model);
    assert!(
        msg.contains("64×48") && msg.contains("320×240") && msg.contains("fix:"),
        "{msg}"
    );
    let msg = refused(&small);
    assert!(msg.contains("shape.yaml") && msg.contains("fix:"), "{msg}");
    // A shape file whose table was edited into something that is not a number.
    let edited = tmp.path().join("edited.yaml");
    let text = std::fs::read_to_string(&model).unwrap();
    // The first value under the table's first `slope:` (a YAML block list).
    let at = text.find("slope:").expect("the table's first bin");
    let start = at + text[at..].find("- ").unwrap() + 2;
    let end = start + text[start..].find('\n').unwrap();
    let mut bad = text.clone();
    bad.replace_range(start..end, ".nan");
    std::fs::write(&edited, bad).unwrap();
    let msg = refused(&edited);
    assert!(
        msg.contains("not numbers") && msg.contains("calibrate again"),
        "{msg}"
    );
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    std::fs::copy(dir.join("background.png"), empty.join("background.png")).unwrap();
    let e = Command::new(gelrig())
        .args([
            "shape".as_ref(),
            "calibrate".as_ref(),
            empty.as_os_str(),
            "--ball-diameter".as_ref(),
            "9.47mm".as_ref(),
        ])
        .args(["--mm-per-px", "0.0634", "--out"])
        .arg(tmp.path().join("x.yaml"))
        .output()
        .unwrap();
    let msg = String::from_utf8_lossy(&e.stderr);
    assert_eq!(e.status.code(), Some(2), "{msg}");
    assert!(msg.contains("no presses") && msg.contains("fix:"), "{msg}");
}

/// Frames of the simulated bench with complete truth: calibrated on its own sphere presses
/// (the portable sensor, markers and noise included), a sphere press it never saw and a flat
/// punch read back against the simulator's surface.
#[test]
fn simulated_presses_read_back_the_simulators_surface() {
    use gelrig::shape::{Circle, Depth, Rgb, SlopeModel};
    use gelrig::sim;
    let (w, h) = (320usize, 240usize);
    let camera_of = |name: &str| {
        let loaded = crate::support::load_ok(&crate::support::protocol(name));
        let spec = sim::plant_spec(&loaded.protocol, &loaded.compiled).unwrap();
        sim::ContactCamera::new(&spec, w as u32, h as u32).unwrap()
    };
    let mut sphere = camera_of("portable-normal-sphere");
    let mm_per_px = sphere.mm_per_px();
    let ball_px = 12.68 / 2.0 / mm_per_px;
    let at_rest = sphere.at_rest(0);
    let press = |camera: &mut sim::ContactCamera, x_mm: f64, y_mm: f64, depth_mm: f64, seq: u64| {
        let pose = sim::ContactPose {
            depth_mm,
            centre_mm: (x_mm, y_mm),
            ..Default::default()
        };
        camera.frame_with_surface(&pose, seq).unwrap()
    };
    let mut cal = Vec::new();
    let mut k = 0;
    for y_mm in [-6.0, -2.0, 2.0, 6.0] {
        for x_mm in [-7.0, -2.5, 2.5, 7.0] {
            k += 1;
            let depth = 0.3 + 0.1 * (k % 4) as f64;
            let (f, _) = press(&mut sphere, x_mm, y_mm, depth, k);
            let circle = Circle {
                x_px: x_mm / mm_per_px + w as f64 / 2.0 - 0.5,
                y_px: y_mm / mm_per_px + h as f64 / 2.0 - 0.5,
                radius_px: f.contact_radius_mm / mm_per_px,
            };
            cal.push((format!("sim_{k}"), f.rgb, circle));
        }
    }
    let background = Rgb::new(w, h, &at_rest.rgb).unwrap();
    let presses: Vec<gelrig::shape::Press<'_>> = cal
        .iter()
        .map(|(n, px, c)| gelrig::shape::Press {
            name: n.clone(),
            frame: Rgb::new(w, h, px).unwrap(),
            circle: *c,
        })
        .collect();
    let calibration = shape_calibrate(background, &presses, ball_px, mm_per_px);
    let calibration_figures = (
        calibration.held_out[0].height_median_pct,
        calibration.held_out[0].height_worst_pct,
    );
    let map = SlopeModel::LocalLinear(calibration.local_linear)
        .prepare(w, h)
        .unwrap();
    let mut depth = Depth::new(map, background, mm_per_px).unwrap();
    // Against the simulator's surface: the rms depth error inside the contact (r < 0.9 a),
    // and the step across the contact's edge (inside, r < 0.8 a, against a ring outside,
    // 1.1–1.3 a) read against the true step; both as shares.
    let mut read = |frame: &[u8], truth: &[f32], radius_mm: f64, centre_mm: (f64, f64), d: f64| {
        let height = depth.height(Rgb::new(w, h, frame).unwrap()).unwrap();
        let (mut sum2, mut n) = (0.0, 0usize);
        // [inside, ring] × [read, true, count]
        let mut step = [[0.0f64; 3]; 2];
        for y in 0..h {
            for x in 0..w {
                let xm = (x as f64 + 0.5 - w as f64 / 2.0) * mm_per_px - centre_mm.0;
                let ym = (y as f64 + 0.5 - h as f64 / 2.0) * mm_per_px - centre_mm.1;
                let r = xm.hypot(ym);
                let i = y * w + x;
                let (got, want) = (-height[i] as f64, truth[i] as f64);
                if r < 0.9 * radius_mm {
                    sum2 += (got - want).powi(2);
                    n += 1;
                }
                let side = if r < 0.8 * radius_mm {
                    Some(0)
                } else if (1.1 * radius_mm..1.3 * radius_mm).contains(&r) {
                    Some(1)
                } else {
                    None
                };
                if let Some(k) = side {
                    step[k][0] += got;
                    step[k][1] += want;
                    step[k][2] += 1.0;
                }
            }
        }
        let mean = |k: usize, c: usize| step[k][c] / step[k][2];
        let (read_step, true_step) = (mean(0, 0) - mean(1, 0), mean(0, 1) - mean(1, 1));
        ((sum2 / n as f64).sqrt() / d, read_step / true_step - 1.0)
    };
    let (f, truth) = press(&mut sphere, -4.5, 3.5, 0.55, 99);
    let (sphere_rms, sphere_step) = read(&f.rgb, &truth, f.contact_radius_mm, (-4.5, 3.5), 0.55);
    let mut punch = camera_of("portable-normal");
    let (f, truth) = press(&mut punch, 0.0, 0.0, 0.3, 7);
    let (punch_rms, punch_step) = read(&f.rgb, &truth, 12.5 / 2.0, (0.0, 0.0), 0.3);
    eprintln!(
        "simulated: held-out presses {:.2} % median, {:.2} % worst (cap height); sphere: rms {:.1} % of the depth, step across the edge {:+.1} %; flat punch: rms {:.1} %, step {:+.1} %",
        calibration_figures.0,
        calibration_figures.1,
        100.0 * sphere_rms,
        100.0 * sphere_step,
        100.0 * punch_rms,
        100.0 * punch_step
    );
    // Measured 30 Nov (flat field, marker ink left out of the fit): 2.62 % / 3.53 %; the
    // sphere rms 10.0 %, its step −1.1 %; the punch rms 83.9 %, its step −43.1 % (docs/explanation/shape.md: the 5 % is met by
    // the sphere's step only: the gel's bulge around a contact is too gentle for the lights
    // and reads flat, and the punch's wall and wide contact defeat the datum).
    let held = &calibration_figures;
    assert!(held.0 <= 3.0 && held.1 <= 5.0, "held-out {held:?}");
    assert!(sphere_step.abs() <= 0.06, "sphere step {sphere_step}");
    assert!(sphere_rms <= 0.12, "sphere rms {sphere_rms}");
    assert!(punch_step.abs() <= 0.45, "punch step {punch_step}");
}

fn shape_calibrate(
    background: gelrig::shape::Rgb<'_>,
    presses: &[gelrig::shape::Press<'_>],
    ball_px: f64,
    mm_per_px: f64,
) -> gelrig::shape::Calibration {
    gelrig::shape::calibrate(background, presses, ball_px, mm_per_px).unwrap()
}

/// `gelrig track RUN --shape`: a shape sensor calibrated on the simulated bench's own ball
/// presses, with circles found in the image (no labels), reads a dry run's sphere steps
/// into depth.csv; the report shows the contact by depth beside the colour change, with
/// height maps of chosen steps.
#[test]
fn track_with_shape_reads_a_runs_depth_and_the_report_shows_it() {
    use gelrig::sim;
    let tmp = tempfile::tempdir().unwrap();
    let loaded = crate::support::load_ok(&crate::support::protocol("portable-normal-sphere"));
    let spec = sim::plant_spec(&loaded.protocol, &loaded.compiled).unwrap();
    let (w, h) = (640u32, 480u32);
    let mut camera = sim::ContactCamera::new(&spec, w, h).unwrap();
    let mm_per_px = camera.mm_per_px();
    let presses = tmp.path().join("presses");
    std::fs::create_dir_all(&presses).unwrap();
    let save = |name: &str, rgb: Vec<u8>| {
        image::RgbImage::from_raw(w, h, rgb)
            .unwrap()
            .save(presses.join(name))
            .unwrap();
    };
    let background = camera.at_rest(0).rgb;
    save("background.png", background.clone());
    // The circle found in each press against the simulator's contact radius.
    let mut radius_ratio = Vec::new();
    let mut k = 0;
    for y_mm in [-6.0, -2.0, 2.0, 6.0] {
        for x_mm in [-7.0, -2.5, 2.5, 7.0] {
            k += 1;
            let pose = sim::ContactPose {
                depth_mm: 0.2 + 0.25 * (k % 4) as f64,
                centre_mm: (x_mm, y_mm),
                ..Default::default()
            };
            let (f, _) = camera.frame_with_surface(&pose, k).unwrap();
            let found = gelrig::shape::find_circle(
                gelrig::shape::Rgb::new(w as usize, h as usize, &background).unwrap(),
                gelrig::shape::Rgb::new(w as usize, h as usize, &f.rgb).unwrap(),
            )
            .unwrap();
            radius_ratio.push(found.radius_px * mm_per_px / f.contact_radius_mm);
            save(&format!("press_{k:02}.png"), f.rgb);
        }
    }
    let model = tmp.path().join("shape.yaml");
    let out = gelrig_ok([
        "shape".as_ref(),
        "calibrate".as_ref(),
        presses.as_os_str(),
        "--ball-diameter".as_ref(),
        "12.68mm".as_ref(),
        "--mm-per-px".as_ref(),
        format!("{mm_per_px}").as_ref(),
        "--out".as_ref(),
        model.as_os_str(),
    ]);
    eprintln!("found radius / simulator's contact radius: {radius_ratio:.3?}");
    // Measured 29 Nov: 0.88–0.99 (the half-change ratio was taken on the real Mini).
    assert!(
        radius_ratio.iter().all(|r| (0.85..1.05).contains(r)),
        "{radius_ratio:?}"
    );
    eprintln!("{out}");
    assert!(out.contains("calibrated on 16 ball presses"), "{out}");
    assert!(out.contains("circles: found in the image"), "{out}");

    let run = tmp.path().join("run");
    crate::support::copy_run_dir(
        &crate::support::shared_dry_run("portable-normal-sphere"),
        &run,
    );
    let out = gelrig_ok([
        "track".as_ref(),
        run.as_os_str(),
        "--shape".as_ref(),
        model.as_os_str(),
    ]);
    assert!(out.contains("depth.csv"), "{out}");
    assert!(out.contains("height maps of 21 steps"), "{out}");
    let depth = crate::support::csv_rows(&run.join("depth.csv"));
    let frames = crate::support::csv_rows(&run.join("frames.csv"));
    assert_eq!(depth.len(), frames.len());
    // Each step's last frame against the depth of the simulator's cap below its contact's
    // edge (R − √(R² − a²), a the simulator's contact radius): what the lights see. The gel
    // piles up around the sphere (a > √(2Rd − d²)), so the stage's depth lies below it.
    let steps = crate::support::csv_rows(&run.join("steps.csv"));
    let sim = crate::support::csv_rows(&run.join("sim_steps.csv"));
    let ball_mm: f64 = 12.68 / 2.0;
    let mut read = Vec::new();
    for s in &steps {
        let last = frames
            .iter()
            .rfind(|f| f["step"] == s["step"])
            .map(|f| f["frame"].clone())
            .unwrap();
        let row = depth.iter().find(|d| d["frame"] == last).unwrap();
        let got: f64 = row["max_depth_mm"].parse().unwrap();
        let a: f64 = sim.iter().find(|r| r["step"] == s["step"]).unwrap()["contact_radius_mm"]
            .parse()
            .unwrap();
        let cap = ball_mm - (ball_mm * ball_mm - a * a).sqrt();
        let stage: f64 = s["position"].parse().unwrap();
        read.push((s["phase"].clone(), stage, cap, got));
    }
    eprintln!("(phase, stage depth, cap below the edge, deepest read): {read:.3?}");
    // Measured 30 Nov (flat field, marker ink left out of the fit): −1 % (1.0 mm) to +16 %
    // (0.1 mm) against the cap; the docs state −5 to +30 %.
    for (_, stage, cap, got) in &read {
        assert!(
            (-0.05..0.30).contains(&(got / cap - 1.0)),
            "at {stage} mm the cap is {cap:.3} mm and reads {got} mm"
        );
    }
    let loading: Vec<f64> = read.iter().filter(|r| r.0 == "load").map(|r| r.3).collect();
    assert!(loading.windows(2).all(|p| p[1] > p[0]), "{read:?}");

    let out = gelrig_ok(["report".as_ref(), run.as_os_str()]);
    assert!(out.contains("Contact depth from the lights"), "{out}");
    let report = run.join("report");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["depth"].as_array().map(Vec::len), Some(20));
    let pictures: Vec<_> = std::fs::read_dir(&report)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with("depth_step_"))
        .collect();
    assert_eq!(pictures.len(), 6);
    assert!(report.join("depth_step_010.png").is_file());
}
