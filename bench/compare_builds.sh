#!/usr/bin/env bash
# Two builds side by side: the same `parallax render` run by two binaries in alternation (A, B,
# A, B, ...; so that a change in the machine's load falls on both), then per binary the median
# over every frame after each run's first of: the denoiser's device time (stages 6 + 7, the
# slowest device) and the frame's wall time, from `render --report`. For speed work that
# changes the binary itself (a kernel, a pass), where one process cannot hold both versions:
# build the old commit elsewhere (git worktree add ../old <commit> && scripts/build there).
#
# Usage: bench/compare_builds.sh --a OLD/parallax --b NEW/parallax [--runs 3] [-- render flags]
# Default render flags: the real-time point, 1 spp, 6 bounces, 2 devices, 320x180, 16 frames,
# still camera, on cornell and atrium in turn (--scene given after -- replaces both).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
a="" b="" runs=3
usage() { sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --a) a="$2"; shift 2 ;;
    --b) b="$2"; shift 2 ;;
    --runs) runs="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    *) echo "compare_builds: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[ -x "$a" ] && [ -x "$b" ] || { echo "compare_builds: --a and --b must name two parallax binaries" >&2; exit 2; }
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "compare_builds: --runs needs a positive integer" >&2; exit 2; }
extra=("$@")
scenes=(cornell atrium)
for x in "${extra[@]}"; do [ "$x" = "--scene" ] && scenes=("")
done
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$root/build/pocl-cache}"

for scene in "${scenes[@]}"; do
  scene_flag=()
  [ -n "$scene" ] && scene_flag=(--scene "$scene")
  for ((r = 1; r <= runs; ++r)); do
    for side in a b; do
      bin=$([ $side = a ] && echo "$a" || echo "$b")
      "$bin" render "${scene_flag[@]}" --pipeline proposed --spp 1 --bounces 6 --devices 2 --width 320 --height 180 \
        --frames 16 --fps 1000000 --no-exr "${extra[@]}" --out "$tmp/out" --overwrite \
        --report "$tmp/${scene:-scene}_${side}_$r.json" >"$tmp/log" 2>&1 ||
        { echo "compare_builds: $bin failed:" >&2; tail -5 "$tmp/log" >&2; exit 1; }
    done
  done
done

/usr/bin/python3 - "$root/scripts" "$tmp" "$runs" "$a" "$b" "${scenes[@]}" <<'PY'
import json, statistics, sys
sys.path.insert(0, sys.argv[1])
from evaluate_denoiser import frame_times  # the evaluation's reading of a report
tmp, runs, a, b, scenes = sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5], sys.argv[6:]
def medians(scene, side):
    svgf, wall = [], []
    for r in range(1, runs + 1):
        s, w = frame_times(json.load(open(f"{tmp}/{scene or 'scene'}_{side}_{r}.json")))
        svgf += s
        wall += w
    return statistics.median(svgf), statistics.median(wall), len(wall)
print(f"a = {a}\nb = {b}")
print(f"{'scene':10s} {'denoise ms a':>13s} {'b':>8s} {'b/a':>6s} {'frame ms a':>11s} {'b':>8s} {'b/a':>6s}  frames")
for scene in scenes:
    sa, wa, n = medians(scene, "a")
    sb, wb, _ = medians(scene, "b")
    ratio = lambda x, y: f"{y / x:6.2f}" if x > 0 else "   n/a"
    print(f"{scene or '(given)':10s} {sa:13.1f} {sb:8.1f} {ratio(sa, sb)} {wa:11.1f} {wb:8.1f} {ratio(wa, wb)}  {n} each")
PY
