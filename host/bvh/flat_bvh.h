// The BVH as the kernels read it: a flat array of 64-byte binary nodes (layout documented in
// kernels/shared/types.h) and the triangles in leaf order. Built on the host with Embree's
// builder API, validated, then uploaded unchanged to every device.
#pragma once

#include "bvh/triangle_source.h"
#include "scene/scene.h"
#include "shared/types.h"

#include <cstdint>
#include <memory>
#include <type_traits>
#include <utility>
#include <optional>
#include <string>
#include <vector>

namespace px {

struct BvhBuildOptions {
  // Spatial splits (Embree RTC_BUILD_QUALITY_HIGH with a splitPrimitive callback and spare
  // primitive capacity). Off: binned SAH only.
  bool spatial_splits = true;
  int max_leaf_size = PX_BVH_MAX_LEAF_SIZE;  // <= PX_BVH_MAX_LEAF_SIZE
  // Work bound for spatial splits, in split-callback calls per triangle (see
  // split_call_budget); past it the build is redone with binned SAH. 0: unbounded (only for
  // measuring what the bound saves on overlapping slivers: docs/measurements.md, split budget).
  std::uint32_t split_calls_per_triangle = 96;
  // Spatial splits on trial for large scenes. For a scene of at least split_trial_triangles
  // triangles, every 16th triangle (or sparser: split_trial_max_sample) is first built both ways,
  // and the scene is built with splits only if they lowered that sample's SAH cost by at least
  // split_min_gain (and kept within their work rate), else with binned SAH: on a heightfield the
  // splits cost several binned builds and gain nothing, on atrium they gain, and the sample
  // predicts both (docs/measurements.md, spatial-split trial). From 200k triangles: with a
  // higher threshold, smaller heightfields started slower than larger ones (same topic).
  // 0: no trial, spatial_splits as asked.
  std::size_t split_trial_triangles = 200000;
  double split_min_gain = 0.02;
  // At most this many triangles in the trial's sample: past 16 x this (4.2M triangles) the
  // stride grows beyond 16. The sample's two builds cost in proportion to its size, and a sample
  // of this size already decides as every-16th did (docs/measurements.md, spatial-split trial).
  // 0: no cap.
  std::size_t split_trial_max_sample = 262144;
  // Scenes of at least this many triangles get leaves sized for the wide layouts' leaf blocks
  // (BvhLeafBlock: 4 triangles tested at once): the SAH counts a leaf's intersection cost per
  // started block of 4 triangles, not per triangle (Embree's sahBlockSize), so leaves fill up to
  // 4: a large scene then has about half the nodes and leaf blocks, and a smaller device layout
  // (docs/measurements.md, block leaves).
  // Smaller scenes keep per-triangle leaves: their trees, and so their images, stay as they
  // were (a tree changes which of two hits at exactly the same distance a ray takes, e.g. on
  // coplanar faces). 0: never.
  std::size_t block_leaves_from = 1000000;
  // Whether a scene of `triangles` triangles gets such leaves.
  bool block_leaves(std::size_t triangles) const { return block_leaves_from > 0 && triangles >= block_leaves_from; }
};

struct BvhBuildStats {
  std::size_t scene_triangles = 0;
  std::size_t leaf_triangles = 0;  // > scene_triangles when spatial splits duplicated some
  std::size_t nodes = 0;
  int depth = 0;                   // root = depth 1... leaves included as a level below nodes
  double build_ms = 0.0;           // includes collapse_ms
  double collapse_ms = 0.0;        // binary -> wide (and compressed) nodes (0 for the binary layout)
  double sah_cost = 0.0;           // SAH cost of the flattened tree (traversal 1, intersection 1)
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

// The most split-callback calls one spatial-split build of `triangles` triangles may make:
// 2^20 + calls_per_triangle * triangles (UINT64_MAX for calls_per_triangle 0, unbounded).
std::uint64_t split_call_budget(std::size_t triangles,
                                std::uint32_t calls_per_triangle = BvhBuildOptions{}.split_calls_per_triangle);

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

// Fills bvh.nodes4 (width 4) or bvh.nodes8 (width 8) from the binary nodes: every wide node is
// a binary node whose children are replaced, largest surface area first, by their own
// children until it has `width` of them or only leaves. Returns the time taken in ms.
double collapse_bvh(FlatBvh& bvh, int width);

// Fills bvh.cnodes and bvh.cleaf_first from bvh.nodes8 (collapsing first if nodes8 is empty):
// quantized boxes as types.h documents for CompressedBvh8Node (host/bvh/compressed_bvh.cpp).
// Returns the time taken in ms, the collapse included.
double compress_bvh8(FlatBvh& bvh);

// An absent child (a root with a single leaf, an unused wide slot): its box is inverted on
// every axis (types.h: min = +FLT_MAX, max = -FLT_MAX), so no ray ever enters it.
inline bool is_absent_box(const float* lo, const float* hi) {
  return lo[0] > hi[0] && lo[1] > hi[1] && lo[2] > hi[2];
}
// Slot i of a wide node (Bvh4Node, Bvh8Node), whose planes are stored structure-of-arrays.
template <typename WideNode>
bool is_absent_slot(const WideNode& n, int i) {
  const float lo[3] = {n.lo_x[i], n.lo_y[i], n.lo_z[i]}, hi[3] = {n.hi_x[i], n.hi_y[i], n.hi_z[i]};
  return is_absent_box(lo, hi);
}

// The node buffer the kernels read for a wide layout (Wide4, Wide8, Compressed8): the wide
// nodes followed by one BvhLeafBlock per leaf (types.h), leaf slots pointing at their blocks
// (Wide4 / Wide8: the blocks in leaf order, that of their first triangle).
// Reads the triangles' flags, so call it after set_triangle_flags. Throws if the wide nodes are
// absent.
std::vector<std::uint32_t> device_wide_nodes(const FlatBvh& bvh, BvhLayout layout);
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
// device_wide_nodes for Wide4 and Wide8, the same words, made from nodes it frees on the way:
// the leaf blocks first, then the nodes (every word written once, none zero-filled first), each
// node's pages handed back once copied. At 10M triangles the nodes and the words are then never
// held whole side by side. With `refs`, the leaf triangles are moved out of `bvh` and become
// BvhLeafRef records as their blocks are written (kernels built with PX_LEAF_REFS read those).
// Throws std::invalid_argument for another layout or absent nodes.
DeviceWords device_wide_nodes_from(FlatBvh& bvh, BvhLayout layout, LeafRefs* refs = nullptr);
// The leaf block (types.h: BvhLeafBlock) of the `count` triangles from `first`; throws if they
// are out of range or count is not 1..4.
BvhLeafBlock leaf_block(const std::vector<BvhTriangle>& tris, std::uint32_t first, std::uint32_t count);
// The Compressed8 part of device_wide_nodes (compressed_bvh.cpp).
std::vector<std::uint32_t> device_compressed_nodes(const FlatBvh& bvh);

// Whether `bvh` carries the nodes of `layout` (the binary nodes always).
bool has_layout(const FlatBvh& bvh, BvhLayout layout);
// Makes sure `bvh` carries the nodes of `layout` (collapsing / compressing if needed). Returns
// the time that took in ms (0 when they were there).
double ensure_layout(FlatBvh& bvh, BvhLayout layout);

// Builds with Embree's rtcBuildBVH (SAH, maxBranchingFactor 2, maxDepth PX_BVH_MAX_DEPTH) and
// flattens the result. Throws std::runtime_error on an empty input or an Embree error.
// The tree carries the nodes of `layout` as well (collapsed: wide, compressed); nullopt: the
// binary nodes alone (a caller that makes the others later, once the scene's triangles are
// gone: DeviceScene).
FlatBvh build_bvh(const TriangleSource& triangles, const BvhBuildOptions& options = {},
                  std::optional<BvhLayout> layout = bvh_layout_for(/*all_gpus=*/false));

// Fills bvh.stats' node and leaf counts, depth and SAH cost from the binary nodes (the builder
// calls it; so does refit_bvh).
void compute_bvh_stats(FlatBvh& bvh);

// Refits `bvh` to `triangles` moved since it was built (same triangles, same order: an animated
// scene posed anew): the leaf triangles take their new vertices, every binary node's child
// boxes are recomputed bottom-up, the wide nodes are dropped (ensure_layout collapses them
// again) and the stats recomputed (a refit tree's SAH cost grows as the pose departs from the
// one it was built for: the caller rebuilds when it has grown too much). The tree must hold
// every scene triangle once (built without spatial splits, whose leaves hold clipped parts):
// throws std::invalid_argument otherwise. Returns the time taken in ms.
double refit_bvh(FlatBvh& bvh, const std::vector<SceneTriangle>& triangles);

// Sets BvhTriangle::flags of every leaf triangle from a per-scene-triangle table
// (PX_TRI_* bits). Throws std::out_of_range if the table is shorter than the scene.
void set_triangle_flags(FlatBvh& bvh, const std::vector<std::uint32_t>& flags_per_scene_triangle);

struct BvhValidation {
  bool ok = true;
  std::vector<std::string> errors;  // first few problems, human readable
};

// Checks the flattened tree against the scene: every scene triangle is referenced by at least
// one leaf; every child box contains its subtree (child boxes inside the parent's box, leaf
// boxes contain their triangles' clipped extent — for spatial splits, the triangle's overlap
// with the box must be non-empty); indices in range; depth <= PX_BVH_MAX_DEPTH; no node reached
// twice; leaf sizes <= PX_BVH_MAX_LEAF_SIZE.
// Wide nodes present (nodes4 / nodes8) are checked the same way: every triangle entry in
// exactly one leaf, child boxes inside the box the parent stores, depth, unused slots absent.
// Compressed nodes present (cnodes) likewise, on their decoded boxes, and besides: the encoding
// (meta / imask agree, exponents in range, every decoded plane an exact float), indices in
// range, and slot by slot against nodes8 (which they must have been built from): the same
// children, each decoded box containing the exact Bvh8Node box with no tolerance.
// `binary_tree` false leaves the binary nodes out (the wide and compressed ones, which are
// derived from them, are still checked): for a tree read back from the BVH cache, whose binary
// nodes were validated before they were written and are protected by the file's checksum.
BvhValidation validate_bvh(const FlatBvh& bvh, const TriangleSource& triangles, bool binary_tree = true);
// The wide and compressed nodes present (nodes4, nodes8, cnodes) checked as validate_bvh checks
// them, with each leaf entry's own vertices standing for its scene triangle's (of
// `scene_triangles`): for nodes made after the scene's triangles are gone (DeviceScene), from a
// tree whose leaf entries validate_bvh found to be copies of the scene's triangles.
BvhValidation validate_layout_from_leaves(const FlatBvh& bvh, std::size_t scene_triangles);

}  // namespace px
