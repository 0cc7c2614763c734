#!/usr/bin/env bash
# Behaviour of the command line as a user meets it: help, exit codes, clear errors, outputs.
# Usage: cli_smoke.sh PATH/TO/parallax SOURCE_DIR [PART: 1 or 2, default both]
set -u
bin="$1"
src="$2"
part="${3:-}"
tmp="$(mktemp -d)"
trap 'mountpoint -q "$tmp/tiny" 2>/dev/null && umount "$tmp/tiny"; rm -rf "$tmp"' EXIT
fails=0
passes=0
# Checks that need what this machine lacks (matplotlib, mount rights, ffmpeg) are skipped one by
# one, each said on a SKIP line and again in the last lines; the rest still run, and the test
# passes on them (CTest has no "partly skipped": exit 77 would hide the checks that ran).
skipped=()
skip() { skipped+=("$1"); echo "SKIP $1"; }

# A signalled run's exit status, with the tracer crash check() describes read as the status the
# run set itself (that crash turns 130 or 143 into 1 after the program has finished; the checks
# after each call still read what the run wrote). Usage: rc=$(signal_rc RC EXPECTED STDERR_FILE)
signal_rc() {
  if [ "$1" -eq 1 ] && grep -q "LeakSanitizer has encountered a fatal error" "$3" &&
     ! grep -qE "detected memory leaks|ERROR: AddressSanitizer|runtime error:" "$3"; then
    echo "note: LeakSanitizer's tracer crashed at exit of a signalled run (no finding); its exit status read as $2" >&2
    echo "$2"
  else
    echo "$1"
  fi
}

check() {  # check NAME EXPECTED_RC PATTERN -- command...
  local name="$1" want_rc="$2" pattern="$3"
  shift 4
  local out rc
  out="$("$@" 2>&1)"
  rc=$?
  # Under the sanitizer build, LeakSanitizer's own tracer now and then crashes at process exit
  # while it stops PoCL's worker threads ("Tracer caught signal 11 ... LeakSanitizer has
  # encountered a fatal error"): the tool failed, it found nothing, and it turned the exit status
  # into 1 after the program had finished. A leak or an ASan/UBSan finding reads differently and
  # still fails. For such a run only the leak check is inconclusive: judge it by its output.
  if [ "$rc" -ne 0 ] && [ "$want_rc" -eq 0 ] && grep -q "LeakSanitizer has encountered a fatal error" <<<"$out" &&
     ! grep -qE "detected memory leaks|ERROR: AddressSanitizer|runtime error:" <<<"$out"; then
    echo "note $name: LeakSanitizer's tracer crashed at exit (no finding); leak check inconclusive for this run"
    rc=0
  fi
  if [ "$rc" -ne "$want_rc" ] && { [ "$want_rc" -ne 1 ] || [ "$rc" -eq 0 ]; }; then
    echo "FAIL $name: exit $rc, expected $want_rc"; echo "$out" | tail -5; fails=$((fails + 1)); return
  fi
  if [ -n "$pattern" ] && ! grep -qiE "$pattern" <<<"$out"; then
    echo "FAIL $name: output lacks /$pattern/"; echo "$out" | tail -5; fails=$((fails + 1)); return
  fi
  echo "ok   $name"; passes=$((passes + 1))
}

ok() { passes=$((passes + 1)); echo "ok   $1"; }
bad() { fails=$((fails + 1)); echo "FAIL $1"; }

# Two halves, so that CTest runs them side by side (cli_smoke_part1, cli_smoke_part2): each is
# self-contained (its own files under $tmp), and no argument runs both, as before.
part_one() {
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
check "render --explain lists the operations with their lanes and waits" 0 "transfer +left +device 1 -> 0 +side +rows \[20, 40\) finished image +after" -- "$bin" render --explain --devices 2 --height 40
check "render --explain --no-overlap puts everything on the main queue" 0 "transfer +left +device 1 -> 0 +main +rows \[20, 40\)" -- "$bin" render --explain --devices 2 --height 40 --no-overlap
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
# The report's BVH block: cornell's 32 triangles all in leaves (no spatial split pays there), a
# SAH cost of at least the root's visit, no trial below its size.
if /usr/bin/python3 -c 'import json, sys; b = json.load(open(sys.argv[1]))["bvh"]; sys.exit(not (b["nodes"] >= 1 and b["leaf_triangles"] >= 32 and b["sah_cost"] >= 1.0 and b["depth"] >= 2 and b["spatial_splits"] in ("yes", "none taken or off") and b["split_trial_gain"] is None))' "$tmp/r_proposed.json"; then
  passes=$((passes + 1)); echo "ok   report gives the BVH's size, SAH cost and splits"
else
  fails=$((fails + 1)); echo "FAIL report's bvh block: $(/usr/bin/python3 -c 'import json, sys; print(json.load(open(sys.argv[1])).get("bvh"))' "$tmp/r_proposed.json" 2>&1)"
fi
check "denoised render with independent seams" 0 "wrote 2 frame" -- "$bin" render --scene cornell --width 32 --height 18 \
  --frames 2 --devices 2 --seams independent --svgf-iterations 2 --out "$tmp/dn"
check "timeline is written" 0 "timeline written" -- "$bin" render --scene cornell --width 32 --height 18 --devices 2 \
  --no-denoise --out "$tmp/tl" --timeline "$tmp/tl.json"
if grep -q '"traceEvents"' "$tmp/tl.json" && grep -q '"path trace left"' "$tmp/tl.json"; then
  passes=$((passes + 1)); echo "ok   timeline has path-tracing slices"
else
  fails=$((fails + 1)); echo "FAIL timeline lacks traceEvents or stage slices"
fi
check "control loop: a bad window is refused" 1 "LO:HI" -- "$bin" render --scene cornell --target-ms 20:11 --out "$tmp/ctl_bad"
# A window of 1-2 microseconds, which no frame on any machine reaches: the loop must have lowered
# every parameter to its minimum by the last frame (one per frame from frame 1 on: iterations,
# bounces, spp). Holding a reachable window is tested in test_control_end_to_end.
check "control loop runs and reports its choices" 0 "spp, .* bounces, .* iterations" -- "$bin" render --scene cornell \
  --width 32 --height 18 --frames 5 --devices 2 --svgf-iterations 2 --target-ms 0.001:0.002 --out "$tmp/ctl" \
  --report "$tmp/ctl.json"
if grep -q '"predicted_ms"' "$tmp/ctl.json" && grep -q '"svgf_iterations"' "$tmp/ctl.json" && grep -q '"target_ms": "0.001:0.002"' "$tmp/ctl.json"; then
  passes=$((passes + 1)); echo "ok   control-loop report fields"
else fails=$((fails + 1)); echo "FAIL report lacks predicted_ms / svgf_iterations / target_ms"; fi
last_ctl="$(grep '"frame":4,' "$tmp/ctl.json")"
if grep -q '"spp":1,' <<<"$last_ctl" && grep -q '"bounces":1,' <<<"$last_ctl" && grep -q '"svgf_iterations":1,' <<<"$last_ctl"; then
  passes=$((passes + 1)); echo "ok   control loop lowers quality to its minimum under an unreachable window"
else fails=$((fails + 1)); echo "FAIL control loop: last frame not at 1 spp, 1 bounce, 1 iteration: $last_ctl"; fi
check "dynamic balance refuses the baseline pipeline" 1 "balance dynamic needs" -- "$bin" render --pipeline baseline \
  --balance dynamic --out "$tmp/bal_bad"
check "explain names the dynamic balance" 0 "balance: dynamic" -- "$bin" render --explain --devices 3 --height 90 \
  --balance dynamic
check "dynamic balance renders and shows the strips" 0 "strips [0-9]+/[0-9]+ rows" -- "$bin" render --scene cornell \
  --width 32 --height 30 --frames 4 --devices 2 --svgf-iterations 2 --balance dynamic --balance-step 2 \
  --out "$tmp/bal" --report "$tmp/bal.json"
if grep -q '"strips":\[\[0,' "$tmp/bal.json" && grep -q '"balance": "dynamic"' "$tmp/bal.json"; then
  passes=$((passes + 1)); echo "ok   report has per-frame strips"
else fails=$((fails + 1)); echo "FAIL report lacks strips / balance"; fi
# The report plots (Debian's python3-matplotlib); skipped where it is not installed.
if /usr/bin/python3 -c "import matplotlib, numpy" 2>/dev/null; then
  check "plot_report draws a report" 0 "strips.png" -- "$src/scripts/plot_report" "$tmp/bal.json" "$tmp/ctl.json" \
    --out "$tmp/plots"
  for f in frame_times.png stages.png strips.png; do
    if [ -s "$tmp/plots/$f" ]; then passes=$((passes + 1)); echo "ok   plot $f"; else fails=$((fails + 1)); echo "FAIL plot $f missing"; fi
  done
  check "plot_report refuses a non-report" 1 "not a parallax render report" -- "$src/scripts/plot_report" \
    "$tmp/tl.json" --out "$tmp/plots2"
else skip "plot_report draws a report (no python3-matplotlib)"; fi
check "bad seam mode is refused" 1 "seams" -- "$bin" render --seams wobbly --out "$tmp/y"
check "--instancing takes on or off only" 1 "instancing: maybe not in \{on,off\}" -- "$bin" render --instancing maybe \
  --out "$tmp/y"
check "explain shows the denoise stage" 0 "denoise" -- "$bin" render --explain --devices 2 --height 100
check "compare gives PSNR" 0 "psnr_db" -- "$bin" compare "$tmp/r_proposed/frame_0000_left.exr" "$tmp/r_mono/frame_0000_left.exr"
check "render --path-tracer wavefront" 0 "wrote 2 frame" -- "$bin" render --scene cornell --pipeline proposed \
  --width 32 --height 18 --frames 2 --devices 2 --path-tracer wavefront --out "$tmp/r_wave" --report "$tmp/r_wave.json"
if grep -q '"path_tracer": "wavefront"' "$tmp/r_wave.json" && grep -q '"bvh_layout": "' "$tmp/r_wave.json"; then
  passes=$((passes + 1)); echo "ok   report names the path tracer and the BVH layout"
else fails=$((fails + 1)); echo "FAIL report lacks path_tracer / bvh_layout"; fi
check "the wavefront tracer gives the megakernel's image" 0 "^identical$" -- "$bin" compare --exact \
  "$tmp/r_wave/frame_0001_right.exr" "$tmp/r_proposed/frame_0001_right.exr"
check "compare --exact reports a difference" 1 "^first difference: x [0-9]+ y [0-9]+ channel [rgb]: " -- "$bin" compare \
  --exact "$tmp/r_proposed/frame_0000_right.exr" "$tmp/r_mono/frame_0000_right.exr"
check "compare --exact refuses images of different sizes" 1 "image is 32x18, reference is 32x16" -- "$bin" compare \
  --exact "$tmp/r_proposed/frame_0000_left.exr" "$tmp/p/left.exr"
check "unknown path tracer is refused" 1 "path-tracer" -- "$bin" render --path-tracer gpu --out "$tmp/x"
check "reference shows progress" 0 "reference_" -- "$bin" reference --scene cornell --width 16 --height 9 --spp 8 --pass-spp 4 --out "$tmp/ref"

# --- nothing lost, nothing mixed ---
# wait_for FILE PID: until FILE exists or PID has exited (no time limit is asserted; ctest's
# timeout bounds a hang).
wait_for() { while [ ! -e "$1" ] && kill -0 "$2" 2>/dev/null; do sleep 0.1; done; [ -e "$1" ]; }
# Every image under DIR is complete and no temporary or lock file is left: each EXR reads back
# (through `parallax compare` against itself), each PNG ends with its IEND chunk (cheaper than a
# process per file; a truncated PNG lacks it).
all_readable() {
  local dir="$1" f n=0
  for f in "$dir"/*.exr; do
    [ -e "$f" ] || continue
    "$bin" compare "$f" "$f" >/dev/null 2>&1 || { echo "  unreadable: $f"; return 1; }
    n=$((n + 1))
  done
  for f in "$dir"/*.png; do
    [ -e "$f" ] || continue
    tail -c 12 "$f" | grep -q IEND || { echo "  truncated: $f"; return 1; }
    n=$((n + 1))
  done
  if ls -A "$dir" | grep -qE '\.partial$|^\.parallax\.lock$'; then echo "  left behind: $(ls -A "$dir" | grep -E 'partial|lock')"; return 1; fi
  [ "$n" -gt 0 ]
}

check "render over 4 frames" 0 "wrote 4 frame" -- "$bin" render --scene cornell --width 16 --height 9 --frames 4 \
  --no-denoise --out "$tmp/stale"
check "--overwrite says it removes the earlier run's frames" 0 "removed 20 file" -- "$bin" render --scene cornell \
  --width 16 --height 9 --frames 2 --no-denoise --out "$tmp/stale" --overwrite
if [ -e "$tmp/stale/frame_0001_stereo.png" ] && ! ls "$tmp/stale" | grep -q 'frame_000[23]'; then
  ok "no stale frames after --overwrite"; else bad "stale frames of the longer run remain"; fi
check "a failed run says why" 1 "unknown scene" -- "$bin" render --scene no-such-scene --out "$tmp/fresh/sub"
if [ ! -e "$tmp/fresh" ]; then ok "a failed run removes the --out folders it created"; else bad "empty $tmp/fresh left"; fi
check "an unwritable report fails before rendering" 1 "cannot write .*nowhere/r\.json" -- "$bin" render --scene cornell \
  --width 16 --height 9 --out "$tmp/norep" --report "$tmp/nowhere/r.json"
printf 'pid 2147483646\n' >"$tmp/lockdead.lock"; mkdir -p "$tmp/lockdead"; cp "$tmp/lockdead.lock" "$tmp/lockdead/.parallax.lock"
check "a lock left by a dead run is explained" 1 "no longer running" -- "$bin" preview --scene cornell --width 8 \
  --height 8 --out "$tmp/lockdead"

# One long render holds its --out: a second run on it is refused; Ctrl-C then stops the first
# after the frame in flight with every file complete and a report for the frames done.
"$bin" render --scene cornell --width 64 --height 36 --spp 16 --frames 100000 --devices 2 --out "$tmp/sig" \
  --report "$tmp/sig.json" >"$tmp/sig.out" 2>"$tmp/sig.err" &
pid=$!
if wait_for "$tmp/sig/frame_0001_stereo.png" "$pid"; then
  check "a second run on a claimed --out is refused" 1 "in use by another parallax run \(pid $pid\)" -- \
    "$bin" preview --scene cornell-glossy --width 8 --height 8 --out "$tmp/sig" --overwrite
  kill -INT "$pid"
  wait "$pid"; rc=$?
  rc=$(signal_rc "$rc" 130 "$tmp/sig.err")
  if [ "$rc" -eq 130 ]; then ok "SIGINT exits 130"; else bad "SIGINT exit $rc, expected 130"; tail -3 "$tmp/sig.err"; fi
  grep -q "interrupted by SIGINT after" "$tmp/sig.out" && ok "says what was written" || bad "no interruption summary"
  if all_readable "$tmp/sig"; then ok "every file of the interrupted render reads back"; else bad "interrupted render left a bad file"; fi
  frames=$(ls "$tmp/sig" | grep -c '_stereo\.png$')
  if grep -q '"frames_done": '"$frames"',' "$tmp/sig.json" && grep -q '"interrupted": true' "$tmp/sig.json"; then
    ok "report covers the $frames frames written"; else bad "report missing or wrong for $frames frames"; fi
else
  bad "long render did not start"; kill "$pid" 2>/dev/null; wait "$pid"
fi

# A second signal stops at once (here during a long frame, 320x180 at 64 spp: at smaller sizes
# the work in flight could finish before the second signal came; docs/measurements.md, signal
# frame size), and still leaves no partial file and no lock. The second signal is sent
# only once the first has been seen, so that the two are not merged into one pending signal.
"$bin" render --scene cornell --width 320 --height 180 --spp 64 --frames 100000 --devices 2 --out "$tmp/sig2" \
  >/dev/null 2>"$tmp/sig2.err" &
pid=$!
if wait_for "$tmp/sig2/frame_0000_stereo.png" "$pid"; then
  kill -TERM "$pid"
  while ! grep -q "finishing the work in flight" "$tmp/sig2.err" && kill -0 "$pid" 2>/dev/null; do sleep 0.01; done
  kill -TERM "$pid" 2>/dev/null
  wait "$pid"; rc=$?
  rc=$(signal_rc "$rc" 143 "$tmp/sig2.err")
  if [ "$rc" -eq 143 ]; then ok "SIGTERM exits 143"; else bad "SIGTERM: exit $rc, expected 143"; fi
  grep -q "stopped at once" "$tmp/sig2.err" && ok "a second signal stops at once" || bad "second signal did not stop at once"
  if all_readable "$tmp/sig2"; then ok "every file after a hard stop reads back"; else bad "hard stop left a bad file"; fi
else
  bad "second long render did not start"; kill "$pid" 2>/dev/null; wait "$pid"
fi

# An interrupted reference writes the average of the passes done.
"$bin" reference --scene cornell --width 16 --height 9 --spp 16777216 --pass-spp 4 --out "$tmp/refint" \
  >"$tmp/refint.out" 2>"$tmp/refint.err" &
pid=$!
while ! grep -q "spp," "$tmp/refint.err" 2>/dev/null && kill -0 "$pid" 2>/dev/null; do sleep 0.1; done
kill -INT "$pid"; wait "$pid"; rc=$?
rc=$(signal_rc "$rc" 130 "$tmp/refint.err")
if [ "$rc" -eq 130 ] && grep -q "interrupted by SIGINT after" "$tmp/refint.out" && all_readable "$tmp/refint" &&
   [ -e "$tmp/refint/reference_left.exr" ]; then
  ok "interrupted reference writes what is done"; else bad "interrupted reference: exit $rc"; cat "$tmp/refint.out"; fi

# A full disk is an error naming the file, never exit 0 with empty files. Needs a small tmpfs
# (root and permission to mount); skipped where that is not possible.
if [ "$(id -u)" -eq 0 ] && mkdir -p "$tmp/tiny" && mount -t tmpfs -o size=40k tmpfs "$tmp/tiny" 2>/dev/null; then
  check "a full disk is an error naming the file" 1 "cannot write $tmp/tiny/full/frame_[0-9]+_[a-z]+\.(exr|png).*No space" -- \
    "$bin" render --scene cornell --width 16 --height 8 --frames 5 --devices 2 --out "$tmp/tiny/full"
  if all_readable "$tmp/tiny/full"; then ok "files written before the disk filled read back"; else bad "full disk left a bad file"; fi
  umount "$tmp/tiny"
else
  skip "a full disk is an error naming the file (needs root and permission to mount a tmpfs)"
fi

printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 1 4 5\n' >"$tmp/degen.obj"
n=$("$bin" preview --scene "$tmp/degen.obj" --width 8 --height 8 --out "$tmp/degen" 2>&1 | grep -c "degenerate")
if [ "$n" -eq 1 ]; then ok "dropped degenerate triangles are reported once"; else bad "degenerate message printed $n times"; fi
cat >"$tmp/cross.json" <<'EOF'
{"generator": "cornell", "camera_path": [
  {"time": 0, "position": [278, 273, -800], "target": [278, 273, 0]},
  {"time": 1, "position": [278, 273, 0], "target": [278, 273, -800]}]}
EOF
check "a camera path whose position meets its target fails before rendering" 1 "frame 15 .*no view direction" -- \
  "$bin" render --scene "$tmp/cross.json" --width 16 --height 9 --frames 20 --fps 30 --no-denoise --out "$tmp/cross"
if [ ! -e "$tmp/cross" ]; then ok "nothing written for a bad camera path"; else bad "frames written before a bad camera"; fi
check "coordinates beyond float range are refused" 1 "1e\+19 units" -- "$bin" preview \
  --scene "$(printf 'v -1e19 0 0\nv 1e19 0 0\nv 0 1e19 0\nf 1 2 3\n' >"$tmp/huge.obj"; echo "$tmp/huge.obj")" --out "$tmp/huge"
yes '{"a":' | head -n 70000 | tr -d '\n' >"$tmp/deep.body"
{ printf '{"generator": "cornell", "generator_params": '; cat "$tmp/deep.body"; printf '1'; yes '}' | head -n 70000 | tr -d '\n'; printf '}'; } >"$tmp/deep.json"
check "deeply nested scene file is a clear error" 1 "nested deeper" -- "$bin" preview --scene "$tmp/deep.json" --out "$tmp/deep"

# --- the end-of-run summary and --video ---
check "render ends with a per-stage summary" 0 "path trace left +[0-9.]+ ms +[0-9.]+ ms" -- "$bin" render --scene cornell \
  --width 16 --height 9 --frames 2 --out "$tmp/sum"
check "render --video refuses an unknown container" 1 "\.mp4, \.mkv or \.mov" -- "$bin" render --scene cornell \
  --width 16 --height 9 --out "$tmp/v_bad" --video "$tmp/v.avi"
check "render --video without ffmpeg names the package" 1 "package ffmpeg" -- env PATH=/nonexistent "$bin" render \
  --scene cornell --width 16 --height 9 --out "$tmp/v_none" --video "$tmp/v_none.mp4"
# scripts/install-deps installs ffmpeg (CI runs it first); elsewhere the encoding is skipped.
if command -v ffmpeg >/dev/null && command -v ffprobe >/dev/null; then
  check "render --video encodes the frames" 0 "video: .*v\.mp4" -- "$bin" render --scene cornell --width 17 --height 9 \
    --frames 3 --fps 24 --out "$tmp/v" --video "$tmp/v.mp4"
  # One H.264 stream, 2 x 17 = 34 wide and 9 rows padded to 10 (yuv420p wants even sizes), at
  # --fps, with 3 frames in the header and 3 that actually decode.
  probe="$(ffprobe -v error -count_frames -show_entries stream=codec_type,codec_name,width,height,r_frame_rate,nb_frames,nb_read_frames \
    -of compact=nokey=0 "$tmp/v.mp4" 2>&1)"
  want="stream|codec_name=h264|codec_type=video|width=34|height=10|r_frame_rate=24/1|nb_frames=3|nb_read_frames=3"
  if [ "$probe" = "$want" ]; then ok "video is one 34x10 H.264 stream of 3 frames at 24 fps"
  else bad "video stream: $probe, expected $want"; fi
  # Its pictures are the frames written: each decoded frame against frame_NNNN_stereo.png
  # (left | right, padded as the encoder pads), in luma PSNR. The 30 dB floor sits between crf
  # 18's frames and swapped, mirrored or black ones (docs/measurements.md, video PSNR).
  psnr="$(ffmpeg -nostats -i "$tmp/v.mp4" -framerate 24 -i "$tmp/v/frame_%04d_stereo.png" \
    -lavfi "[1:v]pad=34:10,format=yuv420p[b];[0:v][b]psnr" -f null - 2>&1 | sed -n 's/.*PSNR y:\([0-9.inf]*\) .*/\1/p')"
  if awk -v p="$psnr" 'BEGIN { exit !(p == "inf" || p + 0 >= 30) }' && [ -n "$psnr" ]; then
    ok "video frames match the stereo PNGs (luma PSNR $psnr dB)"
  else bad "video frames differ from the stereo PNGs: luma PSNR '$psnr' dB (< 30)"; fi
else
  skip "render --video encodes the frames (ffmpeg not installed: scripts/install-deps installs it)"
fi
# glTF: a one-triangle file without any light renders, lit by the default sky (said once);
# --sky off says it stays black; a bad file names itself and exits 1; --sky checks its value.
# The buffer: the float positions (0 0 0) (1 0 0) (0 1 0), base64.
cat >"$tmp/tri.gltf" <<'EOF'
{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
 "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
 "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
 "bufferViews": [{"buffer": 0, "byteLength": 36}],
 "buffers": [{"byteLength": 36, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}]}
EOF
check "a lightless glTF is lit by the default sky" 0 "lit by a default sky" -- "$bin" preview --scene "$tmp/tri.gltf" \
  --width 16 --height 8 --out "$tmp/gltf"
check "--sky off leaves it unlit, and says so" 0 "will be black" -- "$bin" preview --scene "$tmp/tri.gltf" --sky off \
  --width 16 --height 8 --out "$tmp/gltf_off"
sed 's/"count": 3/"count": 30/' "$tmp/tri.gltf" >"$tmp/bad.gltf"
check "a glTF accessor past its buffer is a clear error" 1 "bad\.gltf.*accessor 0" -- "$bin" preview --scene "$tmp/bad.gltf" \
  --out "$tmp/gltf_bad"
check "an unknown --sky value is refused" 1 "sky" -- "$bin" preview --scene "$tmp/tri.gltf" --sky bright --out "$tmp/gltf_sky"
}

part_two() {
# Kernels built for the scene's features: the Cornell box needs only emissive triangles, says so
# on the console and in the report, and gives the general kernels' pixels.
check "render says which features its kernels carry" 0 "compiled for the scene's features: emissive \(" -- "$bin" \
  render --scene cornell --width 24 --height 16 --frames 2 --out "$tmp/k_scene" --report "$tmp/k_scene.json"
if /usr/bin/python3 -c 'import json, sys; r = json.load(open(sys.argv[1])); sys.exit(not (r["kernel_features"] == ["emissive"] and r["kernels"] == "scene"))' "$tmp/k_scene.json"; then
  passes=$((passes + 1)); echo "ok   the report lists the Cornell box's kernel features: emissive only"
else fails=$((fails + 1)); echo "FAIL report kernel_features: $(grep -o '"kernel[^]]*' "$tmp/k_scene.json" | tr '\n' ' ')"; fi
check "--kernels general renders" 0 "general: every feature compiled in" -- "$bin" render --scene cornell --width 24 \
  --height 16 --frames 2 --kernels general --out "$tmp/k_general"
for f in frame_0001_left frame_0001_right; do
  check "--kernels scene and general give identical pixels ($f)" 0 "^identical$" -- "$bin" compare --exact \
    "$tmp/k_scene/$f.exr" "$tmp/k_general/$f.exr"
done
check "an unknown --kernels value is refused" 1 "kernels" -- "$bin" render --kernels fastest --out "$tmp/k_bad"
# --kernel-build: the short runs above built their kernels quickly (auto); optimised kernels
# render the same pixels, and a run that measures speed gets them whatever its length.
check "a short run builds its kernels quickly" 0 "quick build, the compiler's optimisation off.*--kernel-build auto" \
  -- "$bin" render --scene cornell --width 24 --height 16 --frames 2 --out "$tmp/k_auto"
check "--kernel-build optimized renders" 0 "wrote 2 frame" -- "$bin" render --scene cornell --width 24 --height 16 \
  --frames 2 --kernel-build optimized --out "$tmp/k_optimized"
for f in frame_0001_left frame_0001_right; do
  check "quick and optimised kernels give identical pixels ($f)" 0 "^identical$" -- "$bin" compare --exact \
    "$tmp/k_auto/$f.exr" "$tmp/k_optimized/$f.exr"
done
if grep -q "quick build" <<<"$("$bin" render --scene cornell --width 24 --height 16 --frames 2 --kernel-build optimized \
  --overwrite --out "$tmp/k_optimized" 2>&1)"; then bad "--kernel-build optimized built quickly"; else ok "--kernel-build optimized builds optimised"; fi
if /usr/bin/python3 -c 'import json, sys; sys.exit(json.load(open(sys.argv[1]))["kernel_build"] != "optimized")' "$tmp/k_scene.json"; then
  ok "a run with --report builds optimised kernels, and the report says so"
else bad "the --report run's kernel_build: $(grep -o '"kernel_build[^,]*' "$tmp/k_scene.json")"; fi
check "--kernel-build quick says it was asked" 0 "as --kernel-build quick asks" -- "$bin" preview --scene cornell \
  --width 24 --height 16 --kernel-build quick --out "$tmp/k_preview"
check "an unknown --kernel-build value is refused" 1 "kernel-build" -- "$bin" render --kernel-build fast --out "$tmp/k_bad"

# A scene buffer larger than one allocation may hold is refused naming it (the device's limit
# lowered with PARALLAX_MAX_ALLOC_BYTES), and leaves no --out folder behind.
check "a scene over the allocation limit is refused, naming the buffer" 1 "BVH node buffer needs .* bytes.*CL_DEVICE_MAX_MEM_ALLOC_SIZE" -- \
  env PARALLAX_MAX_ALLOC_BYTES=1000 "$bin" render --scene cornell --width 16 --height 8 --out "$tmp/too_big"
if [ ! -e "$tmp/too_big" ]; then passes=$((passes + 1)); echo "ok   the refused render left no --out folder"
else fails=$((fails + 1)); echo "FAIL the refused render left $tmp/too_big"; fi

# Settings that switch SVGF's history off: --alpha-moments 1 would return the noisy image from the
# 4th frame on (variance 0), so it is refused, in render and in view (before any window);
# --alpha 1 is a choice, with a warning naming the flag.
check "--alpha-moments 1 is refused, naming the flag" 1 "alpha-moments 1 keeps no moment history" -- "$bin" render \
  --scene cornell --width 16 --height 8 --frames 4 --alpha 1 --alpha-moments 1 --out "$tmp/alpha_m"
check "view refuses --alpha-moments 1 before opening a window" 1 "alpha-moments 1 keeps no moment history" -- \
  env -u DISPLAY "$bin" view --scene cornell --alpha-moments 1
check "--alpha-moments 1 without denoising is no error" 0 "wrote|frame" -- "$bin" render --scene cornell --width 16 \
  --height 8 --frames 1 --alpha-moments 1 --no-denoise --out "$tmp/alpha_m_raw"
check "--alpha 1 warns that SVGF's colour history is off" 0 "alpha 1 switches SVGF's colour history off" -- "$bin" \
  render --scene cornell --width 16 --height 8 --frames 1 --alpha 1 --out "$tmp/alpha_1"

# --aov: auxiliary EXRs per frame and eye. On the Cornell box (64x36) the albedo is the wall's
# diffuse colour and the normal the wall's, unit length wherever the ray hit; every pipeline and
# device count gives the same files (each device's rows read from the device that wrote them:
# a row read from the wrong one would hold that device's stale or unwritten texels); --overwrite
# removes them; unknown names are refused.
check "--aov refuses an unknown name" 1 "unknown auxiliary image 'depth'" -- "$bin" render --scene cornell --aov albedo,depth \
  --out "$tmp/aov_bad"
check "--aov refuses an empty entry" 1 "empty name" -- "$bin" render --scene cornell --aov albedo, --out "$tmp/aov_bad"
check "--aov refuses --no-exr" 1 "no-exr" -- "$bin" render --scene cornell --width 16 --height 9 --aov normal --no-exr \
  --out "$tmp/aov_bad"
check "render --help lists --aov" 0 "[-]-aov LIST" -- "$bin" render --help
for run in "proposed 1" "proposed 3" "baseline 3" "mono 3"; do
  set -- $run
  check "render --aov albedo,normal ($1, $2 device(s))" 0 "_\{albedo,normal\}\.exr" -- "$bin" render --scene cornell \
    --pipeline "$1" --width 64 --height 36 --frames 2 --devices "$2" --aov albedo,normal --out "$tmp/aov_$1_$2"
done
check "render --aov normal without denoising (mono schedules its G-buffer)" 0 "_normal\.exr" -- "$bin" render --scene cornell \
  --pipeline mono --width 64 --height 36 --frames 2 --devices 3 --aov normal --no-denoise --out "$tmp/aov_mono_raw"
if [ -e "$tmp/aov_mono_raw/frame_0001_left_normal.exr" ] && [ ! -e "$tmp/aov_mono_raw/frame_0001_left_albedo.exr" ]; then
  ok "--aov normal writes normals only"; else bad "--aov normal: wrong files: $(ls "$tmp/aov_mono_raw" | tr '\n' ' ')"; fi
for f in frame_0000_left_albedo frame_0001_left_albedo frame_0001_right_albedo frame_0000_left_normal frame_0001_left_normal \
         frame_0001_right_normal; do
  for other in proposed_3 baseline_3; do
    check "--aov: $other gives proposed on 1 device's $f" 0 "^identical$" -- "$bin" compare --exact \
      "$tmp/aov_proposed_1/$f.exr" "$tmp/aov_$other/$f.exr"
  done
done
# Normals are the G-buffer's, whatever the pipeline (mono's too, with or without denoising).
for f in frame_0001_left_normal frame_0001_right_normal; do
  for other in mono_3 mono_raw; do
    check "--aov: $other gives proposed's $f" 0 "^identical$" -- "$bin" compare --exact \
      "$tmp/aov_proposed_1/$f.exr" "$tmp/aov_$other/$f.exr"
  done
done
if /usr/bin/python3 - "$tmp/aov_proposed_3" <<'PY'
import sys
import numpy as np
import OpenImageIO as oiio

d = sys.argv[1]
fails = 0

def read(name):
    buf = oiio.ImageBuf(f"{d}/{name}")
    px = buf.get_pixels(oiio.FLOAT)
    if buf.has_error or px is None or px.shape != (36, 64, 3):
        raise SystemExit(f"cannot read {name} as 64x36 RGB: {buf.geterror()}")
    return px

def check(cond, what):
    global fails
    print(("  ok   " if cond else "  FAIL ") + what)
    fails += not cond

# Row 18 of the 64x36 Cornell box, in both eyes: the red wall (x ~ 556, facing -x) at column 19,
# the green wall (x = 0, facing +x) at 46, the back wall (facing -z) at 38; no hit at the sides.
walls = {"red": (19, (0.63, 0.065, 0.05), (-1, 0, 0)), "green": (46, (0.14, 0.45, 0.091), (1, 0, 0)),
         "back": (38, (0.725, 0.71, 0.68), (0, 0, -1))}
for eye in ("left", "right"):
    for f in (0, 1):
        a = read(f"frame_{f:04d}_{eye}_albedo.exr")
        n = read(f"frame_{f:04d}_{eye}_normal.exr")
        for wall, (x, kd, normal) in walls.items():
            check(np.allclose(a[18, x], kd, atol=1e-5), f"frame {f} {eye}: {wall} wall albedo {a[18, x]} = {kd}")
            check(float(np.dot(n[18, x], normal)) > 0.999, f"frame {f} {eye}: {wall} wall normal {n[18, x]} ~ {normal}")
        length = np.linalg.norm(n, axis=2)
        hit = length > 0
        check(0.3 < hit.mean() < 0.9, f"frame {f} {eye}: {hit.mean():.2f} of the pixels hit the box")
        check(np.abs(length[hit] - 1).max() < 1e-4, f"frame {f} {eye}: normals unit length on hits")
        check(not hit[18, 2] and not hit[18, 61], f"frame {f} {eye}: no normal (0, 0, 0) where the ray missed")
        check(np.isfinite(a).all() and a.min() >= 0 and a.max() <= 1, f"frame {f} {eye}: albedo finite, within [0, 1]")
sys.exit(1 if fails else 0)
PY
then ok "--aov values: wall albedo and normals, unit length on hits, zero on misses"
else bad "--aov values (above)"; fi
check "--overwrite removes the auxiliary images too" 0 "removed 18 file" -- "$bin" render --scene cornell --width 64 \
  --height 36 --frames 1 --devices 3 --out "$tmp/aov_proposed_3" --overwrite
if ! ls "$tmp/aov_proposed_3" | grep -q '_albedo\|_normal'; then ok "no stale auxiliary images"
else bad "stale auxiliary images after --overwrite"; fi

# Animation (glTF clips): --animation picks clips by name or index, refuses one the file lacks
# (naming those it has) and any on a static scene; the summary says what played and what each
# frame's update cost, the report has it per frame.
if python3 "$src/tests/support/write_animated_gltf.py" "$tmp/slide.gltf"; then
  check "--animation with a clip the file lacks" 1 "its clips: 0 'slide'" -- "$bin" render --scene "$tmp/slide.gltf" \
    --animation jump --width 16 --height 9 --out "$tmp/anim_bad"
  check "--animation on a static scene" 1 "has no animations" -- "$bin" render --scene cornell --animation slide \
    --width 16 --height 9 --out "$tmp/anim_static"
  check "--fps 0 is refused" 105 "fps" -- "$bin" render --scene cornell --fps 0 --width 16 --height 9 --out "$tmp/fps0"
  check "an animated glTF renders its clip" 0 "animation: 'slide' \\(1\\.00 s\\), looping; per frame" -- "$bin" render \
    --scene "$tmp/slide.gltf" --animation 0 --frames 2 --fps 8 --width 32 --height 18 --out "$tmp/anim" \
    --report "$tmp/anim.json"
  if /usr/bin/python3 -c 'import json, sys; r = json.load(open(sys.argv[1])); u = [f["scene_update"] for f in r["frames"]]; sys.exit(not all(x and x["bytes"] > 0 and x["bvh_ms"] >= 0 for x in u))' "$tmp/anim.json"; then
    ok "the report gives each frame's scene update (bytes, times)"
  else bad "the report lacks scene_update per frame"; fi
  check "--animation none renders the rest pose" 0 "wrote 1 frame" -- "$bin" render --scene "$tmp/slide.gltf" \
    --animation none --width 16 --height 9 --out "$tmp/anim_none"
else bad "could not write the animated glTF"; fi

# Instances: in a static file, the cube mesh that 13 nodes draw is stored once and traversed
# through a top level. Two devices give one device's pixels, the scene's kernels the general
# kernels' pixels, and the image is the one of a copy per node (--instancing off) but for
# rounding (the vertices are placed on the device instead of the host).
if python3 "$src/tests/support/write_animated_gltf.py" "$tmp/ring.gltf" --still --copies 12; then
  inst=(render --scene "$tmp/ring.gltf" --width 48 --height 27 --frames 2 --spp 2 --svgf-iterations 2)
  check "a mesh that several nodes draw is stored once" 0 \
    "13 instances of 1 mesh\(es\) draw 156 of the 158 triangles; 14 triangles stored" -- "$bin" "${inst[@]}" \
    --devices 2 --out "$tmp/inst2"
  check "instances are compiled in" 0 "compiled for the scene's features: .*instances" -- "$bin" "${inst[@]}" \
    --devices 1 --out "$tmp/inst1"
  check "instances: 2 devices give 1 device's pixels" 0 "^identical$" -- "$bin" compare --exact \
    "$tmp/inst1/frame_0001_left.exr" "$tmp/inst2/frame_0001_left.exr"
  check "instances: --kernels general renders" 0 "wrote 2 frame" -- "$bin" "${inst[@]}" --devices 1 \
    --kernels general --out "$tmp/inst_general"
  check "instances: --kernels scene and general give identical pixels" 0 "^identical$" -- "$bin" compare --exact \
    "$tmp/inst1/frame_0001_right.exr" "$tmp/inst_general/frame_0001_right.exr"
  check "--instancing off stores a copy per node" 0 "158 triangles" -- "$bin" "${inst[@]}" --instancing off \
    --devices 1 --out "$tmp/inst_flat"
  psnr=$("$bin" compare "$tmp/inst1/frame_0001_left.exr" "$tmp/inst_flat/frame_0001_left.exr" 2>/dev/null |
    awk '/^psnr_db/ {print $2}')
  if awk -v p="${psnr:-0}" 'BEGIN {exit !(p > 40)}'; then ok "instances render the flat copies' image (PSNR $psnr dB)"
  else bad "instances against flat copies: PSNR ${psnr:-none} dB (want > 40)"; fi
else bad "could not write the instanced glTF"; fi
}

case "$part" in
  1) part_one ;;
  2) part_two ;;
  "") part_one; part_two ;;
  *) echo "cli_smoke: unknown part $part (1, 2 or none)"; exit 2 ;;
esac

echo "$passes passed, $fails failed, ${#skipped[@]} skipped"
for s in ${skipped[@]+"${skipped[@]}"}; do echo "  skipped: $s"; done
[ "$fails" -eq 0 ]
