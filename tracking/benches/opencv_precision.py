#!/usr/bin/env python3
"""Precision of OpenCV centroid pipelines and of `gelrig track` on the same synthetic frames
with exact truth (written by `cargo run --release -p tracking --example tracking_frames`).

Two OpenCV pipelines, both one thread:
  weighted:  the pipeline of opencv_baseline.py (darkness against a marker-free background,
             3x3 Gaussian, threshold at 20 % of the marker contrast, darkness-weighted
             centroids of connected components);
  classical: what a lab writes first (grey, Gaussian blur of sigma = marker radius / 3,
             adaptive mean threshold over twice the spacing, connectedComponentsWithStats
             centroids, components smaller than a quarter of the median dropped).
Scoring (the same for all): for every marker whose true centre lies at least
(radius + 2 px) inside the frame, in frames 1.., the nearest reported position within
0.3 spacing; rms of those errors, and the share of such markers found.

Usage: python3 tracking/benches/opencv_precision.py DIR [--gelrig DIR/markers.csv]
"""

import csv
import glob
import math
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import opencv_baseline as base  # noqa: E402

cv2.setNumThreads(1)


def truth_of(folder):
    t = {}
    with open(os.path.join(folder, "truth.csv")) as f:
        for r in csv.DictReader(f):
            t.setdefault(int(r["frame"]), []).append((float(r["x_px"]), float(r["y_px"])))
    return {k: np.array(v) for k, v in t.items()}


def score(found, truth, w, h, spacing, radius):
    """found: frame -> Nx2 positions."""
    errs, seen, total = [], 0, 0
    m = radius + 2.0
    for k, tr in truth.items():
        if k == 0:
            continue
        inside = (tr[:, 0] > m) & (tr[:, 1] > m) & (tr[:, 0] < w - 1 - m) & (tr[:, 1] < h - 1 - m)
        pts = found.get(k, np.zeros((0, 2)))
        for t in tr[inside]:
            total += 1
            if len(pts) == 0:
                continue
            d = np.hypot(pts[:, 0] - t[0], pts[:, 1] - t[1])
            i = d.argmin()
            if d[i] < 0.3 * spacing:
                errs.append(d[i])
                seen += 1
    errs = np.array(errs)
    return math.sqrt((errs ** 2).mean()) if len(errs) else float("nan"), seen / max(total, 1)


def weighted(paths):
    f0 = cv2.imread(paths[0], cv2.IMREAD_COLOR).astype(np.float32)
    inv, low, _ = base.reference(f0)
    out = {}
    for k, p in enumerate(paths[1:], start=1):
        f = cv2.imread(p, cv2.IMREAD_COLOR).astype(np.float32)
        out[k] = base.centroids(base.darkness(f, inv), low)
    return out


def classical(paths, spacing, radius):
    out = {}
    block = int(2 * spacing) | 1
    for k, p in enumerate(paths[1:], start=1):
        g = cv2.cvtColor(cv2.imread(p, cv2.IMREAD_COLOR), cv2.COLOR_BGR2GRAY)
        g = cv2.GaussianBlur(g, (0, 0), max(radius / 3.0, 0.8))
        b = cv2.adaptiveThreshold(g, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, 5)
        n, _, stats, cents = cv2.connectedComponentsWithStats(b)
        if n <= 1:
            out[k] = np.zeros((0, 2))
            continue
        areas = stats[1:, 4]
        keep = areas >= 0.25 * np.median(areas)
        out[k] = cents[1:][keep]
    return out


def gelrig(markers_csv):
    out = {}
    with open(markers_csv) as f:
        for r in csv.DictReader(f):
            if r["state"] == "tracked":
                out.setdefault(int(r["frame"]), []).append((float(r["x_px"]), float(r["y_px"])))
    return {k: np.array(v) for k, v in out.items()}


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    folder = sys.argv[1]
    paths = sorted(glob.glob(os.path.join(folder, "frame_*.png")))
    truth = truth_of(folder)
    t0 = truth[0]
    d = np.hypot(t0[:, None, 0] - t0[None, :, 0], t0[:, None, 1] - t0[None, :, 1])
    np.fill_diagonal(d, np.inf)
    spacing = float(np.median(d.min(axis=1)))
    radius = 0.2778 * spacing  # the box grid: 1.4 mm dots at 2.52 mm
    h, w = cv2.imread(paths[0]).shape[:2]
    rows = [("OpenCV weighted centroids", weighted(paths)),
            ("OpenCV classical (adaptive threshold)", classical(paths, spacing, radius))]
    if "--gelrig" in sys.argv:
        rows.append(("gelrig track (tracked rows)", gelrig(sys.argv[sys.argv.index("--gelrig") + 1])))
    print(f"{os.path.basename(folder.rstrip('/'))}: {w}x{h}, spacing {spacing:.1f} px")
    for name, found in rows:
        rms, recall = score(found, truth, w, h, spacing, radius)
        print(f"  {name}: rms {rms:.4f} px, found {100 * recall:.1f} %")


if __name__ == "__main__":
    main()
