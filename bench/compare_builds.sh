#!/usr/bin/env bash
# Two builds side by side, for speed work that changes the binary itself (a kernel, a pass), where
# one process cannot hold both versions: build the old commit elsewhere
# (git worktree add ../old <commit> && scripts/build there) and give both builds.
# Everything runs in alternation (A, B, A, B, ...), so that a change in the machine's load falls
# on both, and is reported as medians with their ranges and the ratio b / a:
#   - trace: `bench_trace` (when it sits beside both binaries) on cornell and atrium, primary and
#     diffuse rays: kernel Mrays/s and kernel / Embree, Embree measured in the same run;
#   - stages: `parallax render --report` at the real-time point (1 spp, 6 bounces, 2 devices,
#     320x180, 16 frames, still camera; every frame after each run's first): each stage's device
#     time per pixel it works on (summed over devices; hole filling per hole), hole filling per
#     hole over the left eye's path tracing per pixel, the frame's wall time and the makespan.
# Add the figures to the note of every change that touches a kernel or the frame loop.
#
# Usage: bench/compare_builds.sh --a OLD --b NEW [--runs 3] [--no-trace] [--no-render]
#                                [--trace-args "ARGS"] [-- render flags]
# OLD / NEW: a build folder or its parallax binary. --trace-args replaces bench_trace's defaults
# (--scene cornell --scene atrium --width 640 --height 360 --repeats 5). Render flags after --
# are added to every render (a --scene there replaces cornell and atrium).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
a="" b="" runs=3 do_trace=1 do_render=1
trace_args="--scene cornell --scene atrium --width 640 --height 360 --repeats 5"
usage() { sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --a) a="${2:-}"; shift 2 ;;
    --b) b="${2:-}"; shift 2 ;;
    --runs) runs="${2:-}"; shift 2 ;;
    --no-trace) do_trace=0; shift ;;
    --no-render) do_render=0; shift ;;
    --trace-args) trace_args="${2:-}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    --) shift; break ;;
    *) echo "compare_builds: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
binary() { if [ -d "$1" ]; then echo "$1/parallax"; else echo "$1"; fi; }
a="$(binary "$a")" b="$(binary "$b")"
[ -x "$a" ] && [ -x "$b" ] || { echo "compare_builds: --a and --b must name two builds (folders or parallax binaries)" >&2; exit 2; }
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "compare_builds: --runs needs a positive integer" >&2; exit 2; }
extra=("$@")
scenes=(cornell atrium)
for x in "${extra[@]}"; do [ "$x" = "--scene" ] && scenes=(""); done
# The real-time point; a flag given after -- replaces its default.
defaults=()
for pair in "--pipeline proposed" "--spp 1" "--bounces 6" "--devices 2" "--width 320" "--height 180" "--frames 16"; do
  given=0
  for x in "${extra[@]}"; do [ "$x" = "${pair%% *}" ] && given=1; done
  # shellcheck disable=SC2206  # a flag and its value
  [ "$given" = 1 ] || defaults+=($pair)
done
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$root/build/pocl-cache}"
trace_a="$(dirname "$a")/bench_trace" trace_b="$(dirname "$b")/bench_trace"
if [ "$do_trace" = 1 ] && ! { [ -x "$trace_a" ] && [ -x "$trace_b" ]; }; then
  echo "compare_builds: no bench_trace beside both binaries: trace comparison skipped" >&2
  do_trace=0
fi
echo "compare_builds: $runs alternated run(s) per build; load: $(uptime | sed 's/.*load average: //')"

if [ "$do_trace" = 1 ]; then
  for ((r = 1; r <= runs; ++r)); do
    for side in a b; do
      bin=$([ $side = a ] && echo "$trace_a" || echo "$trace_b")
      # shellcheck disable=SC2086  # trace_args: several options
      "$bin" $trace_args --csv "$tmp/trace_${side}_$r.csv" >"$tmp/log" 2>&1 ||
        { echo "compare_builds: $bin failed:" >&2; tail -5 "$tmp/log" >&2; exit 1; }
      echo "  trace $side run $r done"
    done
  done
fi
if [ "$do_render" = 1 ]; then
  for scene in "${scenes[@]}"; do
    scene_flag=()
    [ -n "$scene" ] && scene_flag=(--scene "$scene")
    for ((r = 1; r <= runs; ++r)); do
      for side in a b; do
        bin=$([ $side = a ] && echo "$a" || echo "$b")
        "$bin" render "${scene_flag[@]}" "${defaults[@]}" --fps 1000000 --no-exr "${extra[@]}" --out "$tmp/out" --overwrite \
          --report "$tmp/render_${scene:-scene}_${side}_$r.json" >"$tmp/log" 2>&1 ||
          { echo "compare_builds: $bin failed:" >&2; tail -5 "$tmp/log" >&2; exit 1; }
        echo "  render ${scene:-(given scene)} $side run $r done"
      done
    done
  done
fi
echo "load after: $(uptime | sed 's/.*load average: //')"
/usr/bin/python3 "$root/bench/compare_builds_report.py" "$tmp" "$runs" "$a" "$b" "${scenes[@]}"
