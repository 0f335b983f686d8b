#!/usr/bin/env python3
"""Coverage and depth error of the core's stereo matcher by true depth, on the set written by
`orbfix bench stereo --out DIR` (left/right pairs, the renderer's true disparity, the mask of
pixels whose ground point lies in the 50 m square, the core's disparity; 16-bit PNGs in 1/16
px). Used for docs/stereo.md ("Where the stereo depth is"):

    orbfix bench stereo --out .cache/stereo-cov --locations 6 --seed 2
    .cache/venv-stereo/bin/python scripts/stereo_coverage.py .cache/stereo-cov
"""
import json
import sys

import cv2
import numpy as np


def main() -> None:
    d = sys.argv[1] if len(sys.argv) > 1 else ".cache/stereo-bench"
    try:
        ix = json.load(open(f"{d}/index.json"))
    except OSError as e:
        sys.exit(f"cannot read {d}/index.json ({e}): run `orbfix bench stereo --out {d}` first")
    fb = ix["focal_px"] * ix["baseline_m"]
    bins = [0, 3, 5, 8, 12, 16, 20, 25, 36]
    tot = np.zeros(len(bins) - 1)
    cov = np.zeros(len(bins) - 1)
    err = [[] for _ in bins[:-1]]
    for e in ix["entries"]:
        def rd(k):
            a = cv2.imread(f"{d}/{e[k]}", cv2.IMREAD_UNCHANGED)
            if a is None:
                sys.exit(f"cannot read {d}/{e[k]}")
            return a
        t = rd("truth").astype(np.float32) / 16.0
        c = rd("core").astype(np.float32) / 16.0
        m = rd("mask") > 0
        z = np.where(t > 0, fb / np.maximum(t, 1e-3), 0.0)
        for i in range(len(bins) - 1):
            sel = m & (t > 0) & (z >= bins[i]) & (z < bins[i + 1])
            v = sel & (c > 0)
            tot[i] += sel.sum()
            cov[i] += v.sum()
            err[i] += list(np.abs(fb / c[v] - z[v]))
    print("| true depth, m | pixels | coverage | depth error median, m | p90, m |")
    print("|---|---:|---:|---:|---:|")
    for i in range(len(bins) - 1):
        a = np.array(err[i]) if err[i] else np.zeros(1)
        print(f"| {bins[i]}-{bins[i + 1]} | {int(tot[i])} | {cov[i] / max(tot[i], 1):.2f} | "
              f"{np.median(a):.2f} | {np.percentile(a, 90):.2f} |")


if __name__ == "__main__":
    main()
