#!/usr/bin/env python3
"""The tracking pipeline of the `tracking` crate, written the way labs write it today:
Python with OpenCV and NumPy, one thread. Used only as the speed baseline in BENCHMARKS.md.

Same steps as the Rust core, with the library call for each:
  reference: marker-free background (box blur, mask of dark pixels dilated by 2 px,
             normalised convolution), marker contrast (Otsu), thresholds;
  per frame: darkness 1 - max_c(I_c / B_c) (all channels must darken), 3x3 binomial
             low-pass, threshold, connected components with stats, darkness-weighted
             centroids (np.bincount), identity by mutual nearest neighbour against
             predictions (previous position + previous velocity) within a gate.
It omits what the Rust core adds on top (hysteresis, fragment joining, merged-blob split,
hypothesis voting, propagation, validation), so it is a lower bound on the cost of the
same pipeline in Python.

Usage: python3 tracking/benches/opencv_baseline.py ../shared/data/gelsight-mini-press [--scale 2]
Prints the median ms per frame (decoding excluded) over all frames.

With --whole FOLDER_OUT.csv (frames read from the folder as they are, no --scale): the whole
command the way `gelrig track` runs it — cv2.imread of every frame, tracking, and a CSV row
per marker and frame written to FOLDER_OUT.csv — and its wall time per frame.
"""

import glob
import os
import statistics
import sys
import time

import cv2
import numpy as np

cv2.setNumThreads(1)


def load(paths, scale):
    frames = []
    for p in paths:
        img = cv2.imread(p, cv2.IMREAD_COLOR)
        if img is None:
            sys.exit(f"cannot read {p}")
        if scale != 1:
            img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_LINEAR)
        frames.append(img.astype(np.float32))
    return frames


def reference(f0):
    h, w = f0.shape[:2]
    r0 = max(7, min(w, h) // 16)
    k = (2 * r0 + 1, 2 * r0 + 1)
    coarse = cv2.blur(f0, k, borderType=cv2.BORDER_REPLICATE)
    d0 = (1.0 - f0 / np.maximum(coarse, 1.0)).min(axis=2)
    mask = cv2.dilate((d0 > 0.08).astype(np.uint8), np.ones((5, 5), np.uint8))
    keep = (1 - mask).astype(np.float32)
    num = cv2.blur(f0 * keep[..., None], k, borderType=cv2.BORDER_REPLICATE)
    den = cv2.blur(keep, k, borderType=cv2.BORDER_REPLICATE)
    bg = num / np.maximum(den, 1e-3)[..., None]
    inv = 255.0 / np.maximum(bg, 1.0)
    dark = darkness(f0, inv)
    otsu, _ = cv2.threshold(dark.astype(np.uint8), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    n, labels, stats, _ = cv2.connectedComponentsWithStats((dark > otsu).astype(np.uint8))
    peaks = [dark[labels == i].max() for i in range(1, n) if stats[i, 4] >= 4]
    contrast = float(np.median(peaks))
    low = 0.2 * contrast
    pos = centroids(dark, low)
    return inv, low, pos


def darkness(frame, inv):
    d = 255.0 - np.minimum((frame * inv).max(axis=2), 255.0)
    return cv2.GaussianBlur(d, (3, 3), 0).astype(np.float32)


def centroids(dark, low):
    n, labels, stats, _ = cv2.connectedComponentsWithStats((dark > low).astype(np.uint8))
    w = np.maximum(dark - low, 0).ravel()
    lab = labels.ravel()
    ys, xs = np.indices(dark.shape)
    sw = np.bincount(lab, weights=w, minlength=n)
    sx = np.bincount(lab, weights=w * xs.ravel(), minlength=n)
    sy = np.bincount(lab, weights=w * ys.ravel(), minlength=n)
    ok = (stats[:, 4] >= 10) & (np.arange(n) > 0) & (sw > 0)
    return np.stack([sx[ok] / sw[ok], sy[ok] / sw[ok]], axis=1)


def match(pred, det, gate):
    d = np.linalg.norm(pred[:, None, :] - det[None, :, :], axis=2)
    a = d.argmin(axis=1)
    b = d.argmin(axis=0)
    mutual = (b[a] == np.arange(len(pred))) & (d[np.arange(len(pred)), a] < gate)
    out = pred.copy()
    out[mutual] = det[a[mutual]]
    return out, mutual


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    scale = 1
    if "--scale" in sys.argv:
        scale = int(sys.argv[sys.argv.index("--scale") + 1])
    paths = sorted(glob.glob(os.path.join(sys.argv[1], "*.png")))
    if "--whole" in sys.argv:
        return whole(paths, sys.argv[sys.argv.index("--whole") + 1])
    frames = load(paths, scale)
    inv, low, pos = reference(frames[0])
    spacing = np.median(np.sort(np.linalg.norm(pos[:, None] - pos[None], axis=2), axis=1)[:, 1])
    vel = np.zeros_like(pos)
    times = []
    for f in frames[1:]:
        t0 = time.perf_counter()
        det = centroids(darkness(f, inv), low)
        new, _ = match(pos + vel, det, 0.35 * spacing)
        vel = new - pos
        pos = new
        times.append((time.perf_counter() - t0) * 1e3)
    h, w = frames[0].shape[:2]
    print(f"{w}x{h}: {len(pos)} markers, median {statistics.median(times):.3f} ms/frame "
          f"over {len(times)} frames (OpenCV {cv2.__version__}, 1 thread)")


def whole(paths, out_csv):
    t_start = time.perf_counter()
    f0 = cv2.imread(paths[0], cv2.IMREAD_COLOR).astype(np.float32)
    inv, low, pos = reference(f0)
    ref = pos.copy()
    spacing = np.median(np.sort(np.linalg.norm(pos[:, None] - pos[None], axis=2), axis=1)[:, 1])
    vel = np.zeros_like(pos)
    with open(out_csv, "w") as out:
        out.write("frame,id,x_px,y_px,dx_px,dy_px\n")
        for k, p in enumerate(paths[1:], start=1):
            f = cv2.imread(p, cv2.IMREAD_COLOR)
            if f is None:
                sys.exit(f"cannot read {p}")
            det = centroids(darkness(f.astype(np.float32), inv), low)
            new, _ = match(pos + vel, det, 0.35 * spacing)
            vel = new - pos
            pos = new
            d = pos - ref
            out.write("".join(f"{k},{i},{pos[i, 0]:.4f},{pos[i, 1]:.4f},{d[i, 0]:.4f},{d[i, 1]:.4f}\n"
                              for i in range(len(pos))))
    wall = time.perf_counter() - t_start
    h, w = f0.shape[:2]
    print(f"{w}x{h}: whole command {wall:.3f} s, {1e3 * wall / len(paths):.3f} ms/frame over "
          f"{len(paths)} frames (imread, track, CSV; OpenCV {cv2.__version__}, 1 thread)")


if __name__ == "__main__":
    main()
