#!/usr/bin/env bash
# Memory soak: peak RSS of `parallax render` at a short and a long run, and the growth per frame
# between them. A bench, not a test (it takes about a minute and measures; it asserts nothing
# unless --max-kb-per-frame is given). Defaults: the configuration that grew ~130 KB per frame
# before the fix (SVGF denoising, 2 devices, halo seams, report and timeline written).
# Usage: bench/soak_memory.sh [--bin build/parallax] [--short 40] [--long 240]
#                             [--max-kb-per-frame N] [-- extra render flags]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="$root/build/parallax"
short=40
long=240
max_kb=""
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --short) short="$2"; shift 2 ;;
    --long) long="$2"; shift 2 ;;
    --max-kb-per-frame) max_kb="$2"; shift 2 ;;
    --) shift; break ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
extra=("$@")
[ ${#extra[@]} -eq 0 ] && extra=(--scene cornell --width 32 --height 18 --devices 2)
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$root/build/pocl-cache}"

peak_kb() {  # peak_kb FRAMES: max RSS in KiB of one render of FRAMES frames
  local n="$1"
  /usr/bin/time -f "%M" -o "$tmp/rss_$n" "$bin" render "${extra[@]}" --frames "$n" --out "$tmp/out_$n" \
    --report "$tmp/report_$n.json" --timeline "$tmp/timeline_$n.json" >/dev/null 2>"$tmp/log_$n" ||
    { tail -5 "$tmp/log_$n" >&2; exit 1; }
  rm -rf "$tmp/out_$n"
  cat "$tmp/rss_$n"
}

a="$(peak_kb "$short")"
b="$(peak_kb "$long")"
per_frame="$(awk -v a="$a" -v b="$b" -v s="$short" -v l="$long" 'BEGIN { printf "%.2f", (b - a) / (l - s) }')"
echo "peak RSS: $short frames $a KiB, $long frames $b KiB: $per_frame KiB per frame (${extra[*]})"
if [ -n "$max_kb" ] && awk -v p="$per_frame" -v m="$max_kb" 'BEGIN { exit !(p > m) }'; then
  echo "FAIL: grows more than $max_kb KiB per frame" >&2
  exit 1
fi
