// Refitting: an animated scene's triangles move every frame but keep their count and order, so
// last frame's tree still holds the right triangles in the right leaves; only the boxes are
// stale. Recomputing them bottom-up costs one pass over triangles and nodes, against a full
// SAH build (bench/bench_animation: 1.2M triangles, about 30x less). The tree's quality decays
// as the pose departs from the one it was built for, which the SAH cost measures.

#include "bvh/bvh_builder.h"  // compute_bvh_stats
#include "bvh/bvh_refit.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <string>

namespace px {
namespace {

struct Box {
  float lo[3], hi[3];
};

constexpr float kMax = std::numeric_limits<float>::max();

void set_empty(Box& b) {
  for (int k = 0; k < 3; ++k) b.lo[k] = kMax, b.hi[k] = -kMax;
}

void grow(Box& b, const float* p) {
  for (int k = 0; k < 3; ++k) b.lo[k] = std::min(b.lo[k], p[k]), b.hi[k] = std::max(b.hi[k], p[k]);
}

void grow(Box& b, const float* lo, const float* hi) {
  for (int k = 0; k < 3; ++k) b.lo[k] = std::min(b.lo[k], lo[k]), b.hi[k] = std::max(b.hi[k], hi[k]);
}

void store(const Box& b, float* lo, float* hi) {
  for (int k = 0; k < 3; ++k) lo[k] = b.lo[k], hi[k] = b.hi[k];
}

}  // namespace

double refit_bvh(FlatBvh& bvh, const std::vector<SceneTriangle>& triangles) {
  const auto t0 = std::chrono::steady_clock::now();
  if (bvh.nodes.empty()) throw std::invalid_argument("refit_bvh: the tree is empty");
  if (bvh.triangles.size() != triangles.size())
    throw std::invalid_argument("refit_bvh: the tree holds " + std::to_string(bvh.triangles.size()) +
                                " leaf triangles for " + std::to_string(triangles.size()) +
                                " scene triangles (built with spatial splits?)");
  for (BvhTriangle& t : bvh.triangles) {
    const SceneTriangle& s = triangles.at(t.prim);
    for (int k = 0; k < 3; ++k) {
      t.v0[k] = s.p[0][k];
      t.v1[k] = s.p[1][k];
      t.v2[k] = s.p[2][k];
    }
  }
  // The flattener writes every node before its children (a child's index is larger than its
  // parent's), so a reverse sweep sees each node's children finished before the node.
  for (std::size_t n = bvh.nodes.size(); n-- > 0;) {
    BvhNode& node = bvh.nodes[n];
    const std::uint32_t child[2] = {node.left, node.right};
    const std::uint32_t count[2] = {node.left_count, node.right_count};
    float* lo[2] = {node.lmin, node.rmin};
    float* hi[2] = {node.lmax, node.rmax};
    for (int side = 0; side < 2; ++side) {
      if (count[side] == 0 && child[side] == 0) continue;  // absent: stays inverted
      Box b;
      set_empty(b);
      if (count[side] > 0) {
        if (std::size_t(child[side]) + count[side] > bvh.triangles.size())
          throw std::invalid_argument("refit_bvh: a leaf reaches past the triangles");
        for (std::uint32_t i = child[side]; i < child[side] + count[side]; ++i) {
          const BvhTriangle& t = bvh.triangles[i];
          grow(b, t.v0);
          grow(b, t.v1);
          grow(b, t.v2);
        }
      } else {
        if (child[side] <= n || child[side] >= bvh.nodes.size())
          throw std::invalid_argument("refit_bvh: node " + std::to_string(n) + " has a child before it");
        const BvhNode& c = bvh.nodes[child[side]];
        const bool left_absent = c.left_count == 0 && c.left == 0, right_absent = c.right_count == 0 && c.right == 0;
        if (!left_absent) grow(b, c.lmin, c.lmax);
        if (!right_absent) grow(b, c.rmin, c.rmax);
      }
      store(b, lo[side], hi[side]);
    }
  }
  bvh.nodes4.clear();
  bvh.nodes8.clear();
  bvh.cnodes.clear();
  bvh.cleaf_first.clear();
  compute_bvh_stats(bvh);
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace px
