#!/usr/bin/env bash
# `mpirun -np R parallax render` gives the same EXR pixels as one process with one device:
# strips on R ranks (one device each), halo seams and strip transfers as MPI messages, a
# 3-frame animation with denoising; plus strips that move between ranks (--balance dynamic),
# the baseline pipeline, ReSTIR DI's reservoirs, and a rank that cannot start (its scene file is missing) stopping
# every rank with a message instead of a hang; and an animated glTF posed alike on every rank. Pixels are compared with `parallax compare --exact`
# (every channel of every EXR pixel bit for bit, lights above 1 included).
# Usage: mpi_render.sh PATH/TO/parallax
set -u
bin="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
passes=0
ok() { passes=$((passes + 1)); echo "ok   $1"; }
bad() { fails=$((fails + 1)); echo "FAIL $1"; }
# Root in CI containers; shared-memory transport without cross-memory attach (not permitted in
# most containers).
export OMPI_MCA_btl_vader_single_copy_mechanism=none
mpi=(mpirun --allow-run-as-root --oversubscribe)
common=(render --scene cornell --width 40 --height 29 --frames 3 --spp 1 --bounces 3 --svgf-iterations 3 --overwrite)

same_pixels() {  # same_pixels NAME DIR_A DIR_B
  local f e out
  for f in 0000 0001 0002; do
    for e in left right; do
      out="$("$bin" compare --exact "$2/frame_${f}_$e.exr" "$3/frame_${f}_$e.exr" 2>&1)"
      if ! grep -qx "identical" <<<"$out"; then
        bad "$1: frame $f $e differs from one process ($(tr '\n' ' ' <<<"$out" | cut -c1-300))"; return
      fi
    done
  done
  ok "$1: every EXR pixel equals one process with one device"
}

"$bin" "${common[@]}" --devices 1 --out "$tmp/one" >/dev/null 2>&1 || { echo "FAIL the one-process render"; exit 1; }
"$bin" "${common[@]}" --devices 1 --pipeline baseline --out "$tmp/one_baseline" >/dev/null 2>&1 ||
  { echo "FAIL the one-process baseline render"; exit 1; }

for np in 2 3; do
  if timeout 300 "${mpi[@]}" -np "$np" "$bin" "${common[@]}" --devices 1 --out "$tmp/np$np" --report "$tmp/np$np.json" \
    >"$tmp/np$np.log" 2>&1; then
    if grep -q "\[mpi\] $np ranks" "$tmp/np$np.log"; then ok "mpirun -np $np renders on $np ranks"
    else bad "mpirun -np $np: no '[mpi] $np ranks' line (built without MPI?)"; tail -5 "$tmp/np$np.log"; fi
    same_pixels "mpirun -np $np" "$tmp/one" "$tmp/np$np"
    if grep -q '"bytes_sent":\[\[0,' "$tmp/np$np.json" && grep -q '"ranks": '"$np" "$tmp/np$np.json"; then
      ok "np $np report has per-link MPI bytes"; else bad "np $np report lacks mpi bytes / ranks"; fi
  else
    bad "mpirun -np $np failed"; tail -20 "$tmp/np$np.log"
  fi
done

# Strips moving between ranks every frame: history and last G-buffer travel as MPI messages.
if timeout 300 "${mpi[@]}" -np 3 "$bin" "${common[@]}" --devices 1 --balance dynamic --balance-step 3 \
  --out "$tmp/dyn" >"$tmp/dyn.log" 2>&1; then
  same_pixels "mpirun -np 3 --balance dynamic" "$tmp/one" "$tmp/dyn"
else bad "mpirun -np 3 --balance dynamic failed"; tail -20 "$tmp/dyn.log"; fi

# ReSTIR DI: the spatial neighbours' reservoirs cross rank borders through the halo rows, and last
# frame's reservoirs would travel with strips that move (--balance dynamic; whether they move in three
# frames depends on the measured times), as SVGF's history does.
"$bin" "${common[@]}" --devices 1 --direct-light restir --out "$tmp/one_restir" >/dev/null 2>&1 ||
  bad "the one-process ReSTIR render failed"
if timeout 300 "${mpi[@]}" -np 3 "$bin" "${common[@]}" --devices 1 --direct-light restir --balance dynamic --balance-step 3 \
  --out "$tmp/restir" >"$tmp/restir.log" 2>&1; then
  same_pixels "mpirun -np 3 --direct-light restir --balance dynamic" "$tmp/one_restir" "$tmp/restir"
else bad "mpirun -np 3 --direct-light restir failed"; tail -20 "$tmp/restir.log"; fi

# Two devices on each of two ranks (4 devices), baseline pipeline (strips travel to the owner).
if timeout 300 "${mpi[@]}" -np 2 "$bin" "${common[@]}" --devices 2 --pipeline baseline --out "$tmp/base" \
  >"$tmp/base.log" 2>&1; then
  same_pixels "mpirun -np 2 --devices 2 --pipeline baseline" "$tmp/one_baseline" "$tmp/base"
else bad "mpirun -np 2 --devices 2 baseline failed"; tail -20 "$tmp/base.log"; fi

# --no-exr: finished strips travel as RGBA8 alone; the PNGs equal one process's byte for byte.
if timeout 300 "${mpi[@]}" -np 2 "$bin" "${common[@]}" --devices 1 --no-exr --out "$tmp/png" >"$tmp/png.log" 2>&1; then
  same=1
  for f in 0000 0001 0002; do for e in left right; do
    cmp -s "$tmp/one/frame_${f}_$e.png" "$tmp/png/frame_${f}_$e.png" || same=0
  done; done
  if [ "$same" -eq 1 ] && ! ls "$tmp/png" | grep -q '\.exr$'; then ok "mpirun -np 2 --no-exr: PNGs equal one process, no EXR"
  else bad "mpirun -np 2 --no-exr: PNGs differ or EXRs written"; fi
else bad "mpirun -np 2 --no-exr failed"; tail -20 "$tmp/png.log"; fi

# Only rank 0 writes: no other rank touched the output folder (nothing but frame files there).
if [ "$(ls "$tmp/np2" | grep -cv '^frame_')" -eq 0 ]; then ok "only frame files in the output"; else bad "stray files in output"; fi

# A rank whose scene file is missing (as on a node without the file): every rank stops, with
# the failing rank named, and no hang.
mkdir -p "$tmp/rank0" "$tmp/rank1"
cp "$(dirname "$0")/../scenes/cornell.json" "$tmp/rank0/s.json" 2>/dev/null || echo '{"builtin": "cornell"}' >"$tmp/rank0/s.json"
timeout 120 "${mpi[@]}" -np 2 bash -c "cd $tmp/rank\$OMPI_COMM_WORLD_RANK && exec '$bin' render --scene s.json --width 16 \
  --height 9 --frames 1 --out $tmp/fail_out" >"$tmp/fail.log" 2>&1
rc=$?
if [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && grep -q "rank 1:" "$tmp/fail.log" && grep -qi "could not start" "$tmp/fail.log"; then
  ok "a rank that cannot start stops every rank (exit $rc) and is named"
else bad "failing rank: exit $rc (124 = hang)"; tail -8 "$tmp/fail.log"; fi

# An animated glTF (a cube sliding and turning): every rank poses the same triangles at frame
# f's time f / fps, so two ranks give one process's pixels.
if python3 "$(dirname "$0")/support/write_animated_gltf.py" "$tmp/slide.gltf"; then
  anim=(render --scene "$tmp/slide.gltf" --width 40 --height 29 --frames 3 --fps 8 --spp 1 --bounces 3 --svgf-iterations 3
        --overwrite)
  "$bin" "${anim[@]}" --devices 1 --out "$tmp/anim_one" >/dev/null 2>&1 || bad "the one-process animated render failed"
  if timeout 300 "${mpi[@]}" -np 2 "$bin" "${anim[@]}" --devices 1 --out "$tmp/anim_np2" >"$tmp/anim.log" 2>&1; then
    same_pixels "mpirun -np 2, animated glTF" "$tmp/anim_one" "$tmp/anim_np2"
    if "$bin" compare --exact "$tmp/anim_one/frame_0000_left.exr" "$tmp/anim_one/frame_0002_left.exr" >/dev/null 2>&1; then
      bad "the animated cube did not move between frames 0 and 2"
    else ok "the animated cube moves between frames"; fi
  else bad "mpirun -np 2 animated render failed"; tail -20 "$tmp/anim.log"; fi
else bad "could not write the animated glTF"; fi

# Instances (a static file whose cube mesh 13 nodes draw): two ranks give one process's pixels.
if python3 "$(dirname "$0")/support/write_animated_gltf.py" "$tmp/ring.gltf" --still --copies 12; then
  inst=(render --scene "$tmp/ring.gltf" --width 40 --height 29 --frames 3 --spp 1 --bounces 3 --svgf-iterations 3
        --overwrite)
  "$bin" "${inst[@]}" --devices 1 --out "$tmp/inst_one" >/dev/null 2>&1 || bad "the one-process instanced render failed"
  if timeout 300 "${mpi[@]}" -np 2 "$bin" "${inst[@]}" --devices 1 --out "$tmp/inst_np2" >"$tmp/inst.log" 2>&1; then
    same_pixels "mpirun -np 2, instances" "$tmp/inst_one" "$tmp/inst_np2"
  else bad "mpirun -np 2 instanced render failed"; tail -20 "$tmp/inst.log"; fi
else bad "could not write the instanced glTF"; fi

timeout 120 "${mpi[@]}" -np 2 "$bin" preview --scene cornell --out "$tmp/pv" >"$tmp/pv.log" 2>&1
rc=$?
if [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && grep -q "only .render" "$tmp/pv.log"; then ok "preview under mpirun is refused clearly"
else bad "preview under mpirun: exit $rc"; tail -5 "$tmp/pv.log"; fi

echo "mpi_render: $passes passed, $fails failed"
[ "$fails" -eq 0 ]
