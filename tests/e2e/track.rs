//! `gelrig track` through the binary: on a dry run's frames (the simulator's exact marker
//! centres are the truth), on PNG files, on the real GelSight Mini sequence when
//! `../shared/data` is present, and on every kind of bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::support::{col, csv_rows, gelrig, image_size, shared_dry_run};

fn track(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(gelrig())
        .arg("track")
        .args(args)
        .output()
        .unwrap()
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A copy of a dry run's frames and tables in a fresh folder, so tests never write into
/// the shared run directory.
fn copy_run(name: &str, into: &Path) -> PathBuf {
    let src = shared_dry_run(name);
    let dst = into.join(name);
    std::fs::create_dir_all(dst.join("frames")).unwrap();
    for entry in std::fs::read_dir(&src)
        .unwrap()
        .chain(std::fs::read_dir(src.join("frames")).unwrap())
    {
        let p = entry.unwrap().path();
        if p.is_file() {
            let rel = p.strip_prefix(&src).unwrap();
            std::fs::copy(&p, dst.join(rel)).unwrap();
        }
    }
    dst
}

/// The rms figure `gelrig track` prints against the simulator's exact centres.
fn truth_rms(stdout: &str) -> f64 {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("against the simulator's exact centres"))
        .unwrap_or_else(|| panic!("no truth line in:\n{stdout}"));
    line.split("rms ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn a_dry_run_directory_tracks_to_the_simulators_exact_centres() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("box-shear-sphere", tmp.path());
    let field = tmp.path().join("field");
    let o = track(&[run.as_os_str(), "--field".as_ref(), field.as_os_str()]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}\n{err}");
    let rms = truth_rms(&out);
    assert!(rms < 0.05, "rms {rms} px against the simulator\n{out}");

    // markers.csv: the columns, frame 0 is the reference with zero displacement,
    // every identity in every frame.
    let csv = run.join("markers.csv");
    let header = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    assert_eq!(
        header,
        "frame,file,id,x_px,y_px,dx_px,dy_px,state,confidence"
    );
    let rows = csv_rows(&csv);
    let frames = csv_rows(&run.join("frames.csv")).len();
    let markers = rows.iter().filter(|r| r["frame"] == "0").count();
    assert_eq!(markers, 288, "the box sensor's 18 × 16 dots");
    assert_eq!(rows.len(), frames * markers);
    for r in rows.iter().filter(|r| r["frame"] == "0") {
        assert_eq!(r["dx_px"].parse::<f64>().unwrap(), 0.0);
        assert_eq!(r["dy_px"].parse::<f64>().unwrap(), 0.0);
        assert_eq!(r["state"], "tracked");
    }
    let ids = col(&rows, "id");
    assert!(
        ids.chunks(markers)
            .all(|c| c.iter().enumerate().all(|(k, &id)| id as usize == k))
    );
    // Shear moves markers: the last frame's largest displacement is well above the noise.
    let last = &rows[rows.len() - markers..];
    let moved = col(last, "dx_px")
        .iter()
        .zip(col(last, "dy_px"))
        .map(|(x, y)| x.hypot(y))
        .fold(0.0, f64::max);
    assert!(moved > 1.0, "largest displacement {moved} px");

    // The field folder: one colour-vector and one quiver picture per frame, and the tables.
    for f in [
        "decomposition.csv",
        "radial_profile.csv",
        "central_line.csv",
    ] {
        assert!(field.join(f).is_file(), "{f}");
    }
    let count = |prefix: &str, ext: &str| {
        std::fs::read_dir(&field)
            .unwrap()
            .filter(|e| {
                let n = e
                    .as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .into_owned();
                n.starts_with(prefix) && n.ends_with(ext)
            })
            .count()
    };
    assert_eq!(count("field_", ".png"), frames);
    assert_eq!(count("quiver_", ".png"), frames);
    assert_eq!(count("quiver_", ".svg"), frames);
    let decomposition = csv_rows(&field.join("decomposition.csv"));
    assert_eq!(decomposition.len(), frames);
}

#[test]
fn png_files_with_a_reference_give_the_same_tracks_as_the_run_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("portable-rotation", tmp.path());
    let o = track(&[run.as_os_str()]);
    assert!(o.status.success(), "{:?}", text(&o));
    let from_dir = std::fs::read_to_string(run.join("markers.csv")).unwrap();

    let frames: Vec<PathBuf> = csv_rows(&run.join("frames.csv"))
        .iter()
        .map(|r| run.join(&r["file"]))
        .collect();
    let out = tmp.path().join("files.csv");
    let mut args: Vec<&std::ffi::OsStr> = vec!["--reference".as_ref(), frames[0].as_os_str()];
    args.extend(frames[1..].iter().map(|p| p.as_os_str()));
    args.extend([
        "--out".as_ref(),
        out.as_os_str(),
        "--method".as_ref(),
        "centroid".as_ref(),
    ]);
    let o = track(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(
        !stdout.contains("simulator"),
        "loose files carry no truth:\n{stdout}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), from_dir);
}

#[test]
fn every_method_runs_and_lk_stays_close_to_the_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("portable-rotation", tmp.path());
    for method in ["centroid+lk", "lk"] {
        let out = tmp.path().join(format!("{method}.csv"));
        let o = track(&[
            run.as_os_str(),
            "--method".as_ref(),
            method.as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{method}: {stdout}\n{stderr}");
        let rms = truth_rms(&stdout);
        assert!(rms < 0.05, "{method}: rms {rms} px");
    }
    let o = track(&[run.as_os_str(), "--method".as_ref(), "sift".as_ref()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("centroid"), "{:?}", text(&o));
}

#[test]
fn bad_inputs_are_refused_with_the_place_and_the_fix() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("portable-rotation", tmp.path());
    let frame0 = run.join("frames/000000.png");
    let frame1 = run.join("frames/000001.png");
    let out = tmp.path().join("markers.csv");
    let refused = |args: &[&std::ffi::OsStr], needles: &[&str]| {
        let mut args = args.to_vec();
        args.extend(["--out".as_ref(), out.as_os_str()]);
        let o = track(&args);
        let (out, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}\n{out}\n{err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: {n:?} not in\n{err}");
        }
        assert!(!err.contains("panicked"), "{err}");
    };
    // Loose frames without a reference.
    refused(&[frame1.as_os_str()], &["--reference", "fix:"]);
    // A missing frame.
    let missing = tmp.path().join("nope.png");
    refused(
        &[
            "--reference".as_ref(),
            frame0.as_os_str(),
            missing.as_os_str(),
        ],
        &["nope.png", "fix:"],
    );
    // Not a PNG.
    let junk = tmp.path().join("junk.png");
    std::fs::write(&junk, b"not an image").unwrap();
    refused(
        &["--reference".as_ref(), frame0.as_os_str(), junk.as_os_str()],
        &["junk.png", "PNG", "fix:"],
    );
    // A frame of another size.
    let small = tmp.path().join("small.png");
    write_png(&small, (320, 240), |_, _| [200, 200, 200]);
    refused(
        &[
            "--reference".as_ref(),
            frame0.as_os_str(),
            small.as_os_str(),
        ],
        &["small.png", "320", "fix:"],
    );
    // A reference that is not a marker image at all (a flat grey frame of the right size).
    let grey = tmp.path().join("grey.png");
    let size = image_size(&frame0);
    write_png(&grey, size, |_, _| [128, 128, 128]);
    refused(
        &["--reference".as_ref(), grey.as_os_str(), frame1.as_os_str()],
        &["grey.png", "fix:"],
    );
    // A run directory without its frame table.
    let bare = tmp.path().join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    refused(&[bare.as_os_str()], &["frames.csv", "fix:"]);
    // Impossible numbers, and a blank frame for a reference-free start or detection.
    let f0: &std::ffi::OsStr = frame0.as_os_str();
    for (flag, value) in [
        ("--mm-per-px", "-1"),
        ("--mm-per-px", "nan"),
        ("--contact-min-change", "-0.5"),
    ] {
        refused(
            &[
                "--reference".as_ref(),
                f0,
                frame1.as_os_str(),
                flag.as_ref(),
                value.as_ref(),
            ],
            &[flag, "fix:"],
        );
    }
    refused(
        &["--reference-free".as_ref(), grey.as_os_str()],
        &["grey.png", "fix:"],
    );
    refused(
        &["--detect-only".as_ref(), grey.as_os_str()],
        &["grey.png", "fix:"],
    );
    // markers.csv and contact.csv must not be one file.
    let o = track(&[
        "--reference".as_ref(),
        f0,
        frame1.as_os_str(),
        "--out".as_ref(),
        tmp.path().join("contact.csv").as_os_str(),
    ]);
    let (o_out, o_err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{o_out}\n{o_err}");
    assert!(
        o_err.contains("contact.csv") && o_err.contains("fix:"),
        "{o_err}"
    );
}

#[test]
fn a_bad_frame_midway_keeps_every_frame_tracked_before_it() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("portable-rotation", tmp.path());
    let f = |k: usize| run.join(format!("frames/{k:06}.png"));
    let out = tmp.path().join("partial.csv");
    let missing = tmp.path().join("gone.png");
    let o = track(&[
        "--reference".as_ref(),
        f(0).as_os_str(),
        f(1).as_os_str(),
        f(2).as_os_str(),
        missing.as_os_str(),
        f(3).as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
    let rows = csv_rows(&out);
    let frames: std::collections::BTreeSet<String> =
        rows.iter().map(|r| r["frame"].clone()).collect();
    assert_eq!(frames.into_iter().collect::<Vec<_>>(), ["0", "1", "2"]);
}

/// Reads ../shared/data (a logged skip when absent; a failure under GELRIG_REQUIRE_DATA=1).
#[test]
fn the_real_mini_sequence_tracks_end_to_end() {
    let Some(dir) = crate::support::mini_press_dir("tracking the real GelSight Mini press") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let frames: Vec<PathBuf> = (0..219)
        .map(|k| dir.join(format!("frame_{k:04}.png")))
        .collect();
    let out = tmp.path().join("markers.csv");
    let mut args: Vec<&std::ffi::OsStr> = vec!["--reference".as_ref(), frames[0].as_os_str()];
    args.extend(frames[1..].iter().map(|p| p.as_os_str()));
    args.extend(["--out".as_ref(), out.as_os_str()]);
    // The Mini's automatic exposure drifts on the untouched gel: the documented threshold.
    args.extend([
        std::ffi::OsStr::new("--contact-min-change"),
        std::ffi::OsStr::new("0.2"),
    ]);
    let o = track(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    // Contact: none while the gel is untouched (frames 1–56), a region in most frames of
    // the press (90–140), wider than a few markers.
    let contact = csv_rows(&tmp.path().join("contact.csv"));
    assert_eq!(contact.len(), 219);
    let area = |k: usize| contact[k]["area_px2"].parse::<f64>().unwrap();
    let still: Vec<usize> = (1..=56).filter(|&k| area(k) > 0.0).collect();
    assert!(still.is_empty(), "contact on untouched frames {still:?}");
    let pressed = (90..=140).filter(|&k| area(k) > 4000.0).count();
    assert!(
        pressed >= 40,
        "{pressed} of 51 pressed frames show a contact over 4000 px²"
    );
    let rows = csv_rows(&out);
    let markers = rows.iter().filter(|r| r["frame"] == "0").count();
    assert!(markers >= 75, "{markers} markers");
    assert_eq!(rows.len(), 219 * markers);
    let lost = rows.iter().filter(|r| r["state"] == "lost").count();
    assert_eq!(lost, 0, "no marker of the Mini sequence is ever lost");
    // The largest deformation is the press-and-shear around frames 90–140.
    let line = stdout
        .lines()
        .find(|l| l.starts_with("largest deformation"))
        .unwrap();
    let frame: u32 = line
        .split("frame ")
        .nth(1)
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((90..=140).contains(&frame), "{line}");
}

/// The sphere's contact radius seen in the image against the simulator's, step by step
/// (thesis §5.1 measured contact diameters on the camera's frames).
#[test]
fn the_contact_region_of_a_sphere_matches_the_simulators_contact_radius() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("box-normal-sphere", tmp.path());
    let field = tmp.path().join("field");
    let o = track(&[run.as_os_str(), "--field".as_ref(), field.as_os_str()]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}\n{err}");
    assert!(out.contains("contact in "), "{out}");
    let path = run.join("contact.csv");
    let header = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        header.lines().next().unwrap(),
        "frame,area_px2,area_mm2,cx_px,cy_px,radius_mm,radius_px,sxx_px2,syy_px2,sxy_px2"
    );
    let contact = csv_rows(&path);
    let frames = csv_rows(&run.join("frames.csv"));
    let steps = csv_rows(&run.join("sim_steps.csv"));
    let step_of = |frame: &str| {
        frames
            .iter()
            .find(|r| r["frame"] == frame)
            .map(|r| r["step"].clone())
            .unwrap()
    };
    let (mut checked, mut worst) = (0, 0.0f64);
    for row in &contact {
        let step = step_of(&row["frame"]);
        if step == "0" {
            assert_eq!(
                row["area_px2"].parse::<f64>().ok(),
                Some(0.0),
                "reference: no contact"
            );
            assert_eq!(row["cx_px"], "", "and no centroid");
            continue;
        }
        let truth = steps.iter().find(|s| s["step"] == step).unwrap();
        let depth: f64 = truth["depth_mm"].parse().unwrap();
        let a: f64 = truth["contact_radius_mm"].parse().unwrap();
        if depth < 0.3 {
            continue;
        }
        let r: f64 = row["radius_mm"].parse().unwrap();
        let area: f64 = row["area_mm2"].parse().unwrap();
        assert!((area - std::f64::consts::PI * r * r).abs() < 1e-3 * area.max(1.0));
        let rel = r / a - 1.0;
        assert!(
            rel.abs() <= 0.04,
            "step {step}, depth {depth} mm: radius {r} mm against the simulator's {a} mm"
        );
        // The sphere presses the centre of the view.
        let (cx, cy): (f64, f64) = (row["cx_px"].parse().unwrap(), row["cy_px"].parse().unwrap());
        assert!(
            (cx - 319.5).abs() < 3.0 && (cy - 239.5).abs() < 3.0,
            "({cx}, {cy})"
        );
        // Its region's second moments are a disc's: r²/4 on average, and round (the
        // moment ellipse's axes within 10 % of each other's squares).
        let rp: f64 = row["radius_px"].parse().unwrap();
        let m: Vec<f64> = ["sxx_px2", "syy_px2", "sxy_px2"]
            .iter()
            .map(|c| row[*c].parse().unwrap())
            .collect();
        let disc = rp * rp / 4.0;
        let (mean, half_diff) = (
            0.5 * (m[0] + m[1]),
            (0.25 * (m[0] - m[1]).powi(2) + m[2] * m[2]).sqrt(),
        );
        assert!(
            (mean / disc - 1.0).abs() < 0.1 && half_diff < 0.1 * mean,
            "step {step}: moments {m:?} against a disc's {disc}"
        );
        worst = worst.max(rel.abs());
        checked += 1;
    }
    assert!(checked >= 18, "{checked} steps from 0.3 mm on");
    eprintln!(
        "contact radius: worst {:.1} % over {checked} steps",
        100.0 * worst
    );
    // The outline is drawn on the field pictures (dashed magenta).
    let svg = std::fs::read_to_string(field.join("quiver_000015.svg")).unwrap();
    assert!(
        svg.to_lowercase().contains("e600c8"),
        "no outline in the quiver SVG"
    );

    // Without contact, no contact.csv.
    std::fs::remove_file(&path).unwrap();
    let o = track(&[run.as_os_str(), "--no-contact".as_ref()]);
    assert!(o.status.success(), "{:?}", text(&o));
    assert!(!path.exists());
}

/// A recording that starts at 1.1 mm of the sphere's indentation, with no untouched frame:
/// the lattice from the periphery, displacements against the simulator's.
#[test]
fn a_reference_free_start_measures_the_sphere_from_its_periphery() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("box-normal-sphere", tmp.path());
    let frames: Vec<PathBuf> = (10..=20)
        .map(|k| run.join(format!("frames/{k:06}.png")))
        .collect();
    let out = tmp.path().join("markers.csv");
    let mut args: Vec<&std::ffi::OsStr> = vec!["--reference-free".as_ref()];
    args.extend(frames.iter().map(|p| p.as_os_str()));
    args.extend(["--out".as_ref(), out.as_os_str()]);
    let o = track(&args);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("reference-free start: lattice"), "{stdout}");
    assert!(
        !tmp.path().join("contact.csv").exists(),
        "no contact without the untouched gel"
    );
    // Truth: the simulator's centres, frame 0 of the run being the untouched gel.
    let sim = csv_rows(&run.join("sim_markers.csv"));
    let at = |frame: usize| -> Vec<[f64; 2]> {
        sim.iter()
            .filter(|r| r["frame"] == frame.to_string())
            .map(|r| [r["x_px"].parse().unwrap(), r["y_px"].parse().unwrap()])
            .collect()
    };
    let rest = at(0);
    let rows = csv_rows(&out);
    let (mut sq, mut n, mut worst_site) = (0.0, 0usize, 0.0f64);
    for k in 0..=10usize {
        let truth = at(10 + k);
        for r in rows.iter().filter(|r| r["frame"] == k.to_string()) {
            if r["state"] != "tracked" {
                continue;
            }
            let v = |c: &str| r[c].parse::<f64>().unwrap();
            let site = [v("x_px") - v("dx_px"), v("y_px") - v("dy_px")];
            let (m, d) = rest
                .iter()
                .enumerate()
                .map(|(m, p)| (m, (p[0] - site[0]).hypot(p[1] - site[1])))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap();
            worst_site = worst_site.max(d);
            let moved = [truth[m][0] - rest[m][0], truth[m][1] - rest[m][1]];
            sq += (v("dx_px") - moved[0]).powi(2) + (v("dy_px") - moved[1]).powi(2);
            n += 1;
        }
    }
    let rms = (sq / n as f64).sqrt();
    assert!(n >= 11 * 280, "{n} tracked rows");
    assert!(
        worst_site < 0.15,
        "a site is {worst_site} px from its printed marker"
    );
    assert!(rms < 0.1, "displacement rms {rms} px against the simulator");
    eprintln!(
        "reference-free start on the sphere: sites within {worst_site:.3} px, rms {rms:.3} px"
    );
}

#[test]
fn detect_only_finds_every_marker_of_a_single_frame() {
    let tmp = tempfile::tempdir().unwrap();
    let run = copy_run("box-normal-sphere", tmp.path());
    let frame = run.join("frames/000015.png");
    let out = tmp.path().join("d.csv");
    let o = track(&[
        "--detect-only".as_ref(),
        frame.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stdout}\n{stderr}");
    let header = std::fs::read_to_string(&out).unwrap();
    assert_eq!(
        header.lines().next().unwrap(),
        "frame,id,x_px,y_px,area_px,border"
    );
    let rows = csv_rows(&out);
    let sim = csv_rows(&run.join("sim_markers.csv"));
    let truth: Vec<[f64; 2]> = sim
        .iter()
        .filter(|r| r["frame"] == "15")
        .map(|r| [r["x_px"].parse().unwrap(), r["y_px"].parse().unwrap()])
        .collect();
    assert_eq!(rows.len(), truth.len(), "every marker, nothing else");
    for r in &rows {
        let p = [
            r["x_px"].parse::<f64>().unwrap(),
            r["y_px"].parse::<f64>().unwrap(),
        ];
        let d = truth
            .iter()
            .map(|t| (t[0] - p[0]).hypot(t[1] - p[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(d < 0.1, "detection {p:?} is {d} px from the nearest marker");
    }
    // A run directory is not a frame; random triangles are no lattice.
    let o = track(&["--detect-only".as_ref(), run.as_os_str()]);
    assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
    assert!(text(&o).1.contains("fix:"), "{:?}", text(&o));
    let portable = copy_run("portable-rotation", tmp.path());
    let o = track(&[
        "--reference-free".as_ref(),
        portable.join("frames/000001.png").as_os_str(),
        "--out".as_ref(),
        tmp.path().join("p.csv").as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
    assert!(
        text(&o).1.contains("fix: pass --reference"),
        "{:?}",
        text(&o)
    );
}

fn write_png(path: &Path, (w, h): (u32, u32), px: impl Fn(u32, u32) -> [u8; 3]) {
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb(px(x, y)))
        .save(path)
        .unwrap();
}

/// Writes `motion`'s frames of `scene` as PNG files (frame 0, the reference, first) and
/// returns their paths and every frame's exact marker centres.
fn write_scene(
    dir: &Path,
    scene: &simbench::Scene,
    motion: &simbench::Motion,
) -> (Vec<PathBuf>, Vec<Vec<[f64; 2]>>) {
    let look = simbench::Look::default();
    let (w, h) = scene.size();
    let (mut paths, mut truth) = (Vec::new(), Vec::new());
    for k in 0..motion.frames() {
        let (rgb, centres) = scene.frame(motion, k, &look);
        let p = dir.join(format!("frame_{k:04}.png"));
        image::RgbImage::from_raw(w, h, rgb)
            .unwrap()
            .save(&p)
            .unwrap();
        paths.push(p);
        truth.push(centres);
    }
    (paths, truth)
}

/// Tracks `paths` (the first is the reference) and returns the command's output and the
/// rows of `markers.csv` scored against `truth`: (measured rows, of them wrong by a
/// spacing's third or more, frames with a row).
fn track_scene(
    dir: &Path,
    paths: &[PathBuf],
    truth: &[Vec<[f64; 2]>],
) -> (Output, usize, usize, usize) {
    let out = dir.join("markers.csv");
    let mut args: Vec<&std::ffi::OsStr> = vec!["--reference".as_ref(), paths[0].as_os_str()];
    args.extend(paths[1..].iter().map(|p| p.as_os_str()));
    args.extend(["--out".as_ref(), out.as_os_str(), "--no-contact".as_ref()]);
    let o = track(&args);
    if !o.status.success() {
        return (o, 0, 0, 0);
    }
    let rows = csv_rows(&out);
    let xy = |r: &std::collections::BTreeMap<String, String>| -> [f64; 2] {
        [r["x_px"].parse().unwrap(), r["y_px"].parse().unwrap()]
    };
    // Marker id → printed marker, by the nearest centre on the reference frame.
    let reference: std::collections::BTreeMap<usize, [f64; 2]> = rows
        .iter()
        .filter(|r| r["frame"] == "0")
        .map(|r| (r["id"].parse().unwrap(), xy(r)))
        .collect();
    let printed = |p: [f64; 2]| {
        (0..truth[0].len())
            .min_by(|&a, &b| {
                let da = (truth[0][a][0] - p[0]).hypot(truth[0][a][1] - p[1]);
                let db = (truth[0][b][0] - p[0]).hypot(truth[0][b][1] - p[1]);
                da.total_cmp(&db)
            })
            .unwrap()
    };
    let ids: std::collections::BTreeMap<usize, usize> =
        reference.iter().map(|(&id, &p)| (id, printed(p))).collect();
    let (mut measured, mut wrong) = (0, 0);
    let mut frames = std::collections::BTreeSet::new();
    for r in &rows {
        let frame: usize = r["frame"].parse().unwrap();
        frames.insert(frame);
        if !matches!(r["state"].as_str(), "tracked" | "border" | "merged") || frame == 0 {
            continue;
        }
        measured += 1;
        let t = truth[frame][ids[&r["id"].parse::<usize>().unwrap()]];
        let p = xy(r);
        if (p[0] - t[0]).hypot(p[1] - t[1]) > 10.0 {
            wrong += 1;
        }
    }
    (o, measured, wrong, frames.len())
}

#[test]
fn a_whole_spacing_jump_or_an_ambiguous_pan_is_a_frame_not_a_failure() {
    use simbench::{MarkerLayout, Motion, Scene};
    let grid = MarkerLayout::Grid {
        columns: 18,
        rows: 16,
        spacing_mm: 2.52,
        diameter_mm: 1.4,
    };
    let triangles = MarkerLayout::Random {
        spacing_mm: 2.0,
        size_mm: 0.7,
    };
    // The box grid one spacing larger than the view (its edges in view), 30 px apart, and
    // three spacings larger (a jump of one spacing along a row is then the same image: no
    // tracker can see it, but the command must go on); random triangles jumping two
    // spacings; the larger grid panned half a spacing per frame along a column and back.
    let edged = Scene::new(&grid, (45.36, 40.32), (640, 480), 1);
    let wide = Scene::new(&grid, (45.36, 40.32), (640, 480), 3);
    let dense = Scene::new(&triangles, (46.0, 36.0), (640, 480), 0);
    let (s, t) = (wide.spacing_px(), dense.spacing_px());
    let jump = |by: [f64; 2]| Motion::Jump { by_px: by, hold: 3 };
    let mut pan: Vec<[f64; 2]> = vec![[0.0, 0.5 * s]; 3];
    pan.extend([[0.0, -0.5 * s]; 3]);
    // (name, scene, motion, every measured row must be right)
    let cases = [
        ("grid jump, edges in view", &edged, jump([s, 0.0]), true),
        ("grid jump, the same image", &wide, jump([s, 0.0]), false),
        ("grid pan", &wide, Motion::from_steps(&pan), true),
        ("triangles jump", &dense, jump([1.6 * t, 1.2 * t]), true),
    ];
    for (name, scene, motion, right) in &cases {
        let tmp = tempfile::tempdir().unwrap();
        let (paths, truth) = write_scene(tmp.path(), scene, motion);
        let (o, measured, wrong, frames) = track_scene(tmp.path(), &paths, &truth);
        let (stdout, stderr) = text(&o);
        assert!(o.status.success(), "{name}: {stderr}");
        assert_eq!(frames, paths.len(), "{name}: every frame has its rows");
        if *right {
            assert_eq!(
                wrong, 0,
                "{name}: {wrong} of {measured} measured rows wrong"
            );
        }
        if *name == "grid pan" {
            assert!(stdout.contains("frame(s) ambiguous"), "{name}: {stdout}");
        }
        if name.starts_with("triangles") || name.ends_with("edges in view") {
            // The frames tell the jump: every frame after it is measured.
            let visible: usize = truth[1..]
                .iter()
                .flatten()
                .filter(|p| p[0] > 12.0 && p[1] > 12.0 && p[0] < 627.0 && p[1] < 467.0)
                .count();
            assert!(
                measured as f64 >= 0.95 * visible as f64,
                "{name}: {measured} rows measured of {visible} markers in view"
            );
        }
    }
}
