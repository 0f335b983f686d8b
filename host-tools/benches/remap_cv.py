#!/usr/bin/env python3
"""OpenCV fixed-point remap baseline for `cargo bench -p orbfix-host --bench reproject`.

Usage: remap_cv.py DIR. DIR holds `frames.u8` (the four views stacked vertically,
W x 4H, uint8), `mapx.f32` / `mapy.f32` (N x N source coordinates into the stack, OpenCV
pixel-centre convention, -1 for no data) and `meta.json` ({"w", "h4", "n", "reps"}).
Converts the maps to CV_16SC2 fixed point (cv2.convertMaps), times cv2.remap (bilinear,
constant border 0, one thread) and prints one JSON line: seconds per call (median), the
conversion time, and writes `out_cv.u8`. Prints {"error": ...} if cv2 is missing.
"""
import json
import sys
import time

try:
    import cv2
    import numpy as np
except ImportError as e:  # the bench must not require OpenCV
    print(json.dumps({"error": f"cv2 not available ({e}); pip install opencv-python-headless"}))
    sys.exit(0)

d = sys.argv[1]
meta = json.load(open(f"{d}/meta.json"))
w, h4, n, reps = meta["w"], meta["h4"], meta["n"], meta["reps"]
src = np.fromfile(f"{d}/frames.u8", dtype=np.uint8).reshape(h4, w)
mx = np.fromfile(f"{d}/mapx.f32", dtype=np.float32).reshape(n, n)
my = np.fromfile(f"{d}/mapy.f32", dtype=np.float32).reshape(n, n)
cv2.setNumThreads(1)
t0 = time.perf_counter()
m1, m2 = cv2.convertMaps(mx, my, cv2.CV_16SC2)
t_conv = time.perf_counter() - t0
out = cv2.remap(src, m1, m2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
times = []
for _ in range(reps):
    t0 = time.perf_counter()
    cv2.remap(src, m1, m2, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    times.append(time.perf_counter() - t0)
times.sort()
out.tofile(f"{d}/out_cv.u8")
print(json.dumps({
    "version": cv2.__version__,
    "median_s": times[len(times) // 2],
    "min_s": times[0],
    "convert_s": t_conv,
    "map_bytes": int(m1.nbytes + m2.nbytes),
}))
