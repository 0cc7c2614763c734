// The tree as Embree's builder callbacks make it, before it is flattened (bvh_flattener.h), and
// the state a build shares with its callbacks (embree_build_tree.cpp, spatial_splits.cpp). Used
// by build_bvh (bvh_builder.cpp) only.
#pragma once

#include "shared/types.h"

#include <embree3/rtcore.h>  // before rtcore_builder.h, which does not stand alone
#include <embree3/rtcore_builder.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace px::embree_build {

constexpr float kInf = std::numeric_limits<float>::infinity();

// The tree as Embree's callbacks build it. Nodes live in Embree's thread-local allocator (the
// callbacks run concurrently on TBB threads) and die with the RTCBVH, so the tree is flattened
// before rtcReleaseBVH.

struct TempNode {
  bool is_leaf;
};

struct TempInner : TempNode {
  TempNode* child[2];
  RTCBounds bounds[2];
  // Filled by a single-threaded pass after the build, for the depth limit (see Flattener).
  int height;              // levels below this node: 1 when both children are leaves
  std::size_t leaf_count;  // leaves in this subtree
};

struct TempLeaf : TempNode {
  std::uint32_t count;
  std::uint32_t prims[PX_BVH_MAX_LEAF_SIZE];
};

struct BuildContext {
  // Positions only, 36 bytes a triangle instead of SceneTriangle's 100: the split callback
  // fetches a random triangle per call, so a compact array saves cache misses.
  std::vector<std::array<float, 9>> positions;
  std::uint64_t build_id = 0;  // unique per build, keys the split callback's per-thread cache
  // Set by a callback that saw something the flat layout cannot hold; checked after the build
  // (throwing through Embree's C API from a TBB thread is not an option).
  std::atomic<bool> unexpected_arity{false};
  std::atomic<bool> oversized_leaf{false};
  std::atomic<bool> out_of_memory{false};
  // The spatial-split work budget (see split_call_budget): calls of split_primitive so far
  // (counted per thread, added here in batches of kSplitCountBatch, so up to that many per
  // thread are not included) and the limit; once the count passes it the callback cancels the
  // build by throwing.
  std::atomic<std::uint64_t> split_calls{0};
  std::uint64_t split_budget = 0;
  std::atomic<bool> over_budget{false};
};

// An empty box (inverted on every axis, so that extending it by any point gives that point).
inline void set_empty(RTCBounds* bounds) {
  bounds->lower_x = bounds->lower_y = bounds->lower_z = kInf;
  bounds->upper_x = bounds->upper_y = bounds->upper_z = -kInf;
}

// rtcBuildBVH's callbacks (RTCBuildArguments createNode, setNodeChildren, setNodeBounds,
// createLeaf); `user` is the build's BuildContext. A node or leaf the allocator cannot hold, a
// node that is not binary or a leaf over PX_BVH_MAX_LEAF_SIZE sets the context's flag instead of
// throwing (the callbacks run on TBB threads, under Embree's C API).
void* create_node(RTCThreadLocalAllocator allocator, unsigned int child_count, void* user);
void set_node_children(void* node_ptr, void** children, unsigned int child_count, void*);
void set_node_bounds(void* node_ptr, const RTCBounds** bounds, unsigned int child_count, void*);
void* create_leaf(RTCThreadLocalAllocator allocator, const RTCBuildPrimitive* primitives, size_t primitive_count,
                  void* user);

}  // namespace px::embree_build
