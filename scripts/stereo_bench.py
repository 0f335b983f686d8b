#!/usr/bin/env python3
"""Scores the core's stereo against OpenCV StereoSGBM and StereoBM on the same pairs.

Reads the set (or sets, pooled) `orbfix bench stereo` wrote (index.json, reduced pairs, true disparity,
top-down-square masks, the core's disparity), runs OpenCV on every pair (one thread), and
prints one markdown table: over the pixels with true disparity inside the 50 m square,
coverage (share with an estimate), bad > 1 px and bad > 3 px (share of the estimates whose
error exceeds 1 / 3 px), mean absolute error, the share of all scored pixels with an
estimate within 1 px, and time per view. Optional --json writes it. With --by-depth, a
second table bins the same pixels by true depth (metres along the optical axis): coverage,
share "good" (depth within 5 % + 0.1 m of the truth), mean absolute error and mean signed
error (bias) in pixels, per method. With --gradient-refine RX,RY,IT, a fourth method (analysis
only, not in the core): the core's disparities refined by IT Gauss-Newton steps of a
gradient (Lucas-Kanade) fit over a (2 RX + 1) x (2 RY + 1) window of the Sobel-filtered pair,
the window sheared with the flat ground (--shear pixels of disparity per row), to measure how
much precision a sub-pixel fit could add beyond the core's parabola.
"""
import argparse
import json
import os
import sys
import time

import cv2
import numpy as np


def load16(path):
    a = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if a is None:
        sys.exit(f"cannot read {path}: run `orbfix bench stereo` first")
    return a.astype(np.float32) / 16.0


def gradient_refine(left, right, d_core, sel, rx, ry, iters, shear):
    """The core's disparity refined by a sheared-window gradient fit; 0 stays 0 (no data)."""
    def pre(img):
        return np.clip(cv2.Sobel(img.astype(np.float64), cv2.CV_64F, 1, 0, ksize=3), -124, 124)

    lf, rf = pre(left), pre(right)
    grad = np.zeros_like(rf)
    grad[:, 1:-1] = (rf[:, 2:] - rf[:, :-2]) / 2
    h, w = lf.shape

    def sample(img, y, x):
        x = np.clip(x, 0, w - 1.001)
        x0 = np.floor(x).astype(int)
        f = x - x0
        return img[y, x0] * (1 - f) + img[y, x0 + 1] * f

    ys, xs = np.nonzero(sel & (d_core > 0))
    inside = (ys >= ry) & (ys < h - ry) & (xs >= rx) & (xs < w - rx)
    ys, xs = ys[inside], xs[inside]
    d0 = d_core[ys, xs].astype(np.float64)
    d = d0.copy()
    for _ in range(iters):
        num = np.zeros_like(d)
        den = np.zeros_like(d)
        for dy in range(-ry, ry + 1):
            for dx in range(-rx, rx + 1):
                yy, xx = ys + dy, xs + dx
                x_right = xx - (d + shear * dy)
                g = sample(grad, yy, x_right)
                num += (lf[yy, xx] - sample(rf, yy, x_right)) * g
                den += g * g
        d = d + np.clip(-num / np.maximum(den, 1e-9), -0.5, 0.5)
    out = d_core.copy()
    out[ys, xs] = np.where(np.abs(d - d0) < 1.0, d, d0)
    return out.astype(np.float32)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", nargs="+", default=[".cache/stereo-bench"],
                    help="folder(s) of index.json; several sets (e.g. one per world seed, the "
                         "same settings) are scored as one pool")
    ap.add_argument("--json", help="write the table as JSON here")
    ap.add_argument("--sgbm-block", type=int, default=5, help="SGBM block size (odd)")
    ap.add_argument("--bm-block", type=int, default=7, help="BM block size (odd, >= 5)")
    ap.add_argument("--by-depth", action="store_true",
                    help="also print the table by true depth band (0-5-10-16-24-32 m)")
    ap.add_argument("--gradient-refine", metavar="RX,RY,IT",
                    help="add the core's disparities refined by a gradient fit (analysis only)")
    ap.add_argument("--shear", type=float, default=0.145,
                    help="disparity change per working row of the flat ground, px (B cos 15 deg "
                         "/ 2 m = 0.145 at the nominal pose) for --gradient-refine")
    args = ap.parse_args()
    refine = None
    if args.gradient_refine:
        try:
            refine = [int(v) for v in args.gradient_refine.split(",")]
        except ValueError:
            refine = []
        if len(refine) != 3 or min(refine) < 0:
            sys.exit(f"--gradient-refine wants RX,RY,IT (three integers >= 0), got {args.gradient_refine!r}")
    indices = []
    for folder in args.set:
        ix_path = os.path.join(folder, "index.json")
        try:
            with open(ix_path) as f:
                indices.append((folder, json.load(f)))
        except (OSError, ValueError) as err:
            sys.exit(f"cannot read {ix_path} ({err}): run `orbfix bench stereo --out {folder}` first")
    ix = indices[0][1]
    same = ("size", "downsample", "baseline_m", "focal_px", "max_disparity_px", "params")
    for folder, other in indices[1:]:
        differ = [k for k in same if other.get(k) != ix.get(k)]
        if differ:
            sys.exit(f"{folder} was written with other settings than {indices[0][0]} ({', '.join(differ)}): "
                     "pool only sets of the same `orbfix bench stereo` settings")
    entries = [(folder, other, e) for folder, other in indices for e in other["entries"]]
    cv2.setNumThreads(1)
    ndisp = 16 * ((ix["max_disparity_px"] + 2 + 15) // 16)
    b = args.sgbm_block
    sgbm = cv2.StereoSGBM_create(
        minDisparity=0, numDisparities=ndisp, blockSize=b, P1=8 * b * b, P2=32 * b * b,
        disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=100, speckleRange=2,
        preFilterCap=31, mode=cv2.STEREO_SGBM_MODE_SGBM)
    bm = cv2.StereoBM_create(numDisparities=ndisp, blockSize=args.bm_block)
    bm.setUniquenessRatio(10)
    bm.setTextureThreshold(10)
    bm.setSpeckleWindowSize(100)
    bm.setSpeckleRange(2)
    bm.setDisp12MaxDiff(1)
    bm.setPreFilterCap(31)
    methods = ["orbfix core", "OpenCV StereoSGBM", "OpenCV StereoBM"]
    refined_name = None
    if refine:
        refined_name = f"core + gradient fit {2 * refine[0] + 1} x {2 * refine[1] + 1}, {refine[2]} steps"
        methods.append(refined_name)
    acc = {m: dict(n=0, cover=0, bad1=0, bad3=0, abs=0.0, secs=0.0) for m in methods}
    # Per set (pooled runs): estimates and those off by more than 1 px, core and SGBM.
    per_set = {folder: {m: [0, 0] for m in methods[:2]} for folder, _ in indices}
    bands = [(0, 5), (5, 10), (10, 16), (16, 24), (24, 32)]
    by_depth = {m: {b: dict(n=0, cover=0, good=0, abs=0.0, bias=0.0) for b in bands} for m in methods}
    fb = ix["focal_px"] * ix["baseline_m"]
    for folder, eix, e in entries:
        p = lambda k: os.path.join(folder, e[k])
        left = cv2.imread(p("left"), cv2.IMREAD_GRAYSCALE)
        right = cv2.imread(p("right"), cv2.IMREAD_GRAYSCALE)
        truth = load16(p("truth"))
        mask = cv2.imread(p("mask"), cv2.IMREAD_GRAYSCALE)
        sel = (truth > 0) & (mask > 0)
        z = fb / np.maximum(truth, 1e-6)
        in_band = [sel & (z >= b[0]) & (z < b[1]) for b in bands]
        ests = {"orbfix core": (load16(p("core")), eix["core_ms_per_view"] / 1e3)}
        for name, m in (("OpenCV StereoSGBM", sgbm), ("OpenCV StereoBM", bm)):
            t = time.perf_counter()
            d = m.compute(left, right)
            secs = time.perf_counter() - t
            d = d.astype(np.float32) / 16.0
            d[d <= 0] = 0
            ests[name] = (d, secs)
        if refine:
            t = time.perf_counter()
            d = gradient_refine(left, right, ests["orbfix core"][0], sel, *refine, args.shear)
            ests[refined_name] = (d, time.perf_counter() - t)
        for name, (d, secs) in ests.items():
            a = acc[name]
            a["n"] += int(sel.sum())
            valid = sel & (d > 0)
            err = np.abs(d[valid] - truth[valid])
            a["cover"] += int(valid.sum())
            a["bad1"] += int((err > 1).sum())
            if name in per_set[folder]:
                per_set[folder][name][0] += int(valid.sum())
                per_set[folder][name][1] += int((err > 1).sum())
            a["bad3"] += int((err > 3).sum())
            a["abs"] += float(err.sum())
            a["secs"] += secs
            z_est = fb / np.maximum(d, 1e-6)
            for b, in_b in zip(bands, in_band):
                v = in_b & (d > 0)
                e = d[v] - truth[v]
                bd = by_depth[name][b]
                bd["n"] += int(in_b.sum())
                bd["cover"] += int(v.sum())
                bd["good"] += int((np.abs(z_est[v] - z[v]) <= 0.05 * z[v] + 0.1).sum())
                bd["abs"] += float(np.abs(e).sum())
                bd["bias"] += float(e.sum())
    nviews = len(entries)
    rows = []
    for m in methods:
        a = acc[m]
        c = max(a["cover"], 1)
        rows.append(dict(method=m, coverage=a["cover"] / max(a["n"], 1), bad1=a["bad1"] / c,
                         bad3=a["bad3"] / c, mae=a["abs"] / c, ms_per_view=1e3 * a["secs"] / nviews,
                         good_of_all=(a["cover"] - a["bad1"]) / max(a["n"], 1)))
    if len(indices) > 1:
        for folder, counts in per_set.items():
            (cc, cb), (sc, sb) = counts.values()
            rate = lambda bad, cover: bad / max(cover, 1)
            r = rate(cb, cc) / rate(sb, sc) if sb > 0 else float("inf")
            print(f"{folder}: core bad > 1 px {100 * rate(cb, cc):.2f} %, SGBM {100 * rate(sb, sc):.2f} %, "
                  f"ratio {r:.2f}")
        print()
    w, h = ix["size"]
    sets = f" from {len(indices)} sets" if len(indices) > 1 else ""
    print(f"{nviews} pairs{sets}, {w} x {h} (rendered {ix['render_size'][0]} x {ix['render_size'][1]}, "
          f"downsample {ix['downsample']}), baseline {ix['baseline_m']:.3g} m, noise {ix['noise_sigma']} gray, "
          f"right gain {ix['right_gain']}; OpenCV {cv2.__version__}, numDisparities {ndisp}, 1 thread; "
          f"pixels scored: {acc[methods[0]]['n']} (true disparity, inside the 50 m square)")
    print()
    print("| method | coverage | bad > 1 px | bad > 3 px | mean abs error, px | within 1 px, of all scored | ms per view |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {100 * r['coverage']:.1f} % | {100 * r['bad1']:.2f} % | "
              f"{100 * r['bad3']:.2f} % | {r['mae']:.3f} | {100 * r['good_of_all']:.1f} % | "
              f"{r['ms_per_view']:.2f} |")
    core, sg = rows[0], rows[1]
    ratio = core["bad1"] / sg["bad1"] if sg["bad1"] > 0 else float("inf")
    print()
    print(f"core bad > 1 px / SGBM bad > 1 px: {ratio:.2f} (target <= 1.5)")
    depth_rows = []
    if args.by_depth:
        print()
        print("By true depth (good: depth within 5 % + 0.1 m of the truth; errors in pixels of "
              "the working size): coverage / good / mean abs error / bias")
        print()
        print("| true depth | " + " | ".join(methods) + " |")
        print("|---|" + "---|" * len(methods))
        for b in bands[::-1]:
            cells = []
            for m in methods:
                bd = by_depth[m][b]
                c = max(bd["cover"], 1)
                row = dict(method=m, band_m=list(b), coverage=bd["cover"] / max(bd["n"], 1),
                           good=bd["good"] / c, mae=bd["abs"] / c, bias=bd["bias"] / c)
                depth_rows.append(row)
                cells.append(f"{row['coverage']:.3f} / {row['good']:.3f} / {row['mae']:.3f} / "
                             f"{row['bias']:+.3f}")
            print(f"| {b[0]}-{b[1]} m | " + " | ".join(cells) + " |")
    if args.json:
        with open(args.json + ".tmp", "w") as f:
            json.dump(dict(rows=rows, ratio_bad1_core_over_sgbm=ratio, by_depth=depth_rows,
                           index=[os.path.join(d, "index.json") for d, _ in indices]), f, indent=2)
        os.replace(args.json + ".tmp", args.json)


if __name__ == "__main__":
    main()
