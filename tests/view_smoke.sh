#!/usr/bin/env bash
# The live viewer (parallax view) as a script meets it: under a virtual X server (xvfb-run,
# Mesa's software OpenGL), N frames and a screenshot whose halves are the left and right eye,
# the same images `parallax render` writes for that frame; without a display, a clear error.
# Usage: view_smoke.sh PATH/TO/parallax. Exit 77 (skipped) when xvfb-run is missing.
set -u
bin="$1"
py=/usr/bin/python3  # Debian's, with python3-numpy and python3-openimageio
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fails=0
passes=0
ok() { passes=$((passes + 1)); echo "ok   $1"; }
bad() { fails=$((fails + 1)); echo "FAIL $1"; }

check() {  # check NAME EXPECTED_RC PATTERN -- command...
  local name="$1" want_rc="$2" pattern="$3"
  shift 4
  local out rc
  out="$("$@" 2>&1)"
  rc=$?
  if [ "$rc" -ne "$want_rc" ]; then bad "$name: exit $rc, expected $want_rc"; echo "$out" | tail -8; return; fi
  if [ -n "$pattern" ] && ! grep -qiE "$pattern" <<<"$out"; then
    bad "$name: output lacks /$pattern/"; echo "$out" | tail -8; return
  fi
  ok "$name"
}

check "view --help names its flags" 0 "screenshot .*png" -- "$bin" view --help
check "view without a display is a clear error" 1 "no display.*xvfb" -- \
  env -u DISPLAY -u WAYLAND_DISPLAY "$bin" view --scene cornell --width 16 --height 9 --frames 1
check "view refuses a screenshot that is not PNG" 1 "\.png" -- \
  env -u DISPLAY -u WAYLAND_DISPLAY "$bin" view --frames 1 --screenshot "$tmp/shot.jpg"
check "view refuses a bad control window" 1 "LO:HI" -- "$bin" view --target-ms 20:11
check "view refuses a screenshot in a missing folder" 1 "does not exist" -- \
  env -u DISPLAY -u WAYLAND_DISPLAY "$bin" view --frames 1 --screenshot "$tmp/no/such/shot.png"

if ! command -v xvfb-run >/dev/null 2>&1; then
  echo "skip: xvfb-run is not installed (Debian package xvfb): the windowed checks need it"
  echo "$passes passed, $fails failed"
  [ "$fails" -eq 0 ] && exit 77 || exit 1
fi
# Mesa's software rasteriser whatever GPU the machine has: the same pixels everywhere.
export LIBGL_ALWAYS_SOFTWARE=1
xvfb=(xvfb-run -a -s "-screen 0 640x480x24")

check "view renders 2 frames and saves the window" 0 "wrote .*shot\.png" -- \
  "${xvfb[@]}" "$bin" view --scene cornell --width 96 --height 54 --frames 2 --screenshot "$tmp/shot.png"
check "render of the same frames" 0 "wrote 2 frame" -- \
  "$bin" render --scene cornell --width 96 --height 54 --frames 2 --out "$tmp/r"
check "view with the control loop" 0 "" -- \
  "${xvfb[@]}" "$bin" view --scene cornell --width 32 --height 18 --frames 3 --svgf-iterations 2 --target-ms 1000:2000

# same_as_render NAME SHOT LEFT.png RIGHT.png: the screenshot's halves equal render's PNGs.
same_as_render() {
  if [ -s "$2" ] && [ -s "$3" ]; then
    if "$py" - "$2" "$3" "$4" <<'PY'
import sys
import numpy as np
import OpenImageIO as oiio

def read(path):
    img = oiio.ImageBuf(path)
    if img.has_error:
        sys.exit(f"cannot read {path}: {img.geterror()}")
    return np.asarray(img.get_pixels(oiio.UINT8))[:, :, :3].astype(np.int16)

shot, left, right = (read(p) for p in sys.argv[1:4])
h, w = left.shape[:2]
if shot.shape[:2] != (h, 2 * w):
    sys.exit(f"screenshot is {shot.shape[1]}x{shot.shape[0]}, expected {2 * w}x{h} (both eyes side by side)")
status = 0
for name, half, ref in (("left", shot[:, :w], left), ("right", shot[:, w:], right)):
    if half.std() < 1.0 or half.mean() < 8.0:
        print(f"{name} half is constant or black (mean {half.mean():.1f}, std {half.std():.2f})")
        status = 1
    diff = np.abs(half - ref)
    print(f"{name} half vs render's {name} PNG of that frame: max difference {diff.max()}, mean {diff.mean():.4f}")
    if diff.max() > 1:
        status = 1
sys.exit(status)
PY
    then ok "$1: screenshot halves show an image equal to render's left and right PNGs"
    else bad "$1: screenshot halves differ from render's images (or are empty)"; fi
  else
    bad "$1: screenshot or rendered frame missing"
  fi
}
same_as_render "cornell" "$tmp/shot.png" "$tmp/r/frame_0001_left.png" "$tmp/r/frame_0001_right.png"

# An animated glTF: the viewer's frame f is at f / fps like render's, so its third frame shows
# the cube where render's frame 2 has it.
if python3 "$(dirname "$0")/support/write_animated_gltf.py" "$tmp/slide.gltf"; then
  check "view plays an animated glTF" 0 "wrote .*anim\.png" -- \
    "${xvfb[@]}" "$bin" view --scene "$tmp/slide.gltf" --width 96 --height 54 --frames 3 --fps 8 --screenshot "$tmp/anim.png"
  check "render of the same animated frames" 0 "wrote 3 frame" -- \
    "$bin" render --scene "$tmp/slide.gltf" --width 96 --height 54 --frames 3 --fps 8 --out "$tmp/ra"
  same_as_render "animated glTF, frame 2" "$tmp/anim.png" "$tmp/ra/frame_0002_left.png" "$tmp/ra/frame_0002_right.png"
else bad "could not write the animated glTF"; fi

echo "$passes passed, $fails failed"
[ "$fails" -eq 0 ]
