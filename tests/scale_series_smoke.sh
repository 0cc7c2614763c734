#!/usr/bin/env bash
# bench/scale_series.py at a tiny size, offline: the generated meshes hold the triangles asked
# for (read back from the PLY header and the glTF accessor), the CSV has a row with finite
# times and memory for parallax, and bad input is refused with a non-zero exit.
# Usage: scale_series_smoke.sh SOURCE_DIR BUILD_DIR
set -u
# src, build, tmp, ok, fail, finish
source "$(dirname "$0")/support/script_checks.sh"

if "$src/bench/scale_series.py" --sizes 0.002 --build "$build" --work "$tmp/w" --width 32 --height 18 --offline \
  --repeat 2 >"$tmp/out" 2>"$tmp/err"; then ok "ran"; else fail "exit $?"; tail -5 "$tmp/err"; fi
/usr/bin/python3 - "$tmp/w" <<'PY' && ok "meshes and CSV" || fail "meshes and CSV"
import csv, json, math, struct, sys, glob
w = sys.argv[1]
rows = list(csv.DictReader(open(f"{w}/results.csv")))
assert len(rows) == 1, rows
r = rows[0]
t = int(r["triangles"])
assert t == 2 * 32 * 32, t  # 0.002M asked: the nearest square grid, 32 x 32 quads
for k in ("cold_s", "cold_mib", "warm_s", "warm_mib", "cold_s_min", "cold_s_max"):
    assert math.isfinite(float(r[k])) and float(r[k]) > 0, (k, r[k])
assert int(r["runs"]) == 2 and float(r["cold_s_min"]) <= float(r["cold_s"]) <= float(r["cold_s_max"]), r
assert len(glob.glob(f"{w}/logs/parallax-cold-*.txt")) == 2 and len(glob.glob(f"{w}/logs/parallax-warm-*.txt")) == 2
ply = open(glob.glob(f"{w}/heightfield-{t}.ply")[0], "rb").read(400).decode("latin-1")
assert f"element face {t}" in ply and f"element vertex {33 * 33}" in ply, ply[:200]
glb = open(glob.glob(f"{w}/heightfield-{t}.glb")[0], "rb").read()
magic, version, total = struct.unpack("<III", glb[:12])
n = struct.unpack("<I", glb[12:16])[0]
doc = json.loads(glb[20:20 + n])
assert magic == 0x46546C67 and version == 2 and total == len(glb)
assert doc["accessors"][0]["count"] == 3 * t
PY
if grep -q "^| 0.00M" "$tmp/out"; then ok "table printed"; else fail "table"; cat "$tmp/out"; fi
# Past the cache's threshold (20k triangles): the warm start maps the device layout the filling
# run stored, and renders the very pixels of a start without any cache.
if "$src/bench/scale_series.py" --sizes 0.05 --build "$build" --work "$tmp/w2" --width 32 --height 18 --offline \
  --repeat 1 >"$tmp/out2" 2>"$tmp/err2"; then
  warm="$(ls "$tmp"/w2/logs/parallax-warm-*.txt)" cold="$(ls "$tmp"/w2/logs/parallax-cold-*.txt)"
  if grep -q "BVH [0-9]* ms (its device layout mapped from the cache)" "$warm"; then ok "warm start maps the device layout"
  else fail "warm start did not map the device layout"; grep "start:" "$warm"; fi
  if grep -q "BVH [0-9]* ms (built)" "$cold" && ! grep -q "device layout mapped" "$cold"; then ok "cold start builds"
  else fail "cold start"; grep "start:" "$cold"; fi
  json="$(ls "$tmp"/w2/heightfield-*.json)"
  common=(render --scene "$json" --frames 1 --spp 1 --width 32 --height 18 --devices 2)
  PARALLAX_BVH_CACHE=off "$build/parallax" "${common[@]}" --out "$tmp/none" >/dev/null 2>&1
  PARALLAX_CACHE_DIR="$tmp/w2/bvh-cache" "$build/parallax" "${common[@]}" --out "$tmp/mapped" >"$tmp/mapped.log" 2>&1
  grep -q "device layout mapped from the cache" "$tmp/mapped.log" || fail "the render did not map the layout"
  for eye in left right; do
    if "$build/parallax" compare --exact "$tmp/none/frame_0000_$eye.exr" "$tmp/mapped/frame_0000_$eye.exr" |
      grep -q "^identical$"; then ok "mapped layout gives the uncached pixels ($eye)"
    else fail "mapped layout changed the $eye image"; fi
  done
else fail "scale_series at 0.05M: exit $?"; tail -5 "$tmp/err2"; fi
# --smooth: the same grid with per-vertex unit normals and texture coordinates in both files; the
# render takes the full shading records (no "flat triangles" line).
if "$src/bench/scale_series.py" --sizes 0.002 --smooth --build "$build" --work "$tmp/w3" --width 32 --height 18 \
  --offline --repeat 1 >"$tmp/out3" 2>"$tmp/err3"; then
  /usr/bin/python3 - "$tmp/w3" <<'PY' && ok "smooth meshes carry normals and uvs" || fail "smooth meshes"
import json, struct, sys, glob
import numpy as np
w = sys.argv[1]
glb = open(glob.glob(f"{w}/heightfield-smooth-2048.glb")[0], "rb").read()
n = struct.unpack("<I", glb[12:16])[0]
doc = json.loads(glb[20:20 + n])
attrs = doc["meshes"][0]["primitives"][0]["attributes"]
assert set(attrs) == {"POSITION", "NORMAL", "TEXCOORD_0"}, attrs
acc = doc["accessors"][attrs["NORMAL"]]
view = doc["bufferViews"][acc["bufferView"]]
assert acc["count"] == 33 * 33 and acc["type"] == "VEC3"
start = 20 + n + 8 + view["byteOffset"]
nrm = np.frombuffer(glb[start:start + view["byteLength"]], dtype="<f4").reshape(-1, 3)
assert np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-5) and (nrm[:, 1] > 0).all()
assert doc["accessors"][attrs["TEXCOORD_0"]]["type"] == "VEC2"
ply = open(glob.glob(f"{w}/heightfield-smooth-2048.ply")[0], "rb").read(600).decode("latin-1")
assert "property float nx" in ply and "property float u" in ply, ply[:300]
PY
  if ! grep -q "flat triangles" "$(ls "$tmp"/w3/logs/parallax-cold-*.txt)"; then ok "smooth mesh: full shading records"
  else fail "a smooth mesh was taken as flat"; fi
else fail "scale_series --smooth: exit $?"; tail -5 "$tmp/err3"; fi
if "$src/bench/scale_series.py" --sizes abc --build "$build" --work "$tmp/x" >/dev/null 2>"$tmp/e1"; then
  fail "bad --sizes accepted"; else grep -q "needs numbers" "$tmp/e1" && ok "bad --sizes refused" || fail "message"; fi
if "$src/bench/scale_series.py" --sizes 1 --build "$tmp/nothing" --work "$tmp/y" >/dev/null 2>"$tmp/e2"; then
  fail "missing build accepted"; else grep -q "build first" "$tmp/e2" && ok "missing build refused" || fail "message"; fi
if "$src/bench/scale_series.py" --sizes 1 --repeat 0 --build "$build" --work "$tmp/z" >/dev/null 2>"$tmp/e3"; then
  fail "--repeat 0 accepted"; else grep -q "must be positive" "$tmp/e3" && ok "--repeat 0 refused" || fail "message"; fi
finish scale_series_smoke
