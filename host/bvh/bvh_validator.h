// validate_bvh(): a flattened tree checked against its scene without trusting the builder
// (bvh_validator.cpp).
#pragma once

#include "bvh/flat_bvh.h"
#include "bvh/triangle_source.h"

#include <cstddef>
#include <string>
#include <vector>

namespace px {

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
