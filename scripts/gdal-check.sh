#!/usr/bin/env bash
# GeoTIFF interoperability against GDAL itself (docs/interop.md):
#   orbfix -> GDAL: `orbfix export-geotiff` files give the georeference, CRS and values
#                   orbfix meant under gdalinfo -json, gdallocationinfo and python3-gdal;
#   GDAL -> orbfix: files python3-gdal writes (tiled/striped, compressed, PixelIsArea and
#                   PixelIsPoint, f32/i16/u16/u8, EPSG and IAU CRSs) are read right by
#                   `orbfix geotiff-info`, and what orbfix does not support is refused.
# Installs gdal-bin and python3-gdal (Debian) when missing. Prints "N passed, M failed";
# exits non-zero on any failure.
#   bash scripts/gdal-check.sh              # the checks (about a minute after the build)
#   ORBFIX=path/to/orbfix bash scripts/gdal-check.sh
set -u
cd "$(dirname "$0")/.."
source scripts/env.sh

# python3-gdal is Debian's: use the system interpreter (a pyenv or venv python3 lacks osgeo).
PY=/usr/bin/python3
has_gdal() { command -v gdalinfo >/dev/null 2>&1 && "$PY" -c "from osgeo import gdal" 2>/dev/null; }
if ! has_gdal; then
  echo "gdal-check: installing gdal-bin and python3-gdal" >&2
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
  $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq gdal-bin python3-gdal >/dev/null \
    || { echo "gdal-check: cannot install gdal-bin python3-gdal" >&2; exit 2; }
fi

if [ -z "${ORBFIX:-}" ]; then
  cargo build --release -q -p orbfix-host || exit 2
  ORBFIX="${CARGO_TARGET_DIR:-target}/release/orbfix"
fi
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
pass=0; fail=0
ok() { pass=$((pass + 1)); echo "PASS $1"; }
ko() { fail=$((fail + 1)); echo "FAIL $1${2:+: $2}"; }
# check NAME COMMAND...: passes when the command succeeds; its output is shown on failure.
check() {
  local name=$1; shift
  local out
  if out=$("$@" 2>&1); then ok "$name"; else ko "$name" "$(echo "$out" | tail -5)"; fi
}
# refused NAME FILE WORD: orbfix must refuse FILE with a message containing WORD.
refused() {
  local out
  if out=$("$ORBFIX" geotiff-info "$2" 2>&1); then ko "$1" "accepted: $out"
  elif echo "$out" | grep -qi -- "$3"; then ok "$1"; else ko "$1" "message lacks '$3': $out"; fi
}

# ---------------------------------------------------------------- orbfix -> GDAL
X=3000; Y=2000; S=64; R=0.5   # 128 x 128 px, NW corner (2968, 2032)
if "$ORBFIX" export-geotiff --seed 1 --x $X --y $Y --size-m $S --m-per-px $R \
     --out-dem "$T/dem.tif" --out-ortho "$T/ortho.tif" >/dev/null; then
  ok "export-geotiff writes both files"
else
  ko "export-geotiff writes both files"
fi
"$ORBFIX" map --seed 1 --x $X --y $Y --size-m $S --m-per-px $R --out "$T/map.png" >/dev/null 2>&1
for i in 1 2 3; do
  case $i in 1) px=2968.25; py=2031.75;; 2) px=3000.25; py=1999.75;; 3) px=3031.75; py=1968.25;; esac
  "$ORBFIX" elevation --seed 1 --x $px --y $py > "$T/elev$i.txt"
done
check "gdalinfo: DEM georeference, size, type, CRS = IAU_2015:30110" "$PY" - "$T" <<'EOF'
import json, subprocess, sys
from osgeo import osr
t = sys.argv[1]
for f, typ in (("dem.tif", "Float32"), ("ortho.tif", "Byte")):
    j = json.loads(subprocess.check_output(["gdalinfo", "-json", f"{t}/{f}"]))
    gt = j["geoTransform"]
    assert gt == [2968.0, 0.5, 0.0, 2032.0, 0.0, -0.5], (f, gt)
    assert j["size"] == [128, 128], j["size"]
    assert len(j["bands"]) == 1 and j["bands"][0]["type"] == typ, j["bands"]
    assert j["metadata"][""]["AREA_OR_POINT"] == "Area", j["metadata"]
    srs = osr.SpatialReference(); srs.ImportFromWkt(j["coordinateSystem"]["wkt"])
    ref = osr.SpatialReference(); ref.SetFromUserInput("IAU_2015:30110")
    assert srs.IsProjected() and srs.GetLinearUnits() == 1.0, f
    assert srs.IsSame(ref), (f, srs.ExportToWkt())
    assert "Moon (2015)" in j["coordinateSystem"]["wkt"]
    c = j["cornerCoordinates"]
    assert c["upperLeft"] == [2968.0, 2032.0] and c["lowerRight"] == [3032.0, 1968.0], c
EOF
check "gdallocationinfo: DEM values = orbfix elevation at pixel centres" "$PY" - "$T" <<'EOF'
import subprocess, sys
t = sys.argv[1]
pts = [(2968.25, 2031.75), (3000.25, 1999.75), (3031.75, 1968.25)]
for i, (x, y) in enumerate(pts, 1):
    g = float(subprocess.check_output(["gdallocationinfo", "-valonly", "-geoloc", f"{t}/dem.tif", str(x), str(y)]))
    o = float(open(f"{t}/elev{i}.txt").read())
    assert abs(g - o) < 1e-3, (x, y, g, o)
EOF
check "python3-gdal: orthoimage pixels = orbfix map's PNG of the same region" "$PY" - "$T" <<'EOF'
import sys
from osgeo import gdal
import numpy as np
t = sys.argv[1]
a = gdal.Open(f"{t}/ortho.tif").ReadAsArray()
b = gdal.Open(f"{t}/map.png").ReadAsArray()
assert a.shape == (128, 128) and a.dtype == np.uint8, (a.shape, a.dtype)
assert (a == b).all(), int((a != b).sum())
assert a.std() > 5, a.std()
EOF

# ---------------------------------------------------------------- GDAL -> orbfix
"$PY" - "$T" <<'EOF' || ko "python3-gdal writes the test files"
import sys
from osgeo import gdal, osr
import numpy as np
t = sys.argv[1]
def make(name, arr, gt, srs, dtype, opts=(), point=False, nodata=None, bands=1):
    drv = gdal.GetDriverByName("GTiff")
    h, w = arr.shape
    ds = drv.Create(f"{t}/{name}", w, h, bands, dtype, list(opts))
    ds.SetGeoTransform(gt)
    if srs is not None:
        s = osr.SpatialReference(); s.SetFromUserInput(srs); ds.SetProjection(s.ExportToWkt())
    if point:
        ds.SetMetadataItem("AREA_OR_POINT", "Point")
    for b in range(1, bands + 1):
        band = ds.GetRasterBand(b)
        if nodata is not None:
            band.SetNoDataValue(nodata)
        band.WriteArray(arr)
    ds = None
r, c = np.mgrid[0:80, 0:100]
dem = (1000.0 + 0.25 * c - 0.5 * r).astype(np.float32)
dem[7, 9] = -9999.0
gt = (500000.0, 2.0, 0.0, 4100000.0, 0.0, -2.0)
make("g_f32_tiled.tif", dem, gt, "EPSG:32633", gdal.GDT_Float32,
     ["TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16", "COMPRESS=DEFLATE"], nodata=-9999.0)
make("g_f32_point.tif", dem, gt, "EPSG:32633", gdal.GDT_Float32, ["COMPRESS=LZW"], point=True)
make("g_i16_iau.tif", (dem * 2).astype(np.int16), (-1200.0, 0.25, 0.0, 800.0, 0.0, -0.25),
     "IAU_2015:30110", gdal.GDT_Int16, ["COMPRESS=PACKBITS"])
make("g_u16.tif", (c * 300 + r).astype(np.uint16), gt, "EPSG:3031", gdal.GDT_UInt16)
make("g_u8.tif", ((c * 7 + r * 3) % 256).astype(np.uint8), gt, "EPSG:32633", gdal.GDT_Byte,
     ["TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=32", "COMPRESS=LZW"])
# Refused ones.
make("r_geographic.tif", dem, (10.0, 0.001, 0.0, 20.0, 0.0, -0.001), "EPSG:4326", gdal.GDT_Float32)
make("r_moon_geographic.tif", dem, (10.0, 0.001, 0.0, 20.0, 0.0, -0.001), "IAU_2015:30100", gdal.GDT_Float32)
make("r_rotated.tif", dem, (500000.0, 2.0, 0.3, 4100000.0, 0.3, -2.0), "EPSG:32633", gdal.GDT_Float32)
make("r_rgb.tif", (c % 256).astype(np.uint8), gt, "EPSG:32633", gdal.GDT_Byte, bands=3)
make("r_f64.tif", dem.astype(np.float64), gt, "EPSG:32633", gdal.GDT_Float64)
make("r_feet.tif", dem, gt, "EPSG:2263", gdal.GDT_Float32)
make("r_nonsquare.tif", dem, (500000.0, 2.0, 0.0, 4100000.0, 0.0, -3.0), "EPSG:32633", gdal.GDT_Float32)
make("r_nocrs.tif", dem, gt, None, gdal.GDT_Float32)
EOF
for f in g_f32_tiled g_f32_point g_i16_iau g_u16 g_u8; do
  "$ORBFIX" geotiff-info "$T/$f.tif" --pixel 0,0 --pixel 9,7 --pixel 99,79 --pixel 41,3 > "$T/$f.json" 2>"$T/$f.err" \
    || echo "{\"error\": \"$(tr -d '"\n' < "$T/$f.err")\"}" > "$T/$f.json"
done
check "orbfix reads GDAL's files: origin, pixel size, CRS, samples, no-data, values" "$PY" - "$T" <<'EOF'
import json, sys
from osgeo import gdal
t = sys.argv[1]
def info(n):
    j = json.load(open(f"{t}/{n}.json"))
    assert "error" not in j, (n, j)
    return j
def vals(j): return [v["value"] for v in j["values"]]
def exp(f):  # the DEM's formula at the checked pixels
    return [f(c, r) for c, r in ((0, 0), (9, 7), (99, 79), (41, 3))]
plane = lambda c, r: 1000.0 + 0.25 * c - 0.5 * r
for n, kind in (("g_f32_tiled", "f32"), ("g_f32_point", "f32")):
    j = info(n)
    gt = gdal.Open(f"{t}/{n}.tif").GetGeoTransform()
    assert (j["origin_x_m"], j["origin_y_m"], j["m_per_px"]) == (gt[0], gt[3], gt[1]), (n, j, gt)
    assert (j["width"], j["height"], j["sample"], j["epsg"]) == (100, 80, kind, 32633), j
j = info("g_f32_tiled")
assert j["raster_type"] == "PixelIsArea" and j["nodata"] == -9999.0, j
e = exp(plane); e[1] = None
assert vals(j) == e, (vals(j), e)
j = info("g_f32_point")
assert j["raster_type"] == "PixelIsPoint" and j["nodata"] is None, j
assert (j["origin_x_m"], j["origin_y_m"]) == (500000.0, 4100000.0), j
e = exp(plane); e[1] = -9999.0
assert vals(j) == e, vals(j)
j = info("g_i16_iau")
assert (j["sample"], j["epsg"], j["origin_x_m"], j["origin_y_m"], j["m_per_px"]) == ("i16", None, -1200.0, 800.0, 0.25), j
assert "Moon (2015)" in j["crs"], j["crs"]
e = exp(lambda c, r: float(int(2 * plane(c, r)))); e[1] = -19998.0
assert vals(j) == e, vals(j)
j = info("g_u16")
assert (j["sample"], j["epsg"]) == ("u16", 3031) and vals(j) == exp(lambda c, r: float(c * 300 + r)), j
j = info("g_u8")
assert j["sample"] == "u8" and vals(j) == exp(lambda c, r: float((c * 7 + r * 3) % 256)), j
EOF
refused "refuses a geographic CRS (EPSG:4326, degrees)" "$T/r_geographic.tif" "geographic"
refused "refuses a geographic Moon CRS (IAU_2015:30100)" "$T/r_moon_geographic.tif" "degrees"
refused "refuses rotation / shear" "$T/r_rotated.tif" "rotation"
refused "refuses three bands" "$T/r_rgb.tif" "single-band"
refused "refuses f64 samples" "$T/r_f64.tif" "u8, u16, i16 or f32"
refused "refuses a CRS in US survey feet (EPSG:2263)" "$T/r_feet.tif" "not metre"
refused "refuses non-square pixels" "$T/r_nonsquare.tif" "not square"
refused "refuses a file without a CRS" "$T/r_nocrs.tif" "no GeoKeyDirectoryTag"

# GDAL rewrites orbfix's export (tiled, LZW, PixelIsPoint) and orbfix reads the same raster.
gdal_translate -q -co TILED=YES -co COMPRESS=LZW -mo AREA_OR_POINT=Point "$T/dem.tif" "$T/dem_gdal.tif"
"$ORBFIX" geotiff-info "$T/dem.tif" --pixel 0,0 --pixel 64,64 --pixel 127,127 > "$T/a.json"
"$ORBFIX" geotiff-info "$T/dem_gdal.tif" --pixel 0,0 --pixel 64,64 --pixel 127,127 > "$T/b.json"
check "orbfix export -> gdal_translate (tiled, LZW, PixelIsPoint) -> orbfix: same georeference and values" "$PY" - "$T" <<'EOF'
import json, sys
t = sys.argv[1]
a, b = (json.load(open(f"{t}/{n}.json")) for n in "ab")
for k in ("width", "height", "origin_x_m", "origin_y_m", "m_per_px", "values"):
    assert a[k] == b[k], (k, a[k], b[k])
assert b["raster_type"] == "PixelIsPoint" and a["crs"] == b["crs"], (a["crs"], b["crs"])
EOF

# ---------------------------------------------------------------- a GDAL-written DEM site
# scripts/dem_site.py (python3-gdal; a synthetic Mars site, IAU_2015:49910, far from the CRS
# origin): `orbfix map --dem` is the orthoimage's own pixels where the grids align; maps off
# the site, sites too small for an evaluation and mixed CRSs are refused with what to do.
if "$PY" scripts/dem_site.py --size-m 200 --seed 3 --out-dem "$T/site_dem.tif" \
     --out-ortho "$T/site_ortho.tif" >/dev/null; then
  ok "dem_site.py: python3-gdal writes a DEM + orthoimage site"
else
  ko "dem_site.py: python3-gdal writes a DEM + orthoimage site"
fi
"$ORBFIX" map --dem "$T/site_dem.tif" --ortho "$T/site_ortho.tif" --x 100 --y 900 --size-m 50 \
  --out "$T/site_map.png" > "$T/site_map.txt" 2>&1
check "orbfix map --dem: the map is the orthoimage's pixels, offset (4590000, 1090000) in MAP.json" "$PY" - "$T" <<'EOF'
import json, sys
from osgeo import gdal
t = sys.argv[1]
m = json.load(open(f"{t}/site_map.json"))
assert m["crs_offset_m"] == [4590000.0, 1090000.0], m
assert (m["origin_x_m"], m["origin_y_m"], m["m_per_px"]) == (75.0, 925.0, 0.25), m
assert m["world_seed"] is None and m["sun_deg"] is None, m
a = gdal.Open(f"{t}/site_map.png").ReadAsArray()
# World (75, 925) = CRS (4590075, 1090925): orthoimage column 300, row 300.
o = gdal.Open(f"{t}/site_ortho.tif").ReadAsArray(300, 300, 200, 200)
assert a.shape == (200, 200) and (a == o).all(), int((a != o).sum())
assert "Mars (2015)" in open(f"{t}/site_map.txt").read()
EOF
# refused_cmd NAME WORD COMMAND...: the command must fail with a message containing WORD.
refused_cmd() {
  local name=$1 word=$2 out; shift 2
  if out=$("$@" 2>&1); then ko "$name" "accepted: $out"
  elif echo "$out" | grep -qi -- "$word"; then ok "$name"; else ko "$name" "message lacks '$word': $out"; fi
}
refused_cmd "orbfix map --dem refuses a map off the site" "leaves the rasters' common region" \
  "$ORBFIX" map --dem "$T/site_dem.tif" --ortho "$T/site_ortho.tif" --x 10 --y 900 --size-m 50 --out "$T/x.png"
refused_cmd "orbfix eval --dem refuses a site too small for its map and prior" "overlap less than" \
  "$ORBFIX" eval --dem "$T/site_dem.tif" --ortho "$T/site_ortho.tif" --queries 1 --json "$T/e.json" --quiet
gdal_translate -q -a_srs EPSG:32633 "$T/site_ortho.tif" "$T/site_ortho_utm.tif"
refused_cmd "orbfix map --dem refuses a DEM and orthoimage in different CRSs" "gdalwarp" \
  "$ORBFIX" map --dem "$T/site_dem.tif" --ortho "$T/site_ortho_utm.tif" --x 100 --y 900 --out "$T/x.png"

# `orbfix generate --dem`: a smoke dataset of the GDAL-written site; its rows' heights are the
# DEM's (bilinear between pixel centres, read by GDAL), its satellite crops the orthoimage's
# 2 x 2 means, its dataset.json the site's CRS offset.
"$ORBFIX" generate --preset smoke --seed 3 --dem "$T/site_dem.tif" --ortho "$T/site_ortho.tif" \
  --dem-margin 30 --out "$T/site_ds" --quiet >/dev/null 2>&1
check "orbfix generate --dem: rows on the site with GDAL's heights, crops from the orthoimage" "$PY" - "$T" <<'EOF'
import json, sys
import numpy as np
from osgeo import gdal
t = sys.argv[1]
info = json.load(open(f"{t}/site_ds/dataset.json"))
ox, oy = info["dem_frame"]["crs_offset_m"]
assert (ox, oy) == (4590000.0, 1090000.0), info["dem_frame"]
assert info["zones"] == [["dem", [30.0, 830.0, 170.0, 970.0]]], info["zones"]
o = gdal.Open(f"{t}/site_ortho.tif"); a = o.ReadAsArray().astype(float); ga = o.GetGeoTransform()
d = gdal.Open(f"{t}/site_dem.tif"); h = d.ReadAsArray().astype(float); gd = d.GetGeoTransform()
rows = [json.loads(l) for l in open(f"{t}/site_ds/manifest.jsonl")]
assert len(rows) == 6
for r in rows:
    e, n = r["x_m"] + ox, r["y_m"] + oy
    c, k = (e - gd[0]) / gd[1] - 0.5, (n - gd[3]) / gd[5] - 0.5
    c0, k0 = int(c), int(k)
    fc, fk = c - c0, k - k0
    z = (h[k0, c0] * (1 - fc) + h[k0, c0 + 1] * fc) * (1 - fk) + (h[k0 + 1, c0] * (1 - fc) + h[k0 + 1, c0 + 1] * fc) * fk
    assert abs(z - r["ground_z_m"]) < 1e-3, (r["id"], z, r["ground_z_m"])
    s = gdal.Open(f"{t}/site_ds/{r['satellite']}").ReadAsArray().astype(float)
    m = 0.5
    xs = e - 25 + (np.arange(100) + 0.5) * m
    ys = n + 25 - (np.arange(100) + 0.5) * m
    cc = np.round((xs - ga[0]) / ga[1] - 1).astype(int)
    rr = np.round((ys - ga[3]) / ga[5] - 1).astype(int)
    w = (a[np.ix_(rr, cc)] + a[np.ix_(rr + 1, cc)] + a[np.ix_(rr, cc + 1)] + a[np.ix_(rr + 1, cc + 1)]) / 4
    corr = np.corrcoef(s.ravel(), w.ravel())[0, 1]
    assert corr > 0.9 and np.abs(s - w).mean() < 12, (r["id"], corr, np.abs(s - w).mean())
EOF
refused_cmd "orbfix generate --dem refuses a map sun (the crops are the orthoimage)" "no effect with --dem" \
  "$ORBFIX" generate --dem "$T/site_dem.tif" --ortho "$T/site_ortho.tif" --map-sun-elevation 40 --out "$T/x"
refused_cmd "orbfix generate --dem refuses a margin that leaves no site" "dem-margin" \
  "$ORBFIX" generate --dem "$T/site_dem.tif" --ortho "$T/site_ortho.tif" --dem-margin 120 --out "$T/x"

echo "$pass passed, $fail failed"
[ "$fail" = 0 ]
