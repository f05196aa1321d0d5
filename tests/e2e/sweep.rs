//! `gelrig sweep`: a protocol over a grid of its parameters, each point its own `gelrig run`;
//! a finished point never run again, a failed one recorded without stopping the others,
//! every point checked before any runs; shards merged equal to a local run point for point,
//! on a real single-node Slurm too; the campaign in `gelrig runs` and in Parquet with the
//! parameters as columns.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::support::{csv_rows, gelrig, gelrig_ok, python_peer};

/// Four points of the 4 s flat-punch protocol: two punch sizes × two seeds.
const GRID: &str = "sweep: punch-demo\nprotocol: box-normal-flat\ngrid:\n  indenter.diameter: [6 mm, 9.5 mm]\n  seed: [1, 2]\n";

fn sweep_file(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("sweep.yaml");
    std::fs::write(&p, text).unwrap();
    p
}

fn sweep(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(gelrig())
        .arg("sweep")
        .args(args)
        .output()
        .unwrap()
}

/// The 4-point grid run into `tmp/<name>`: the sweep file and the campaign folder.
fn grid_campaign(tmp: &Path, name: &str) -> (PathBuf, PathBuf) {
    let file = sweep_file(tmp, GRID);
    let dir = tmp.join(name);
    let out = sweep(&[file.as_os_str(), "--out".as_ref(), dir.as_os_str()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (file, dir)
}

/// Every point's recorded tables, by point name: the run's steps, force, frames and the
/// simulator's truth, byte for byte.
fn tables(campaign: &Path) -> Vec<(String, Vec<Vec<u8>>)> {
    let mut out = Vec::new();
    for row in csv_rows(&campaign.join("campaign.csv")) {
        assert_eq!(row["status"], "completed", "{row:?}");
        let run = campaign.join(&row["run_dir"]);
        let files = [
            "steps.csv",
            "force.csv",
            "frames.csv",
            "sim_steps.csv",
            "frames/000005.png",
        ]
        .iter()
        .map(|f| std::fs::read(run.join(f)).unwrap())
        .collect();
        out.push((row["name"].clone(), files));
    }
    out
}

#[test]
fn a_sweep_runs_every_point_once_records_failures_and_merges_its_shards_identically() {
    let tmp = tempfile::tempdir().unwrap();
    let file = sweep_file(tmp.path(), GRID);
    let local = tmp.path().join("local");
    let out = sweep(&[
        file.as_os_str(),
        "--out".as_ref(),
        local.as_os_str(),
        "-j".as_ref(),
        "2".as_ref(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("4 points; 0 done before, 4 to run, 2 at a time"),
        "{err}"
    );
    let rows = csv_rows(&local.join("campaign.csv"));
    assert_eq!(rows.len(), 4);
    assert_eq!(rows[3]["name"], "0003_diameter-9.5mm_seed-2");
    assert_eq!(
        (
            rows[3]["indenter.diameter"].as_str(),
            rows[3]["seed"].as_str()
        ),
        ("9.5 mm", "2")
    );
    // Each run recorded its point: the edited protocol and the seed.
    let run = local.join(&rows[3]["run_dir"]);
    let protocol = std::fs::read_to_string(run.join("protocol.yaml")).unwrap();
    assert!(protocol.contains("9.5 mm"), "{protocol}");
    assert_eq!(crate::support::manifest(&run).seed, 2);

    // Run again: nothing to do.
    let out = sweep(&[file.as_os_str(), "--out".as_ref(), local.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && err.contains("4 done before, 0 to run"),
        "{err}"
    );

    // The same sweep as two shards, one by flag and one as a Slurm array task reads it,
    // then merged: the same points, the same recorded data.
    let sharded = tmp.path().join("sharded");
    let out = sweep(&[
        file.as_os_str(),
        "--out".as_ref(),
        sharded.as_os_str(),
        "--shard".as_ref(),
        "1/2".as_ref(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(gelrig())
        .arg("sweep")
        .arg(&file)
        .arg("--out")
        .arg(&sharded)
        .env("SLURM_ARRAY_TASK_ID", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "2")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && err.contains("2 points in shard 2/2 of 4"),
        "{err}"
    );
    let merged = gelrig_ok([
        "sweep".as_ref(),
        file.as_os_str(),
        "--out".as_ref(),
        sharded.as_os_str(),
        "--merge".as_ref(),
    ]);
    assert!(
        merged.contains("4 completed, 0 failed, 0 not run"),
        "{merged}"
    );
    assert_eq!(tables(&local), tables(&sharded));

    // `gelrig runs` lists the campaign's runs.
    let listing = crate::support::runs_listing(&local);
    assert_eq!(listing.matches("completed").count(), 4, "{listing}");
}

#[test]
fn a_failing_point_is_recorded_and_the_others_run() {
    let tmp = tempfile::tempdir().unwrap();
    // The second point's force limit stops its run at the first step (exit 3).
    let file = sweep_file(
        tmp.path(),
        "sweep: limits\nprotocol: box-normal-flat\nlist:\n  - {seed: 1}\n  - {seed: 2, safety.max_fz: 0.5 N}\n  - {seed: 3}\n",
    );
    let dir = tmp.path().join("c");
    let out = sweep(&[
        file.as_os_str(),
        "--out".as_ref(),
        dir.as_os_str(),
        "-j".as_ref(),
        "1".as_ref(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let rows = csv_rows(&dir.join("campaign.csv"));
    let status: Vec<&str> = rows.iter().map(|r| r["status"].as_str()).collect();
    assert_eq!(status, ["completed", "failed", "completed"]);
    assert_eq!(rows[1]["exit_code"], "3");
    assert!(
        rows[1]["message"].contains("max_fz") || rows[1]["message"].contains("force"),
        "{:?}",
        rows[1]
    );
    assert_eq!(rows[1]["safety.max_fz"], "0.5 N");
    // Run again: only the failed point runs (and fails again).
    let out = sweep(&[file.as_os_str(), "--out".as_ref(), dir.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("2 done before, 1 to run"), "{err}");
}

#[test]
fn a_bad_sweep_is_refused_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("c");
    // A point whose value the protocol refuses: no point runs.
    let file = sweep_file(
        tmp.path(),
        "sweep: bad\nprotocol: box-normal-flat\ngrid:\n  indenter.diameter: [6 mm, -2 mm]\n",
    );
    let out = sweep(&[file.as_os_str(), "--out".as_ref(), dir.as_os_str()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("0001_diameter--2mm") && err.contains("no point was run"),
        "{err}"
    );
    assert!(!dir.join("points").exists());
    // A sweep file with a typo names the key.
    let file = sweep_file(
        tmp.path(),
        "sweep: bad\nprotocol: box-normal-flat\ngird: {seed: [1]}\n",
    );
    let out = sweep(&[file.as_os_str(), "--plan".as_ref()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("gird") && err.contains("unknown key"), "{err}");
    // A shard that cannot be.
    let file = sweep_file(tmp.path(), GRID);
    let out = sweep(&[
        file.as_os_str(),
        "--out".as_ref(),
        dir.as_os_str(),
        "--shard".as_ref(),
        "3/2".as_ref(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("I/N"), "{err}");
    // The plan shows every point and runs nothing.
    let plan = gelrig_ok(["sweep".as_ref(), file.as_os_str(), "--plan".as_ref()]);
    assert!(
        plan.contains("4 points") && plan.contains("0002_diameter-9.5mm_seed-1"),
        "{plan}"
    );
}

#[test]
fn parquet_has_the_parameters_as_columns() {
    if !python_peer(
        "import pandas, pyarrow",
        "reading a campaign's Parquet with pandas",
        "pip install pandas pyarrow",
    ) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (_, dir) = grid_campaign(tmp.path(), "c");
    let pq = tmp.path().join("pq");
    gelrig_ok([
        "export".as_ref(),
        dir.as_os_str(),
        "--format".as_ref(),
        "parquet".as_ref(),
        "--out".as_ref(),
        pq.as_os_str(),
    ]);
    let script = "import pandas as pd, sys, json\n\
        s = pd.read_parquet(sys.argv[1] + '/steps.parquet')\n\
        g = s.groupby(['indenter.diameter_mm', 'seed'])['fz_n'].max()\n\
        print(json.dumps({'columns': list(s.columns[:3]), 'groups': len(g), 'dtype': str(s['indenter.diameter_mm'].dtype), 'fz': {str(k): v for k, v in g.items()}}))\n";
    let out = Command::new("python3")
        .args(["-c", script])
        .arg(&pq)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        v["columns"],
        serde_json::json!(["run", "indenter.diameter_mm", "seed"])
    );
    assert_eq!(v["groups"], 4);
    assert_eq!(v["dtype"], "float64");
    // The larger punch presses harder at the same depth.
    let fz = |k: &str| v["fz"][k].as_f64().unwrap();
    assert!(fz("(9.5, 1)") > 1.5 * fz("(6.0, 1)"), "{v}");
}

/// On a real single-node Slurm (`.ci/slurm up`): the array of four shards (the issue's) and
/// its merge job, submitted as `--slurm` writes them, give the local run's data point for
/// point.
#[test]
fn a_slurm_array_runs_the_sweep_as_a_local_run_does() {
    let up = Command::new("sinfo")
        .args(["-h", "-o", "%t"])
        .output()
        .is_ok_and(|o| o.status.success() && String::from_utf8_lossy(&o.stdout).contains("idle"));
    if !up {
        testkit::skip(
            testkit::Need::Slurm,
            "a sweep as a Slurm job array",
            "no Slurm answers here (sinfo): apt-get install slurm-wlm munge, then .ci/slurm up",
        );
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (file, local) = grid_campaign(tmp.path(), "local");
    let cluster = tmp.path().join("cluster");
    let wrote = gelrig_ok([
        "sweep".as_ref(),
        file.as_os_str(),
        "--out".as_ref(),
        cluster.as_os_str(),
        "--slurm".as_ref(),
        "--shards".as_ref(),
        "4".as_ref(),
    ]);
    assert!(wrote.contains("Slurm array of 4 tasks"), "{wrote}");
    let submit = Command::new("bash")
        .arg(cluster.join("slurm/submit.sh"))
        .env("GELRIG_BIN", gelrig())
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&submit.stdout).into_owned();
    assert!(
        submit.status.success(),
        "{}",
        String::from_utf8_lossy(&submit.stderr)
    );
    let merge_job = said
        .rsplit("merge job ")
        .next()
        .map(|s| s.trim().to_string())
        .unwrap();
    // Wait for the merge job (it runs after every array task) to leave the queue.
    let started = std::time::Instant::now();
    loop {
        let q = Command::new("squeue")
            .args(["-h", "-j", &merge_job])
            .output()
            .unwrap();
        if String::from_utf8_lossy(&q.stdout).trim().is_empty() {
            break;
        }
        assert!(
            started.elapsed().as_secs() < 600,
            "the Slurm jobs did not finish in 10 min: {said}"
        );
        std::thread::sleep(std::time::Duration::from_millis(500));
    }
    let csv = cluster.join("campaign.csv");
    assert!(
        csv.is_file(),
        "no campaign.csv: {:?}",
        std::fs::read_dir(cluster.join("slurm")).map(|d| d.count())
    );
    assert_eq!(tables(&local), tables(&cluster));
    let logs: Vec<_> = std::fs::read_dir(cluster.join("slurm"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".out"))
        .collect();
    assert_eq!(logs.len(), 5, "four array tasks and the merge");
}

/// `gelrig export CAMPAIGN --format dataset`: Hugging Face `datasets` loads the folder as it
/// is — every frame a decoded image, the labels typed, the sweep's parameters as columns.
#[test]
fn a_campaign_becomes_a_dataset_that_hugging_face_datasets_loads() {
    if !python_peer(
        "import datasets, PIL",
        "loading the dataset with Hugging Face datasets (and Pillow, which decodes its images)",
        "pip install datasets pillow",
    ) {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (_, dir) = grid_campaign(tmp.path(), "c");
    let ds = tmp.path().join("ds");
    let said = gelrig_ok([
        "export".as_ref(),
        dir.as_os_str(),
        "--format".as_ref(),
        "dataset".as_ref(),
        "--out".as_ref(),
        ds.as_os_str(),
    ]);
    // box-normal-flat: the reference frame and one a step, 20 steps, 4 runs.
    assert!(said.contains("84 frames of 4 run(s)"), "{said}");
    let card = std::fs::read_to_string(ds.join("README.md")).unwrap();
    assert!(card.contains("path: data/train-*.parquet") && card.contains("`indenter.diameter_mm`"));
    let script = "import datasets, json, sys\n\
        ds = datasets.load_dataset(sys.argv[1], split='train', cache_dir=sys.argv[2])\n\
        r = ds[5]\n\
        big = [x for x in ds if x['indenter.diameter_mm'] == 9.5 and x['seed'] == 1]\n\
        deepest = max(big, key=lambda x: x['sim_depth_mm'] or 0)\n\
        print(json.dumps({'rows': len(ds), 'image': type(r['image']).__name__, 'size': list(r['image'].size),\n\
            'image_feature': type(ds.features['image']).__name__, 'markers': len(r['marker_dx_px']),\n\
            'deepest_depth': deepest['sim_depth_mm'], 'deepest_fz': deepest['fz_n'],\n\
            'deepest_shift': max(abs(v) for v in deepest['marker_dx_px'] + deepest['marker_dy_px']),\n\
            'indenter': json.loads(r['indenter'])}))\n";
    let out = Command::new("python3")
        .args(["-c", script])
        .arg(&ds)
        .arg(tmp.path().join("hf-cache"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["rows"], 84, "{v}");
    assert_eq!(
        (v["image_feature"].as_str(), v["image"].as_str()),
        (Some("Image"), Some("PngImageFile"))
    );
    assert_eq!(v["size"], serde_json::json!([640, 480]));
    assert!(v["markers"].as_u64().unwrap() > 100, "{v}");
    assert_eq!(v["indenter"]["shape"], "flat_circle");
    // The deepest step: 20 % of the 4.2 mm gel, pressing and moving the markers.
    assert!(
        (v["deepest_depth"].as_f64().unwrap() - 0.84).abs() < 0.05,
        "{v}"
    );
    assert!(v["deepest_fz"].as_f64().unwrap() > 5.0, "{v}");
    assert!(v["deepest_shift"].as_f64().unwrap() > 0.5, "{v}");
}
