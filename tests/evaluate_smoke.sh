#!/usr/bin/env bash
# scripts/evaluate as CI runs it: tiny (--quick), then checks that every CSV, plot and the
# summary exist, are non-empty and that the summary carries its tables; and that bad input is
# refused with a clear message and a non-zero exit.
# Usage: evaluate_smoke.sh SOURCE_DIR BUILD_DIR
set -u
# src, build, tmp, ok, fail, finish
source "$(dirname "$0")/support/script_checks.sh"

refused() {  # refused NAME PATTERN -- args...: non-zero exit and a message matching PATTERN
  local name="$1" pattern="$2"
  shift 3
  local out
  if out="$("$src/scripts/evaluate" --build "$build" "$@" 2>&1)"; then fail "$name: exit 0"; return; fi
  if grep -qiE "$pattern" <<<"$out"; then ok "$name"; else fail "$name: output lacks /$pattern/"; echo "$out" | tail -3; fi
}

if "$src/scripts/evaluate" --help | grep -q -- "--quick"; then ok "--help lists the flags"; else fail "--help"; fi
refused "unknown flag" "unknown option" -- --frobnicate
refused "zero width" "width.*positive" -- --width 0 --out "$tmp/w"
refused "missing value" "needs a value" -- --out
refused "bad build dir" "build first" -- --build "$tmp/nothing" --out "$tmp/b"

out="$tmp/eval"
if "$src/scripts/evaluate" --quick --build "$build" --out "$out"; then ok "evaluate --quick ran"; else fail "evaluate --quick exit $?"; fi
for f in pipelines_stages.csv pipelines_makespan.csv pipelines_frames.csv seams.csv seams_frames.csv speed_error.csv \
         table1_stage_times.png table2_makespan.png fig5_seam_psnr.png seam_images.png speed_vs_error.png \
         fig4_control_loop.png control_report.json summary.md; do
  if [ -s "$out/$f" ]; then ok "wrote $f"; else fail "$f missing or empty"; fi
done
for f in "$out"/*.csv; do  # a header and at least one row
  if [ "$(wc -l <"$f")" -ge 2 ]; then ok "$(basename "$f") has rows"; else fail "$(basename "$f") has no rows"; fi
done
for heading in "## Machine" "## Beside the paper" "## Table 1" "## Table 2" "## Table 3" "## Speed vs error" "## Fig. 4: the control loop" \
               "FLIP" "CAMBI"; do
  if grep -qF "$heading" "$out/summary.md"; then ok "summary has '$heading'"; else fail "summary lacks '$heading'"; fi
done
if grep -qE '^\| cornell \| proposed \|' "$out/summary.md" && grep -qE '^\| cornell \| halo \|' "$out/summary.md"; then
  ok "summary tables have rows"
else
  fail "summary tables lack cornell rows"
fi
refused "non-empty --out refused" "not empty" -- --quick --out "$out"

# The values, not only the files: every scene / pipeline / mode / spp row present once, the
# numbers finite and in range, the flags of --quick echoed, totals recomputed from the per-frame
# CSV, the control window recomputed from Table 2 as scripts/evaluate derives it, and the CSV's
# "identical" (inf dB) against `parallax compare` on the images bench_seams wrote.
cat >"$tmp/values.py" <<'EOF'
import csv, json, math, statistics, sys

out, quick_scenes = sys.argv[1], sys.argv[2].split(",")
width, height, devices, frames, warmup, seam_frames, ref_spp, spp_levels = 32, 18, 2, 2, 1, 2, 16, [1, 2]
fails = 0

def check(ok, what):
    global fails
    print(("ok   " if ok else "FAIL ") + what)
    fails += not ok

def rows(name):
    with open(f"{out}/{name}") as f:
        return list(csv.DictReader(f))

def num(v):
    return float(v)  # "inf" and "nan" parse too: the checks below decide what is allowed

def finite(v, lo=-math.inf, hi=math.inf):
    x = num(v)
    return math.isfinite(x) and lo <= x <= hi

def close(a, b, rel=2e-5):  # the benches write 6 significant digits
    return abs(a - b) <= rel * max(abs(a), abs(b))

pipelines = ["proposed", "baseline", "mono"]
# Tables 1-2.
makespan = rows("pipelines_makespan.csv")
framerows = rows("pipelines_frames.csv")
stages = rows("pipelines_stages.csv")
for s in quick_scenes:
    for p in pipelines:
        mine = [r for r in makespan if r["scene"] == s and r["pipeline"] == p]
        check(len(mine) == 1, f"pipelines_makespan.csv: one row for {s} / {p} (found {len(mine)})")
        if len(mine) != 1: continue
        r = mine[0]
        check((int(r["devices"]), int(r["width"]), int(r["height"]), int(r["frames"]), int(r["ref_spp"])) ==
              (devices, width, height, frames, ref_spp), f"{s} / {p}: devices, size, frames and ref_spp as --quick sets them")
        walls = [num(f["wall_ms"]) for f in framerows if f["scene"] == s and f["pipeline"] == p]
        check(sorted(int(f["frame"]) for f in framerows if f["scene"] == s and f["pipeline"] == p) ==
              list(range(warmup, warmup + frames)), f"{s} / {p}: pipelines_frames.csv holds the timed frames {warmup}..{warmup + frames - 1}")
        check(all(math.isfinite(w) and w > 0 for w in walls), f"{s} / {p}: frame times finite and > 0")
        if len(walls) == frames:
            check(close(num(r["makespan_ms"]), sum(walls)), f"{s} / {p}: makespan_ms {r['makespan_ms']} = sum of the frames {sum(walls):.6g}")
            check(close(num(r["median_frame_ms"]), statistics.median(walls)), f"{s} / {p}: median_frame_ms = median of the frames")
            check(close(num(r["hz"]), 1000.0 * frames / sum(walls), 5e-5), f"{s} / {p}: hz {r['hz']} = 1000 x frames / makespan")
        share = num(r["reprojected"])
        check(0.0 < share < 1.0 if p != "mono" else share == 0.0,
              f"{s} / {p}: reprojected share {share} " + ("in (0, 1)" if p != "mono" else "0 (mono traces both eyes)"))
        for c in ("right_psnr_db", "last_right_psnr_db"):
            check(finite(r[c], 5.0, 80.0), f"{s} / {p}: {c} {r[c]} finite, 5..80 dB (1 spp against a 16 spp reference)")
        for c in ("right_rel_mse", "last_right_rel_mse"):
            check(finite(r[c], 0.0, 10.0), f"{s} / {p}: {c} {r[c]} finite, >= 0")
        mine = [x for x in stages if x["scene"] == s and x["pipeline"] == p]
        owners = {x["device"] for x in mine if x["owner"] == "1"}
        check(mine and len(owners) == 1 and all(0 <= int(x["device"]) < devices and finite(x["median_device_ms"], 0.0)
                                                 for x in mine),
              f"{s} / {p}: stage rows name devices < {devices}, one owner, finite times >= 0")
names = {}
for x in stages: names.setdefault(x["stage"], set()).add(x["stage_name"])
check(all(len(v) == 1 for v in names.values()), "pipelines_stages.csv: one name per stage number")

# Table 3 / Fig. 5: 1 device, then the three seam modes on `devices` devices, a row per device.
seams = rows("seams.csv")
per_frame = rows("seams_frames.csv")
modes = {"1 device": 1, "independent": devices, "bilateral": devices, "halo": devices}
for s in quick_scenes:
    mine = [r for r in seams if r["scene"] == s]
    check(sorted((r["mode"], int(r["device"])) for r in mine) ==
          sorted((m, d) for m, n in modes.items() for d in range(n)), f"seams.csv: {s} has a row per mode and device")
    check(len({r["reference_cambi"] for r in mine}) == 1 and all(int(r["ref_spp"]) == ref_spp for r in mine),
          f"seams.csv: {s}: one reference CAMBI, ref_spp {ref_spp}")
    for r in mine:
        what = f"seams.csv: {s} / {r['mode']} device {r['device']}"
        check(int(r["devices"]) == modes[r["mode"]], f"{what}: devices {r['devices']}")
        check(all(finite(r[c], 0.0) for c in ("denoise_ms", "transfer_ms")), f"{what}: times finite, >= 0")
        check(finite(r["psnr_db"], 5.0, 80.0) and finite(r["seam_band_psnr_db"], 5.0, 80.0) and finite(r["rel_mse"], 0.0, 10.0),
              f"{what}: PSNR {r['psnr_db']}, band PSNR {r['seam_band_psnr_db']} dB, relMSE {r['rel_mse']} in range")
        # CAMBI scores are at most 1 (host/image/cambi.h).
        check(finite(r["cambi"], 0.0, 1.0) and finite(r["reference_cambi"], 0.0, 1.0), f"{what}: CAMBI in [0, 1]")
        # The 1-device image against itself is identical; halo rows claim N devices = 1 device.
        vs = num(r["band_psnr_vs_single_db"])
        if r["mode"] in ("1 device", "halo"):
            check(vs == math.inf, f"{what}: band PSNR against 1 device is inf (identical), got {vs}")
        else:
            check(math.isfinite(vs) and vs > 10.0, f"{what}: band PSNR against 1 device finite, got {vs}")
    one = next((r for r in mine if r["mode"] == "1 device"), None)
    for r in mine:
        if one and r["mode"] == "halo":
            check(all(r[c] == one[c] for c in ("psnr_db", "rel_mse", "seam_band_psnr_db", "cambi")),
                  f"seams.csv: {s}: halo's errors equal the 1-device ones")
    for m in modes:
        got = [r for r in per_frame if r["scene"] == s and r["mode"] == m]
        check(sorted(int(r["frame"]) for r in got) == list(range(1, seam_frames)),
              f"seams_frames.csv: {s} / {m} has frames 1..{seam_frames - 1}")
        last = [r for r in got if int(r["frame"]) == seam_frames - 1]
        row = next((r for r in mine if r["mode"] == m), None)
        if last and row:
            check(all(last[0][c] == row[c] for c in ("psnr_db", "rel_mse", "seam_band_psnr_db", "cambi")),
                  f"seams_frames.csv: {s} / {m}: the last frame's errors are seams.csv's")

# Speed vs error: a row per scene and spp level.
speed = rows("speed_error.csv")
for s in quick_scenes:
    got = sorted(int(r["spp"]) for r in speed if r["scene"] == s)
    check(got == spp_levels, f"speed_error.csv: {s} has spp {spp_levels} (found {got})")
for r in speed:
    check(finite(r["wall_ms"], 0.0) and num(r["wall_ms"]) > 0 and finite(r["device_ms"], 0.0) and
          finite(r["rel_mse"], 0.0, 10.0) and finite(r["psnr_db"], 5.0, 80.0),
          f"speed_error.csv: {r['scene']} spp {r['spp']}: times > 0, relMSE and PSNR finite and in range")

# Fig. 4: the window scripts/evaluate derives from the first scene's proposed median frame time
# ([2m + 1, 3.5m + 2], rounded), the run's report with every frame.
machine = dict(line.split("=", 1) for line in open(f"{out}/machine.txt").read().splitlines() if "=" in line)
m = next((num(r["median_frame_ms"]) for r in makespan if r["scene"] == quick_scenes[0] and r["pipeline"] == "proposed"), None)
if m is not None:
    window = "%.0f:%.0f" % (2 * m + 1, 3.5 * m + 2)
    check(machine.get("target_ms") == window, f"machine.txt target_ms {machine.get('target_ms')} = {window} from Table 2")
rep = json.load(open(f"{out}/control_report.json"))
n = int(machine.get("control_frames", "0"))
check((rep["frames_requested"], rep["frames_done"], len(rep["frames"])) == (n, n, n) and rep["target_ms"] == machine.get("target_ms"),
      f"control_report.json: {n} frames done under target_ms {rep['target_ms']}")
walls = [f["wall_ms"] for f in rep["frames"]]
check(n > 1 and close(rep["makespan_ms"], sum(walls), 1e-9) and
      close(rep["hz"], 1000.0 * (n - 1) / (sum(walls) - walls[0]), 1e-6),
      "control_report.json: makespan and Hz (frames after the first) recomputed from its frames")
sys.exit(1 if fails else 0)
EOF
if /usr/bin/python3 "$tmp/values.py" "$out" cornell; then ok "CSV, report and machine values"; else fail "CSV, report and machine values (above)"; fi
# "inf" in the CSV (1 device and halo against the 1-device image) means identical images:
# parallax compare agrees on the PNGs bench_seams wrote; independent seams are not identical.
for m in halo independent; do
  cmp_out="$("$build/parallax" compare "$out/images/0/$m.png" "$out/images/0/single.png" 2>&1)"
  psnr="$(sed -n 's/^psnr_db //p' <<<"$cmp_out")"
  if [ "$m" = halo ]; then want='^inf$'; else want='^[0-9.]+$'; fi
  if grep -qE "$want" <<<"$psnr"; then ok "parallax compare $m.png single.png: $psnr dB"
  else fail "parallax compare $m.png single.png: '$psnr' dB, expected /$want/: $cmp_out"; fi
done

finish evaluate_smoke
