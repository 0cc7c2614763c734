#!/usr/bin/env bash
# scripts/evaluate as CI runs it: tiny (--quick), then checks that every CSV, plot and the
# summary exist, are non-empty and that the summary carries its tables; and that bad input is
# refused with a clear message and a non-zero exit.
# Usage: evaluate_smoke.sh SOURCE_DIR BUILD_DIR
set -u
src="$1"
build="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
ok() { echo "ok   $*"; }
fail() { echo "FAIL $*"; fails=$((fails + 1)); }

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

echo "evaluate_smoke: $fails failure(s)"
[ "$fails" -eq 0 ]
