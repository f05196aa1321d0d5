"""Speed of the Python package against its targets (docs/benchmarks/python.md), side by side
in one process:

- `Tracker.track` on a 640×480 numpy frame, result out included, against the Rust
  pipeline's own call on the very same pixels (gelrig/examples/track_cost.rs, given the
  frames), in turn, twice; and against the OpenCV-Python centroid tracker of
  tracking/benches/opencv_baseline.py on the same frames (if OpenCV is installed);
- `Run(path).force` for a run of 1 million force rows;
- `sim.Bench.press` frames per second at 640×480 after the first.

Run: python python/benches/bench.py  (after `pip install ./python`).
"""

import importlib.util
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import gelrig


def median_ms(f, n):
    times = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times)


def press_frames():
    """The reference and 16 frames of a 12.68 mm sphere pressed 0.05–0.8 mm, 640×480."""
    bench = gelrig.sim.Bench("box", indenter={"shape": "sphere", "diameter": "12.68 mm"}, width=640, height=480)
    ref, _, _ = bench.reference()
    return ref, [bench.press(0.05 + 0.05 * k)[0] for k in range(16)]


def cycle(track, frames, warm=50, n=400):
    k = [0]

    def one():
        track(frames[k[0] % len(frames)])
        k[0] += 1

    for _ in range(warm):
        one()
    return median_ms(one, n)


def tracker_cost(ref, frames):
    tracker = gelrig.Tracker(ref, contact=False)
    return cycle(tracker.track, frames)


def rust_cost(folder: Path):
    """The same frames through the Rust pipeline alone (gelrig/examples/track_cost.rs)."""
    repo = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        ["cargo", "run", "-q", "--release", "-p", "gelrig", "--example", "track_cost", "--", str(folder)],
        cwd=repo, capture_output=True, text=True, check=True,
    )
    return float(re.search(r"([0-9.]+) ms median", done.stdout).group(1))


def opencv_cost(ref, frames):
    """The same frames through the OpenCV-Python centroid tracker of
    tracking/benches/opencv_baseline.py (its convention: the frame's conversion to float32
    is not timed), or None without OpenCV."""
    try:
        import cv2  # noqa: F401
    except ImportError:
        return None
    repo = Path(__file__).resolve().parents[2]
    spec = importlib.util.spec_from_file_location("opencv_baseline", repo / "tracking/benches/opencv_baseline.py")
    cvt = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cvt)
    inv, low, pos = cvt.reference(ref.astype(np.float32))
    spacing = np.median(np.sort(np.linalg.norm(pos[:, None] - pos[None], axis=2), axis=1)[:, 1])
    state = {"pos": pos, "vel": np.zeros_like(pos)}

    def track(f):
        det = cvt.centroids(cvt.darkness(f, inv), low)
        new, _ = cvt.match(state["pos"] + state["vel"], det, 0.35 * spacing)
        state["vel"], state["pos"] = new - state["pos"], new

    return cycle(track, [f.astype(np.float32) for f in frames], warm=20, n=200)


def force_table_cost(tmp: Path):
    run = tmp / "big"
    run.mkdir()
    n = 1_000_000
    t = np.arange(n, dtype=np.int64) * 142_857
    cols = {
        "t_ns": t,
        "step": np.repeat(np.arange(1, 21), n // 20),
        "trial": np.zeros(n, dtype=np.int64),
        "fx_n": np.random.default_rng(0).normal(0, 0.01, n),
        "fy_n": np.random.default_rng(1).normal(0, 0.01, n),
        "fz_n": np.linspace(0, 12, n),
        "tx_nmm": np.zeros(n),
        "ty_nmm": np.zeros(n),
        "tz_nmm": np.zeros(n),
        "ft_seq": np.arange(n, dtype=np.int64),
        "status": np.zeros(n, dtype=np.int64),
    }
    import pandas as pd

    pd.DataFrame(cols).to_csv(run / "force.csv", index=False, float_format="%.4f")
    (run / "run.yaml").write_text("status: completed\n")
    times = []
    for _ in range(5):
        r = gelrig.Run(run)
        t0 = time.perf_counter()
        df = r.force
        times.append(time.perf_counter() - t0)
    assert len(df) == n and df["t_ns"].dtype == np.int64
    return statistics.median(times)


def press_rate():
    bench = gelrig.sim.Bench("box", width=640, height=480)
    bench.press(0.1)
    depths = np.linspace(0.05, 0.8, 60)
    t0 = time.perf_counter()
    for d in depths:
        bench.press(float(d))
    return len(depths) / (time.perf_counter() - t0)


def main():
    ref, frames = press_frames()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "ref.rgb").write_bytes(ref.tobytes())
        for k, f in enumerate(frames):
            (folder / f"{k:02}.rgb").write_bytes(f.tobytes())
        # In turn, on the same pixels, the order swapped each round (this machine's speed
        # drifts by ±10 % over minutes): the median of the rounds' ratios.
        rounds = []
        for r in range(6):
            if r % 2:
                py, rust = tracker_cost(ref, frames), rust_cost(folder)
            else:
                rust, py = rust_cost(folder), tracker_cost(ref, frames)
            rounds.append((py, rust, py / rust))
            print(f"  round {r + 1}: Tracker.track {py:.3f} ms, Rust {rust:.3f} ms, ratio {py / rust:.3f}")
        py, rust, ratio = (statistics.median(x) for x in zip(*rounds))
        print(f"Tracker.track, 640×480 numpy frame, box sphere press: {py:.3f} ms median;"
              f" Rust Pipeline::track on the same frames {rust:.3f} ms; ratio {ratio:.3f}"
              f" (median of {len(rounds)} rounds; {min(r[2] for r in rounds):.3f}–{max(r[2] for r in rounds):.3f})")
    cv = opencv_cost(ref, frames)
    if cv is None:
        print("OpenCV-Python: not installed (pip install opencv-python-headless)")
    else:
        print(f"OpenCV-Python centroid tracker on the same frames: {cv:.3f} ms median;"
              f" Tracker.track is {cv / py:.1f}× faster")
    with tempfile.TemporaryDirectory() as tmp:
        print(f"Run(path).force, 1,000,000 rows: {force_table_cost(Path(tmp)):.3f} s median of 5")
    print(f"sim.Bench.press, 640×480, box flat punch: {press_rate():.1f} frames/s")


if __name__ == "__main__":
    main()
