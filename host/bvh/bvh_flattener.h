// The tree of Embree's callbacks flattened into the binary nodes the kernels read, within
// PX_BVH_MAX_DEPTH (bvh_flattener.cpp).
#pragma once

#include "bvh/embree_build_tree.h"
#include "bvh/flat_bvh.h"
#include "bvh/triangle_source.h"

#include <cstdint>
#include <vector>

namespace px::embree_build {

// Flattening, with a depth guarantee.
//
// Embree honours maxDepth by switching to median splits 8 levels above it; if more than
// 2^8 * maxLeafSize primitives are still together there, it fails ("depth limit reached").
// build_bvh then builds again with a generous maxDepth, and the flattener rebuilds any subtree
// that would end below PX_BVH_MAX_DEPTH as a balanced tree over that subtree's leaves (leaves
// are kept whole, so their boxes and sizes stay valid). It rebuilds as deep in the tree as
// possible, so the SAH tree above is untouched.
//
// flatten_tree writes the nodes of the tree under `root` to out.nodes (depth-first, the root
// first) and the leaves' scene triangle indices, in leaf order, to `leaf_prims`. Throws
// std::runtime_error if even balanced subtrees cannot keep the leaves within `max_depth`.
void flatten_tree(const TriangleSource& scene, TempNode* root, FlatBvh& out, std::vector<std::uint32_t>& leaf_prims,
                  int max_depth);

}  // namespace px::embree_build
