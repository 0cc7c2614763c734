// The BVH as the kernels read it: a flat array of 64-byte binary nodes (layout documented in
// kernels/shared/types.h) and the triangles in leaf order, with the same tree's wide and
// compressed nodes when made. Built on the host with Embree's builder API (bvh_builder.h),
// validated (bvh_validator.h), collapsed to the device layouts (bvh_layout.h, wide_bvh.h,
// compressed_bvh.h), then uploaded unchanged to every device.
#pragma once

#include "shared/types.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace px {

struct BvhBuildStats {
  std::size_t scene_triangles = 0;
  std::size_t leaf_triangles = 0;  // > scene_triangles when spatial splits duplicated some
  std::size_t nodes = 0;
  int depth = 0;             // root = depth 1... leaves included as a level below nodes
  double build_ms = 0.0;     // includes collapse_ms
  double collapse_ms = 0.0;  // binary -> wide (and compressed) nodes (0 for the binary layout)
  double sah_cost = 0.0;     // SAH cost of the flattened tree (traversal 1, intersection 1)
  // Spatial splits are bounded in work: a build may call the split callback at most
  // split_call_budget(scene_triangles) times; past that it is redone with binned SAH
  // (split_budget_exceeded), which on overlapping slivers costs a small fraction of what the
  // splits would. split_calls: callback calls of the last spatial-split build attempt (counted
  // in per-thread batches of 256, so it may be short by up to 255 per build thread).
  bool split_budget_exceeded = false;
  std::uint64_t split_calls = 0;
  // Whether the leaves were sized for 4-triangle blocks (BvhBuildOptions::block_leaves_from).
  // Not kept in the BVH caches (a cached tree reports false).
  bool block_leaves = false;
  // The spatial-split trial (BvhBuildOptions::split_trial_triangles), when one ran: the sampled
  // subtrees' relative SAH gain from splits, their triangles, and whether the scene was then built
  // with splits. Not kept in the BVH caches: a cached tree reports split_trial false.
  bool split_trial = false;
  double split_trial_gain = 0.0;
  std::size_t split_trial_sampled = 0;
  bool split_trial_taken = false;
  double split_trial_ms = 0.0;
};

struct FlatBvh {
  std::vector<BvhNode> nodes;          // nodes[0] is the root; never empty for a built BVH
  std::vector<BvhTriangle> triangles;  // leaf order; BvhTriangle::prim indexes the scene
  // The same tree collapsed to wide nodes (empty unless built: collapse_bvh); leaves index
  // `triangles` exactly as the binary leaves do.
  std::vector<Bvh4Node> nodes4;
  std::vector<Bvh8Node> nodes8;
  // nodes8 with quantized boxes (empty unless built: compress_bvh8). Same nodes, same slots;
  // the interior children of a node are contiguous, and its leaves are contiguous entries of
  // cleaf_first (the first triangle of each leaf; the count is in the slot's meta byte).
  std::vector<CompressedBvh8Node> cnodes;
  std::vector<std::uint32_t> cleaf_first;
  BvhBuildStats stats;
};

// Largest triangle or node index + 1 the wide layouts allow (the kernels pack a leaf's first
// triangle and count into one word).
constexpr std::uint32_t kWideIndexLimit = 1u << 29;

// An absent child (a root with a single leaf, an unused wide slot): its box is inverted on
// every axis (types.h: min = +FLT_MAX, max = -FLT_MAX), so no ray ever enters it.
inline bool is_absent_box(const float* lo, const float* hi) { return lo[0] > hi[0] && lo[1] > hi[1] && lo[2] > hi[2]; }
// Slot i of a wide node (Bvh4Node, Bvh8Node), whose planes are stored structure-of-arrays.
template <typename WideNode>
bool is_absent_slot(const WideNode& n, int i) {
  const float lo[3] = {n.lo_x[i], n.lo_y[i], n.lo_z[i]}, hi[3] = {n.hi_x[i], n.hi_y[i], n.hi_z[i]};
  return is_absent_box(lo, hi);
}

// An allocator whose resize() leaves new elements uninitialised: the pages of a large array are
// touched, and counted as resident, only as they are written, not all at once by a zero fill.
template <typename T>
struct UninitializedAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <typename U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
using DeviceWords = std::vector<std::uint32_t, UninitializedAllocator<std::uint32_t>>;

// Leaf triangles as BvhLeafRef records (types.h: no vertices, its leaf block's offset instead),
// made in the memory of the BvhTriangle array they replace; the pages past the records are
// handed back to the system. `memory` owns that block; its first `count` records are the refs.
struct LeafRefs {
  std::vector<BvhTriangle> memory;
  std::size_t count = 0;
  const BvhLeafRef* data() const { return reinterpret_cast<const BvhLeafRef*>(memory.data()); }
  std::size_t bytes() const { return count * sizeof(BvhLeafRef); }
};

}  // namespace px
