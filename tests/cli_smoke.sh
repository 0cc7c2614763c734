#!/usr/bin/env bash
# Behaviour of the command line as a user meets it: help, exit codes, clear errors, outputs.
# Usage: cli_smoke.sh PATH/TO/parallax SOURCE_DIR
set -u
bin="$1"
src="$2"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
passes=0

check() {  # check NAME EXPECTED_RC PATTERN -- command...
  local name="$1" want_rc="$2" pattern="$3"
  shift 4
  local out rc
  out="$("$@" 2>&1)"
  rc=$?
  if [ "$rc" -ne "$want_rc" ] && { [ "$want_rc" -ne 1 ] || [ "$rc" -eq 0 ]; }; then
    echo "FAIL $name: exit $rc, expected $want_rc"; echo "$out" | tail -5; fails=$((fails + 1)); return
  fi
  if [ -n "$pattern" ] && ! grep -qiE "$pattern" <<<"$out"; then
    echo "FAIL $name: output lacks /$pattern/"; echo "$out" | tail -5; fails=$((fails + 1)); return
  fi
  echo "ok   $name"; passes=$((passes + 1))
}

check "help" 0 "devices|preview" -- "$bin" --help
check "no subcommand is an error" 1 "subcommand" -- "$bin"
check "devices lists a platform" 0 "platform 0" -- "$bin" devices --devices 2
check "unknown scene is a clear error" 1 "unknown scene|not found|no such" -- "$bin" preview --scene no-such-scene --out "$tmp/a"
check "bad width is refused" 1 "width" -- "$bin" preview --width 0 --out "$tmp/b"
check "missing OBJ file names the file" 1 "missing\.obj" -- "$bin" preview --scene "$tmp/missing.obj" --out "$tmp/c"
check "preview writes both eyes" 0 "stereo.png" -- "$bin" preview --scene cornell --width 64 --height 48 --devices 2 --out "$tmp/p"
for f in left.exr right.exr left.png right.png stereo.png; do
  if [ -s "$tmp/p/$f" ]; then passes=$((passes + 1)); echo "ok   wrote $f"; else fails=$((fails + 1)); echo "FAIL $f not written"; fi
done
check "non-empty output dir is refused" 1 "not empty|overwrite" -- "$bin" preview --scene cornell --width 32 --height 16 --out "$tmp/p"
check "--overwrite allows it" 0 "stereo.png" -- "$bin" preview --scene cornell --width 32 --height 16 --out "$tmp/p" --overwrite
check "scene json from scenes/" 0 "stereo.png" -- "$bin" preview --scene "$src/scenes/cornell-glossy.json" --width 32 --height 16 --out "$tmp/j"

check "render --explain prints the workload table" 0 "\(0\.250, 0\.000\)" -- "$bin" render --explain --devices 4 --height 720
check "unknown pipeline is refused" 1 "pipeline" -- "$bin" render --pipeline nope --out "$tmp/x"
for p in proposed baseline mono; do
  check "render --pipeline $p" 0 "wrote 2 frame" -- "$bin" render --scene cornell --pipeline "$p" --width 32 --height 18 \
    --frames 2 --devices 2 --out "$tmp/r_$p" --report "$tmp/r_$p.json"
  if grep -q '"schema": "parallax-render-report/1"' "$tmp/r_$p.json" && grep -q '"device_ms"' "$tmp/r_$p.json"; then
    passes=$((passes + 1)); echo "ok   report for $p"
  else
    fails=$((fails + 1)); echo "FAIL report for $p lacks schema or device times"
  fi
done
check "denoised render with independent seams" 0 "wrote 2 frame" -- "$bin" render --scene cornell --width 32 --height 18 \
  --frames 2 --devices 2 --seams independent --svgf-iterations 2 --out "$tmp/dn"
check "timeline is written" 0 "timeline written" -- "$bin" render --scene cornell --width 32 --height 18 --devices 2 \
  --no-denoise --out "$tmp/tl" --timeline "$tmp/tl.json"
if grep -q '"traceEvents"' "$tmp/tl.json" && grep -q '"path trace left"' "$tmp/tl.json"; then
  passes=$((passes + 1)); echo "ok   timeline has path-tracing slices"
else
  fails=$((fails + 1)); echo "FAIL timeline lacks traceEvents or stage slices"
fi
check "bad seam mode is refused" 1 "seams" -- "$bin" render --seams wobbly --out "$tmp/y"
check "explain shows the denoise stage" 0 "denoise" -- "$bin" render --explain --devices 2 --height 100
check "compare gives PSNR" 0 "psnr_db" -- "$bin" compare "$tmp/r_proposed/frame_0000_left.exr" "$tmp/r_mono/frame_0000_left.exr"
check "reference shows progress" 0 "reference_" -- "$bin" reference --scene cornell --width 16 --height 9 --spp 8 --pass-spp 4 --out "$tmp/ref"

echo "$passes passed, $fails failed"
[ "$fails" -eq 0 ]
