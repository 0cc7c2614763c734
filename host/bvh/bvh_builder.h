// build_bvh(): the scene's tree, built with Embree's builder API and flattened into the layout the
// kernels read (bvh_builder.cpp), with its options and statistics.
#pragma once

#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"
#include "bvh/triangle_source.h"

#include <cstddef>
#include <cstdint>
#include <optional>
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
  // At most this many triangles in the trial's sample: past 16 x this (1M triangles) the stride
  // grows beyond 16. The sample's two builds cost in proportion to its size, and a sample of this
  // size decides as every-16th did (the 4M heightfield: 0.1% either way, the trial 210 -> 55 ms;
  // docs/measurements.md, spatial-split trial and "A first run"). 0: no cap.
  std::size_t split_trial_max_sample = 65536;
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

// The most split-callback calls one spatial-split build of `triangles` triangles may make:
// 2^20 + calls_per_triangle * triangles (UINT64_MAX for calls_per_triangle 0, unbounded).
std::uint64_t split_call_budget(std::size_t triangles,
                                std::uint32_t calls_per_triangle = BvhBuildOptions{}.split_calls_per_triangle);

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

// Sets BvhTriangle::flags of every leaf triangle from a per-scene-triangle table
// (PX_TRI_* bits). Throws std::out_of_range if the table is shorter than the scene.
void set_triangle_flags(FlatBvh& bvh, const std::vector<std::uint32_t>& flags_per_scene_triangle);
// The same where the flags follow from the material alone (BvhTriangle::material indexes
// `flags_per_material`). Throws std::out_of_range for a material past the table.
void set_triangle_flags_by_material(FlatBvh& bvh, const std::vector<std::uint32_t>& flags_per_material);

}  // namespace px
