"""Speed of the Python package against its targets (docs/benchmarks/python.md), side by side
in one process:

- `Tracker.track` on a 640×480 numpy frame, copy in and result out included, against the
  Rust pipeline's own call on the same frames (gelrig/examples/track_cost.rs), one after the
  other;
- `Run(path).force` for a run of 1 million force rows;
- `sim.Bench.press` frames per second at 640×480 after the first.

Run: python python/benches/bench.py  (after `pip install ./python`).
"""

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


def tracker_cost():
    bench = gelrig.sim.Bench("box", indenter={"shape": "sphere", "diameter": "12.68 mm"}, width=640, height=480)
    ref, _, _ = bench.reference()
    frames = [bench.press(0.05 + 0.05 * k)[0] for k in range(16)]
    tracker = gelrig.Tracker(ref, contact=False)
    k = [0]

    def one():
        tracker.track(frames[k[0] % len(frames)])
        k[0] += 1

    for _ in range(50):
        one()
    py_ms = median_ms(one, 400)
    return py_ms


def rust_cost():
    """The same frames through the Rust pipeline alone (gelrig/examples/track_cost.rs)."""
    repo = Path(__file__).resolve().parents[2]
    done = subprocess.run(
        ["cargo", "run", "-q", "--release", "-p", "gelrig", "--example", "track_cost"],
        cwd=repo, capture_output=True, text=True, check=True,
    )
    return float(re.search(r"([0-9.]+) ms median", done.stdout).group(1))


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
    rust = rust_cost()
    py = tracker_cost()
    print(f"Tracker.track, 640×480 numpy frame, box sphere press: {py:.3f} ms median;"
          f" Rust Pipeline::track on the same frames {rust:.3f} ms; ratio {py / rust:.3f}")
    with tempfile.TemporaryDirectory() as tmp:
        print(f"Run(path).force, 1,000,000 rows: {force_table_cost(Path(tmp)):.3f} s median of 5")
    print(f"sim.Bench.press, 640×480, box flat punch: {press_rate():.1f} frames/s")


if __name__ == "__main__":
    main()
