#!/usr/bin/env bash
# Start-up cost of instances: wall time and peak RSS of a one-frame `parallax render` of a glTF
# whose one mesh (a UV sphere, ~4k triangles, indexed, with normals) is drawn by N nodes on a
# grid, beside a ground quad drawn once, a perspective camera and a directional light (the
# sun). Each N is rendered as loaded (a mesh drawn by >= 2 nodes becomes instances: stored
# once, a matrix per node) and with --instancing off (flat world-space copies). With N = 1 the
# two modes load the same scene (one node: nothing to instance).
# Goal: instanced at N = 1024 takes at most 1.5x the memory of N = 1 and at most 3x its
# start time + 2 s. Exit status 1 when the goal is missed.
#
# Every distinct kernel set is compiled once, untimed, before the timed runs (PoCL caches
# compiled kernels in POCL_CACHE_DIR, default BUILD/pocl-cache), so the table shows start-up,
# not first-time compilation. The BVH cache is off (PARALLAX_BVH_CACHE=off) unless --bvh-cache
# is given: every run builds its trees, as a first start does (and no 300 MiB flat tree is
# left in ~/.cache/parallax).
#
# Usage: bench/instances_start.sh [--build DIR] [--out DIR] [--counts 1,1024] [--repeats R] [--bvh-cache]
#   --build DIR   build directory holding `parallax` (default: build)
#   --out DIR     where the glTF files, logs and images go (default: a temporary directory,
#                 removed at exit)
#   --counts L    comma list of N (default 1,1024; the first is the baseline of the ratios)
#   --repeats R   timed runs per N and mode, the median reported (default 1)
#   --bvh-cache   leave parallax's BVH cache as the environment has it (a warm cache skips the
#                 flat scene's tree build)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build"
out=""
counts="1,1024"
repeats=1
bvh_cache=0
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --counts) counts="$2"; shift 2 ;;
    --repeats) repeats="$2"; shift 2 ;;
    --bvh-cache) bvh_cache=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
build="$(cd "$build" && pwd)"
bin="$build/parallax"
[ -x "$bin" ] || { echo "no parallax binary at $bin (build the target parallax)" >&2; exit 2; }
[ -x /usr/bin/time ] || { echo "needs /usr/bin/time (GNU time)" >&2; exit 2; }
if [ -z "$out" ]; then
  out="$(mktemp -d)"
  trap 'rm -rf "$out"' EXIT
else
  mkdir -p "$out"
  out="$(cd "$out" && pwd)"
fi
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$build/pocl-cache}"
[ "$bvh_cache" = 1 ] || export PARALLAX_BVH_CACHE=off

IFS=',' read -r -a ns <<<"$counts"

# make_gltf N FILE: the scene, as FILE (.gltf) and FILE's .bin beside it.
make_gltf() {
  python3 - "$1" "$2" <<'PY'
import json, math, os, struct, sys

n, path = int(sys.argv[1]), sys.argv[2]
segments, rings, radius = 64, 32, 0.8       # 2 * 64 + 2 * 64 * 30 = 3,968 triangles

# UV sphere: a pole vertex at each end, rings - 1 latitude circles between.
pos, nrm, idx = [], [], []
def vertex(p):
    pos.append(p)
    l = math.sqrt(sum(c * c for c in p))
    nrm.append(tuple(c / l for c in p))
    return len(pos) - 1
top = vertex((0.0, radius, 0.0))
circles = []
for r in range(1, rings):
    theta = math.pi * r / rings
    circles.append([vertex((radius * math.sin(theta) * math.cos(2 * math.pi * s / segments),
                            radius * math.cos(theta),
                            -radius * math.sin(theta) * math.sin(2 * math.pi * s / segments)))
                    for s in range(segments)])
bottom = vertex((0.0, -radius, 0.0))
for s in range(segments):                    # counter-clockwise seen from outside
    t = (s + 1) % segments
    idx += [top, circles[0][s], circles[0][t]]
    for r in range(rings - 2):
        a, b = circles[r], circles[r + 1]
        idx += [a[s], b[s], b[t], a[s], b[t], a[t]]
    idx += [bottom, circles[-1][t], circles[-1][s]]

side = max(1, math.ceil(math.sqrt(n)))
spacing = 2.0
half = spacing * side / 2.0
g = half + 1.0
quad_pos = [(-g, -radius, g), (g, -radius, g), (g, -radius, -g), (-g, -radius, -g)]
quad_nrm = [(0.0, 1.0, 0.0)] * 4
quad_idx = [0, 1, 2, 0, 2, 3]

blob = bytearray()
views, accessors = [], []
def add(data, fmt, count, comp, kind, target, minmax=None):
    while len(blob) % 4:
        blob.append(0)
    start = len(blob)
    blob.extend(struct.pack("<%d%s" % (len(data), fmt), *data))
    views.append({"buffer": 0, "byteOffset": start, "byteLength": len(blob) - start, "target": target})
    acc = {"bufferView": len(views) - 1, "componentType": comp, "count": count, "type": kind}
    if minmax:
        acc["min"], acc["max"] = minmax
    accessors.append(acc)
    return len(accessors) - 1
def bounds(ps):
    return [[min(p[a] for p in ps) for a in range(3)], [max(p[a] for p in ps) for a in range(3)]]
flat = lambda vs: [c for v in vs for c in v]
ARRAY, ELEMENTS, FLOAT, UINT = 34962, 34963, 5126, 5125
s_pos = add(flat(pos), "f", len(pos), FLOAT, "VEC3", ARRAY, bounds(pos))
s_nrm = add(flat(nrm), "f", len(nrm), FLOAT, "VEC3", ARRAY)
s_idx = add(idx, "I", len(idx), UINT, "SCALAR", ELEMENTS)
q_pos = add(flat(quad_pos), "f", 4, FLOAT, "VEC3", ARRAY, bounds(quad_pos))
q_nrm = add(flat(quad_nrm), "f", 4, FLOAT, "VEC3", ARRAY)
q_idx = add(quad_idx, "I", 6, UINT, "SCALAR", ELEMENTS)

nodes = []
for i in range(n):
    x = spacing * (i % side) - half + spacing / 2
    z = spacing * (i // side) - half + spacing / 2
    nodes.append({"mesh": 0, "translation": [x, 0.0, z]})
nodes.append({"mesh": 1, "name": "ground"})
# Camera above and behind the grid, pitched down to look at its centre (glTF cameras look
# down -z): a rotation about x.
height, dist = 1.2 * half + 2.0, 2.2 * half + 3.0
pitch = -math.atan2(height, dist)
nodes.append({"camera": 0, "translation": [0.0, height, dist],
              "rotation": [math.sin(pitch / 2), 0.0, 0.0, math.cos(pitch / 2)]})
# The sun: light travelling down -z of its node, turned to come from above at an angle.
a = -1.0
nodes.append({"extensions": {"KHR_lights_punctual": {"light": 0}},
              "rotation": [math.sin(a / 2), 0.0, 0.0, math.cos(a / 2)]})

base = os.path.splitext(os.path.basename(path))[0] + ".bin"
doc = {
    "asset": {"version": "2.0", "generator": "bench/instances_start.sh"},
    "extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 3.0}]}},
    "scene": 0,
    "scenes": [{"nodes": list(range(len(nodes)))}],
    "nodes": nodes,
    "meshes": [
        {"name": "sphere", "primitives": [{"attributes": {"POSITION": s_pos, "NORMAL": s_nrm}, "indices": s_idx, "material": 0}]},
        {"name": "ground", "primitives": [{"attributes": {"POSITION": q_pos, "NORMAL": q_nrm}, "indices": q_idx, "material": 1}]},
    ],
    "materials": [
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.3, 0.2, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}},
        {"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}},
    ],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 16 / 9, "znear": 0.05}}],
    "buffers": [{"uri": base, "byteLength": len(blob)}],
    "bufferViews": views,
    "accessors": accessors,
}
with open(os.path.join(os.path.dirname(path), base), "wb") as f:
    f.write(blob)
with open(path, "w") as f:
    json.dump(doc, f)
print(len(idx) // 3)
PY
}

# render_once N MODE TAG: one render; sets wall (s) and rss (KiB).
render_once() {
  local n="$1" mode="$2" tag="$3"
  local flat=()
  [ "$mode" = flat ] && flat=(--instancing off)
  rm -rf "$out/img_$tag"
  if ! /usr/bin/time -v -o "$out/time_$tag.txt" "$bin" render --scene "$out/instances_$n.gltf" "${flat[@]}" \
      --frames 1 --width 160 --height 90 --out "$out/img_$tag" --overwrite >"$out/log_$tag.txt" 2>&1; then
    echo "render of N=$n ($mode) failed:" >&2
    tail -5 "$out/log_$tag.txt" >&2
    exit 1
  fi
  rm -rf "$out/img_$tag"
  # "Elapsed (wall clock) time (h:mm:ss or m:ss): 0:01.23"
  wall="$(awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, p, ":"); s = 0; for (i = 1; i <= n; ++i) s = s * 60 + p[i]; printf "%.3f", s }' "$out/time_$tag.txt")"
  rss="$(awk -F': ' '/Maximum resident set size/ { print $2 }' "$out/time_$tag.txt")"
}

median() { sort -g | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else printf "%.3f\n", (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

for n in "${ns[@]}"; do
  tris="$(make_gltf "$n" "$out/instances_$n.gltf")"
  echo "scene N=$n: $n nodes draw one ${tris}-triangle sphere, + ground quad ($((n * tris + 2)) triangles drawn)"
done

# Untimed: compile the kernels of both feature sets (with instances, at the largest N; without,
# at the first) into the PoCL cache.
last="${ns[$((${#ns[@]} - 1))]}"
render_once "$last" instanced warm_i
render_once "${ns[0]}" flat warm_f

declare -A W R
for n in "${ns[@]}"; do
  for mode in instanced flat; do
    ws=() rs=()
    for ((r = 0; r < repeats; ++r)); do
      render_once "$n" "$mode" "${n}_${mode}_$r"
      ws+=("$wall")
      rs+=("$rss")
    done
    W[$n,$mode]="$(printf '%s\n' "${ws[@]}" | median)"
    R[$n,$mode]="$(printf '%s\n' "${rs[@]}" | median)"
  done
done

echo
printf '%8s %10s %10s %14s\n' N mode "wall s" "peak RSS MiB"
for n in "${ns[@]}"; do
  for mode in instanced flat; do
    printf '%8s %10s %10.2f %14.1f\n' "$n" "$mode" "${W[$n,$mode]}" "$(awk -v k="${R[$n,$mode]}" 'BEGIN { print k / 1024 }')"
  done
done

b="${ns[0]}"
echo
status=0
for n in "${ns[@]:1}"; do
  awk -v n="$n" -v b="$b" -v wi="${W[$n,instanced]}" -v w1="${W[$b,instanced]}" -v ri="${R[$n,instanced]}" \
      -v r1="${R[$b,instanced]}" -v wf="${W[$n,flat]}" -v rf="${R[$n,flat]}" 'BEGIN {
    mem = ri / r1; time = wi / w1; limit = 3 * w1 + 2
    printf "instanced(%s)/instanced(%s): memory %.2fx (goal <= 1.5x): %s\n", n, b, mem, mem <= 1.5 ? "met" : "MISSED"
    printf "instanced(%s)/instanced(%s): time %.2fx, %.2f s against 3 x %.2f s + 2 s = %.2f s: %s\n", n, b, time, wi, w1, limit, wi <= limit ? "met" : "MISSED"
    printf "flat(%s)/instanced(%s) at N=%s: memory %.2fx, time %.2fx\n", n, n, n, rf / ri, wf / wi
    exit !(mem <= 1.5 && wi <= limit)
  }' || status=1
done
exit $status
