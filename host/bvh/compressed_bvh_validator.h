// The compressed nodes' own checks (compressed_bvh_validator.cpp), and their slots decoded as the
// kernels decode them; validate_bvh (bvh_validator.cpp) walks them like the other layouts.
#pragma once

#include "bvh/flat_bvh.h"
#include "bvh/validation_report.h"

#include <cstdint>
#include <cstring>

namespace px::bvh_validation {

// A slot's plane decoded to a float exactly as the kernels decode it.
inline float decode_plane(const CompressedBvh8Node& n, int axis, std::uint8_t q) {
  // The kernels' q * scale + p, scale from the biased exponent's bit pattern (types.h).
  const std::uint32_t bits = std::uint32_t{n.e[axis]} << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return static_cast<float>(q) * scale + n.p[axis];
}

inline unsigned meta_count(std::uint8_t m) { return (m >> PX_CWBVH_META_COUNT_SHIFT) & 7u; }
inline unsigned meta_rank(std::uint8_t m) { return m & PX_CWBVH_RANK_MASK; }

// What the generic walk cannot see in the compressed layout: the encoding itself, and each
// decoded box against the exact box of the Bvh8Node slot it was built from (no tolerance: the
// quantization is exact arithmetic, compressed_bvh.cpp). Together with the wide8 checks
// (exact boxes contain their subtrees), every decoded box contains its subtree.
void validate_compressed(const FlatBvh& bvh, Report& report);

}  // namespace px::bvh_validation
