#!/usr/bin/env bash
# Every OpenCL kernel file compiles for an NVIDIA GPU as well as for PoCL's CPU devices: clang's
# OpenCL C front end and its PTX back end (target nvptx64-nvidia-nvcl), OpenCL C 1.2 with the
# options DeviceSet::program passes, once per BVH layout the kernels are built for
# (-DPX_BVH_WIDTH 2, 4, 8, 9). PoCL compiles for the CPU it runs on, so CI would never see a
# construct only x86 accepts; GPU machines are lent for minutes, and a kernel that does not
# build there wastes them. Nothing runs and no speed is checked.
# Usage: kernels_ptx.sh SOURCE_DIR. Exit 77 (skipped) when clang or its NVPTX back end is missing
# (scripts/install-deps --fuzz installs clang; CI has it).
set -u
src="$1"
clang_bin="${CLANG:-clang}"
if ! command -v "$clang_bin" >/dev/null 2>&1; then echo "skip: no clang"; exit 77; fi
if ! "$clang_bin" --print-targets 2>/dev/null | grep -q nvptx64; then echo "skip: clang has no NVPTX back end"; exit 77; fi
# Every BVH layout with every feature, then the wide layout with no scene feature and with two
# complementary halves of them (PX_FEATURES, kernels/shared/types.h): a build for a scene's
# features must compile, and without warnings (a constant operand in a feature test warns).
# Last, the data layouts a static scene's start picks: leaf refs, flat and indexed shading records.
variants=("2 0x1fff" "4 0x1fff" "8 0x1fff" "9 0x1fff" "8 0x000" "8 0x1555" "8 0x0aaa"
          "8 0x1fff -DPX_LEAF_REFS=1 -DPX_FLAT_SHADING=1" "9 0x000 -DPX_FLAT_SHADING=1"
          "8 0x1fff -DPX_LEAF_REFS=1 -DPX_INDEXED_SHADING=1" "2 0x000 -DPX_INDEXED_SHADING=1")
# One compilation: FILE (under kernels/) WIDTH FEATURES [EXTRA...]; prints a FAIL block or nothing.
# Each is a single-threaded clang: they run one per core.
compile_one() {
  local rel="$1" width="$2" features="$3" out
  shift 3
  if ! out="$("$clang_bin" -x cl -cl-std=CL1.2 -target nvptx64-nvidia-nvcl -Xclang -finclude-default-header \
      -cl-single-precision-constant -O2 -DPX_BVH_WIDTH="$width" -DPX_FEATURES="$features" "$@" -I"$src/kernels" -S \
      -o /dev/null "$src/kernels/$rel" 2>&1)" || grep -q "warning:" <<<"$out"; then
    # One write, so that the parallel compilations' reports do not interleave.
    printf 'FAIL %s (PX_BVH_WIDTH=%s PX_FEATURES=%s%s):\n%s\n' "$rel" "$width" "$features" \
      "${*:+ $*}" "$(head -20 <<<"$out")"
  fi
}
export -f compile_one
export clang_bin src
jobs="$(nproc 2>/dev/null || echo 2)"
files=()
while IFS= read -r -d '' file; do files+=("${file#"$src"/kernels/}"); done < <(find "$src/kernels" -name '*.cl' -print0 | sort -z)
[ "${#files[@]}" -gt 0 ] || { echo "FAIL no kernel files under $src/kernels"; exit 1; }
# One line per compilation: the file's path under kernels/ (none has a space) and the variant.
log="$(for file in "${files[@]}"; do for variant in "${variants[@]}"; do echo "$file $variant"; done; done |
  xargs -P "$jobs" -L 1 bash -c 'compile_one "$@"' _)"
count=$((${#files[@]} * ${#variants[@]}))
[ -n "$log" ] && echo "$log"
fails="$(grep -c '^FAIL' <<<"$log")"
for file in "${files[@]}"; do
  grep -qF "FAIL $file (" <<<"$log" || echo "ok   $file"
done
echo "kernels_ptx: $count compilations, $fails failure(s)"
[ "$fails" -eq 0 ]
