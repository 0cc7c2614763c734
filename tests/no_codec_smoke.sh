#!/usr/bin/env bash
# The build without an image reader (cmake -DPX_OPENIMAGEIO=OFF), as a machine without the
# project's packages builds it (e.g. a GPU machine the project is carried to as a bundle): it
# must compile, render with a report and a timeline, write its frames' EXR and PNG files (its
# own writers need no OpenImageIO), turn a texture into a warning that says why, and refuse
# `compare` saying why. Builds into build-nocodec/ (host code at -O0: only compiling matters).
# Usage: tests/no_codec_smoke.sh [BUILD_DIR]
set -u
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build-nocodec}"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O0" -DPX_OPENIMAGEIO=OFF -DPX_MPI=OFF \
  -DPX_VIEWER=OFF >/dev/null || exit 1
cmake --build "$build" -j "$(nproc 2>/dev/null || echo 2)" --target parallax >/dev/null || { echo "FAIL build"; exit 1; }
bin="$build/parallax"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$build/pocl-cache}" PARALLAX_CACHE_DIR="${PARALLAX_CACHE_DIR:-$build/parallax-cache}"
fails=0
ok() { echo "ok   $*"; }
fail() { echo "FAIL $*"; fails=$((fails + 1)); }

if ldd "$bin" | grep -qi openimageio; then fail "the binary links OpenImageIO"; else ok "no OpenImageIO linked"; fi
out="$("$bin" render --width 32 --height 18 --frames 2 --out "$tmp/r" --report "$tmp/r.json" --timeline "$tmp/t.json" 2>&1)"
rc=$?
if [ $rc -eq 0 ]; then ok "render runs"; else fail "render exit $rc"; echo "$out" | tail -5; fi
if grep -q "wrote 2 frame(s)" <<<"$out"; then ok "summary names the files"; else fail "summary"; fi
if [ -s "$tmp/r.json" ] && [ -s "$tmp/t.json" ]; then ok "report and timeline written"; else fail "report or timeline missing"; fi
# Every frame's files, each starting with its format's signature (their pixels are checked
# against OpenImageIO by test_image_writers in the default build).
magic() { head -c "$2" "$1" | od -An -tx1 | tr -d ' \n'; }
files_ok=1
for f in 0000 0001; do
  for n in left right; do
    [ "$(magic "$tmp/r/frame_${f}_$n.exr" 4)" = 762f3101 ] || files_ok=0
    [ "$(magic "$tmp/r/frame_${f}_$n.png" 8)" = 89504e470d0a1a0a ] || files_ok=0
  done
  [ "$(magic "$tmp/r/frame_${f}_stereo.png" 8)" = 89504e470d0a1a0a ] || files_ok=0
done
if [ $files_ok -eq 1 ]; then ok "EXR and PNG files written"; else fail "image files missing or not EXR / PNG"; ls -la "$tmp/r"; fi
out="$("$bin" compare "$tmp/r/frame_0000_left.exr" "$tmp/r/frame_0001_left.exr" 2>&1)"
rc=$?
if [ $rc -ne 0 ] && grep -q "PX_OPENIMAGEIO=OFF" <<<"$out"; then ok "compare says it reads no images"; else
  fail "compare: exit $rc"; echo "$out" | tail -3; fi

# A textured OBJ: the texture is a warning naming the missing codec, the render goes on.
printf 'newmtl tex\nKd 1 1 1\nmap_Kd albedo.png\n' >"$tmp/m.mtl"
printf 'mtllib m.mtl\nv -1 -1 3\nv 1 -1 3\nv 0 1 3\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl tex\nf 1/1 2/2 3/3\n' >"$tmp/t.obj"
printf '\x89PNG\r\n\x1a\n' >"$tmp/albedo.png"
out="$("$bin" render --scene "$tmp/t.obj" --width 32 --height 18 --out "$tmp/o" 2>&1)"
rc=$?
if [ $rc -eq 0 ] && grep -q "PX_OPENIMAGEIO=OFF" <<<"$out"; then ok "a texture is a warning"; else
  fail "textured OBJ: exit $rc"; echo "$out" | tail -5; fi

echo "no_codec_smoke: $fails failure(s)"
[ $fails -eq 0 ]
