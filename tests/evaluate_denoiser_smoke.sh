#!/usr/bin/env bash
# scripts/evaluate_denoiser run tiny and offline (48x27, 32-spp references, the Cornell box's still
# camera): the CSV has its columns, a row per eye and finite numbers (FLIP and OIDN finite or
# "n/a": PyPI is never asked); references are cached and reused; bad input (an unknown option, a
# bad case, a reference cache entry missing a file, a non-empty --out) fails with a message and a
# non-zero exit.
# Usage: evaluate_denoiser_smoke.sh SOURCE_DIR BUILD_DIR
set -u
# src, build, tmp, ok, fail, finish
source "$(dirname "$0")/support/script_checks.sh"
script="$src/scripts/evaluate_denoiser"
tiny=(--build "$build" --offline --width 48 --height 27 --ref-spp 32 --scenes cornell --refs "$tmp/refs")

refused() {  # refused NAME PATTERN -- args...: non-zero exit and a message matching PATTERN
  local name="$1" pattern="$2"
  shift 3
  local out
  if out="$("$script" "$@" 2>&1)"; then fail "$name: exit 0"; return; fi
  if grep -qiE "$pattern" <<<"$out"; then ok "$name"; else fail "$name: output lacks /$pattern/"; echo "$out" | tail -3; fi
}

if "$script" --help | grep -q -- "--ref-spp"; then ok "--help lists the flags"; else fail "--help"; fi
refused "unknown flag" "unknown option" -- --frobnicate
refused "missing value" "needs a value" -- --out
refused "zero width" "width.*positive" -- --width 0 --out "$tmp/w"
refused "bad camera" "still or moving" -- --build "$build" --scenes cornell:sideways --out "$tmp/c"
refused "missing scene file" "not found" -- --build "$build" --scenes "$tmp/nothing.json" --out "$tmp/c"
refused "bad build dir" "build first" -- --build "$tmp/nothing" --out "$tmp/b"

out="$tmp/eval"
if log="$("$script" "${tiny[@]}" --out "$out" 2>&1)"; then ok "evaluate_denoiser ran"; else fail "evaluate_denoiser exit $?"; echo "$log" | tail -20; fi
for f in results.csv summary.md machine.txt cases/cornell-still/report.json; do
  if [ -s "$out/$f" ]; then ok "wrote $f"; else fail "$f missing or empty"; fi
done
for heading in "## Against the reference" "## Flicker and time" "## Definitions" "| cornell-still | left |"; do
  if grep -qF "$heading" "$out/summary.md" 2>/dev/null; then ok "summary has '$heading'"; else fail "summary lacks '$heading'"; fi
done

cat >"$tmp/values.py" <<'EOF'
import csv, math, sys

path, expect_na = sys.argv[1], sys.argv[2] == "na"
want = ["case", "scene", "camera", "fps", "eye", "width", "height", "frame", "psnr_peak"]
methods = ["svgf", "raw", "oidn_color", "oidn_aux"]
want += [f"{m}_{k}" for m in methods for k in ("lum_bias_pct", "psnr_db", "flip")]
want += ["flicker_svgf_flip", "flicker_raw_flip", "flicker_oidn_aux_flip", "flicker_reference_flip", "svgf_ms",
         "frame_ms", "oidn_aux_ms"]
fails = 0

def check(cond, what):
    global fails
    print(("ok   " if cond else "FAIL ") + what)
    fails += not cond

with open(path) as f:
    reader = csv.DictReader(f)
    check(reader.fieldnames == want, f"the {len(want)} columns in order (got {reader.fieldnames})")
    rows = list(reader)
check(sorted(r["eye"] for r in rows) == ["left", "right"], "a row per eye")
pypi = [c for c in want if "flip" in c or "oidn" in c]  # flip-evaluator or pyoidn
for r in rows:
    check((r["case"], r["camera"], r["fps"], r["width"], r["height"], r["frame"]) ==
          ("cornell-still", "still", "1000000", "48", "27", "15"), f"{r['eye']}: case, camera, fps, size and frame")
    for c in want[9:]:
        v = r[c]
        if c in pypi and v == "n/a":
            continue
        if expect_na and c in pypi:
            check(False, f"{r['eye']}: {c} is n/a without the PyPI packages (got {v})")
            continue
        try:
            x = float(v)
        except ValueError:
            check(False, f"{r['eye']}: {c} = {v!r} is a number")
            continue
        check(math.isfinite(x), f"{r['eye']}: {c} = {v} is finite")
        if c.endswith("psnr_db"):
            check(5.0 < x < 80.0, f"{r['eye']}: {c} = {v} within 5..80 dB")
        if c.endswith("flip"):
            check(0.0 <= x <= 1.0, f"{r['eye']}: {c} = {v} within [0, 1]")
        if c in ("svgf_ms", "frame_ms", "psnr_peak"):
            check(x > 0.0, f"{r['eye']}: {c} = {v} > 0")
sys.exit(1 if fails else 0)
EOF
if /usr/bin/python3 "$tmp/values.py" "$out/results.csv" any; then ok "results.csv columns and values"; else fail "results.csv (above)"; fi

# Without the packages (a --venv that does not exist, --offline): said once, and n/a in their columns.
if log="$("$script" "${tiny[@]}" --venv "$tmp/no-venv" --out "$tmp/eval_na" 2>&1)"; then ok "ran without the PyPI packages"
else fail "without the PyPI packages: exit $?"; echo "$log" | tail -5; fi
if [ "$(grep -c 'columns are n/a' <<<"$log")" -eq 1 ]; then ok "says once that FLIP and OIDN are n/a"
else fail "the n/a notice is not said exactly once"; fi
if grep -q "reference of frame 15 cached" <<<"$log"; then ok "the second run reuses the cached references"
else fail "the second run did not reuse the cached references"; fi
if /usr/bin/python3 "$tmp/values.py" "$tmp/eval_na/results.csv" na; then ok "n/a in the FLIP and OIDN columns"; else fail "n/a columns (above)"; fi

refused "non-empty --out refused" "not empty" -- "${tiny[@]}" --out "$out"
# A cache entry that lost a file is an error naming it, not silently used or rendered again.
entry="$(dirname "$(find "$tmp/refs" -name key.txt -path '*frame15*' | head -1)")"
rm -f "$entry/reference_right.exr"
refused "a reference cache entry missing a file" "incomplete \(no reference_right\.exr\)" -- "${tiny[@]}" --out "$tmp/eval_bad"
if [ ! -e "$tmp/eval_bad" ]; then ok "the refused run wrote no --out"; else fail "the refused run created $tmp/eval_bad"; fi

finish evaluate_denoiser_smoke
