#!/usr/bin/python3
"""A synthetic planetary site written by GDAL: DEM + orthoimage GeoTIFFs for `orbfix eval --dem`.

Not orbfix's procedural world: its own terrain model, drawn with NumPy and written with GDAL's
Python bindings (Debian's python3-gdal), in a real registered CRS (default IAU_2015:49910,
"Mars (2015) - Sphere / Ocentric / Equirectangular, clon = 0", projected metres) far from the
CRS origin (default north-west corner (4 590 000, 1 091 000) m: Jezero crater's longitude and
latitude), as a real product would come.

Terrain (built at the orthoimage's pixel size, then block-averaged to the DEM's):
- background relief: spectral (fractal) noise, height power spectrum ~ f^-4, RMS 1.5 m;
- craters: diameters 3-80 m with a cumulative density N(>D) = 27 000 D^-2 per km^2 (D in m),
  depth 0.2 D, rim 0.04 D, rim falloff r^-3 outside, each degraded by a random factor;
- boulders: 0.4-2.5 m hemispheroids, 1500 per km^2, brighter than the regolith;
- albedo: low-frequency patches (+-20 %), fresh-crater haloes, pixel-scale regolith texture.
Orthoimage: Lambert shading under one sun (default 30 deg elevation, azimuth 135 deg) with cast
shadows, display gamma 2.2, 8-bit. DEM: Float32 heights in metres, the orthoimage's heights
averaged over 2 x 2 pixels (a DTM coarser than its orthoimage, as HiRISE and LROC products are).

Usage:
  /usr/bin/python3 scripts/dem_site.py --out-dem out/site/dem.tif --out-ortho out/site/ortho.tif
      [--size-m 1000] [--ortho-m-per-px 0.25] [--dem-factor 2] [--seed 7]
      [--crs IAU_2015:49910] [--west 4590000] [--north 1091000]
      [--sun-elevation 30] [--sun-azimuth 135]
"""
import argparse
import math
import sys

import numpy as np
from osgeo import gdal, osr

gdal.UseExceptions()


def fractal(rng, n, m_per_px, beta, rms):
    """Square n x n field with power spectrum ~ f^-beta, scaled to the given RMS."""
    fy = np.fft.fftfreq(n, d=m_per_px)[:, None]
    fx = np.fft.rfftfreq(n, d=m_per_px)[None, :]
    f = np.sqrt(fx * fx + fy * fy)
    f[0, 0] = np.inf
    f = np.maximum(f, 1.0 / 400.0)  # no power beyond 400 m wavelengths
    amp = f ** (-beta / 2.0)
    amp[0, 0] = 0.0
    spec = amp * np.exp(2j * np.pi * rng.random(amp.shape))
    z = np.fft.irfft2(spec, s=(n, n)).astype(np.float32)
    z *= rms / max(float(z.std()), 1e-12)
    return z


def add_craters(rng, h, alb, m_per_px, size_m):
    n = h.shape[0]
    area_km2 = (size_m / 1000.0) ** 2
    d_min, d_max, a = 3.0, 80.0, 27000.0
    count = rng.poisson(a * (d_min ** -2 - d_max ** -2) * area_km2)
    # Inverse CDF of N(>D) ~ D^-2 between d_min and d_max.
    u = rng.random(count)
    d = (d_min ** -2 - u * (d_min ** -2 - d_max ** -2)) ** -0.5
    d.sort()
    for dia in d[::-1]:  # big ones first, small ones on top
        r_m = dia / 2.0
        reach = 2.5 * r_m
        cx, cy = rng.random(2) * n * m_per_px
        c0 = max(int((cx - reach) / m_per_px), 0)
        c1 = min(int((cx + reach) / m_per_px) + 1, n)
        r0 = max(int((cy - reach) / m_per_px), 0)
        r1 = min(int((cy + reach) / m_per_px) + 1, n)
        if c0 >= c1 or r0 >= r1:
            continue
        yy, xx = np.mgrid[r0:r1, c0:c1]
        rr = np.hypot((xx + 0.5) * m_per_px - cx, (yy + 0.5) * m_per_px - cy) / r_m
        fresh = rng.random() ** 2  # most craters are degraded
        depth = 0.2 * dia * (0.25 + 0.75 * fresh)
        rim = 0.04 * dia * (0.3 + 0.7 * fresh)
        prof = np.where(rr < 1.0, (depth + rim) * (rr * rr - 1.0) + rim, rim * np.maximum(rr, 1.0) ** -3)
        prof = np.where(rr < 2.5, prof, 0.0).astype(np.float32)
        h[r0:r1, c0:c1] += prof
        if fresh > 0.6:  # a bright halo of fresh ejecta
            halo = np.where(rr < 2.0, 0.25 * fresh * np.exp(-((rr - 1.0) ** 2) / 0.3), 0.0)
            alb[r0:r1, c0:c1] *= (1.0 + halo).astype(np.float32)
    return count


def add_boulders(rng, h, alb, m_per_px, size_m):
    n = h.shape[0]
    count = rng.poisson(1500.0 * (size_m / 1000.0) ** 2)
    for _ in range(count):
        dia = 0.4 + 2.1 * rng.random() ** 2
        r_m = dia / 2.0
        cx, cy = rng.random(2) * n * m_per_px
        c0, c1 = max(int((cx - r_m) / m_per_px), 0), min(int((cx + r_m) / m_per_px) + 2, n)
        r0, r1 = max(int((cy - r_m) / m_per_px), 0), min(int((cy + r_m) / m_per_px) + 2, n)
        if c0 >= c1 or r0 >= r1:
            continue
        yy, xx = np.mgrid[r0:r1, c0:c1]
        q = 1.0 - (np.hypot((xx + 0.5) * m_per_px - cx, (yy + 0.5) * m_per_px - cy) / r_m) ** 2
        bump = (0.6 * dia * np.sqrt(np.maximum(q, 0.0))).astype(np.float32)
        h[r0:r1, c0:c1] += bump
        alb[r0:r1, c0:c1] = np.where(q > 0, alb[r0:r1, c0:c1] * 1.3, alb[r0:r1, c0:c1])
    return count


def shade(h, m_per_px, elev_deg, az_deg):
    """Lambert shading with cast shadows; sun azimuth clockwise from north, towards the sun."""
    el, az = math.radians(elev_deg), math.radians(az_deg)
    sx, sy, sz = math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)
    gy, gx = np.gradient(h, m_per_px)  # gy along rows (southwards), gx eastwards
    dzdx, dzdy = gx, -gy  # dz/d(east), dz/d(north)
    norm = np.sqrt(dzdx * dzdx + dzdy * dzdy + 1.0)
    lam = np.maximum((-dzdx * sx - dzdy * sy + sz) / norm, 0.0)
    # Cast shadows: march towards the sun in whole-pixel steps (nearest pixel).
    n = h.shape[0]
    lit = np.ones_like(h, dtype=bool)
    relief = float(h.max() - h.min())
    steps = int(min(relief / math.tan(el) / m_per_px + 2, 4 * n))
    dc, dr = math.sin(az), -math.cos(az)  # columns east, rows south
    tan_el = math.tan(el)
    for k in range(1, steps + 1):
        oc, orow = int(round(k * dc)), int(round(k * dr))
        if abs(oc) >= n or abs(orow) >= n:
            break
        dist = math.hypot(oc, orow) * m_per_px
        src = h[max(orow, 0):n + min(orow, 0), max(oc, 0):n + min(oc, 0)]
        dst = (slice(max(-orow, 0), n + min(-orow, 0)), slice(max(-oc, 0), n + min(-oc, 0)))
        lit[dst] &= src <= h[dst] + dist * tan_el
    return (lam * lit + 0.02).astype(np.float32)


def write(path, arr, west, north, m_per_px, srs, dtype, opts):
    drv = gdal.GetDriverByName("GTiff")
    rows, cols = arr.shape
    ds = drv.Create(path, cols, rows, 1, dtype, opts)
    ds.SetGeoTransform((west, m_per_px, 0.0, north, 0.0, -m_per_px))
    ds.SetProjection(srs.ExportToWkt())
    ds.SetMetadataItem("AREA_OR_POINT", "Area")
    ds.GetRasterBand(1).WriteArray(arr)
    ds.FlushCache()
    ds = None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out-dem", required=True)
    p.add_argument("--out-ortho", required=True)
    p.add_argument("--size-m", type=float, default=1000.0)
    p.add_argument("--ortho-m-per-px", type=float, default=0.25)
    p.add_argument("--dem-factor", type=int, default=2, help="DEM pixel = this many ortho pixels")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--crs", default="IAU_2015:49910")
    p.add_argument("--west", type=float, default=4590000.0)
    p.add_argument("--north", type=float, default=1091000.0)
    p.add_argument("--sun-elevation", type=float, default=30.0)
    p.add_argument("--sun-azimuth", type=float, default=135.0)
    a = p.parse_args()
    m = a.ortho_m_per_px
    n = int(round(a.size_m / m))
    if n % a.dem_factor:
        sys.exit(f"--size-m / --ortho-m-per-px = {n} px must be a multiple of --dem-factor")
    srs = osr.SpatialReference()
    if srs.SetFromUserInput(a.crs) != 0 or not srs.IsProjected():
        sys.exit(f"--crs {a.crs}: not a projected CRS GDAL knows")
    rng = np.random.default_rng(a.seed)
    h = fractal(rng, n, m, 4.0, 1.5)
    alb = 1.0 + 0.2 * fractal(rng, n, m, 2.0, 1.0) / 2.5
    alb *= 1.0 + 0.10 * rng.standard_normal((n, n)).astype(np.float32)
    alb = np.clip(alb, 0.3, 2.0).astype(np.float32)
    nc = add_craters(rng, h, alb, m, a.size_m)
    nb = add_boulders(rng, h, alb, m, a.size_m)
    rad = alb * shade(h, m, a.sun_elevation, a.sun_azimuth)
    ref = float(np.percentile(rad, 99.7))
    gray = np.clip(255.0 * np.clip(rad / ref, 0.0, 1.0) ** (1.0 / 2.2) + 0.5, 0, 255).astype(np.uint8)
    f = a.dem_factor
    dem = h.reshape(n // f, f, n // f, f).mean(axis=(1, 3)).astype(np.float32)
    dem += 1450.0  # a plausible elevation above the datum
    write(a.out_dem, dem, a.west, a.north, m * f, srs, gdal.GDT_Float32,
          ["TILED=YES", "COMPRESS=DEFLATE"])
    write(a.out_ortho, gray, a.west, a.north, m, srs, gdal.GDT_Byte,
          ["TILED=YES", "COMPRESS=LZW"])
    print(f"{a.out_dem}: {n // f} x {n // f} px at {m * f} m, heights {dem.min():.1f}..{dem.max():.1f} m; "
          f"{a.out_ortho}: {n} x {n} px at {m} m; {nc} craters, {nb} boulders; CRS {srs.GetName()}; "
          f"north-west corner ({a.west:.0f}, {a.north:.0f})")


if __name__ == "__main__":
    main()
