// The BVH as the kernels read it: a flat array of 64-byte binary nodes (layout documented in
// kernels/shared/types.h) and the triangles in leaf order. Built on the host with Embree's
// builder API, validated, then uploaded unchanged to every device.
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <string>
#include <vector>

namespace px {

struct BvhBuildOptions {
  // Spatial splits (Embree RTC_BUILD_QUALITY_HIGH with a splitPrimitive callback and spare
  // primitive capacity). Off: binned SAH only.
  bool spatial_splits = true;
  int max_leaf_size = PX_BVH_MAX_LEAF_SIZE;  // <= PX_BVH_MAX_LEAF_SIZE
};

struct BvhBuildStats {
  std::size_t scene_triangles = 0;
  std::size_t leaf_triangles = 0;  // > scene_triangles when spatial splits duplicated some
  std::size_t nodes = 0;
  int depth = 0;                   // root = depth 1... leaves included as a level below nodes
  double build_ms = 0.0;
  double sah_cost = 0.0;           // SAH cost of the flattened tree (traversal 1, intersection 1)
};

struct FlatBvh {
  std::vector<BvhNode> nodes;          // nodes[0] is the root; never empty for a built BVH
  std::vector<BvhTriangle> triangles;  // leaf order; BvhTriangle::prim indexes the scene
  BvhBuildStats stats;
};

// Builds with Embree's rtcBuildBVH (SAH, maxBranchingFactor 2, maxDepth PX_BVH_MAX_DEPTH) and
// flattens the result. Throws std::runtime_error on an empty input or an Embree error.
FlatBvh build_bvh(const std::vector<SceneTriangle>& triangles, const BvhBuildOptions& options = {});

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
BvhValidation validate_bvh(const FlatBvh& bvh, const std::vector<SceneTriangle>& triangles);

}  // namespace px
