#!/usr/bin/env bash
# `render` writes the BVH and device layout caches on a thread of its own, beside the first frame
# (host/io/background_writes.h): the process still waits for them, so once it has exited both
# files are there, whole (no temporary left), and the next runs read them back: the same layout
# mapped, the tree read for another layout, every image the same bits as the first run's; an
# interrupt during the start leaves no half-written file.
# Usage: tests/cache_writes.sh PARALLAX_BINARY
set -u
bin="$1"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$(dirname "$bin")/pocl-cache}" PARALLAX_CACHE_DIR="$tmp/cache"
unset PARALLAX_BVH_CACHE
fails=0
ok() { echo "ok   $*"; }
fail() { echo "FAIL $*"; fails=$((fails + 1)); }

# A 120 x 100 grid of quads (24,000 triangles: past the caches' threshold of 20,000) under the sky.
awk 'BEGIN {
  nx = 120; ny = 100
  for (j = 0; j <= ny; j++) for (i = 0; i <= nx; i++)
    printf "v %.4f %.4f %.4f\n", 0.05 * i - 3, 0.2 * sin(0.3 * i + 0.1 * j) - 1, -0.05 * j - 1
  for (j = 0; j < ny; j++) for (i = 0; i < nx; i++) {
    a = j * (nx + 1) + i + 1; b = a + 1; c = a + nx + 1; d = c + 1
    print "f", a, b, c; print "f", b, d, c
  }
}' >"$tmp/grid.obj"
common=(render --scene "$tmp/grid.obj" --sky on --width 48 --height 32 --frames 1 --spp 2 --devices 2 --no-denoise)
runs() { "$bin" "${common[@]}" --out "$tmp/$1" "${@:2}" 2>&1; }

out="$(runs cold)" || { fail "cold render"; echo "$out" | tail -5; }
if grep -q "cache write [0-9]* ms in the background" <<<"$out"; then ok "the start line says the writes ran in the background"
else fail "no background cache write on the start line"; echo "$out" | grep "^start:"; fi
bvh_files=$(find "$tmp/cache" -name 'bvh-*.bin' | wc -l)
layout_files=$(find "$tmp/cache" -name 'device-layout-*.bin' | wc -l)
partials=$(find "$tmp/cache" -name '.*' -type f | wc -l)
if [ "$bvh_files" = 1 ] && [ "$layout_files" = 1 ] && [ "$partials" = 0 ]; then ok "both cache files there after the exit, no temporary"
else fail "cache files after the exit: $bvh_files BVH, $layout_files device layout, $partials temporary"; fi

out="$(runs warm)" || fail "warm render"
if grep -q "its device layout mapped from the cache" <<<"$out"; then ok "the next run maps the layout"; else fail "the layout was not mapped"; fi
out="$(runs binary --bvh-layout binary)" || fail "binary-layout render"
if grep -q "BVH [0-9]* ms (read from the cache)" <<<"$out"; then ok "a run in another layout reads the tree"; else fail "the tree was not read back"; echo "$out" | grep "^start:"; fi
for run in warm binary; do
  for eye in left right; do
    if "$bin" compare --exact "$tmp/$run/frame_0000_$eye.exr" "$tmp/cold/frame_0000_$eye.exr" >/dev/null 2>&1; then
      ok "$run $eye eye: the cold run's image"
    else
      fail "$run $eye eye differs from the cold run's"
    fi
  done
done

# Ctrl-C a second into a run of 400 frames (during its start or its frames): it stops (130) and
# still waits for its cache writes; whatever the folder holds then is whole: no temporary file,
# and a run from it renders the cold run's image.
export PARALLAX_CACHE_DIR="$tmp/cache-int"
"$bin" render --scene "$tmp/grid.obj" --sky on --width 48 --height 32 --frames 400 --spp 2 --devices 2 --no-denoise \
  --out "$tmp/int" >"$tmp/int.log" 2>&1 &
pid=$!
sleep 1
kill -INT "$pid" 2>/dev/null
wait "$pid"
rc=$?
if [ "$rc" = 130 ]; then ok "interrupted run ends (130)"; else fail "interrupted run exit $rc"; tail -3 "$tmp/int.log"; fi
if [ -z "$(find "$tmp/cache-int" -name '.*' -type f 2>/dev/null)" ]; then ok "no temporary file after the interrupt"
else fail "a temporary cache file was left"; fi
runs after-int >/dev/null || fail "run after the interrupt"
for eye in left right; do
  if "$bin" compare --exact "$tmp/after-int/frame_0000_$eye.exr" "$tmp/cold/frame_0000_$eye.exr" >/dev/null 2>&1; then
    ok "after the interrupt, $eye eye: the cold run's image"
  else
    fail "after the interrupt, $eye eye differs"
  fi
done

if [ "$fails" -eq 0 ]; then echo "cache_writes: all passed"; else echo "cache_writes: $fails failed"; fi
[ "$fails" -eq 0 ]
