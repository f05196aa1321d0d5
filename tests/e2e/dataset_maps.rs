//! A dataset's traction maps (`record: {traction_maps: 4}`), read by numpy and Hugging Face
//! `datasets` with no gelrig, against what the simulator knew apart from them: the pressure
//! against the normal force of its tables, the contact mask against its contact radius, the
//! shear and twist traction against the loads its plant carried. The tolerances are
//! docs/reference/dataset.md's.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::support::{gelrig, gelrig_ok, python_peer, root};

/// `gelrig run ARGS --quiet --out DIR`'s run directory.
fn run_into(dir: &Path, args: &[&str]) -> PathBuf {
    let out = Command::new(gelrig())
        .args(args)
        .args(["--quiet", "--out"])
        .arg(dir)
        .current_dir(root())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    PathBuf::from(String::from_utf8_lossy(&out.stdout).trim())
}

/// Per run: the largest relative differences of the maps from the simulator's own figures.
const CHECK: &str = r#"
import datasets, json, math, sys, numpy as np, pathlib
ds = datasets.load_dataset(sys.argv[1], split="train", cache_dir=sys.argv[2])
out = {}
for r in ds:
    key = r["run"].split("_", 1)[1]
    o = out.setdefault(key, {"frames": 0, "fz": 0.0, "area": 0.0, "shear": 0.0, "torque": 0.0,
                             "npy_same": True, "mask_size": None, "loaded": 0})
    o["frames"] += 1
    if r["pressure_kpa"] is None:
        continue
    h, w, c = r["maps_height"], r["maps_width"], r["maps_cell_mm"]
    p = np.array(r["pressure_kpa"], dtype=np.float32).reshape(h, w)
    qx = np.array(r["shear_x_kpa"], dtype=np.float32).reshape(h, w)
    qy = np.array(r["shear_y_kpa"], dtype=np.float32).reshape(h, w)
    mask = np.array(r["contact_mask"]) > 127
    o["mask_size"] = list(r["contact_mask"].size)
    npy = np.load(pathlib.Path(sys.argv[3]) / r["run"] / "sim_maps" / ("%06d.npy" % r["frame"]))
    o["npy_same"] &= bool(np.array_equal(npy[0], p) and np.array_equal(npy[3] > 0.5, mask))
    area = c * c
    fz = float(p.sum()) * area / 1000
    if r["sim_fz_n"] is None or r["sim_fz_n"] < 0.05 or r["sim_frame_depth_mm"] <= 0:
        continue
    o["loaded"] += 1
    o["fz"] = max(o["fz"], abs(fz / r["sim_fz_n"] - 1))
    a = r["sim_contact_radius_mm"]
    if a >= 1.0:
        o["area"] = max(o["area"], abs(mask.sum() * area / (math.pi * a * a) - 1))
    s = r["sim_frame_shear_n"]
    if abs(s) > 0.05:
        o["shear"] = max(o["shear"], abs(float(qx.sum()) * area / 1000 / s - 1))
    t = r["sim_frame_torque_nmm"]
    if abs(t) > 0.05:
        ys, xs = np.mgrid[0:h, 0:w]
        x = (xs + 0.5) * c - w * c / 2 - r["sim_centre_x_mm"]
        y = (ys + 0.5) * c - h * c / 2 - r["sim_centre_y_mm"]
        tz = float((x * qy - y * qx).sum()) * area / 1000
        o["torque"] = max(o["torque"], abs(tz / t - 1))
print(json.dumps(out))
"#;

/// Sphere and flat-punch presses, a shear and a twist, with traction maps: the dataset's
/// maps carry the simulator's loads (pressure within 1 % of its normal force, shear and
/// twist within 1 %, the mask's area within 7 % of its contact once the contact's radius is
/// 1 mm or more), numpy reads the same values from the run's `.npy` files, and a run
/// without maps in the same dataset has null map columns.
#[test]
fn traction_maps_carry_the_simulators_loads_into_the_dataset() {
    if !python_peer(
        "import datasets, PIL, numpy",
        "checking the traction maps with numpy and Hugging Face datasets",
        "pip install datasets pillow numpy",
    ) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let runs = tmp.path().join("runs");
    let press = root().join("protocols/dataset-press.yaml");
    let press = press.to_str().unwrap();
    run_into(&runs, &["run", press, "--name", "sphere"]);
    run_into(
        &runs,
        &[
            "run",
            press,
            "--name",
            "punch",
            "--set",
            "indenter={shape: flat_circle, diameter: 8 mm}",
        ],
    );
    for p in ["portable-shear", "portable-rotation"] {
        run_into(
            &runs,
            &["run", p, "--name", p, "--set", "record.traction_maps=4"],
        );
    }
    run_into(&runs, &["run", "box-normal-flat", "--name", "no-maps"]);
    let ds = tmp.path().join("ds");
    gelrig_ok([
        "export".as_ref(),
        runs.as_os_str(),
        "--format".as_ref(),
        "dataset".as_ref(),
        "--out".as_ref(),
        ds.as_os_str(),
    ]);
    let out = Command::new("python3")
        .args(["-c", CHECK])
        .arg(&ds)
        .arg(tmp.path().join("hf-cache"))
        .arg(&runs)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let get = |run: &str, k: &str| v[run][k].as_f64().unwrap_or(f64::NAN);
    for run in ["sphere", "punch", "portable-shear", "portable-rotation"] {
        assert!(v[run]["npy_same"] == true, "{run}: {v}");
        assert_eq!(v[run]["mask_size"], serde_json::json!([160, 120]), "{run}");
        assert!(get(run, "loaded") >= 10.0, "{run}: {v}");
        assert!(
            get(run, "fz") <= 0.01,
            "{run}: pressure vs normal force {v}"
        );
    }
    for run in ["sphere", "punch"] {
        assert!(get(run, "area") <= 0.07, "{run}: mask vs contact {v}");
    }
    assert!(get("portable-shear", "shear") > 0.0 && get("portable-shear", "shear") <= 0.01);
    let twist = get("portable-rotation", "torque");
    assert!(twist > 0.0 && twist <= 0.01, "{v}");
    assert_eq!(v["no-maps"]["mask_size"], serde_json::Value::Null, "{v}");
    assert!(get("no-maps", "frames") > 10.0, "{v}");
}

/// `gelrig validate box-normal-flat --set record.traction_maps=PX [--rig RIG]`: what it said,
/// asserting it refused.
fn refused(px: u32, rig: Option<&Path>) -> String {
    let mut cmd = Command::new(gelrig());
    cmd.args(["validate", "box-normal-flat", "--set"])
        .arg(format!("record.traction_maps={px}"))
        .current_dir(root());
    if let Some(r) = rig {
        cmd.arg("--rig").arg(r);
    }
    let out = cmd.output().unwrap();
    let said =
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{said}");
    said
}

/// `traction_maps:` refused where it cannot be honoured: a cell size out of range, and a rig
/// whose camera is not simulated; each names the key and the fix.
#[test]
fn traction_maps_are_refused_where_they_cannot_be_made() {
    let said = refused(0, None);
    assert!(
        said.contains("traction maps of 0 px cells") && said.contains("write `traction_maps: 4`"),
        "{said}"
    );
    let tmp = tempfile::tempdir().unwrap();
    let rig = tmp.path().join("folder.yaml");
    std::fs::write(
        &rig,
        "name: folder\naxes:\n  normal: {driver: sim, travel: [0 mm, 25 mm], max_speed: 2 mm/s, resolution: 0.002 mm}\n\
         force: {driver: sim, model: nano17}\n\
         camera: {driver: image_folder, path: frames, width: 640, height: 480, fps: 25 Hz}\n\
         sim: {normal_contact: 10 mm}\n",
    )
    .unwrap();
    let said = refused(4, Some(&rig));
    assert!(
        said.contains("has no simulated camera") && said.contains("remove `traction_maps:`"),
        "{said}"
    );
}
