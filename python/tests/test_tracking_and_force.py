"""The tracker, the force reader and the simulated bench on numpy frames: the same numbers
as the command on the same pixels."""

import csv
import os
import resource
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import gelrig
from conftest import gelrig_cli, mini_press, portable_runs


def test_the_tracker_gives_the_commands_numbers_on_real_gelsight_mini_frames(tmp_path):
    frames = mini_press()[:40]
    out = tmp_path / "markers.csv"
    gelrig_cli(["track", "--reference", str(frames[0]), *map(str, frames[1:]), "--out", str(out)])
    rows = list(csv.DictReader(open(out, newline="")))
    tracker = gelrig.Tracker(gelrig.read_image(frames[0]))
    n = len(tracker)
    assert len(rows) == n * len(frames)
    compared = 0
    for k, path in enumerate(frames[1:], start=1):
        result = tracker.track(gelrig.read_image(path))
        mine = rows[k * n : (k + 1) * n]
        assert [r["state"] for r in mine] == result.state, path.name
        xy = np.array([[float(r["x_px"]), float(r["y_px"])] for r in mine])
        # The CSV keeps four decimals.
        assert np.max(np.abs(xy - result.xy)) <= 6e-5, path.name
        compared += n
    assert compared > 1000


def test_wrong_frames_are_errors_that_say_what_to_give():
    bench = gelrig.sim.Bench("portable", width=320, height=240)
    ref, _, _ = bench.reference()
    tracker = gelrig.Tracker(ref)
    with pytest.raises(ValueError, match="same camera"):
        tracker.track(np.zeros((100, 100, 3), np.uint8))
    with pytest.raises(ValueError, match=r"\(height, width, 3\)"):
        tracker.track(np.zeros((240, 320, 4), np.uint8))
    with pytest.raises(TypeError):
        tracker.track(np.zeros((240, 320, 3), np.float32))
    with pytest.raises(ValueError, match="centroid"):
        gelrig.Tracker(ref, method="sift")
    # A strided view (BGR → RGB) is tracked as its pixels are.
    assert len(tracker.track(np.ascontiguousarray(ref)[:, :, ::-1][:, :, ::-1])) == len(tracker)


def test_frames_of_the_bench_track_back_to_their_truth():
    bench = gelrig.sim.Bench(
        "box", indenter={"shape": "sphere", "diameter": "12.68 mm"}, seed=1, max_depth_mm=1.2
    )
    ref, _, rest = bench.reference()
    tracker = gelrig.Tracker(ref, mm_per_px=None)
    ids = [int(np.argmin(np.hypot(*(rest["markers_px"] - p).T))) for p in tracker.reference_xy]
    for depth in (0.3, 0.6, 1.2):
        frame, wrench, truth = bench.press(depth)
        result = tracker.track(frame)
        tracked = np.array(result.state) == "tracked"
        err = np.hypot(*(result.xy[tracked] - truth["markers_px"][ids][tracked]).T)
        assert tracked.sum() > 200 and np.median(err) < 0.1, (depth, np.median(err))
        assert wrench["fz_n"] > 0 and truth["contact_radius_mm"] > 0
        assert result.contact is not None
    with pytest.raises(ValueError, match="depth"):
        bench.press(bench.max_depth_mm * 2)
    with pytest.raises(ValueError, match="sensor `glove`"):
        gelrig.sim.Bench("glove")


def test_a_sheared_press_carries_the_force_its_partial_slip_sets():
    """`shear_mm` and `twist_deg` are stage displacements from the pressed state (Yuan 2014,
    §3.3): the force grows while the stuck area shrinks, and saturates once it slides."""
    bench = gelrig.sim.Bench(
        "box", indenter={"shape": "sphere", "diameter": "12.68 mm"}, seed=2, max_depth_mm=1.0
    )
    ref, _, rest = bench.reference()
    forces, sticks = [], []
    for shear_mm in (0.0, 0.05, 0.2, 0.5, 2.0, 3.0):
        _, wrench, truth = bench.press(0.8, shear_mm=shear_mm)
        forces.append(wrench["fx_n"])
        sticks.append(truth["stick_fraction"])
        assert truth["stick_fraction"] == truth["stick_fraction_shear"]
    assert forces[0] == 0 and sticks[0] == 1
    assert all(b > a for a, b in zip(forces[:5], forces[1:5])), forces
    assert all(b < a for a, b in zip(sticks[:5], sticks[1:5])), sticks
    # Sliding: nothing sticks and the force no longer grows.
    assert sticks[-1] == 0 and forces[-1] == pytest.approx(forces[-2], rel=1e-9)
    _, wrench, truth = bench.press(0.8, twist_deg=5.0)
    assert wrench["tz_nmm"] > 0 and 0 < truth["stick_fraction"] < 1
    _, wrench, truth = bench.press(0.8, shear_mm=-0.2, twist_deg=5.0)
    assert wrench["fx_n"] == pytest.approx(-forces[2]) and truth["stick_fraction"] is None
    # The frame shows it: inside the contact the markers moved along +x, tracked back.
    frame, _, truth = bench.press(0.8, shear_mm=0.2)
    result = gelrig.Tracker(ref).track(frame)
    tracked = np.array(result.state) == "tracked"
    ids = [int(np.argmin(np.hypot(*(rest["markers_px"] - p).T))) for p in result.xy - result.dxy]
    err = np.hypot(*(result.xy[tracked] - truth["markers_px"][ids][tracked]).T)
    assert np.median(err) < 0.1, np.median(err)
    assert result.dxy[tracked, 0].max() > 1.0


def test_the_force_reader_gives_track_sensors_reading(portable_sensor, runs_dir):
    (held_out, *_) = portable_runs(runs_dir, 2)
    gelrig_cli(["track", str(held_out.path), "--sensor", str(portable_sensor)])
    wrench = {int(r["frame"]): r for r in csv.DictReader(open(held_out.path / "wrench.csv", newline=""))}
    sensor = gelrig.ForceSensor.load(portable_sensor)
    frames = held_out.frames
    errors = []
    for frame, t_ns in zip(frames["frame"], frames["t_ns"]):
        reading = sensor.read(held_out.frame(int(frame)), t_s=t_ns / 1e9)
        if int(frame) in wrench and wrench[int(frame)]["fz_n"]:
            errors.append(abs(reading["fz_n"] - float(wrench[int(frame)]["fz_n"])))
    span = float(np.ptp(held_out.steps["fz_n"]))
    assert len(errors) >= 10
    # Frame by frame from pixels, as `track --sensor` reads the recorded markers.
    assert max(errors) <= 0.01 * span, (max(errors), span)


def test_a_frame_in_any_memory_order_tracks_the_same():
    """Row-major frames are read in place; Fortran-ordered ones (MATLAB data) and strided
    views are the same pixels, and must track to the same numbers."""
    bench = gelrig.sim.Bench("portable", width=320, height=240)
    ref, _, _ = bench.reference()
    frame, _, _ = bench.press(0.3)
    want = gelrig.Tracker(ref).track(frame)
    for name, convert in [
        ("fortran", np.asfortranarray),
        ("strided", lambda a: np.ascontiguousarray(a[:, :, ::-1])[:, :, ::-1]),
        ("padded", lambda a: np.pad(a, ((0, 0), (0, 5), (0, 0)))[:, :-5]),
    ]:
        got = gelrig.Tracker(convert(ref)).track(convert(frame))
        assert np.array_equal(got.xy, want.xy), name
        assert got.state == want.state, name


def test_ten_thousand_track_calls_do_not_grow_memory():
    bench = gelrig.sim.Bench("portable", width=320, height=240)
    ref, _, _ = bench.reference()
    frame, _, _ = bench.press(0.3)
    tracker = gelrig.Tracker(ref, contact=False)

    def rss_kb():
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024

    for _ in range(1000):
        tracker.track(frame)
    before = rss_kb()
    for _ in range(9000):
        tracker.track(frame).xy
    grown = rss_kb() - before
    assert grown < 4096, f"{grown} kB more after 9000 more calls"


def test_ctrl_c_during_a_run_retracts_and_ends_aborted(tmp_path):
    # Ctrl-C raises KeyboardInterrupt as in an interactive Python, even when this test runs
    # under a shell that started it in the background (which ignores SIGINT, and a Python
    # started with SIGINT ignored keeps ignoring it).
    script = textwrap.dedent(
        f"""
        import signal
        signal.signal(signal.SIGINT, signal.default_int_handler)
        import gelrig
        gelrig.run("box-normal-flat", out={str(tmp_path)!r}, seed=1, time_scale=60)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline and not any(p.is_dir() for p in tmp_path.iterdir()):
        time.sleep(0.2)
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode != 0 and "KeyboardInterrupt" in err, err
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    run = gelrig.Run(run_dir)
    assert run.status == "aborted", run.manifest
    journal = (run_dir / "journal.jsonl").read_text()
    assert "retract" in journal
