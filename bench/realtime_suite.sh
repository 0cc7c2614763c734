#!/usr/bin/env bash
# The measurements behind the real-time goal (2 x 1280 x 720, 1 spp, 6 bounces, SVGF, one
# device), in one run, so that a machine lent for a few minutes yields all of them:
#   1. trace.csv         bench_trace: kernel vs Embree, primary and diffuse rays, per BVH layout
#   2. frame*.csv        bench_pipelines: per-stage device medians for proposed (side queue on),
#                        proposed-1q (one queue), proposed-gpass (the G-buffer pass traces every
#                        centre ray again), proposed-general (every kernel feature compiled in,
#                        not only the scene's; its log also lists each kernel's private memory
#                        per work-item for both builds), baseline and mono, with PSNR / relMSE
#                        against a reference at frame 0 and at the last frame
#   3. frame_wide8*.csv  the same with the 8-wide BVH (--bvh-layout wide8; a GPU's default is
#                        binary, so 2 and 3 compare the layouts on whole frames)
#   4. frame_wavefront*.csv  the same with the wavefront path tracer (--path-tracer wavefront),
#                        no reference: its images are the megakernel's to the bit
#   5. render.json, timeline.json
#                        one render: per-stage report and the Chrome trace, whose slices name each
#                        SVGF pass (per-pass times) and show the side queue's overlap
#   6. frame4spp_*.csv   bench_pipelines at 4 spp (hole filling's per-pixel cost at more samples),
#                        with stage 5's samples spread over work-items (auto: on GPUs) and not
#   7. frame_notiles*.csv  step 2's settings with SVGF's a-trous taps read from global memory
#                        (--atrous-tiles off; a GPU's default reads steps 1-4 from local tiles)
# plus devices.txt and each step's log. The whole run keeps within --budget seconds (default 540,
# under a lent machine's 10-minute limit per command): each step may take at most 150 s, and
# never so much that the steps after it would get less than 20 s each (or, with a small budget,
# an equal share). A step that fails or runs
# out of time is noted in summary.txt and the suite goes on.
#
# Usage: bench/realtime_suite.sh [--out DIR] [--run "PREFIX"] [--quick] [--scene S] [--budget S]
#   --run PREFIX  a command that starts a program of the build given its name and arguments, e.g.
#                 --run "bash .gpu/run.sh" for a bundle (default: the programs in build/)
#   --quick       small sizes and few frames, to check the suite itself on a CPU (a minute or two)
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out=realtime-suite
run=""
quick=0
scene=atrium
budget=540
while [ $# -gt 0 ]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --run) run="$2"; shift 2 ;;
    --quick) quick=1; shift ;;
    --scene) scene="$2"; shift 2 ;;
    --budget) budget="$2"; shift 2 ;;
    -h|--help) sed -n '2,/^set -uo pipefail/{/^set/!p}' "$0"; exit 0 ;;
    *) echo "realtime_suite: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
case "$budget" in ''|*[!0-9]*) echo "realtime_suite: --budget must be a number of seconds" >&2; exit 2 ;; esac
if [ $quick = 1 ]; then
  w=96 h=54 frames=4 ref=16 repeats=2 threads=2
else
  w=1280 h=720 frames=50 ref=256 repeats=7 threads=$(nproc)
fi
steps_left=9  # the steps below (frame4spp runs twice)
deadline=$((SECONDS + budget))
mkdir -p "$out" || { echo "realtime_suite: cannot create $out" >&2; exit 1; }
out=$(cd "$out" && pwd)  # absolute: a --run wrapper may start the programs in another directory
summary="$out/summary.txt"
: >"$summary"

# step NAME PROGRAM ARGS...: runs one program of the build under its share of the budget.
step() {
  local name="$1"; shift
  local t0=$SECONDS
  steps_left=$((steps_left - 1))
  local left=$((deadline - SECONDS))
  local seconds=$((left - 20 * steps_left)) share=$((left / (steps_left + 1)))
  [ $seconds -lt $share ] && seconds=$share  # a small budget: an equal share each
  [ $seconds -gt 150 ] && seconds=150
  [ $seconds -lt 5 ] && seconds=5
  if [ $left -lt 5 ]; then
    printf '%-14s %-28s\n' "$name" "SKIPPED (budget spent)" >>"$summary"
    return
  fi
  echo "[realtime_suite] $name ..." >&2
  local prog="$1"; shift
  local cmd
  if [ -n "$run" ]; then read -ra cmd <<<"$run"; cmd+=("$prog"); else cmd=("$root/build/$prog"); fi
  timeout -k 10 "$seconds" "${cmd[@]}" "$@" >"$out/$name.log" 2>&1
  local rc=$?
  local note="ok"
  [ $rc = 124 ] || [ $rc = 137 ] && note="TIMED OUT after ${seconds} s"
  [ $rc != 0 ] && [ "$note" = ok ] && note="FAILED (exit $rc)"
  printf '%-14s %-28s %4d s  %s\n' "$name" "$note" $((SECONDS - t0)) "$(tail -1 "$out/$name.log" | cut -c1-80)" >>"$summary"
}

step devices parallax devices
step trace bench_trace --scene "$scene" --scene cornell --width $w --height $h --repeats $repeats \
  --threads "$threads" --layout wide8 --layout cwbvh --layout binary --csv "$out/trace.csv"
common=(--scene "$scene" --width $w --height $h --spp 1 --frames $frames --warmup 2 --devices 1)
step frame bench_pipelines "${common[@]}" --ref-spp $ref --compare-overlap --compare-gbuffer --compare-kernels \
  --csv "$out/frame.csv" \
  --summary-csv "$out/frame_summary.csv" --frames-csv "$out/frame_frames.csv"
step frame_wide8 bench_pipelines --bvh-layout wide8 "${common[@]}" --ref-spp $ref \
  --csv "$out/frame_wide8.csv" --summary-csv "$out/frame_wide8_summary.csv"
step frame_wavefront bench_pipelines "${common[@]}" --ref-spp 0 --path-tracer wavefront \
  --csv "$out/frame_wavefront.csv" --summary-csv "$out/frame_wavefront_summary.csv"
step render parallax render --scene "$scene" --width $w --height $h --spp 1 --frames 20 --devices 1 \
  --out "$out/render" --overwrite --no-exr --report "$out/render.json" --timeline "$out/timeline.json"
for spread in auto off; do
  step frame4spp_$spread bench_pipelines --scene "$scene" --width $w --height $h --spp 4 \
    --frames $((frames / 2 + 1)) --warmup 1 --devices 1 --ref-spp 0 --hole-spread $spread \
    --csv "$out/frame4spp_$spread.csv" --summary-csv "$out/frame4spp_${spread}_summary.csv"
done
step frame_notiles bench_pipelines "${common[@]}" --ref-spp 0 --atrous-tiles off \
  --csv "$out/frame_notiles.csv" --summary-csv "$out/frame_notiles_summary.csv"
rm -rf "$out/render"
cat "$summary"
