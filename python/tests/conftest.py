"""Shared fixtures: dry runs made once per session with the package itself, and the real
GelSight Mini frames of ../shared/data (beside the checkout)."""

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import gelrig

REPO = Path(__file__).resolve().parents[2]
DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def runs_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("runs")


@pytest.fixture(scope="session")
def box_run(runs_dir):
    """box-normal-flat, seed 1."""
    return gelrig.run("box-normal-flat", out=runs_dir / "box", seed=1)


def portable_runs(runs_dir, seed):
    return [
        gelrig.run(name, out=runs_dir / f"seed{seed}", seed=seed)
        for name in ("portable-normal", "portable-shear", "portable-rotation")
    ]


@pytest.fixture(scope="session")
def portable_sensor(runs_dir):
    """The portable sensor calibrated by the `gelrig` command the wheel installs, on dry
    runs of seed 1."""
    runs = portable_runs(runs_dir, 1)
    sensor = runs_dir / "portable.yaml"
    gelrig_cli(["calibrate", *[str(r.path) for r in runs], "--out", str(sensor)])
    return sensor


def gelrig_cli(args, **kw):
    """Runs the `gelrig` script of this environment (the wheel's) and returns its output."""
    exe = shutil.which("gelrig", path=scripts_path())
    assert exe, f"the wheel installs the `gelrig` command into {scripts_path()}"
    done = subprocess.run([exe, *args], capture_output=True, text=True, **kw)
    assert done.returncode == 0, f"gelrig {' '.join(args)}: {done.stderr}"
    return done.stdout


def scripts_path():
    """Where pip put this environment's scripts (the wheel's `gelrig` among them)."""
    return os.pathsep.join([sysconfig.get_path("scripts"), str(Path(sys.executable).parent)])


def mini_press():
    """The real GelSight Mini press sequence, or a skip saying where it was looked for (a
    failure where the data must be there: GELRIG_REQUIRE_DATA=1, as in CI)."""
    d = DATA / "gelsight-mini-press"
    if d.is_dir():
        return sorted(d.glob("*.png"))
    if os.environ.get("GELRIG_REQUIRE_DATA") == "1":
        pytest.fail(f"{d} is absent and GELRIG_REQUIRE_DATA=1: put ../shared beside the checkout")
    pytest.skip(f"skipped: {d} is absent (CI has it; a fresh clone does not)")
