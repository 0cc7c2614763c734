#!/usr/bin/env bash
# More devices than cores: `render --devices N` runs to the end, again and again, with every EXR
# pixel equal to one device. On a 2-core machine N >= 3 are queues on one PoCL device; that is
# where PoCL 3.1's work-group-function cache aborted (pocl_release_dlhandle_cache, exit 134) in
# 32 of 40 such runs before host/cl/pocl_launch_guard.h. Each N in {3, 4, 6, 8} runs RUNS times
# (default 3; PARALLAX_STRESS_RUNS) with static and with dynamic strips, denoised, 3 frames; plus
# N = 2, 5, 7, 12, 16 once, and PoCL's POCL_DEVICES list (3 platform devices), once per balance.
# The first run of a case compares every frame, later runs the last frame (it carries the
# earlier frames' history).
# Usage: many_devices.sh PATH/TO/parallax
set -u
bin="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
runs="${PARALLAX_STRESS_RUNS:-3}"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
passes=0
ok() { passes=$((passes + 1)); echo "ok   $1"; }
bad() { fails=$((fails + 1)); echo "FAIL $1"; }
common=(render --scene atrium --pipeline proposed --width 96 --height 64 --frames 3 --spp 1 --bounces 3 --svgf-iterations 3)

same_pixels() {  # same_pixels NAME DIR FRAMES...
  local name="$1" dir="$2" f e out
  shift 2
  for f in "$@"; do
    for e in left right; do
      out="$("$bin" compare --exact "$dir/frame_${f}_$e.exr" "$tmp/one/frame_${f}_$e.exr" 2>&1)"
      if ! grep -qx "identical" <<<"$out"; then
        bad "$name: frame $f $e differs from one device ($(tr '\n' ' ' <<<"$out" | cut -c1-300))"; return 1
      fi
    done
  done
}

run_case() {  # run_case NAME RUN_INDEX ARGS... (env set by the caller)
  local name="$1" i="$2" rc
  shift 2
  rm -rf "$tmp/n"
  timeout 300 "$bin" "${common[@]}" "$@" --out "$tmp/n" >"$tmp/n.log" 2>&1
  rc=$?
  if [ "$rc" -ne 0 ]; then
    bad "$name, run $i: exit $rc"; grep -E "Assertion|error" "$tmp/n.log" | head -3; return
  fi
  if [ "$i" -eq 1 ]; then same_pixels "$name, run $i" "$tmp/n" 0000 0001 0002 || return
  else same_pixels "$name, run $i" "$tmp/n" 0002 || return; fi
  ok "$name, run $i: exit 0, pixels equal one device"
}

"$bin" "${common[@]}" --devices 1 --out "$tmp/one" >"$tmp/one.log" 2>&1 ||
  { echo "FAIL the one-device render"; tail -5 "$tmp/one.log"; echo "0 passed, 1 failed"; exit 1; }

for n in 3 4 6 8; do
  for balance in static dynamic; do
    for i in $(seq 1 "$runs"); do run_case "--devices $n --balance $balance" "$i" --devices "$n" --balance "$balance"; done
  done
done
for n in 2 5 7 12 16; do run_case "--devices $n" 1 --devices "$n"; done
for balance in static dynamic; do
  POCL_DEVICES="pthread pthread pthread" run_case "POCL_DEVICES x3, --device-mode platform --balance $balance" 1 \
    --devices 3 --device-mode platform --balance "$balance"
done
# Dynamic strips over queues render, say what they do, and still move the boundaries.
dyn=(render --scene atrium --pipeline proposed --width 96 --height 64 --frames 6 --spp 1 --bounces 3 --svgf-iterations 3)
if "$bin" "${dyn[@]}" --devices 4 --balance dynamic --out "$tmp/dyn" >"$tmp/dyn.log" 2>&1; then
  if grep -q "dynamic over 4 queues on one OpenCL device" "$tmp/dyn.log"; then ok "dynamic strips over queues say what they do"
  else bad "no note on dynamic strips over queues"; fi
  first="$(grep -o 'strips [0-9/]* rows' "$tmp/dyn.log" | head -1)"
  last="$(grep -o 'strips [0-9/]* rows' "$tmp/dyn.log" | tail -1)"
  if [ -n "$first" ] && [ "$first" != "$last" ]; then ok "dynamic strips over queues move ($first -> $last)"
  else bad "dynamic strips over queues never moved ($first -> $last)"; fi
else
  bad "--devices 4 --balance dynamic over 6 frames failed"; tail -5 "$tmp/dyn.log"
fi

echo "$passes passed, $fails failed"
[ "$fails" -eq 0 ]
