#!/usr/bin/env bash
# bench/compare_builds.sh runs end to end on a tiny frame (the build against itself, one run): its
# trace table and per-stage table come out with a ratio for every row. Nothing is timed here.
# Usage: compare_builds_smoke.sh SOURCE_DIR BUILD_DIR
set -u
out="$("$1/bench/compare_builds.sh" --a "$2" --b "$2" --runs 1 \
  --trace-args "--scene cornell --width 32 --height 18 --repeats 1" -- --scene cornell --width 32 --height 18 --frames 3 2>&1)"
rc=$?
echo "$out" | tail -25
[ "$rc" -eq 0 ] || { echo "FAIL compare_builds.sh exited $rc"; exit 1; }
fails=0
for want in "| cornell | primary |" "| cornell | diffuse-bounce |" "| 2 path trace left |" "| 5 hole filling |" \
            "| hole filling per hole / left per pixel |" "| frame wall ms |"; do
  grep -qF "$want" <<<"$out" || { echo "FAIL no row '$want'"; fails=$((fails + 1)); }
done
if grep -E '^\| (2 path trace left|frame wall ms) ' <<<"$out" | grep -q 'n/a'; then echo "FAIL a ratio is n/a"; fails=$((fails + 1)); fi
[ "$fails" -eq 0 ] && echo "compare_builds_smoke: ok"
[ "$fails" -eq 0 ]
