#!/usr/bin/env bash
# bench/direct_light_bench.sh at a tiny size (rooms, 32x18, 3 frames, an 8-spp reference): the
# table and CSV have a row per mode the build accepts with finite errors and times, its relMSE and
# PSNR are what `parallax compare` says for the same images (an independent implementation), a
# rerun reuses the cached reference, and bad input is refused with exit 2.
# Usage: direct_light_bench_smoke.sh SOURCE_DIR BUILD_DIR
set -u
# src, build, tmp, ok, fail, finish
source "$(dirname "$0")/support/script_checks.sh"
/usr/bin/python3 -c 'import numpy, OpenImageIO' 2>/dev/null || { echo "python3-numpy / python3-openimageio missing"; exit 77; }

bench=("$src/bench/direct_light_bench.sh" --build "$build" --scenes rooms --width 32 --height 18 --frames 3
       --ref-spp 8 --refs "$tmp/refs")
if "${bench[@]}" --out "$tmp/a" >"$tmp/out" 2>"$tmp/err"; then ok "ran"; else fail "exit $?"; tail -5 "$tmp/err"; fi
grep -q '^| rooms | power |' "$tmp/out" && ok "table row" || fail "no rooms/power row in the table"
/usr/bin/python3 - "$tmp/a" "$build/parallax" <<'PY' && ok "CSV values and parallax compare agree" || fail "CSV / compare"
import csv, glob, math, subprocess, sys
out, parallax = sys.argv[1], sys.argv[2]
rows = list(csv.DictReader(open(f"{out}/results.csv")))
modes = [r["mode"] for r in rows]
assert "power" in modes and all(r["scene"] == "rooms" for r in rows), modes
for r in rows:
    for k, v in r.items():
        if k in ("scene", "mode") or k.startswith("stage_ms:") and v == "":
            continue
        assert math.isfinite(float(v)) and float(v) > 0, (k, v)
    assert float(r["relmse_den_left"]) < float(r["relmse_raw_left"]), r  # the denoiser helps
p = next(r for r in rows if r["mode"] == "power")
assert float(p["eff_den_vs_power"]) == 1.0, p
ref = glob.glob(f"{out}/../refs/rooms/*/reference_left.exr")
assert len(ref) == 1, ref
for kind in ("raw", "denoised"):
    got = subprocess.run([parallax, "compare", f"{out}/cases/rooms/power/{kind}/frame_0002_left.exr", ref[0]],
                         capture_output=True, text=True, check=True).stdout.split()
    values = dict(zip(got[0::2], map(float, got[1::2])))
    short = "raw" if kind == "raw" else "den"
    assert math.isclose(values["rel_mse"], float(p[f"relmse_{short}_left"]), rel_tol=1e-4), (values, p)
    assert abs(values["psnr_db"] - float(p[f"psnr_{short}_left"])) < 2e-3, (values, p)
PY
if "${bench[@]}" --out "$tmp/b" >"$tmp/out2" 2>"$tmp/err2" && grep -q "reference cached" "$tmp/err2"; then
  ok "rerun reuses the reference"
else
  fail "rerun"; tail -5 "$tmp/err2"
fi
for bad in "--modes nonesuch" "--width 0" "--frames 1" "--scenes /nonexistent/s.json" "--bogus 1"; do
  # shellcheck disable=SC2086
  "$src/bench/direct_light_bench.sh" --build "$build" --out "$tmp/c" --refs "$tmp/refs" $bad >/dev/null 2>&1
  rc=$?
  [ $rc -eq 2 ] && ok "refused: $bad" || fail "$bad: exit $rc, expected 2"
done
finish direct_light_bench_smoke
