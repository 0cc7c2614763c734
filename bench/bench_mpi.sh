#!/usr/bin/env bash
# MPI traffic and time per frame for R = 1, 2, 3 ranks on this machine (one device per rank):
# per frame, the bytes each link carried (rank -> rank) and each rank's host time in MPI
# calls, medians over the frames after the first; plus the frame wall time.
# Usage: bench/bench_mpi.sh [--ranks "1 2 3"] [--build build] [-- extra render flags]
# Default render: atrium 160x90, 1 spp, 6 bounces, SVGF (halo seams), 10 frames.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build"
ranks="1 2 3"
while [ $# -gt 0 ]; do
  case "$1" in
    --ranks) ranks="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --) shift; break ;;
    -h|--help) sed -n 2,6p "$0"; exit 0 ;;
    *) echo "bench_mpi: unknown argument $1" >&2; exit 1 ;;
  esac
done
extra=("$@")
[ ${#extra[@]} -eq 0 ] && extra=(--scene atrium --width 160 --height 90 --frames 10)
command -v mpirun >/dev/null || { echo "bench_mpi: mpirun not found (apt-get install openmpi-bin)" >&2; exit 1; }
export OMPI_MCA_btl_vader_single_copy_mechanism=none
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for r in $ranks; do
  echo "[bench_mpi] R = $r ..." >&2
  mpirun --allow-run-as-root --oversubscribe -np "$r" "$build/parallax" render "${extra[@]}" --devices 1 \
    --out "$tmp/out$r" --overwrite --report "$tmp/r$r.json" >"$tmp/log$r" 2>&1 || { tail -20 "$tmp/log$r"; exit 1; }
done
/usr/bin/python3 - "$tmp" $ranks <<'PY'
import json, statistics, sys
tmp, ranks = sys.argv[1], [int(r) for r in sys.argv[2:]]
print("median per frame after the first; MPI ms = host time inside MPI calls, waiting for the sender included")
print(f"{'R':>2} {'wall ms':>9} {'link (from->to)':>16} {'KB/frame':>10} {'MPI ms/frame per rank':>24}")
for r in ranks:
    rep = json.load(open(f"{tmp}/r{r}.json"))
    frames = rep["frames"][1:] or rep["frames"]
    wall = statistics.median(f["wall_ms"] for f in frames)
    if r == 1 or not frames[0].get("mpi"):
        print(f"{r:>2} {wall:>9.1f} {'(one process)':>16} {0:>10} {'-':>24}")
        continue
    ms = [statistics.median(f["mpi"]["ms"][k] for f in frames) for k in range(r)]
    first = True
    for a in range(r):
        for b in range(r):
            if a == b: continue
            kb = statistics.median(f["mpi"]["bytes_sent"][a][b] for f in frames) / 1024
            if kb == 0: continue
            print(f"{r if first else '':>2} {f'{wall:.1f}' if first else '':>9} {f'{a}->{b}':>16} {kb:>10.1f} "
                  f"{' '.join(f'{m:.1f}' for m in ms) if first else '':>24}")
            first = False
PY
