// The 8-wide tree with quantized child boxes (types.h: CompressedBvh8Node, "cwbvh";
// compressed_bvh.cpp).
#pragma once

#include "bvh/flat_bvh.h"

#include <cstdint>
#include <vector>

namespace px {

// Fills bvh.cnodes and bvh.cleaf_first from bvh.nodes8 (collapsing first if nodes8 is empty):
// quantized boxes as types.h documents for CompressedBvh8Node (host/bvh/compressed_bvh.cpp).
// Returns the time taken in ms, the collapse included.
double compress_bvh8(FlatBvh& bvh);

// The Compressed8 part of device_wide_nodes (compressed_bvh.cpp).
std::vector<std::uint32_t> device_compressed_nodes(const FlatBvh& bvh);

}  // namespace px
