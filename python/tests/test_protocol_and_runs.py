"""Protocols and run directories from Python: the same checks, plans and tables as the
command, typed as the CSVs are."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import gelrig
from conftest import gelrig_cli


def test_a_protocol_loads_by_name_and_plans():
    p = gelrig.Protocol.load("box-normal-flat")
    assert p.valid and p.validate() == []
    plan = p.plan()
    assert len(plan) == 20
    lo, hi = plan.duration_s
    assert 3600 < lo <= hi
    # The same plan as `gelrig plan --json`.
    cli = json.loads(gelrig_cli(["plan", "box-normal-flat", "--json"]))
    assert [s["step"] for s in cli["steps"]] == list(plan["step"])
    assert cli["duration_s"]["max"] == pytest.approx(hi)


def test_the_package_carries_every_shipped_protocol(tmp_path):
    """The wheel holds the repository's `protocols/` (every file, byte for byte), and a
    Python started anywhere, with no `GELRIG_PROTOCOLS`, finds them there by name."""
    package = Path(gelrig.__file__).parent / "protocols"
    repo = Path(__file__).resolve().parents[2] / "protocols"
    shipped = sorted(p.relative_to(repo) for p in repo.rglob("*.yaml"))
    assert len(shipped) >= 16
    assert sorted(p.relative_to(package) for p in package.rglob("*.yaml")) == shipped
    for rel in shipped:
        assert (package / rel).read_bytes() == (repo / rel).read_bytes(), rel
    env = {k: v for k, v in os.environ.items() if k != "GELRIG_PROTOCOLS"}
    found = subprocess.run(
        [sys.executable, "-c", "import gelrig; print(gelrig.Protocol.load('portable-shear').path)"],
        cwd=tmp_path, env=env, capture_output=True, text=True, check=True,
    ).stdout.strip()
    assert Path(found) == (package / "portable-shear.yaml").resolve()
    # Found without touching the environment a subprocess inherits.
    leaked = subprocess.run(
        [sys.executable, "-c", "import os, gelrig; print(os.environ.get('GELRIG_PROTOCOLS'))"],
        cwd=tmp_path, env=env, capture_output=True, text=True, check=True,
    ).stdout.strip()
    assert leaked == "None"


def test_a_protocol_that_does_not_check_raises_with_its_diagnostics():
    p = gelrig.Protocol.load("box-normal-flat", set={"indenter.diameter": "1000 mm"})
    assert not p.valid
    with pytest.raises(gelrig.ProtocolError) as e:
        p.validate()
    d = e.value.diagnostics
    assert d and d[0]["severity"] == "error" and d[0]["line"] > 0 and d[0]["column"] > 0
    assert "diameter" in d[0]["message"] and d[0]["fix"]
    assert str(d[0]["line"]) in str(e.value)
    # Running it is refused the same way, before anything runs.
    with pytest.raises(gelrig.ProtocolError):
        gelrig.run(p, out="never")
    missing = gelrig.Protocol.load("no/such/protocol.yaml")
    with pytest.raises(gelrig.ProtocolError, match="no/such/protocol.yaml"):
        missing.validate()


def csv_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_run_tables_are_dataframes_typed_as_the_csvs(box_run):
    run = box_run
    assert run.status == "completed"
    assert run.manifest["status"] == "completed" and run.manifest["seed"] == 1
    for name in ("force", "steps", "frames"):
        df = run.table(name)
        rows = csv_rows(run.path / f"{name}.csv")
        assert len(df) == len(rows), name
        assert list(df.columns) == list(rows[0].keys()), name
    force = run.force
    assert force["t_ns"].dtype == np.int64 and force["step"].dtype == np.int64
    for c in ("fx_n", "fy_n", "fz_n", "tz_nmm"):
        assert force[c].dtype == np.float64, c
    assert run.steps["fz_n"].dtype == np.float64
    first = csv_rows(run.path / "force.csv")[100]
    assert force["t_ns"][100] == int(first["t_ns"])
    assert force["fz_n"][100] == pytest.approx(float(first["fz_n"]))
    frame = run.frame(int(run.frames["frame"][0]))
    assert frame.dtype == np.uint8 and frame.shape[2] == 3
    with pytest.raises(gelrig.GelrigError, match="no table `nope`"):
        run.table("nope")
    with pytest.raises(gelrig.GelrigError, match="markers"):
        run.markers  # not tracked yet: the message says how


def test_report_export_and_listing(box_run, tmp_path):
    folder, summary = box_run.report(out=tmp_path / "report")
    assert (folder / "report.html").is_file()
    assert summary["run"]["status"] == "completed"
    files = box_run.export("parquet", tmp_path / "pq")
    assert any(f.name.startswith("force") for f in files)
    mcap = box_run.export("mcap", tmp_path / "run.mcap")
    assert mcap[0].stat().st_size > 0
    with pytest.raises(gelrig.GelrigError, match="parquet"):
        box_run.export("xlsx", tmp_path / "x")
    listing = gelrig.runs(box_run.path.parent)
    assert list(listing["status"]) == ["completed"]


def test_a_run_is_the_commands_run_seed_for_seed(box_run, tmp_path):
    gelrig_cli(["run", "box-normal-flat", "--seed", "1", "--out", str(tmp_path), "--quiet"])
    (cli_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert (cli_dir / "steps.csv").read_text() == (box_run.path / "steps.csv").read_text()
    assert (cli_dir / "force.csv").read_text() == (box_run.path / "force.csv").read_text()


def test_events_arrive_as_the_run_goes(tmp_path):
    kinds = []
    run = gelrig.run("box-normal-flat", out=tmp_path, seed=2, on_event=lambda e: kinds.append(e["kind"]))
    assert kinds.count("step_done") == 20
    assert kinds[-1] == "end" and "force" in kinds and "frame" in kinds
    assert run.status == "completed"


def test_an_exception_in_the_callback_stops_the_run_cleanly(tmp_path):
    def boom(event):
        if event["kind"] == "step_done":
            raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        gelrig.run("box-normal-flat", out=tmp_path, seed=3, on_event=boom)
    (d,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert gelrig.Run(d).status == "aborted"


def test_a_grasp_runs_trials_are_a_dataframe(tmp_path):
    p = gelrig.Protocol.load("lifting-can", set={"sequence.2.repeat.times": "2"})
    run = gelrig.run(p, out=tmp_path, seed=1)
    trials = run.trials
    assert len(trials) == 2
    assert (run.path / "report" / "summary.json").is_file()
    assert len(run.tactile) > 0 and run.tactile["t_ns"].dtype == np.int64
    with pytest.raises(gelrig.GelrigError, match="no trials"):
        gelrig.Run(gelrig.run("box-normal-flat", out=tmp_path / "box", seed=1).path).trials
