#!/usr/bin/env python3
"""Load an `orbfix generate` dataset into NumPy arrays (docs/dataset.md).

    from load_dataset import load_dataset
    ds = load_dataset("DIR")                      # every location
    ds = load_dataset("DIR", split="train")       # one split
    ds["views"]        # uint8 [N, 4, H, W]   front, right, rear, left (8-bit gray)
    ds["satellite"]    # uint8 [N, S, S]      north-up crop centred on the rover
    ds["range_m"]      # float32 [N, 4, H, W] metres along the ray, NaN = sky
                       #   (only when generated with --range, else None)
    ds["x_m"], ds["y_m"], ds["ground_z_m"], ds["yaw_deg"], ...   float64 [N]
    ds["id"], ds["split"]                                         lists of str
    ds["info"]         # dataset.json as a dict (camera, resolutions, suns, zones)

Needs numpy and Pillow. Run as a script to print a summary:
    python3 scripts/load_dataset.py DIR [--split train]
"""

import json
import os
import sys

import numpy as np
from PIL import Image

SCALARS = ("x_m", "y_m", "ground_z_m", "yaw_deg", "pitch_deg", "roll_deg")


def _png(path, dtype, shape):
    """Decodes one PNG exactly (8-bit gray or 16-bit gray) and checks its size."""
    try:
        with Image.open(path) as im:
            im.load()
            a = np.array(im)
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: cannot decode the PNG ({e}); run orbfix generate again to re-render it")
    if a.dtype != dtype:
        # Pillow gives 16-bit gray as int32 ("I") on some versions: the values are exact.
        if dtype == np.uint16 and a.dtype in (np.int32, np.uint32) and a.min() >= 0 and a.max() < 65536:
            a = a.astype(np.uint16)
        else:
            raise ValueError(f"{path}: expected {np.dtype(dtype).name} pixels, got {a.dtype}")
    if a.shape != shape:
        raise ValueError(f"{path}: expected {shape[1]}x{shape[0]} pixels, got {a.shape}")
    return a


def load_dataset(root, split=None):
    """Reads dataset.json, manifest.jsonl and every image of `root` (optionally one split)."""
    with open(os.path.join(root, "dataset.json")) as f:
        info = json.load(f)
    cfg = info["config"]
    w, h = cfg["render"]["camera"]["width_px"], cfg["render"]["camera"]["height_px"]
    s = cfg["satellite_px"]
    with open(os.path.join(root, "manifest.jsonl")) as f:
        rows = [json.loads(line) for line in f if line.strip()]
    if split is not None:
        rows = [r for r in rows if r["split"] == split]
    n = len(rows)
    views = np.zeros((n, 4, h, w), np.uint8)
    sat = np.zeros((n, s, s), np.uint8)
    has_range = n > 0 and all("range" in r for r in rows)
    range_m = np.zeros((n, 4, h, w), np.float32) if has_range else None
    unit = info["range_m_per_unit"]
    for i, r in enumerate(rows):
        for k, p in enumerate(r["views"]):
            views[i, k] = _png(os.path.join(root, p), np.uint8, (h, w))
        sat[i] = _png(os.path.join(root, r["satellite"]), np.uint8, (s, s))
        if has_range:
            for k, p in enumerate(r["range"]):
                counts = _png(os.path.join(root, p), np.uint16, (h, w))
                m = counts.astype(np.float32) * np.float32(unit)
                m[counts == 0] = np.nan
                range_m[i, k] = m
    out = {
        "info": info,
        "id": [r["id"] for r in rows],
        "split": [r["split"] for r in rows],
        "views": views,
        "satellite": sat,
        "range_m": range_m,
        "sun_view": np.array([[r["sun_view"]["elevation_deg"], r["sun_view"]["azimuth_deg"]] for r in rows], np.float64).reshape(n, 2),
        "sun_map": np.array([[r["sun_map"]["elevation_deg"], r["sun_map"]["azimuth_deg"]] for r in rows], np.float64).reshape(n, 2),
    }
    for k in SCALARS:
        out[k] = np.array([r.get(k, 0.0) for r in rows], np.float64)
    return out


def main():
    import argparse

    p = argparse.ArgumentParser(description="Load an orbfix generate dataset into NumPy arrays and summarize it.")
    p.add_argument("root")
    p.add_argument("--split", choices=["train", "validation", "test"])
    a = p.parse_args()
    ds = load_dataset(a.root, a.split)
    print(f"{len(ds['id'])} locations")
    for k in ("views", "satellite", "range_m", "x_m", "sun_view"):
        v = ds[k]
        print(f"  {k:10s} " + ("absent (generate with --range)" if v is None else f"{v.dtype} {list(v.shape)}"))
    if ds["range_m"] is not None:
        r = ds["range_m"]
        print(f"  range: {np.nanmin(r):.2f}..{np.nanmax(r):.2f} m, {np.isnan(r).mean() * 100:.1f} % sky")
    return 0


if __name__ == "__main__":
    sys.exit(main())
