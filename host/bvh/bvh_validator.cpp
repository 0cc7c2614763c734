// validate_bvh(): checks a flattened BVH against its scene without trusting the builder. Used by
// tests after every build and by the CLI before uploading a tree the kernels will walk without
// bounds checks.
#include "bvh/bvh_validator.h"

#include "bvh/compressed_bvh_validator.h"
#include "bvh/validation_report.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <sstream>
#include <thread>

namespace px {

using namespace bvh_validation;

namespace {

struct Box {
  double lo[3];
  double hi[3];
};

struct Vec3d {
  double x, y, z;
  double operator[](int k) const { return k == 0 ? x : (k == 1 ? y : z); }
};
Vec3d operator-(const Vec3d& a, const Vec3d& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3d cross(const Vec3d& a, const Vec3d& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

Vec3d vertex(const BuildTriangle& t, int i) { return {t.p[i].x, t.p[i].y, t.p[i].z}; }

// Float tolerance for "contains" and "overlaps": a few float ulps of the largest magnitude
// involved, so exact builder output passes at any scale and real errors do not.
double tolerance(const Box& box, const BuildTriangle* tri) {
  double scale = 0.0;
  for (int k = 0; k < 3; ++k) scale = std::max({scale, std::abs(box.lo[k]), std::abs(box.hi[k])});
  if (tri)
    for (const auto& p : tri->p)
      scale = std::max({scale, double(std::abs(p.x)), double(std::abs(p.y)), double(std::abs(p.z))});
  return 1e-6 * scale + 1e-30;
}

bool contains(const Box& outer, const Box& inner, double tol) {
  for (int k = 0; k < 3; ++k)
    if (inner.lo[k] < outer.lo[k] - tol || inner.hi[k] > outer.hi[k] + tol) return false;
  return true;
}

bool contains_point(const Box& box, const Vec3d& p, double tol) {
  for (int k = 0; k < 3; ++k)
    if (p[k] < box.lo[k] - tol || p[k] > box.hi[k] + tol) return false;
  return true;
}

Box triangle_box(const BuildTriangle& t) {
  Box b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = std::min({t.p[0][k], t.p[1][k], t.p[2][k]});
    b.hi[k] = std::max({t.p[0][k], t.p[1][k], t.p[2][k]});
  }
  return b;
}

// Triangle/box overlap by the separating axis theorem (Akenine-Möller 2001): the two convex sets
// are disjoint iff their projections are disjoint on one of 13 axes (3 box normals, the triangle
// normal, 9 edge cross products). Deliberately a different method from the builder's polygon
// clipping, so the two check each other. The box is grown by `tol`.
bool triangle_overlaps_box(const BuildTriangle& tri, const Box& box, double tol) {
  const Vec3d center = {0.5 * (box.lo[0] + box.hi[0]), 0.5 * (box.lo[1] + box.hi[1]), 0.5 * (box.lo[2] + box.hi[2])};
  const double half[3] = {0.5 * (box.hi[0] - box.lo[0]) + tol, 0.5 * (box.hi[1] - box.lo[1]) + tol,
                          0.5 * (box.hi[2] - box.lo[2]) + tol};
  const Vec3d v[3] = {vertex(tri, 0) - center, vertex(tri, 1) - center, vertex(tri, 2) - center};
  const Vec3d edge[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};

  auto separated = [&](const Vec3d& axis) {
    const double p0 = dot(axis, v[0]), p1 = dot(axis, v[1]), p2 = dot(axis, v[2]);
    const double r = half[0] * std::abs(axis.x) + half[1] * std::abs(axis.y) + half[2] * std::abs(axis.z);
    // A relative slack keeps rounding of the projections from separating touching sets.
    const double slack = 1e-12 * (std::abs(p0) + std::abs(p1) + std::abs(p2) + r);
    return std::min({p0, p1, p2}) > r + slack || std::max({p0, p1, p2}) < -r - slack;
  };

  const Vec3d unit[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (const Vec3d& axis : unit)
    if (separated(axis)) return false;
  if (separated(cross(edge[0], edge[1]))) return false;
  for (const Vec3d& e : edge)
    for (const Vec3d& u : unit)
      if (separated(cross(u, e))) return false;
  return true;
}

bool has_nan(const float* lo, const float* hi) {
  for (int k = 0; k < 3; ++k)
    if (std::isnan(lo[k]) || std::isnan(hi[k])) return true;
  return false;
}

// Points every triangle must have inside the union of the leaf boxes that reference it:
// vertices, edge midpoints, centroid and three interior points.
constexpr double kSamples[][3] = {{1, 0, 0},
                                  {0, 1, 0},
                                  {0, 0, 1},
                                  {0.5, 0.5, 0},
                                  {0, 0.5, 0.5},
                                  {0.5, 0, 0.5},
                                  {1. / 3, 1. / 3, 1. / 3},
                                  {0.6, 0.2, 0.2},
                                  {0.2, 0.6, 0.2},
                                  {0.2, 0.2, 0.6}};

// One child slot of a node, whatever the layout.
struct ChildSlot {
  const float* lo;  // 3 floats (binary layout) ...
  const float* hi;
  float lo_copy[3], hi_copy[3];  // ... or gathered from the wide layout's rows
  std::uint32_t index, count;
};

struct BinaryNodes {
  static constexpr int kWidth = 2;
  static constexpr bool kNestedBoxes = true;  // child boxes lie inside the box the parent stores
  const std::vector<BvhNode>& nodes;
  const char* name = "";
  std::size_t size() const { return nodes.size(); }
  ChildSlot slot(std::size_t n, int side) const {
    const BvhNode& node = nodes[n];
    ChildSlot c;
    c.lo = side == 0 ? node.lmin : node.rmin;
    c.hi = side == 0 ? node.lmax : node.rmax;
    c.index = side == 0 ? node.left : node.right;
    c.count = side == 0 ? node.left_count : node.right_count;
    return c;
  }
  static const char* side_name(int side) { return side == 0 ? "left" : "right"; }
};

template <int W, typename Node>
struct WideNodes {
  static constexpr int kWidth = W;
  static constexpr bool kNestedBoxes = true;
  const std::vector<Node>& nodes;
  const char* name;
  std::size_t size() const { return nodes.size(); }
  ChildSlot slot(std::size_t n, int i) const {
    const Node& node = nodes[n];
    ChildSlot c;
    c.lo_copy[0] = node.lo_x[i], c.lo_copy[1] = node.lo_y[i], c.lo_copy[2] = node.lo_z[i];
    c.hi_copy[0] = node.hi_x[i], c.hi_copy[1] = node.hi_y[i], c.hi_copy[2] = node.hi_z[i];
    c.lo = c.lo_copy;
    c.hi = c.hi_copy;
    c.index = node.child[i];
    c.count = node.count[i];
    return c;
  }
  static const char* side_name(int side) {
    static const char* names[8] = {"slot 0", "slot 1", "slot 2", "slot 3", "slot 4", "slot 5", "slot 6", "slot 7"};
    return names[side];
  }
};

// The compressed nodes, slots decoded to float boxes exactly as the kernels decode them. Nested
// boxes are not required: a child's grid may be coarser than its parent's, so its decoded boxes
// can stick out of the (also rounded-out) box the parent stores for it by less than a grid step;
// validate_compressed checks each decoded box against the exact Bvh8Node box instead.
struct CompressedNodes {
  static constexpr int kWidth = 8;
  static constexpr bool kNestedBoxes = false;
  const std::vector<CompressedBvh8Node>& nodes;
  const std::vector<std::uint32_t>& leaf_first;
  const char* name;
  std::size_t size() const { return nodes.size(); }
  ChildSlot slot(std::size_t n, int i) const {
    const CompressedBvh8Node& node = nodes[n];
    ChildSlot c;
    c.lo = c.lo_copy;
    c.hi = c.hi_copy;
    const std::uint8_t m = node.meta[i];
    if (m == 0) {  // unused: as the other layouts' absent slots
      for (int k = 0; k < 3; ++k)
        c.lo_copy[k] = std::numeric_limits<float>::max(), c.hi_copy[k] = -std::numeric_limits<float>::max();
      c.index = 0;
      c.count = 0;
      return c;
    }
    const std::uint8_t* qlo[3] = {node.qlo_x, node.qlo_y, node.qlo_z};
    const std::uint8_t* qhi[3] = {node.qhi_x, node.qhi_y, node.qhi_z};
    for (int k = 0; k < 3; ++k) {
      c.lo_copy[k] = decode_plane(node, k, qlo[k][i]);
      c.hi_copy[k] = decode_plane(node, k, qhi[k][i]);
    }
    c.count = meta_count(m);
    if (c.count == 0) {
      c.index = node.child_base + meta_rank(m);
    } else {
      const std::uint64_t leaf = std::uint64_t{node.leaf_base} + meta_rank(m);
      // Out of range: an index past every triangle, which the leaf check reports.
      c.index = leaf < leaf_first.size() ? leaf_first[leaf] : std::numeric_limits<std::uint32_t>::max();
    }
    return c;
  }
  static const char* side_name(int side) { return WideNodes<8, Bvh8Node>::side_name(side); }
};

// Trees of fewer triangle entries are not worth a thread.
constexpr std::size_t kThreadedFrom = 100000;

// Threads for one tree's validation: one per core (at most 8), or 1 below kThreadedFrom entries.
unsigned validation_parts(std::size_t entries) {
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  return entries >= kThreadedFrom ? std::min(cores, 8u) : 1u;
}

// Runs job(0) .. job(count - 1): jobs 1 .. threads - 1 on threads of their own, the rest (job 0
// first) on this one; an exception of any is rethrown once all have finished.
template <typename Job>
void run_jobs(std::size_t count, std::size_t threads, const Job& job) {
  if (count == 0) return;
  std::vector<std::exception_ptr> failures(count);
  const auto run = [&](std::size_t i) {
    try {
      job(i);
    } catch (...) {
      failures[i] = std::current_exception();
    }
  };
  const std::size_t spawned = std::min(count, std::max<std::size_t>(threads, 1)) - 1;
  std::vector<std::thread> pool;
  for (std::size_t i = 1; i <= spawned; ++i) pool.emplace_back(run, i);
  for (std::size_t i = 0; i < count; ++i)
    if (i == 0 || i > spawned) run(i);
  for (std::thread& t : pool) t.join();
  for (const std::exception_ptr& f : failures)
    if (f) std::rethrow_exception(f);
}

// Walks the tree from the root depth first, checking every node and slot, and hands each leaf
// (its box as the parent stores it, first entry, count) to `on_leaf` once its index range is
// known to be in bounds. Returns the nodes reached (node_seen).
template <typename Nodes, typename OnLeaf>
std::vector<std::uint8_t> walk_tree(const Nodes& tree, std::size_t tri_count, Report& report, OnLeaf&& on_leaf) {
  const bool wide = Nodes::kWidth > 2;
  const std::size_t node_count = tree.size();
  std::vector<std::uint8_t> node_seen(node_count, 0);
  struct Entry {
    std::uint32_t node;
    int depth;  // root = 1, as BvhBuildStats::depth counts
    Box box;    // the box the parent stores for this node
    bool has_box;
  };
  std::vector<Entry> stack;
  stack.push_back({0, 1, {}, false});
  while (!stack.empty()) {
    const Entry e = stack.back();
    stack.pop_back();
    if (node_seen[e.node]) {
      report.error(tree.name, "node ", e.node, " is reached more than once (cycle or shared subtree)");
      continue;
    }
    node_seen[e.node] = 1;
    const char* side_name[Nodes::kWidth];
    const float* lo[Nodes::kWidth];
    const float* hi[Nodes::kWidth];
    std::uint32_t index[Nodes::kWidth], count[Nodes::kWidth];
    ChildSlot slots[Nodes::kWidth];
    for (int side = 0; side < Nodes::kWidth; ++side) {
      slots[side] = tree.slot(e.node, side);
      // Wide slots were gathered into the slot's own arrays: point at the stored copy.
      lo[side] = wide ? slots[side].lo_copy : slots[side].lo;
      hi[side] = wide ? slots[side].hi_copy : slots[side].hi;
      index[side] = slots[side].index;
      count[side] = slots[side].count;
      side_name[side] = Nodes::side_name(side);
    }
    int present = 0;

    for (int side = 0; side < Nodes::kWidth; ++side) {
      if (has_nan(lo[side], hi[side])) {
        report.error(tree.name, "node ", e.node, " ", side_name[side], " box has NaN");
        continue;
      }
      if (is_absent_box(lo[side], hi[side])) {
        // Binary: only the root of a one-leaf scene may have an absent child, and only with
        // count 0. Wide: any node may have unused slots, with child 0 and count 0.
        if (wide ? (count[side] != 0 || index[side] != 0) : (e.node != 0 || count[side] != 0))
          report.error(tree.name, "node ", e.node, " ", side_name[side],
                       wide ? " slot is unused (inverted box) but has a child or count"
                            : " child is absent (inverted box); only the root's may be");
        continue;
      }
      ++present;
      Box box;
      for (int k = 0; k < 3; ++k) box.lo[k] = lo[side][k], box.hi[k] = hi[side][k];
      bool inverted = false;
      for (int k = 0; k < 3; ++k) inverted |= box.lo[k] > box.hi[k];
      if (inverted) {
        report.error(tree.name, "node ", e.node, " ", side_name[side], " box is inverted on some axis");
        continue;
      }
      if (Nodes::kNestedBoxes && e.has_box && !contains(e.box, box, tolerance(e.box, nullptr)))
        report.error(tree.name, "node ", e.node, " ", side_name[side],
                     " box is not inside the box its parent stores for it");

      const int child_depth = e.depth + 1;
      if (count[side] > 0) {
        if (child_depth > PX_BVH_MAX_DEPTH)
          report.error(tree.name, "leaf under node ", e.node, " at depth ", child_depth, " exceeds PX_BVH_MAX_DEPTH ",
                       PX_BVH_MAX_DEPTH);
        if (count[side] > PX_BVH_MAX_LEAF_SIZE)
          report.error(tree.name, "leaf under node ", e.node, " holds ", count[side],
                       " triangles, more than PX_BVH_MAX_LEAF_SIZE");
        if (wide && index[side] >= kWideIndexLimit)
          report.error(tree.name, "leaf under node ", e.node, " starts at triangle ", index[side],
                       ", past the wide layout's index limit");
        const std::uint64_t first = index[side];
        if (first + count[side] > tri_count) {
          report.error(tree.name, "leaf under node ", e.node, " references triangles ", first, "..",
                       first + count[side] - 1, " but there are ", tri_count);
          continue;
        }
        on_leaf(box, first, count[side]);
      } else {
        if (index[side] == 0 || index[side] >= node_count) {
          report.error(tree.name, "node ", e.node, " ", side_name[side], " child index ", index[side],
                       index[side] == 0 ? " points at the root" : " is out of range");
          continue;
        }
        stack.push_back({index[side], child_depth, box, true});
      }
    }
    if (present == 0) report.error(tree.name, "node ", e.node, " has no children");
  }
  return node_seen;
}

// The tree against the scene. Memory is what limits this at paper scale (it runs on a tree of
// 10M triangles beside the scene and the tree itself): the first walk keeps per triangle entry
// a leaf count and per scene triangle one byte, its reference count (up to 127) and whether a
// leaf box failed to hold it whole: 2 bytes per triangle. Only scene triangles in several
// leaves (spatial splits) need their leaf boxes side by side; two more walks, run only when
// there are such triangles, count their references exactly and gather those boxes alone.
// (Keeping every leaf box and every (triangle, leaf) pair for a sort took about 50 bytes per
// triangle, twice over when two layouts are checked at once.)
// Where validate_tree reads a triangle's vertices: the scene's triangles (each leaf entry is also
// checked to be a copy of its scene triangle), or, for nodes made after the scene's triangles
// are gone (DeviceScene), the leaf entries themselves, which a validation against the scene has
// found to be such copies.
struct SceneSource {
  const TriangleSource& triangles;
  std::size_t size() const { return triangles.size(); }
  BuildTriangle at(std::uint32_t prim, std::uint64_t /*entry*/) const { return triangles[prim]; }
  template <typename Name>
  void check_entry(const Name& name, std::uint64_t i, const BvhTriangle& t, Report& report) const {
    const BuildTriangle s = triangles[t.prim];
    bool same = t.material == s.material;
    for (int k = 0; k < 3; ++k) same = same && t.v0[k] == s.p[0][k] && t.v1[k] == s.p[1][k] && t.v2[k] == s.p[2][k];
    if (!same)
      report.error(name, "triangle entry ", i, " does not match scene triangle ", t.prim, " (vertices or material)");
  }
};
struct LeafSource {
  const FlatBvh& bvh;
  std::size_t scene_triangles;
  std::size_t size() const { return scene_triangles; }
  BuildTriangle at(std::uint32_t /*prim*/, std::uint64_t entry) const {
    const BvhTriangle& t = bvh.triangles[entry];
    BuildTriangle s{};
    s.p[0] = {t.v0[0], t.v0[1], t.v0[2]};
    s.p[1] = {t.v1[0], t.v1[1], t.v1[2]};
    s.p[2] = {t.v2[0], t.v2[1], t.v2[2]};
    s.material = t.material;
    return s;
  }
  template <typename Name>
  void check_entry(const Name&, std::uint64_t, const BvhTriangle&, Report&) const {}
};

// `parts` threads share the first walk, the costly one: each walks the whole tree (node checks
// are cheap beside a leaf's triangles) and checks the leaf entries of its own range of the
// triangle array, counting the scene triangles' references in one shared byte each (atomic: a
// scene triangle's leaf entries may fall in several parts). One byte array for all parts, not
// one per part: the start's highest point at 4M triangles is this walk, beside the corners, the
// leaf triangles and the nodes. Only part 0 reports what is wrong with the nodes; entry problems
// are merged in part order, so the report does not depend on the threads. (The 10M
// heightfield's binary tree: 0.93 s on one thread.)
template <typename Nodes, typename Source>
void validate_tree(const Nodes& tree, const FlatBvh& bvh, const Source& source, Report& report, unsigned parts = 1) {
  const std::size_t tri_count = bvh.triangles.size();
  std::vector<std::uint8_t> entry_refs(tri_count, 0);  // leaves covering each triangle entry (up to 255)
  // Per scene triangle: kRefMask, its leaf entries (saturating); kOutside, some leaf box does
  // not hold it whole.
  constexpr std::uint8_t kRefMask = 0x7f, kOutside = 0x80;
  const std::size_t scene_count = source.size();
  parts = std::max(1u, std::min<unsigned>(parts, static_cast<unsigned>(std::max<std::size_t>(tri_count, 1))));
  std::vector<std::uint8_t> prim_state(scene_count, 0);
  std::vector<Report> part_reports(parts);
  std::vector<std::uint8_t> node_seen;
  const auto walk_part = [&](std::size_t part) {
    const std::uint64_t lo = tri_count * part / parts, hi = tri_count * (part + 1) / parts;
    Report& entries = part_reports[part];
    Report node_problems;  // part 0's go to `report`; the others' are the same ones again
    Report& nodes = part == 0 ? report : node_problems;
    std::vector<std::uint8_t> seen =
        walk_tree(tree, tri_count, nodes, [&](const Box& box, std::uint64_t first, std::uint32_t count) {
          const std::uint64_t begin = std::max<std::uint64_t>(first, lo),
                              end = std::min<std::uint64_t>(first + count, hi);
          for (std::uint64_t i = begin; i < end; ++i) {
            if (entry_refs[i] < 255) ++entry_refs[i];
            const BvhTriangle& t = bvh.triangles[i];
            if (t.prim >= scene_count) {
              entries.error(tree.name, "triangle entry ", i, " has prim ", t.prim, " but the scene has ", scene_count);
              continue;
            }
            source.check_entry(tree.name, i, t, entries);
            const auto& s = source.at(t.prim, i);
            // Add a reference (saturating at kRefMask) and the outside bit in one exchange.
            const std::uint8_t outside = contains(box, triangle_box(s), tolerance(box, &s)) ? 0 : kOutside;
            std::atomic_ref<std::uint8_t> state(prim_state[t.prim]);
            std::uint8_t old = state.load(std::memory_order_relaxed), next;
            do {
              next = static_cast<std::uint8_t>(((old & kRefMask) < kRefMask ? old + 1 : old) | outside);
            } while (!state.compare_exchange_weak(old, next, std::memory_order_relaxed));
          }
        });
    if (part == 0) node_seen = std::move(seen);
  };
  run_jobs(parts, parts, walk_part);
  for (const Report& r : part_reports) report.merge(r);
  const auto refs = [&](std::size_t p) { return prim_state[p] & kRefMask; };

  const std::size_t node_count = tree.size();
  std::size_t unreached = 0, first_unreached = 0;
  for (std::size_t i = node_count; i-- > 0;)
    if (!node_seen[i]) ++unreached, first_unreached = i;
  if (unreached > 0)
    report.error(tree.name, unreached, " nodes are not reachable from the root (first: ", first_unreached, ")");
  for (std::size_t i = 0; i < tri_count; ++i)
    if (entry_refs[i] != 1)
      report.error(tree.name, "triangle entry ", i, " is in ", int(entry_refs[i]),
                   entry_refs[i] == 255 ? " or more" : "", " leaves (expected 1)");
  std::vector<std::uint8_t>().swap(entry_refs);

  // Scene triangles in several leaves: their leaf boxes, grouped by triangle with a counting
  // sort, in walk order within a triangle. `slot[p]` is where triangle p's boxes start.
  std::vector<std::uint32_t> slot;
  std::vector<Box> split_boxes;
  std::vector<std::uint64_t> split_entries;  // the leaf entry of each box (LeafSource reads its vertices)
  bool any_split = false;
  for (std::size_t p = 0; p < scene_count && !any_split; ++p) any_split = refs(p) > 1;
  if (any_split) {
    Report ignored;  // the first walk reported what is wrong with the tree itself
    // Each split triangle's exact reference count (its byte saturates), then where its boxes go.
    slot.assign(scene_count + 1, 0);
    walk_tree(tree, tri_count, ignored, [&](const Box&, std::uint64_t first, std::uint32_t count) {
      for (std::uint64_t i = first; i < first + count; ++i) {
        const std::uint32_t p = bvh.triangles[i].prim;
        if (p < scene_count && refs(p) > 1) ++slot[p + 1];
      }
    });
    for (std::size_t p = 0; p < scene_count; ++p) slot[p + 1] += slot[p];
    std::vector<std::uint32_t> next(slot.begin(), slot.end() - 1);
    split_boxes.resize(slot.back());
    split_entries.resize(slot.back());
    walk_tree(tree, tri_count, ignored, [&](const Box& box, std::uint64_t first, std::uint32_t count) {
      for (std::uint64_t i = first; i < first + count; ++i) {
        const std::uint32_t p = bvh.triangles[i].prim;
        if (p < scene_count && refs(p) > 1) {
          split_entries[next[p]] = i;
          split_boxes[next[p]++] = box;
        }
      }
    });
  }

  // Per scene triangle: referenced at all; a single leaf box must contain the whole triangle;
  // with several (spatial splits), each must overlap it and together they must cover it.
  for (std::uint32_t prim = 0; prim < scene_count; ++prim) {
    if (refs(prim) == 0) {
      report.error(tree.name, "scene triangle ", prim, " is not referenced by any leaf");
      continue;
    }
    if (refs(prim) == 1) {
      if (prim_state[prim] & kOutside)
        report.error(tree.name, "scene triangle ", prim, " is not inside the box of its leaf");
      continue;
    }
    const std::size_t begin = slot[prim], end = slot[prim + 1];
    const auto& tri = source.at(prim, split_entries[begin]);
    for (std::size_t j = begin; j < end; ++j) {
      const Box& box = split_boxes[j];
      if (!triangle_overlaps_box(tri, box, tolerance(box, &tri)))
        report.error(tree.name, "scene triangle ", prim, " does not overlap the box of a leaf holding it");
    }
    for (const auto& w : kSamples) {
      const Vec3d p = {w[0] * tri.p[0].x + w[1] * tri.p[1].x + w[2] * tri.p[2].x,
                       w[0] * tri.p[0].y + w[1] * tri.p[1].y + w[2] * tri.p[2].y,
                       w[0] * tri.p[0].z + w[1] * tri.p[1].z + w[2] * tri.p[2].z};
      bool covered = false;
      for (std::size_t j = begin; j < end && !covered; ++j) {
        const Box& box = split_boxes[j];
        covered = contains_point(box, p, tolerance(box, &tri));
      }
      if (!covered) {
        report.error(tree.name, "scene triangle ", prim, ": point (", p.x, ", ", p.y, ", ", p.z,
                     ") lies in none of its ", end - begin, " leaf boxes");
        break;
      }
    }
  }
  // References to prims >= triangles.size() were reported above and are counted nowhere.
}

}  // namespace

BvhValidation validate_bvh(const FlatBvh& bvh, const TriangleSource& triangles, bool binary_tree) {
  Report report;
  if (bvh.nodes.empty()) {
    report.error("the BVH has no nodes");
    return report.finish();
  }
  // One job per layout present; they only read the tree, so they run side by side (the 10M
  // heightfield's binary and wide8 trees: 5.2 s one after the other on two cores). Their reports
  // are merged in this order, so the messages do not depend on the threads.
  std::vector<std::function<void(Report&, unsigned)>> jobs;
  const SceneSource source{triangles};
  if (binary_tree)
    jobs.push_back([&](Report& r, unsigned parts) { validate_tree(BinaryNodes{bvh.nodes}, bvh, source, r, parts); });
  if (!bvh.nodes4.empty())
    jobs.push_back([&](Report& r, unsigned parts) {
      validate_tree(WideNodes<4, Bvh4Node>{bvh.nodes4, "wide4 "}, bvh, source, r, parts);
    });
  if (!bvh.nodes8.empty())
    jobs.push_back([&](Report& r, unsigned parts) {
      validate_tree(WideNodes<8, Bvh8Node>{bvh.nodes8, "wide8 "}, bvh, source, r, parts);
    });
  if (!bvh.cnodes.empty())
    jobs.push_back([&](Report& r, unsigned parts) {
      validate_tree(CompressedNodes{bvh.cnodes, bvh.cleaf_first, "cwbvh "}, bvh, source, r, parts);
      validate_compressed(bvh, r);
    });
  // A single layout (the binary tree of a start whose wide nodes come later) is split over the
  // cores itself (validate_tree's parts).
  if (jobs.size() == 1) {
    jobs[0](report, validation_parts(bvh.triangles.size()));
    return report.finish();
  }
  std::vector<Report> reports(jobs.size());
  // Small trees are not worth a thread; large ones get one per job beyond the first, up to the
  // cores. There may be no job (a cached binary tree without wide nodes).
  const std::size_t cores = std::max(1u, std::thread::hardware_concurrency());
  const bool threaded = bvh.triangles.size() >= kThreadedFrom && cores > 1;
  run_jobs(jobs.size(), threaded ? cores : 1, [&](std::size_t i) { jobs[i](reports[i], 1); });
  for (const Report& r : reports) report.merge(r);
  return report.finish();
}

BvhValidation validate_layout_from_leaves(const FlatBvh& bvh, std::size_t scene_triangles) {
  Report report;
  if (bvh.nodes4.empty() && bvh.nodes8.empty() && bvh.cnodes.empty()) {
    report.error("no wide or compressed nodes to validate");
    return report.finish();
  }
  const LeafSource source{bvh, scene_triangles};
  const unsigned parts = validation_parts(bvh.triangles.size());
  if (!bvh.nodes4.empty()) validate_tree(WideNodes<4, Bvh4Node>{bvh.nodes4, "wide4 "}, bvh, source, report, parts);
  if (!bvh.nodes8.empty()) validate_tree(WideNodes<8, Bvh8Node>{bvh.nodes8, "wide8 "}, bvh, source, report, parts);
  if (!bvh.cnodes.empty()) {
    validate_tree(CompressedNodes{bvh.cnodes, bvh.cleaf_first, "cwbvh "}, bvh, source, report, parts);
    validate_compressed(bvh, report);
  }
  return report.finish();
}

}  // namespace px
