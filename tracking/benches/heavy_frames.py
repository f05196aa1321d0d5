#!/usr/bin/env python3
"""Heavy frames for the whole-command benchmark (docs/benchmarks/tracking.md, "Heavy frames"):
a run's frames played forward and back to N frames, each with fresh Gaussian noise (sigma 3
grey levels), written by OpenCV at its default PNG compression (about 580 KB for a 640x480
box-sensor frame, as heavy as the frames the issue measured).

    python3 tracking/benches/heavy_frames.py RUN_DIR/frames OUT_DIR [N]
"""
import glob
import os
import sys

import cv2
import numpy as np


def main():
    src, out = sys.argv[1], sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else 301
    files = sorted(glob.glob(os.path.join(src, "*.png")))
    if not files:
        sys.exit(f"error: no PNG frames in {src}")
    seq = files + files[::-1]
    rng = np.random.default_rng(11)
    os.makedirs(out, exist_ok=True)
    for i in range(n):
        im = cv2.imread(seq[i % len(seq)]).astype(np.float32)
        noisy = np.clip(im + rng.normal(0, 3, im.shape), 0, 255).astype(np.uint8)
        cv2.imwrite(os.path.join(out, "frame_%04d.png" % i), noisy)
    sizes = [os.path.getsize(f) for f in glob.glob(os.path.join(out, "*.png"))]
    print(f"{len(sizes)} frames, {sum(sizes) / len(sizes) / 1e3:.0f} KB each on average")


if __name__ == "__main__":
    main()
