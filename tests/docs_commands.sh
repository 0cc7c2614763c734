#!/usr/bin/env bash
# The commands the documentation shows are real: every line of README.md and docs/usage.md inside
# a ```sh / ```bash / ``` block that runs parallax (build/parallax ..., parallax ..., mpirun ...
# build/parallax, xvfb-run ... build/parallax) runs here at a tiny size and must exit 0. Sizes are
# rewritten in place (CLI11 refuses a repeated option): --width 32 --height 18, --frames at most 2,
# --spp 1 (a reference 4), and added where a command leaves them at their defaults. Each file's
# commands run in order in one temporary folder (a compare reads what a render above it wrote),
# after tiny example inputs the docs name (model.gltf, model.glb) are made there; `echo ... > F`
# lines run as shown. A command that cannot run here is in SKIP below with its reason; a shown
# command neither run nor skipped fails the test, so a command added to the docs is checked.
# Usage: docs_commands.sh PATH/TO/parallax SOURCE_DIR. Exit 77 (skipped) when nothing could run.
set -u
bin="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
src="$(cd "$2" && pwd)"
py=/usr/bin/python3  # Debian's, as the other script tests use
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# Substring of the shown command -> why it does not run here. Checked before anything runs.
SKIP=(
  "BoxAnimated.glb|Khronos's sample file, not in the repository (no network here)"
  "CesiumMan.glb|Khronos's sample file, not in the repository (no network here)"
  "RiggedSimple.glb|Khronos's sample file, not in the repository (no network here)"
)
have() { command -v "$1" >/dev/null 2>&1; }
[ -n "${DISPLAY:-}" ] || have xvfb-run || SKIP+=("parallax view|no display and no xvfb-run (Debian xvfb)")
have mpirun || SKIP+=("mpirun |mpirun missing (Debian openmpi-bin)")
have ffmpeg || SKIP+=("--video |ffmpeg missing (Debian ffmpeg)")

# Extract and rewrite: one record per shown parallax line, "ORIGINAL<TAB>REWRITTEN<TAB>FILE".
extract() {
  "$py" - "$src" "$@" <<'EOF'
import os, re, shlex, sys
src, files = sys.argv[1], sys.argv[2:]
SIZE = {"--width": "32", "--height": "18"}
for f in files:
    fence = False
    for raw in open(f"{src}/{f}", encoding="utf-8"):
        line = raw.rstrip("\n")
        m = re.match(r"^\s*```(\w*)\s*$", line)
        if m:
            if fence: fence = False
            else: fence = m.group(1) in ("", "sh", "bash")
            continue
        if not fence: continue
        cmd = re.sub(r"\s+#\s.*$", "", line).strip()
        if not cmd or cmd.startswith("#"): continue
        if cmd.startswith("echo ") and ">" in cmd:
            print(f"{cmd}\t{cmd}\t{f}"); continue
        if not re.search(r"(^|[\s/])parallax(\s|$)", cmd): continue  # not a parallax command
        try: words = shlex.split(cmd)
        except ValueError: print(f"{cmd}\tUNPARSED\t{f}"); continue
        # The program: build/parallax anywhere, or a bare `parallax` first or after a launcher
        # (`scripts/build parallax` names a target, it does not run the program).
        i = next((k for k, w in enumerate(words) if w == "build/parallax" or
                  (w == "parallax" and (k == 0 or words[0] in ("mpirun", "xvfb-run")))), None)
        if i is None: continue
        prefix, args = words[:i], words[i + 1:]
        sub = args[0] if args else ""
        out = []
        k = 0
        seen = set()
        while k < len(args):
            w = args[k]
            if w in SIZE and k + 1 < len(args):
                out += [w, SIZE[w]]; seen.add(w); k += 2; continue
            if w == "--frames" and k + 1 < len(args):
                out += [w, str(min(int(args[k + 1]), 2))]; seen.add(w); k += 2; continue
            if w == "--spp" and k + 1 < len(args):
                out += [w, "4" if sub == "reference" else "1"]; k += 2; continue
            if w == "--target-ms" and k + 1 < len(args):
                out += [w, "1:100000"]; k += 2; continue  # any window: the loop runs, the frames stay tiny
            out.append(w); k += 1
        if sub in ("render", "view", "preview", "reference"):
            for s, v in SIZE.items():
                if s not in seen: out += [s, v]
        if sub == "view" and "--frames" not in seen:
            out += ["--frames", "2"]
        if prefix and prefix[0] == "mpirun" and "--oversubscribe" not in prefix:
            root = ["--allow-run-as-root"] if os.geteuid() == 0 else []  # containers run as root
            prefix = prefix[:1] + root + ["--oversubscribe"] + prefix[1:]
        print(f"{cmd}\t{shlex.join(prefix + ['@BIN@'] + out)}\t{f}")
EOF
}

# Tiny example inputs the docs name: one lit triangle as .gltf (embedded buffer) and as .glb.
make_inputs() {
  "$py" - "$1" <<'EOF'
import base64, json, struct, sys
d = sys.argv[1]
pos = struct.pack("<9f", -1, 0, -1, 1, 0, -1, 0, 0, 1)
doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
       "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
       "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1]}}],
       "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                      "min": [-1, 0, -1], "max": [1, 0, 1]}],
       "bufferViews": [{"buffer": 0, "byteLength": len(pos)}],
       "buffers": [{"byteLength": len(pos)}]}
glb_doc = json.loads(json.dumps(doc))
doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(pos).decode()
open(f"{d}/model.gltf", "w").write(json.dumps(doc))
j = json.dumps(glb_doc).encode(); j += b" " * (-len(j) % 4)
b = pos + b"\0" * (-len(pos) % 4)
body = struct.pack("<II", len(j), 0x4E4F534A) + j + struct.pack("<II", len(b), 0x004E4942) + b
open(f"{d}/model.glb", "wb").write(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
EOF
}

fails=0 runs=0 skips=0
records="$(extract README.md docs/usage.md)" || { echo "FAIL could not read the docs"; exit 1; }
[ -n "$records" ] || { echo "FAIL no parallax command found in README.md or docs/usage.md"; exit 1; }
export PARALLAX_CACHE_DIR="$tmp/cache"
declare -A made
while IFS=$'\t' read -r shown cmd file; do
  dir="$tmp/${file//\//_}"
  if [ -z "${made[$dir]:-}" ]; then mkdir -p "$dir" && make_inputs "$dir"; made[$dir]=1; fi
  reason=""
  for entry in "${SKIP[@]}"; do
    if [[ "$shown" == *"${entry%%|*}"* ]]; then reason="${entry#*|}"; break; fi
  done
  if [ -n "$reason" ]; then echo "skip [$file] $shown  ($reason)"; skips=$((skips + 1)); continue; fi
  case "$cmd" in
    "echo "*|"@BIN@ "*|"mpirun "*|"xvfb-run "*) ;;
    *) echo "FAIL [$file] neither run nor skipped (add it to SKIP with a reason): $shown"; fails=$((fails + 1)); continue ;;
  esac
  if [[ "$cmd" == "@BIN@ view"* ]] && [ -z "${DISPLAY:-}" ]; then cmd="xvfb-run -a $cmd"; fi
  run="${cmd//@BIN@/$bin}"
  start=$SECONDS
  out="$(cd "$dir" && timeout 300 bash -c "$run" 2>&1 </dev/null)"
  rc=$?
  runs=$((runs + 1))
  if [ "$rc" -ne 0 ]; then
    echo "FAIL [$file] exit $rc: $shown"; echo "     ran: $run"; echo "$out" | tail -8
    fails=$((fails + 1))
  else
    echo "ok   [$file] $((SECONDS - start)) s: $shown"
  fi
done <<<"$records"

echo "$runs run, $skips skipped, $fails failed"
[ "$fails" -eq 0 ] || exit 1
[ "$runs" -gt 0 ] || exit 77
exit 0
