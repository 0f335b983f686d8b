#!/usr/bin/env python3
"""Test of scripts/load_dataset.py on a dataset written by
`orbfix generate --preset smoke --range --out DIR` (run by scripts/python-check.sh).

    python3 scripts/test_load_dataset.py DIR
"""

import json
import os
import shutil
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from load_dataset import load_dataset  # noqa: E402


def main(root):
    checks = 0

    def check(cond, msg):
        nonlocal checks
        if not cond:
            raise AssertionError(msg)
        checks += 1

    info = json.load(open(os.path.join(root, "dataset.json")))
    cfg = info["config"]
    w, h, s = cfg["render"]["camera"]["width_px"], cfg["render"]["camera"]["height_px"], cfg["satellite_px"]
    ds = load_dataset(root)
    n = info["total"]
    check(len(ds["id"]) == n, f"{len(ds['id'])} rows, dataset.json says {n}")
    check(ds["views"].shape == (n, 4, h, w) and ds["views"].dtype == np.uint8, f"views {ds['views'].shape}")
    check(ds["satellite"].shape == (n, s, s) and ds["satellite"].dtype == np.uint8, f"satellite {ds['satellite'].shape}")
    check(ds["range_m"] is not None, "range images missing (generate with --range)")
    check(ds["range_m"].shape == (n, 4, h, w) and ds["range_m"].dtype == np.float32, "range shape")
    # Images have content: no constant view or crop.
    check(all(v.std() > 1.0 for v in ds["views"].reshape(-1, h, w)), "a constant view")
    check(all(c.std() > 1.0 for c in ds["satellite"]), "a constant satellite crop")
    # Range is metres along the ray from a camera 2 m above the ground, 15 deg down: the
    # bottom row of every view is near ground (a few metres), the horizon rows far or sky,
    # and no ground point is nearer than about the camera height. (A byte-swapped 16-bit PNG
    # reads as hundreds of metres at the bottom row.)
    r = ds["range_m"]
    bottom = np.nanmedian(r[:, :, -1, :], axis=-1)
    check(np.all((bottom > 1.5) & (bottom < 15.0)), f"bottom-row ranges {bottom.round(2)} m")
    check(np.nanmin(r) > 1.0, f"a range of {np.nanmin(r):.2f} m")
    middle = np.nanmedian(r[:, :, h // 2, :], axis=-1)
    check(np.all(middle > bottom), "ranges must grow from the bottom row towards the horizon")
    check(np.isnan(r[:, :, 0, :]).mean() > 0.5, "the top row should be mostly sky (NaN)")
    # Manifest values come through as arrays.
    rows = [json.loads(line) for line in open(os.path.join(root, "manifest.jsonl"))]
    check(np.allclose(ds["x_m"], [r["x_m"] for r in rows]), "x_m")
    check(np.allclose(ds["sun_view"][:, 1], [r["sun_view"]["azimuth_deg"] for r in rows]), "sun azimuth")
    # Splits: 4 / 1 / 1 on the smoke preset.
    counts = {k: len(load_dataset(root, split=k)["id"]) for k in ("train", "validation", "test")}
    check(counts == dict(zip(("train", "validation", "test"), cfg["counts"])), f"split counts {counts}")
    # A truncated view is a clear error naming the file.
    with tempfile.TemporaryDirectory() as t:
        bad = os.path.join(t, "ds")
        shutil.copytree(root, bad)
        p = os.path.join(bad, rows[2]["views"][1])
        data = open(p, "rb").read()
        open(p, "wb").write(data[: len(data) // 2])
        try:
            load_dataset(bad)
            check(False, "a truncated PNG was read without error")
        except ValueError as e:
            check(rows[2]["views"][1] in str(e) and "generate" in str(e), f"unclear error: {e}")
    print(f"load_dataset: {checks} checks passed on {n} locations")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1]))
