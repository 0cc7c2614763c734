// BvhLayout: which node layout the kernels traverse, and each device set's default
// (bvh_layout.cpp).
#pragma once

#include "shared/types.h"

#include <string>

namespace px {

// The node layout the kernels traverse: the binary nodes, or the same tree collapsed into
// 4- or 8-wide nodes (types.h: Bvh4Node, Bvh8Node), or the 8-wide tree with quantized child
// boxes (types.h: CompressedBvh8Node, "cwbvh"). Every kernel build of a device set must agree
// with the nodes uploaded to it: DeviceSet::bvh_layout() names the set's layout, its programs
// are built with the matching -DPX_BVH_WIDTH, and DeviceScene uploads the matching array.
// A layout may be asked for with the set (DeviceOptions::bvh_layout, `--bvh-layout`); else the
// set takes its device type's default (bvh_layout_for).
// The values are the kernels' PX_BVH_WIDTH (9 = PX_BVH_COMPRESSED8, 8 children per node).
enum class BvhLayout { Binary = 2, Wide4 = 4, Wide8 = 8, Compressed8 = PX_BVH_COMPRESSED8 };
// The default layout of a device set, by device type (a set asked for a layout takes that one).
//  - CPUs (and sets that mix device kinds): Wide8: 8 boxes per float8 test in one work-item, close
//    to Embree's single-ray speed on PoCL; cwbvh's decode costs time there (docs/measurements.md,
//    BVH layouts).
//  - Sets of GPUs only: Binary, the fastest layout on an NVIDIA H200 for primary and diffuse rays
//    and the whole stereo frame (same topic). A GPU work-item walks one node of two boxes at a
//    time; the wide layouts' loops over 8 children and their private stacks cost it occupancy.
// A CPU set's default, bvh_layout_for(false), is what the host collapses a freshly built tree
// into ahead of time unless told otherwise (build_bvh, load_and_build); a set in another layout
// has its DeviceScene make its own nodes.
BvhLayout bvh_layout_for(bool all_gpus);
// The value of PX_BVH_WIDTH the kernels are built with for `layout` (not always the number of
// children: Compressed8 is 9, PX_BVH_COMPRESSED8).
inline int bvh_layout_width(BvhLayout layout) { return static_cast<int>(layout); }
const char* to_string(BvhLayout layout);
BvhLayout parse_bvh_layout(const std::string& name);  // throws std::invalid_argument

}  // namespace px
