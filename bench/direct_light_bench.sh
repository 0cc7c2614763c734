#!/usr/bin/env bash
# Equal-time comparison of the direct-light samplers (issue 49): for each scene and each
# `--direct-light` mode the build accepts, `parallax render` at the real-time point (1 spp,
# 16 frames, 2 devices, 320x180), denoised and raw (--no-denoise), frame 15 of both eyes
# against a cached `parallax reference` of the same frame. Reports per scene and mode relMSE
# (raw and denoised, both eyes), PSNR, the denoised mean luminance over the reference's, the
# median frame time, efficiency = 1 / (relMSE x frame time) and its ratio to `power`'s, and every
# stage the render report lists (bench/direct_light_metrics.py has the definitions).
#
# Usage: bench/direct_light_bench.sh [options]     (every option also from an environment variable)
#   --out DIR        results (default BUILD/bench-direct-light/run; DLB_OUT); emptied of earlier results
#   --scenes LIST    comma list of built-in names or scene files (DLB_SCENES; default rooms,cornell,
#                    cornell-glossy,atrium and the shared bunny, ../shared/scenes/real/bunny/bunny.json,
#                    when that folder exists)
#   --modes LIST     direct-light modes (DLB_MODES; an entry MODE:FLAG=VALUE:... adds render flags to
#                    that row, e.g. restir:--restir-candidates=2; default every mode `render --help` lists for
#                    --direct-light; `power` alone, with no flag passed, where the build has no such flag)
#   --width W --height H   pixels per eye (DLB_WIDTH 320, DLB_HEIGHT 180)
#   --frames N       frames rendered; the last (N - 1) is measured (DLB_FRAMES 16)
#   --devices N      OpenCL devices (DLB_DEVICES 2)
#   --spp N          samples per pixel of the renders (DLB_SPP 1)
#   --bounces N      path length (DLB_BOUNCES 6)
#   --fps F          frame rate: frame N - 1 is at time (N - 1) / F on the camera path
#                    (DLB_FPS 1000000: a still camera, as scripts/evaluate_denoiser's still cases)
#   --ref-spp N      samples per pixel of the references (DLB_REF_SPP 1024)
#   --ref-direct-light MODE   sampler of the references (DLB_REF_DIRECT_LIGHT; default `tree` when
#                    `reference --help` lists --direct-light with it, else the build's only one)
#   --refs DIR       reference cache (DLB_REFS; default BUILD/bench-direct-light/refs), keyed by
#                    scene, size, frame, fps, spp, bounces and sampler; reruns reuse it
#   --build DIR      where parallax is (DLB_BUILD; default build/ beside this script)
# Writes OUT/results.{md,csv,json}, OUT/cases/SCENE/MODE/{denoised,raw}/ (the measured frame's
# files and the reports), OUT/logs/, OUT/machine.txt; prints the Markdown tables.
# Example: bench/direct_light_bench.sh --scenes rooms --width 160 --height 90 --ref-spp 256
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

die() { echo "direct_light_bench: error: $*" >&2; exit 2; }
given_args="$*"
build="${DLB_BUILD:-$root/build}"
out="${DLB_OUT:-}" scenes="${DLB_SCENES:-}" modes="${DLB_MODES:-}" width="${DLB_WIDTH:-320}"
height="${DLB_HEIGHT:-180}" frames="${DLB_FRAMES:-16}" devices="${DLB_DEVICES:-2}" spp="${DLB_SPP:-1}"
bounces="${DLB_BOUNCES:-6}" fps="${DLB_FPS:-1000000}" ref_spp="${DLB_REF_SPP:-1024}"
ref_dl="${DLB_REF_DIRECT_LIGHT:-}" refs="${DLB_REFS:-}"
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) sed -n '2,/^set -euo pipefail/{/^set/!p}' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    --out|--scenes|--modes|--width|--height|--frames|--devices|--spp|--bounces|--fps|--ref-spp|--ref-direct-light|--refs|--build)
      [ $# -ge 2 ] || die "$1 needs a value"
      case "$1" in
        --out) out="$2" ;; --scenes) scenes="$2" ;; --modes) modes="$2" ;; --width) width="$2" ;;
        --height) height="$2" ;; --frames) frames="$2" ;; --devices) devices="$2" ;; --spp) spp="$2" ;;
        --bounces) bounces="$2" ;; --fps) fps="$2" ;; --ref-spp) ref_spp="$2" ;; --ref-direct-light) ref_dl="$2" ;;
        --refs) refs="$2" ;; --build) build="$2" ;;
      esac
      shift 2 ;;
    *) die "unknown option '$1' (see --help)" ;;
  esac
done
for v in width height frames devices spp ref_spp; do
  [[ "${!v}" =~ ^[0-9]+$ ]] && [ "${!v}" -gt 0 ] || die "--${v//_/-} needs a positive integer, got '${!v}'"
done
[[ "$bounces" =~ ^[0-9]+$ ]] || die "--bounces needs a non-negative integer, got '$bounces'"
[[ "$fps" =~ ^[0-9]+([.][0-9]+)?$ ]] || die "--fps needs a number, got '$fps'"
[ "$frames" -ge 2 ] || die "--frames must be at least 2 (the first frame's time includes compilation)"
[ -x "$build/parallax" ] || die "$build/parallax not found: build first (scripts/build parallax), or pass --build DIR"
build="$(cd "$build" && pwd)"
out="${out:-$build/bench-direct-light/run}"
refs="${refs:-$build/bench-direct-light/refs}"
py=/usr/bin/python3  # Debian's python, with python3-numpy and python3-openimageio
"$py" -c 'import numpy, OpenImageIO' 2>/dev/null || die "python3-numpy / python3-openimageio missing for $py (scripts/install-deps)"
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$build/pocl-cache}"

# The modes a command accepts for --direct-light, from its --help (CLI11: TEXT:{a,b,c}); empty without the flag.
accepted_modes() {
  "$build/parallax" "$1" --help 2>/dev/null | sed -n 's/.*--direct-light[^{]*{\([^}]*\)}.*/\1/p' | head -1
}
render_modes="$(accepted_modes render)"
reference_modes="$(accepted_modes reference)"
if [ -z "$modes" ]; then modes="${render_modes:-power}"; fi
IFS=, read -r -a mode_list <<<"$modes"
for entry in "${mode_list[@]}"; do
  [ -n "$entry" ] || die "--modes has an empty entry: '$modes'"
  m="${entry%%:*}"
  if [ -z "$render_modes" ]; then
    [ "$m" = power ] || die "this build's render has no --direct-light: only 'power' (today's sampler) can run, not '$m'"
  elif [[ ",$render_modes," != *",$m,"* ]]; then
    die "render --direct-light does not accept '$m' (it accepts $render_modes)"
  fi
done
if [ -z "$ref_dl" ]; then
  if [[ ",$reference_modes," == *",tree,"* ]]; then ref_dl=tree; else ref_dl=power; fi
fi
ref_flag=()
if [ -n "$reference_modes" ]; then
  [[ ",$reference_modes," == *",$ref_dl,"* ]] || die "reference --direct-light does not accept '$ref_dl' ($reference_modes)"
  ref_flag=(--direct-light "$ref_dl")
else
  [ "$ref_dl" = power ] || die "this build's reference has no --direct-light: its sampler is power, not '$ref_dl'"
fi

if [ -z "$scenes" ]; then
  scenes="rooms,cornell,cornell-glossy,atrium"
  shared=""
  for d in "$root/../shared" "$root/../../shared"; do [ -d "$d/scenes/real" ] && { shared="$(cd "$d" && pwd)"; break; }; done
  if [ -n "$shared" ] && [ -f "$shared/scenes/real/bunny/bunny.json" ]; then
    scenes+=",$shared/scenes/real/bunny/bunny.json"
  else
    echo "direct_light_bench: note: no ../shared/scenes/real/bunny/bunny.json beside the checkout: the bunny is left out" >&2
  fi
fi

# Cases: a key (cache and folder name) per scene.
scene_list=() key_list=()
IFS=, read -r -a entries <<<"$scenes"
for s in "${entries[@]}"; do
  [ -n "$s" ] || die "--scenes has an empty entry: '$scenes'"
  if [[ "$s" == */* || "$s" == *.json || "$s" == *.obj || "$s" == *.gltf || "$s" == *.glb ]]; then
    [ -f "$s" ] || die "scene file '$s' not found"
    s="$(cd "$(dirname "$s")" && pwd)/$(basename "$s")"
    k="$(basename "$s")"; k="${k%.*}-$(sha1sum "$s" | cut -c1-12)"  # an edited file gets new references
  else
    k="$s"
  fi
  [[ "$k" =~ ^[A-Za-z0-9._-]+$ ]] || die "scene '$s': use a built-in name or a file named with letters, digits, '.', '_', '-'"
  scene_list+=("$s") key_list+=("$k")
done

mkdir -p "$out" "$refs"
out="$(cd "$out" && pwd)" refs="$(cd "$refs" && pwd)"
rm -rf "$out/cases" "$out/logs" "$out"/results.* "$out/cases.tsv"
mkdir -p "$out/cases" "$out/logs"
frame=$((frames - 1))
tag="$(printf 'frame_%04d' "$frame")"
start=$SECONDS
log() { echo "[direct_light_bench] $((SECONDS - start))s: $*" >&2; }
run() {  # run LOGNAME command...
  local name="$1"; shift
  if ! "$@" >"$out/logs/$name.txt" 2>&1; then
    tail -20 "$out/logs/$name.txt" >&2
    die "$name failed (log: $out/logs/$name.txt)"
  fi
}
git_rev="$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
{
  echo "date_utc=$(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
  echo "cores=$(nproc)"
  echo "git=$git_rev$(git -C "$root" diff --quiet HEAD 2>/dev/null || echo ' (with local changes)')"
  echo "command=bench/direct_light_bench.sh $given_args"
  echo "width=$width height=$height frames=$frames frame=$frame devices=$devices spp=$spp bounces=$bounces fps=$fps"
  echo "modes=$modes render_accepts=${render_modes:-none (power only)} ref_spp=$ref_spp ref_direct_light=$ref_dl"
  echo "scenes=$scenes refs=$refs"
} >"$out/machine.txt"

for i in "${!scene_list[@]}"; do
  s="${scene_list[$i]}" k="${key_list[$i]}"
  ref="$refs/$k/${width}x${height}_frame${frame}_fps${fps}_spp${ref_spp}_b${bounces}_${ref_dl}"
  if [ -s "$ref/reference_left.exr" ] && [ -s "$ref/reference_right.exr" ] && [ -s "$ref/key.txt" ]; then
    log "$k: reference cached ($ref)"
  else
    log "$k: reference of frame $frame, $ref_spp spp (sampler $ref_dl)"
    tmp="$ref.tmp.$$"
    rm -rf "$tmp" && mkdir -p "$(dirname "$ref")"
    t0=$SECONDS
    run "${k}_reference" "$build/parallax" reference --scene "$s" --width "$width" --height "$height" --frame "$frame" \
      --fps "$fps" --spp "$ref_spp" --bounces "$bounces" --devices "$devices" "${ref_flag[@]}" --out "$tmp"
    printf 'scene=%s\nsampler=%s\nseconds=%s\ngit=%s\n' "$s" "$ref_dl" "$((SECONDS - t0))" "$git_rev" >"$tmp/key.txt"
    rm -rf "$ref" && mv "$tmp" "$ref"
    log "$k: reference took $((SECONDS - t0)) s"
  fi
  for entry in "${mode_list[@]}"; do
    # MODE or MODE:FLAG=VALUE:FLAG=VALUE... (more render flags for that row, e.g. restir:--restir-candidates=2)
    m="$entry"
    IFS=: read -r -a parts <<<"$entry"
    dl=()
    [ -n "$render_modes" ] && dl=(--direct-light "${parts[0]}")
    dl+=("${parts[@]:1}")
    safe="$(printf '%s' "$m" | tr -c 'A-Za-z0-9._-' '_')"
    dir="$out/cases/$k/$safe"
    common=(--scene "$s" --spp "$spp" --bounces "$bounces" --devices "$devices" --width "$width" --height "$height"
            --frames "$frames" --fps "$fps" "${dl[@]}")
    for kind in denoised raw; do
      extra=()
      [ "$kind" = raw ] && extra=(--no-denoise)
      log "$k / $m: render, $kind"
      run "${k}_${safe}_$kind" "$build/parallax" render "${common[@]}" "${extra[@]}" --report "$dir/$kind.json" \
        --out "$dir/$kind"
      find "$dir/$kind" -name 'frame_*' ! -name "${tag}_*" -delete  # only the measured frame is kept
    done
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$k" "$m" "$dir/denoised" "$dir/raw" "$ref" "$dir/denoised.json" \
      "$dir/raw.json" >>"$out/cases.tsv"
  done
done

log "metrics"
"$py" "$root/bench/direct_light_metrics.py" "$out" "$out/cases.tsv" "$frame" || die "the metrics failed"
log "done: $out/results.md, results.csv, results.json (reference sampler: $ref_dl)"
