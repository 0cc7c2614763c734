// build_bvh(): Embree's rtcBuildBVH (binned SAH, optionally with spatial splits) builds a
// binary tree through our callbacks; we then flatten it into the 64-byte node layout the kernels
// read (kernels/shared/types.h).
#include "bvh/bvh_builder.h"

#include "bvh/bvh_flattener.h"
#include "bvh/embree_build_tree.h"
#include "bvh/embree_reference.h"  // embree_device(), take_embree_error()
#include "bvh/spatial_splits.h"
#include "bvh/wide_bvh.h"  // ensure_layout
#include "io/free_heap.h"
#include "util/parallel_parts.h"

#include <embree3/rtcore_builder.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <new>
#include <stdexcept>
#include <malloc.h>
#include <string>
#include <vector>

namespace px {

using namespace embree_build;

namespace {

// Builds from this many triangles hand the allocator's free memory back (malloc_trim) after
// Embree's tree is released.
constexpr std::size_t kTrimFrom = 1000000;

std::atomic<std::uint64_t> g_next_build_id{1};  // BuildContext::build_id

// The spatial-split work budget. Embree's spatial binning calls split_primitive for every
// primitive at every bin plane its box crosses (up to 15 planes on each of 3 axes), at every node
// where the best object split leaves overlapping children, whether or not a spatial split is
// then taken. On ordinary scenes that is ~70 calls per triangle (atrium: 38M calls for 551k
// triangles). On overlapping slivers every node overlaps and every sliver crosses
// most planes: ~530 calls per triangle, 54M for 101k triangles, 12 s against 1.7 s for Embree's
// own spatial-split build of the same triangles, while the splits gain ~10% SAH. So a build may
// spend at most BvhBuildOptions::split_calls_per_triangle (default 96, ~1.4x atrium's need)
// calls per triangle plus a floor for small scenes; past it the build is cancelled and redone
// with binned SAH, which costs a fraction of what Embree's own spatial-split build does.
constexpr std::uint64_t kSplitCallsFloor = std::uint64_t{1} << 20;

double half_area(const float lo[3], const float hi[3]) {
  const double dx = double(hi[0]) - lo[0], dy = double(hi[1]) - lo[1], dz = double(hi[2]) - lo[2];
  if (dx < 0.0 || dy < 0.0 || dz < 0.0) return 0.0;  // absent child
  return dx * dy + dy * dz + dz * dx;
}

}  // namespace

// Depth and SAH cost of the flattened tree (traversal cost 1 per node visit, intersection
// cost 1 per triangle), measured on what the kernels will actually traverse.
void compute_bvh_stats(FlatBvh& bvh) {
  BvhBuildStats& s = bvh.stats;
  s.nodes = bvh.nodes.size();
  s.leaf_triangles = bvh.triangles.size();
  const BvhNode& root = bvh.nodes[0];
  float rlo[3], rhi[3];
  for (int k = 0; k < 3; ++k) {
    rlo[k] = root.lmin[k], rhi[k] = root.lmax[k];
    if (root.rmin[k] <= root.rmax[k]) {
      rlo[k] = std::min(rlo[k], root.rmin[k]);
      rhi[k] = std::max(rhi[k], root.rmax[k]);
    }
  }
  const double root_area = half_area(rlo, rhi);
  // A scene flat along two axes has zero area everywhere; count every box as always hit.
  auto ratio = [root_area](double area) { return root_area > 0.0 ? area / root_area : 1.0; };

  double cost = 1.0;  // the root is always visited
  int depth = 0;
  struct Entry {
    std::uint32_t node;
    int depth;
  };
  std::vector<Entry> stack{{0, 1}};
  while (!stack.empty()) {
    const Entry e = stack.back();
    stack.pop_back();
    const BvhNode& n = bvh.nodes[e.node];
    const std::uint32_t child[2] = {n.left, n.right};
    const std::uint32_t count[2] = {n.left_count, n.right_count};
    const float* lo[2] = {n.lmin, n.rmin};
    const float* hi[2] = {n.lmax, n.rmax};
    for (int side = 0; side < 2; ++side) {
      if (lo[side][0] > hi[side][0]) continue;  // absent
      const double area = ratio(half_area(lo[side], hi[side]));
      if (count[side] > 0) {
        cost += area * count[side];
        depth = std::max(depth, e.depth + 1);
      } else {
        cost += area;
        stack.push_back({child[side], e.depth + 1});
      }
    }
  }
  s.depth = depth;
  s.sah_cost = cost;
}

namespace {

// A large scene's passes over every triangle (the build primitives, the leaf triangles: random
// reads of the scene's corners, 0.1-0.2 s each at 4M on one core) run on every core from here.
constexpr std::size_t kPartsFrom = std::size_t{1} << 18;

// The BvhTriangles of the scene triangles `leaf_prims`, in that (leaf) order.
std::vector<BvhTriangle> leaf_triangles(const TriangleSource& triangles, const std::vector<std::uint32_t>& leaf_prims) {
  const std::size_t n = leaf_prims.size();
  const unsigned parts = parallel_parts(n, kPartsFrom);
  std::vector<BvhTriangle> out;
  resize_in_parts(out, n, parts);
  run_parts(parts, [&](unsigned part) {
    const PartRange r = part_range(n, part, parts);
    for (std::size_t i = r.begin; i < r.end; ++i) {
      const std::uint32_t prim = leaf_prims[i];
      const glm::vec3* p = triangles.p(prim);
      BvhTriangle& t = out[i];
      for (int k = 0; k < 3; ++k) {
        t.v0[k] = p[0][k];
        t.v1[k] = p[1][k];
        t.v2[k] = p[2][k];
      }
      t.prim = prim;
      t.flags = 0;  // filled from materials by set_triangle_flags()
      t.material = triangles.material(prim);
    }
  });
  return out;
}

// One rtcBuildBVH run. Returns false if Embree failed (message in `error`) or, with spatial
// splits, if the split budget ran out (`over_budget` set); throws for failures a retry cannot
// fix.
bool build_once(const TriangleSource& triangles, const BvhBuildOptions& options, unsigned int sah_block,
                unsigned int max_depth, FlatBvh& out, std::string& error, bool& over_budget) {
  over_budget = false;
  RTCDevice device = embree_device();
  take_embree_error();
  rtcGetDeviceError(device);

  const std::size_t count = triangles.size();
  // Spatial splits write the extra fragments behind the input in this same array, so it must
  // be allocated at full capacity. Embree falls back to plain binned SAH when the capacity is
  // not larger than the count.
  const std::size_t capacity = options.spatial_splits ? 2 * count : count;
  // Uninitialised: the parts below write every element in use (a value-initialised vector
  // cleared all 32 bytes a triangle on one thread first), and the spare capacity spatial splits
  // write into is Embree's to fill.
  std::vector<RTCBuildPrimitive, UninitializedAllocator<RTCBuildPrimitive>> primitives;
  const unsigned parts = parallel_parts(count, kPartsFrom);
  resize_in_parts(primitives, capacity, parts, /*touched=*/count);
  run_parts(parts, [&](unsigned part) {
    const PartRange r = part_range(count, part, parts);
    for (std::size_t i = r.begin; i < r.end; ++i) {
      const glm::vec3* t = triangles.p(i);
      RTCBuildPrimitive& p = primitives[i];
      p.lower_x = std::min({t[0].x, t[1].x, t[2].x});
      p.lower_y = std::min({t[0].y, t[1].y, t[2].y});
      p.lower_z = std::min({t[0].z, t[1].z, t[2].z});
      p.upper_x = std::max({t[0].x, t[1].x, t[2].x});
      p.upper_y = std::max({t[0].y, t[1].y, t[2].y});
      p.upper_z = std::max({t[0].z, t[1].z, t[2].z});
      p.geomID = 0;  // Embree keeps per-primitive split budgets in geomID's top bits
      p.primID = static_cast<unsigned int>(i);
    }
  });

  BuildContext context;
  context.build_id = g_next_build_id.fetch_add(1);
  context.split_budget = split_call_budget(count, options.split_calls_per_triangle);
  if (options.spatial_splits) {
    context.positions.resize(count);
    for (std::size_t i = 0; i < count; ++i)
      for (int v = 0; v < 3; ++v)
        for (int k = 0; k < 3; ++k) context.positions[i][3 * v + k] = triangles.p(i)[v][k];
  }

  RTCBVH bvh = rtcNewBVH(device);
  if (!bvh) {
    error = take_embree_error();
    throw std::runtime_error("Embree: rtcNewBVH failed: " + error);
  }

  RTCBuildArguments args = rtcDefaultBuildArguments();
  args.buildQuality = options.spatial_splits ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM;
  args.buildFlags = RTC_BUILD_FLAG_NONE;
  args.maxBranchingFactor = 2;
  args.maxDepth = max_depth;
  args.sahBlockSize = sah_block;
  args.minLeafSize = 1;
  args.maxLeafSize = static_cast<unsigned int>(options.max_leaf_size);
  // The same unit costs as BvhBuildStats::sah_cost, so the builder minimises what we report.
  args.traversalCost = 1.0f;
  args.intersectionCost = 1.0f;
  args.bvh = bvh;
  args.primitives = primitives.data();
  args.primitiveCount = count;
  args.primitiveArrayCapacity = capacity;
  args.createNode = create_node;
  args.setNodeChildren = set_node_children;
  args.setNodeBounds = set_node_bounds;
  args.createLeaf = create_leaf;
  args.splitPrimitive = options.spatial_splits ? split_primitive : nullptr;
  args.buildProgress = nullptr;
  args.userPtr = &context;

  void* root = rtcBuildBVH(&args);
  // The tree's leaves hold their triangle indices: the primitives (32 bytes a triangle, twice
  // that with splits) are not read again, and go before the flat copy is made beside the tree.
  decltype(primitives)().swap(primitives);
  std::vector<std::array<float, 9>>().swap(context.positions);
  error = take_embree_error();
  if (options.spatial_splits) out.stats.split_calls = context.split_calls.load();
  if (context.over_budget) {
    over_budget = true;
    rtcReleaseBVH(bvh);
    return false;
  }
  const RTCError code = rtcGetDeviceError(device);
  if (error.empty() && code != RTC_ERROR_NONE) error = "RTCError " + std::to_string(int(code));
  if (error.empty() && !root) error = "rtcBuildBVH returned no root";
  if (!error.empty()) {
    rtcReleaseBVH(bvh);
    return false;
  }

  std::vector<std::uint32_t> leaf_prims;  // the leaves' scene triangles, in leaf order
  try {
    if (context.out_of_memory) throw std::runtime_error("BVH: Embree allocator out of memory");
    if (context.unexpected_arity) throw std::runtime_error("BVH: Embree produced a node without exactly two children");
    if (context.oversized_leaf)
      throw std::runtime_error("BVH: Embree produced a leaf larger than PX_BVH_MAX_LEAF_SIZE");
    out.nodes.clear();
    out.triangles.clear();
    out.nodes.reserve(count);  // about count / 2 nodes for leaves of ~2 triangles
    leaf_prims.reserve(count);
    flatten_tree(triangles, static_cast<TempNode*>(root), out, leaf_prims, PX_BVH_MAX_DEPTH);
  } catch (...) {
    rtcReleaseBVH(bvh);
    throw;
  }
  rtcReleaseBVH(bvh);  // node memory goes with it; the flat copy is complete
  // Embree's build leaves freed blocks in the allocator's arenas (under glibc's mmap threshold,
  // which grows as large blocks are freed): handed back before the leaf triangles are made, the
  // start's peak (the 10M heightfield: at this point) is about 30 MiB lower.
  if (count >= kTrimFrom) malloc_trim(0);
  // The leaf triangles (48 bytes each) only now, after Embree's tree (about 35 bytes a triangle)
  // is gone: the two are never held side by side.
  out.triangles = leaf_triangles(triangles, leaf_prims);
  return true;
}

}  // namespace

std::uint64_t split_call_budget(std::size_t triangles, std::uint32_t calls_per_triangle) {
  if (calls_per_triangle == 0) return std::numeric_limits<std::uint64_t>::max();
  return kSplitCallsFloor + std::uint64_t{calls_per_triangle} * triangles;
}

namespace {

// One tree over `triangles` with `options`, whatever it takes: spatial splits past their work
// budget are redone with binned SAH, and a build that hits Embree's depth limit is redone with a
// relaxed one (the flattener restores the limit). Leaves the stats to the caller.
void build_tree(const TriangleSource& triangles, const BvhBuildOptions& options, unsigned int sah_block, FlatBvh& bvh) {
  BvhBuildOptions used = options;
  std::string first_error;
  bool over_budget = false;
  bool built = build_once(triangles, used, sah_block, PX_BVH_MAX_DEPTH, bvh, first_error, over_budget);
  if (!built && over_budget) {
    // Spatial splits would cost far more than they gain here (see split_call_budget).
    bvh.stats.split_budget_exceeded = true;
    used.spatial_splits = false;
    built = build_once(triangles, used, sah_block, PX_BVH_MAX_DEPTH, bvh, first_error, over_budget);
  }
  if (!built) {
    // Almost always "depth limit reached": more primitives than median splits can separate in
    // the last levels. Build without the tight limit; the flattener restores it.
    constexpr unsigned int kRelaxedDepth = 256;  // Embree recurses: keep its stack bounded
    std::string second_error;
    built = build_once(triangles, used, sah_block, kRelaxedDepth, bvh, second_error, over_budget);
    if (!built && over_budget) {
      bvh.stats.split_budget_exceeded = true;
      used.spatial_splits = false;
      built = build_once(triangles, used, sah_block, kRelaxedDepth, bvh, second_error, over_budget);
    }
    if (!built)
      throw std::runtime_error("Embree: rtcBuildBVH failed: " + first_error + "; retry with " + "maxDepth " +
                               std::to_string(kRelaxedDepth) + ": " + second_error);
  }
}

// The spatial-split trial (BvhBuildOptions::split_trial_triangles): every 16th triangle of the
// scene (sparser past split_trial_max_sample) is built both ways, and the result is the relative
// SAH gain of the splits. Spatial splits pay where triangles are large against the nodes they
// land in (long walls, floors, slivers across a room), and a sparse sample keeps the triangles'
// sizes against the scene's extent. Its triangles lie further apart than the scene's, so the
// sample over-states the gain rather than missing it. A compact sample (a subtree of the binned
// tree) was tried first: it missed atrium's 12% gain, which lives in its top levels.
double sampled_split_gain(const TriangleSource& triangles, const BvhBuildOptions& options, unsigned int sah_block,
                          std::size_t& sampled) {
  std::size_t stride = 16;
  const std::size_t cap = options.split_trial_max_sample;
  if (cap > 0 && triangles.size() > stride * cap) stride = (triangles.size() + cap - 1) / cap;
  std::vector<BuildTriangle> part;
  part.reserve(triangles.size() / stride + 1);
  for (std::size_t i = 0; i < triangles.size(); i += stride) part.push_back(triangles[i]);
  sampled = part.size();
  if (part.size() < 2) return 0.0;
  BvhBuildOptions split = options, plain = options;
  split.spatial_splits = true;
  plain.spatial_splits = false;
  split.split_trial_triangles = plain.split_trial_triangles = 0;
  FlatBvh with_splits, without;
  build_tree(part, split, sah_block, with_splits);
  build_tree(part, plain, sah_block, without);
  compute_bvh_stats(with_splits);
  compute_bvh_stats(without);
  // Splits that ran out of their budget on the sample would do so on the scene: no gain. The
  // sample's own budget has the small-scene floor (kSplitCallsFloor), so its calls per triangle
  // are held to the scene's rate as well.
  const bool over_rate = options.split_calls_per_triangle > 0 &&
                         with_splits.stats.split_calls > std::uint64_t{options.split_calls_per_triangle} * part.size();
  if (with_splits.stats.split_budget_exceeded || over_rate || without.stats.sah_cost <= 0.0) return 0.0;
  return 1.0 - with_splits.stats.sah_cost / without.stats.sah_cost;
}

}  // namespace

FlatBvh build_bvh(const TriangleSource& triangles, const BvhBuildOptions& options, std::optional<BvhLayout> layout) {
  const auto start = std::chrono::steady_clock::now();
  if (triangles.empty()) throw std::runtime_error("BVH: cannot build over an empty scene");
  if (triangles.size() >= PX_NO_HIT) throw std::runtime_error("BVH: too many triangles for 32-bit indices");
  if (options.max_leaf_size < 1 || options.max_leaf_size > PX_BVH_MAX_LEAF_SIZE)
    throw std::invalid_argument("BVH: max_leaf_size must be in 1.." + std::to_string(PX_BVH_MAX_LEAF_SIZE));
  if (!(options.split_min_gain >= 0.0 && options.split_min_gain <= 1.0))
    throw std::invalid_argument("BVH: split_min_gain must be in [0, 1]");
  for (std::size_t i = 0; i < triangles.size(); ++i)
    for (int c = 0; c < 3; ++c)
      if (const glm::vec3& p = triangles.p(i)[c]; !std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw std::runtime_error("BVH: triangle " + std::to_string(i) + " has a non-finite vertex");

  FlatBvh bvh;
  // Leaves sized for the wide layouts' 4-triangle blocks (BvhBuildOptions::block_leaves_from):
  // Embree's SAH then counts a leaf's intersection cost per started block of 4 triangles.
  const bool block_leaves = options.block_leaves(triangles.size());
  const unsigned int sah_block = block_leaves ? 4u : 1u;
  const bool trial =
      options.spatial_splits && options.split_trial_triangles > 0 && triangles.size() >= options.split_trial_triangles;
  if (trial) {
    // The trial first, while nothing but the scene is held: run after the scene's tree, its
    // sample and two small trees stood beside that tree's leaf triangles at the start's peak
    // (the 10M heightfield: about 50 MiB). Then one tree, with or without splits.
    const auto t = std::chrono::steady_clock::now();
    std::size_t sampled = 0;
    const double gain = sampled_split_gain(triangles, options, sah_block, sampled);
    const double trial_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
    if (triangles.size() >= kTrimFrom) malloc_trim(0);
    const bool take = gain >= options.split_min_gain;
    BvhBuildOptions chosen = options;
    chosen.spatial_splits = take;
    build_tree(triangles, chosen, sah_block, bvh);
    bvh.stats.split_trial = true;
    bvh.stats.split_trial_gain = gain;
    bvh.stats.split_trial_sampled = sampled;
    bvh.stats.split_trial_taken = take;
    bvh.stats.split_trial_ms = trial_ms;
  } else {
    build_tree(triangles, options, sah_block, bvh);
  }

  // The flattener's leaf indices and Embree's freed blocks are in the heap now: handed back
  // before the validator's tables stand beside the tree (io/free_heap.h).
  give_back_free_heap(triangles.size());
  compute_bvh_stats(bvh);
  bvh.stats.scene_triangles = triangles.size();
  bvh.stats.block_leaves = block_leaves;
  // The wide nodes the kernels traverse (when the caller's layout is a wide one).
  if (layout && *layout != BvhLayout::Binary) bvh.stats.collapse_ms = ensure_layout(bvh, *layout);
  bvh.stats.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return bvh;
}

// Hook for the renderer: BvhTriangle::flags (PX_TRI_* bits) from one value per scene triangle,
// e.g. derived from its material. build_bvh leaves flags at 0.
void set_triangle_flags(FlatBvh& bvh, const std::vector<std::uint32_t>& flags_per_scene_triangle) {
  for (BvhTriangle& t : bvh.triangles) {
    if (t.prim >= flags_per_scene_triangle.size())
      throw std::out_of_range("set_triangle_flags: fewer flags than scene triangles");
    t.flags = flags_per_scene_triangle[t.prim];
  }
}

void set_triangle_flags_by_material(FlatBvh& bvh, const std::vector<std::uint32_t>& flags_per_material) {
  for (BvhTriangle& t : bvh.triangles) {
    if (t.material >= flags_per_material.size())
      throw std::out_of_range("set_triangle_flags_by_material: a material past the table");
    t.flags = flags_per_material[t.material];
  }
}

}  // namespace px
