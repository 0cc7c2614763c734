// build_bvh(): Embree's rtcBuildBVH (binned SAH, optionally with spatial splits) builds a
// binary tree through our callbacks; we then flatten it into the 64-byte node layout the kernels
// read (kernels/shared/types.h).
#include "bvh/bvh_builder.h"

#include "bvh/embree_reference.h"  // embree_device(), take_embree_error()
#include "bvh/wide_bvh.h"        // ensure_layout

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

namespace {

// Builds from this many triangles hand the allocator's free memory back (malloc_trim) after
// Embree's tree is released.
constexpr std::size_t kTrimFrom = 1000000;

constexpr float kInf = std::numeric_limits<float>::infinity();

// ---------------------------------------------------------------------------------------------
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
  int height;             // levels below this node: 1 when both children are leaves
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

void* create_node(RTCThreadLocalAllocator allocator, unsigned int child_count, void* user) {
  auto* context = static_cast<BuildContext*>(user);
  if (child_count != 2) context->unexpected_arity = true;
  void* memory = rtcThreadLocalAlloc(allocator, sizeof(TempInner), alignof(TempInner));
  if (!memory) {
    context->out_of_memory = true;
    return nullptr;
  }
  auto* node = new (memory) TempInner;
  node->is_leaf = false;
  node->child[0] = node->child[1] = nullptr;
  node->height = 0;
  node->leaf_count = 0;
  return node;
}

void set_node_children(void* node_ptr, void** children, unsigned int child_count, void*) {
  auto* node = static_cast<TempInner*>(node_ptr);
  if (!node) return;
  for (unsigned int i = 0; i < std::min(child_count, 2u); ++i)
    node->child[i] = static_cast<TempNode*>(children[i]);
}

void set_node_bounds(void* node_ptr, const RTCBounds** bounds, unsigned int child_count, void*) {
  auto* node = static_cast<TempInner*>(node_ptr);
  if (!node) return;
  for (unsigned int i = 0; i < std::min(child_count, 2u); ++i) node->bounds[i] = *bounds[i];
}

void* create_leaf(RTCThreadLocalAllocator allocator, const RTCBuildPrimitive* primitives,
                  size_t primitive_count, void* user) {
  auto* context = static_cast<BuildContext*>(user);
  void* memory = rtcThreadLocalAlloc(allocator, sizeof(TempLeaf), alignof(TempLeaf));
  if (!memory) {
    context->out_of_memory = true;
    return nullptr;
  }
  auto* leaf = new (memory) TempLeaf;
  leaf->is_leaf = true;
  leaf->count = 0;
  for (size_t i = 0; i < primitive_count; ++i) {
    // With spatial splits two fragments of one triangle can land in the same leaf; the leaf
    // box already covers both, so one reference is enough and saves an intersection.
    const std::uint32_t prim = primitives[i].primID;
    if (std::find(leaf->prims, leaf->prims + leaf->count, prim) != leaf->prims + leaf->count)
      continue;
    if (leaf->count == PX_BVH_MAX_LEAF_SIZE) {
      context->oversized_leaf = true;
      break;
    }
    leaf->prims[leaf->count++] = prim;
  }
  return leaf;
}

// ---------------------------------------------------------------------------------------------
// Spatial splits. Embree asks: the part of primitive `prim` inside its current box (a fragment
// of one triangle, possibly already split several times), cut by the plane x[dim] = pos — what
// are the boxes of the two pieces? We answer exactly: clip the triangle to the fragment's box
// (a convex polygon), cut the polygon at the plane and take each side's bounds. Embree's own
// triangle splitter cuts the unclipped triangle and intersects with the box, which can leave a
// box larger than the fragment; exact boxes are tighter and so give lower SAH.

struct Point3d {
  double x[3];
};

constexpr int kMaxPolygon = 12;  // a triangle clipped by 6 box planes has at most 9 vertices

// Keeps the part of the convex polygon `in` on one side of the plane x[axis] = plane: below it
// (x <= plane) when keep_below, above it otherwise. Vertices on the plane are kept.
int clip_polygon(const Point3d* in, int n, int axis, double plane, bool keep_below, Point3d* out) {
  int m = 0;
  const double sign = keep_below ? 1.0 : -1.0;
  // Signed distance to the plane, negative inside the kept half-space.
  double da = sign * (in[n - 1].x[axis] - plane);
  for (int i = 0, prev = n - 1; i < n; prev = i++) {
    const Point3d& a = in[prev];
    const Point3d& b = in[i];
    const double db = sign * (b.x[axis] - plane);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
      const double t = da / (da - db);
      Point3d& p = out[m++];
      for (int k = 0; k < 3; ++k) p.x[k] = a.x[k] + t * (b.x[k] - a.x[k]);
      p.x[axis] = plane;  // exactly on the plane, whatever the rounding above did
    }
    if (db <= 0.0) out[m++] = b;
    da = db;
  }
  return m;
}

// Float bounds that never shrink the double value they round: round to nearest, and where that
// went the wrong way step outwards by at least one ulp (|f| 2^-23 >= ulp(f) for normal f; FLT_MIN
// covers zero and subnormals without feeding a subnormal operand to the FPU, which would cost a
// microcode assist). At most 2 ulps looser than exact; plain arithmetic instead of
// std::nextafter because a large spatial-split build calls this ~10^8 times.
float outward_step(float f) {
  return std::max(std::abs(f) * 0x1p-23f, std::numeric_limits<float>::min());
}
// The step is masked by the comparison instead of chosen by it: which way rounding to nearest
// went is a coin toss, and GCC turns a ?: here into a branch; ~10^8 mispredicted branches were a
// quarter of a large spatial-split build. f - 0 and f + 0 are f exactly.
float masked_step(float f, bool wrong_way) {
  const std::uint32_t mask = 0u - static_cast<std::uint32_t>(wrong_way);
  return std::bit_cast<float>(std::bit_cast<std::uint32_t>(outward_step(f)) & mask);
}
float round_down(double value) {
  const float f = static_cast<float>(value);
  return f - masked_step(f, static_cast<double>(f) > value);
}
float round_up(double value) {
  const float f = static_cast<float>(value);
  return f + masked_step(f, static_cast<double>(f) < value);
}

void set_empty(RTCBounds* bounds) {
  bounds->lower_x = bounds->lower_y = bounds->lower_z = kInf;
  bounds->upper_x = bounds->upper_y = bounds->upper_z = -kInf;
}

struct BoundsD {
  double lo[3] = {kInf, kInf, kInf};
  double hi[3] = {-kInf, -kInf, -kInf};
  void extend(const double* p) {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  }
  bool empty() const { return lo[0] > hi[0]; }
};

// `bounds` rounded outwards to float and clipped to the box [lo, hi].
void to_rtc_bounds(const BoundsD& bounds, const float lo[3], const float hi[3], RTCBounds* out) {
  if (bounds.empty()) {
    set_empty(out);
    return;
  }
  float bmin[3], bmax[3];
  for (int k = 0; k < 3; ++k) {
    // The exact polygon lies inside the box; clamping only removes rounding noise.
    bmin[k] = std::max(round_down(bounds.lo[k]), lo[k]);
    bmax[k] = std::min(round_up(bounds.hi[k]), hi[k]);
  }
  if (bmin[0] > bmax[0] || bmin[1] > bmax[1] || bmin[2] > bmax[2]) {
    set_empty(out);
    return;
  }
  out->lower_x = bmin[0];
  out->lower_y = bmin[1];
  out->lower_z = bmin[2];
  out->upper_x = bmax[0];
  out->upper_y = bmax[1];
  out->upper_z = bmax[2];
}

// Embree's spatial binning walks each primitive across the bin planes of one axis: it splits
// the primitive's box at the first plane, then splits the right piece at the next plane, and so
// on (and starts again from the full box for the next axis). Clipping the triangle to the box
// is most of the work of a split, so each thread remembers the clipped polygons of the last full
// box and of the last right piece: a hit skips the clipping. The polygon of a right piece is
// the triangle clipped to that piece's box, too (the box lies inside the old box, on the right
// of the plane, and contains the piece), so reusing it is exact, not an approximation.
struct PolygonCache {
  std::uint64_t build_id = 0;  // 0: empty
  std::uint32_t prim = 0;
  float box[6] = {};
  int n = 0;
  Point3d poly[kMaxPolygon];

  bool matches(std::uint64_t id, std::uint32_t p, const float lo[3], const float hi[3]) const {
    return build_id == id && prim == p && box[0] == lo[0] && box[1] == lo[1] && box[2] == lo[2] &&
           box[3] == hi[0] && box[4] == hi[1] && box[5] == hi[2];
  }
  void store(std::uint64_t id, std::uint32_t p, const float lo[3], const float hi[3],
             const Point3d* polygon, int count) {
    build_id = id, prim = p, n = count;
    for (int k = 0; k < 3; ++k) box[k] = lo[k], box[3 + k] = hi[k];
    std::copy(polygon, polygon + count, poly);
  }
};
// Per thread: the last full box, and two slots for right pieces used alternately (the piece
// being split is read from one while the new right piece is written to the other).
struct SplitCaches {
  PolygonCache full_box;
  PolygonCache right_piece[2];
  int current_right = 0;
  // Calls not yet added to BuildContext::split_calls (one shared counter bumped on every call
  // would bounce its cache line between the build threads ~10^7 times).
  std::uint64_t pending_build = 0;
  std::uint32_t pending_calls = 0;
};
constexpr std::uint32_t kSplitCountBatch = 256;
thread_local SplitCaches t_caches;

std::atomic<std::uint64_t> g_next_build_id{1};

// Thrown by split_primitive to cancel a build whose split budget ran out.
struct SplitBudgetExceeded : std::exception {
  const char* what() const noexcept override { return "BVH: spatial-split budget exceeded"; }
};

// The triangle clipped to the box [lo, hi]; returns the vertex count (0: rounding lost a
// grazing sliver). `scratch` holds two polygons; the result points into it.
int clip_triangle_to_box(const std::array<float, 9>& p, const float lo[3], const float hi[3],
                         Point3d (*scratch)[kMaxPolygon], const Point3d** result) {
  int current = 0;
  int n = 3;
  for (int v = 0; v < 3; ++v)
    for (int k = 0; k < 3; ++k) scratch[0][v].x[k] = p[3 * v + k];
  // Only planes the triangle actually crosses cost anything.
  for (int k = 0; k < 3 && n > 0; ++k) {
    const float tmin = std::min({p[k], p[3 + k], p[6 + k]});
    const float tmax = std::max({p[k], p[3 + k], p[6 + k]});
    if (tmin < lo[k]) {
      n = clip_polygon(scratch[current], n, k, lo[k], false, scratch[1 - current]);
      current = 1 - current;
    }
    if (n > 0 && tmax > hi[k]) {
      n = clip_polygon(scratch[current], n, k, hi[k], true, scratch[1 - current]);
      current = 1 - current;
    }
  }
  *result = scratch[current];
  return n;
}

void split_primitive(const RTCBuildPrimitive* primitive, unsigned int dim, float pos,
                     RTCBounds* left, RTCBounds* right, void* user) {
  auto* context = static_cast<BuildContext*>(user);
  const std::uint32_t prim = primitive->primID;
  const float lo[3] = {primitive->lower_x, primitive->lower_y, primitive->lower_z};
  const float hi[3] = {primitive->upper_x, primitive->upper_y, primitive->upper_z};
  float left_hi[3] = {hi[0], hi[1], hi[2]};
  float right_lo[3] = {lo[0], lo[1], lo[2]};
  left_hi[dim] = std::min(pos, hi[dim]);
  right_lo[dim] = std::max(pos, lo[dim]);
  auto box_halves = [&] {
    // The halves of the box itself certainly bound whatever part of the triangle is there.
    left->lower_x = lo[0], left->lower_y = lo[1], left->lower_z = lo[2];
    left->upper_x = left_hi[0], left->upper_y = left_hi[1], left->upper_z = left_hi[2];
    right->lower_x = right_lo[0], right->lower_y = right_lo[1], right->lower_z = right_lo[2];
    right->upper_x = hi[0], right->upper_y = hi[1], right->upper_z = hi[2];
  };

  SplitCaches& caches = t_caches;
  if (caches.pending_build != context->build_id) {
    caches.pending_build = context->build_id;
    caches.pending_calls = 0;
  }
  if (++caches.pending_calls == kSplitCountBatch) {
    caches.pending_calls = 0;
    if (context->split_calls.fetch_add(kSplitCountBatch, std::memory_order_relaxed) +
            kSplitCountBatch > context->split_budget)
      context->over_budget.store(true, std::memory_order_relaxed);
  }
  if (context->over_budget.load(std::memory_order_relaxed)) {
    // Cancel the build. Embree cancels its own builds the same way (its progress monitor
    // throws from inside the build tasks; TBB carries the exception to the calling thread and
    // rtcBuildBVH catches it and reports an error), so the unwinding path is one it supports.
    // Its buildProgress callback would be too late: Embree only calls it below its single-thread
    // threshold, after the expensive top levels.
    throw SplitBudgetExceeded{};
  }
  const PolygonCache& last_right = caches.right_piece[caches.current_right];
  Point3d scratch[2][kMaxPolygon];
  const Point3d* poly = nullptr;
  int n = 0;
  if (last_right.matches(context->build_id, prim, lo, hi)) {
    poly = last_right.poly;
    n = last_right.n;
  } else if (caches.full_box.matches(context->build_id, prim, lo, hi)) {
    poly = caches.full_box.poly;
    n = caches.full_box.n;
  } else {
    n = clip_triangle_to_box(context->positions[prim], lo, hi, scratch, &poly);
    caches.full_box.store(context->build_id, prim, lo, hi, poly, n);
  }

  if (n == 0) {
    // The box only grazes the triangle and rounding lost the sliver. Stay conservative.
    box_halves();
    return;
  }

  // Left piece: bounds only, in one pass over the edges (each vertex extends the side it lies
  // on, each edge crossing the plane contributes its crossing point).
  BoundsD lbounds;
  for (int i = 0, prev = n - 1; i < n; prev = i++) {
    const double* a = poly[prev].x;
    const double* b = poly[i].x;
    if (b[dim] <= pos) lbounds.extend(b);
    if ((a[dim] < pos && pos < b[dim]) || (b[dim] < pos && pos < a[dim])) {
      const double t = (pos - a[dim]) / (b[dim] - a[dim]);
      double c[3];
      for (int k = 0; k < 3; ++k) c[k] = a[k] + t * (b[k] - a[k]);
      c[dim] = pos;
      lbounds.extend(c);
    }
  }
  to_rtc_bounds(lbounds, lo, left_hi, left);

  // Right piece: the polygon itself, written straight into the free cache slot, since
  // Embree's next call is likely about it.
  PolygonCache& next_right = caches.right_piece[1 - caches.current_right];
  const int m = clip_polygon(poly, n, static_cast<int>(dim), pos, false, next_right.poly);
  BoundsD rbounds;
  for (int i = 0; i < m; ++i) rbounds.extend(next_right.poly[i].x);
  to_rtc_bounds(rbounds, right_lo, hi, right);
  if (m > 0 && right->lower_x <= right->upper_x) {
    next_right.build_id = context->build_id;
    next_right.prim = prim;
    next_right.n = m;
    const float box[6] = {right->lower_x, right->lower_y, right->lower_z,
                          right->upper_x, right->upper_y, right->upper_z};
    std::copy(box, box + 6, next_right.box);
    caches.current_right = 1 - caches.current_right;
  } else {
    next_right.build_id = 0;  // whatever the slot held was overwritten
  }
}

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

// ---------------------------------------------------------------------------------------------
// Flattening, with a depth guarantee.
//
// Embree honours maxDepth by switching to median splits 8 levels above it; if more than
// 2^8 * maxLeafSize primitives are still together there, it fails ("depth limit reached").
// build_bvh then builds again with a generous maxDepth, and the flattener rebuilds any subtree
// that would end below PX_BVH_MAX_DEPTH as a balanced tree over that subtree's leaves (leaves
// are kept whole, so their boxes and sizes stay valid). It rebuilds as deep in the tree as
// possible, so the SAH tree above is untouched.

int ceil_log2(std::size_t n) {
  int bits = 0;
  while ((std::size_t{1} << bits) < n) ++bits;
  return bits;
}

// Heights and leaf counts of every inner node (single-threaded, after the build).
void annotate(TempNode* node) {
  if (node->is_leaf) return;
  auto* inner = static_cast<TempInner*>(node);
  inner->height = 1;
  inner->leaf_count = 0;
  for (TempNode* child : inner->child) {
    if (child->is_leaf) {
      inner->leaf_count += 1;
    } else {
      annotate(child);
      const auto* c = static_cast<const TempInner*>(child);
      inner->height = std::max(inner->height, c->height + 1);
      inner->leaf_count += c->leaf_count;
    }
  }
}

class Flattener {
 public:
  // Writes the nodes to out.nodes and the leaves' scene triangle indices, in leaf order, to
  // `leaf_prims` (leaf_triangles makes the BvhTriangles of them once Embree's tree is gone).
  Flattener(const TriangleSource& scene, FlatBvh& out, std::vector<std::uint32_t>& leaf_prims,
            int max_depth)
      : scene_(scene), out_(out), leaf_prims_(leaf_prims), max_depth_(max_depth) {}

  void flatten(TempNode* root) {
    if (root->is_leaf) {
      // The whole scene fits one leaf: the root node's left child is that leaf and its right
      // child is absent (inverted box, never entered).
      const auto* leaf = static_cast<const TempLeaf*>(root);
      RTCBounds box;
      set_empty(&box);
      for (std::uint32_t i = 0; i < leaf->count; ++i) extend(box, scene_.p(leaf->prims[i]));
      out_.nodes.emplace_back();
      set_child(0, 0, box, emit_leaf(leaf), leaf->count);
      constexpr float kMax = std::numeric_limits<float>::max();
      const RTCBounds absent = {kMax, kMax, kMax, 0.0f, -kMax, -kMax, -kMax, 0.0f};
      set_child(0, 1, absent, 0, 0);
      return;
    }
    auto* inner = static_cast<TempInner*>(root);
    annotate(inner);
    if (1 + ceil_log2(inner->leaf_count) > max_depth_)
      throw std::runtime_error("BVH: too many leaves for the depth limit");
    emit(inner, 1);
  }

 private:
  struct LeafItem {
    const TempLeaf* leaf;
    RTCBounds box;
    float centroid[3];
  };

  static void extend(RTCBounds& box, const glm::vec3* corners) {
    for (int c = 0; c < 3; ++c) {
      const glm::vec3& p = corners[c];
      box.lower_x = std::min(box.lower_x, p.x), box.upper_x = std::max(box.upper_x, p.x);
      box.lower_y = std::min(box.lower_y, p.y), box.upper_y = std::max(box.upper_y, p.y);
      box.lower_z = std::min(box.lower_z, p.z), box.upper_z = std::max(box.upper_z, p.z);
    }
  }

  void set_child(std::uint32_t node_index, int side, const RTCBounds& box, std::uint32_t index,
                 std::uint32_t count) {
    BvhNode& node = out_.nodes[node_index];
    float* lo = side == 0 ? node.lmin : node.rmin;
    float* hi = side == 0 ? node.lmax : node.rmax;
    lo[0] = box.lower_x, lo[1] = box.lower_y, lo[2] = box.lower_z;
    hi[0] = box.upper_x, hi[1] = box.upper_y, hi[2] = box.upper_z;
    (side == 0 ? node.left : node.right) = index;
    (side == 0 ? node.left_count : node.right_count) = count;
  }

  // Appends the leaf's triangles; returns the index of the first.
  std::uint32_t emit_leaf(const TempLeaf* leaf) {
    const auto first = static_cast<std::uint32_t>(leaf_prims_.size());
    leaf_prims_.insert(leaf_prims_.end(), leaf->prims, leaf->prims + leaf->count);
    return first;
  }

  // Writes `node` placed at `depth` (root = 1). Precondition: a balanced tree over its leaves
  // fits, depth + ceil_log2(leaf_count) <= max_depth_.
  std::uint32_t emit(const TempInner* node, int depth) {
    bool keep = depth + node->height <= max_depth_;
    if (!keep) {
      // Descend if both children can still be made to fit one level down; otherwise this is
      // the deepest place where a balanced rebuild fits.
      keep = true;
      for (const TempNode* child : node->child)
        if (!child->is_leaf &&
            depth + 1 + ceil_log2(static_cast<const TempInner*>(child)->leaf_count) > max_depth_)
          keep = false;
      if (!keep) {
        std::vector<LeafItem> items;
        items.reserve(node->leaf_count);
        collect_leaves(node, items);
        return emit_balanced(items.data(), items.size(), depth);
      }
    }
    const auto index = static_cast<std::uint32_t>(out_.nodes.size());
    out_.nodes.emplace_back();
    for (int side = 0; side < 2; ++side) {
      const TempNode* child = node->child[side];
      if (child->is_leaf) {
        const auto* leaf = static_cast<const TempLeaf*>(child);
        set_child(index, side, node->bounds[side], emit_leaf(leaf), leaf->count);
      } else {
        // Depth-first: the left child's subtree follows its parent directly in memory.
        const std::uint32_t child_index = emit(static_cast<const TempInner*>(child), depth + 1);
        set_child(index, side, node->bounds[side], child_index, 0);
      }
    }
    return index;
  }

  void collect_leaves(const TempInner* node, std::vector<LeafItem>& items) {
    for (int side = 0; side < 2; ++side) {
      const TempNode* child = node->child[side];
      if (!child->is_leaf) {
        collect_leaves(static_cast<const TempInner*>(child), items);
        continue;
      }
      LeafItem item;
      item.leaf = static_cast<const TempLeaf*>(child);
      item.box = node->bounds[side];
      item.centroid[0] = 0.5f * (item.box.lower_x + item.box.upper_x);
      item.centroid[1] = 0.5f * (item.box.lower_y + item.box.upper_y);
      item.centroid[2] = 0.5f * (item.box.lower_z + item.box.upper_z);
      items.push_back(item);
    }
  }

  static RTCBounds merged(const LeafItem* items, std::size_t n) {
    RTCBounds box;
    set_empty(&box);
    for (std::size_t i = 0; i < n; ++i) {
      const RTCBounds& b = items[i].box;
      box.lower_x = std::min(box.lower_x, b.lower_x), box.upper_x = std::max(box.upper_x, b.upper_x);
      box.lower_y = std::min(box.lower_y, b.lower_y), box.upper_y = std::max(box.upper_y, b.upper_y);
      box.lower_z = std::min(box.lower_z, b.lower_z), box.upper_z = std::max(box.upper_z, b.upper_z);
    }
    return box;
  }

  // Balanced binary tree over n >= 2 leaves, split at the median centroid along the widest
  // centroid axis: leaves end at depth + ceil_log2(n).
  std::uint32_t emit_balanced(LeafItem* items, std::size_t n, int depth) {
    float cmin[3] = {kInf, kInf, kInf}, cmax[3] = {-kInf, -kInf, -kInf};
    for (std::size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        cmin[k] = std::min(cmin[k], items[i].centroid[k]);
        cmax[k] = std::max(cmax[k], items[i].centroid[k]);
      }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (cmax[k] - cmin[k] > cmax[axis] - cmin[axis]) axis = k;
    const std::size_t half = (n + 1) / 2;
    std::nth_element(items, items + half, items + n, [axis](const LeafItem& a, const LeafItem& b) {
      return a.centroid[axis] < b.centroid[axis];
    });

    const auto index = static_cast<std::uint32_t>(out_.nodes.size());
    out_.nodes.emplace_back();
    const std::size_t begin[2] = {0, half};
    const std::size_t count[2] = {half, n - half};
    for (int side = 0; side < 2; ++side) {
      LeafItem* part = items + begin[side];
      if (count[side] == 1) {
        set_child(index, side, part->box, emit_leaf(part->leaf), part->leaf->count);
      } else {
        const std::uint32_t child = emit_balanced(part, count[side], depth + 1);
        set_child(index, side, merged(part, count[side]), child, 0);
      }
    }
    return index;
  }

  const TriangleSource& scene_;
  FlatBvh& out_;
  std::vector<std::uint32_t>& leaf_prims_;
  int max_depth_;
};

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

// The BvhTriangles of the scene triangles `leaf_prims`, in that (leaf) order.
std::vector<BvhTriangle> leaf_triangles(const TriangleSource& triangles,
                                        const std::vector<std::uint32_t>& leaf_prims) {
  std::vector<BvhTriangle> out;
  out.reserve(leaf_prims.size());
  for (const std::uint32_t prim : leaf_prims) {
    const glm::vec3* p = triangles.p(prim);
    BvhTriangle t;
    for (int k = 0; k < 3; ++k) {
      t.v0[k] = p[0][k];
      t.v1[k] = p[1][k];
      t.v2[k] = p[2][k];
    }
    t.prim = prim;
    t.flags = 0;  // filled from materials by set_triangle_flags()
    t.material = triangles.material(prim);
    out.push_back(t);
  }
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
  std::vector<RTCBuildPrimitive> primitives(capacity);
  for (std::size_t i = 0; i < count; ++i) {
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
  std::vector<RTCBuildPrimitive>().swap(primitives);
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
    if (context.unexpected_arity)
      throw std::runtime_error("BVH: Embree produced a node without exactly two children");
    if (context.oversized_leaf)
      throw std::runtime_error("BVH: Embree produced a leaf larger than PX_BVH_MAX_LEAF_SIZE");
    out.nodes.clear();
    out.triangles.clear();
    out.nodes.reserve(count);  // about count / 2 nodes for leaves of ~2 triangles
    leaf_prims.reserve(count);
    Flattener(triangles, out, leaf_prims, PX_BVH_MAX_DEPTH).flatten(static_cast<TempNode*>(root));
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
void build_tree(const TriangleSource& triangles, const BvhBuildOptions& options, unsigned int sah_block,
                FlatBvh& bvh) {
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
      throw std::runtime_error("Embree: rtcBuildBVH failed: " + first_error + "; retry with " +
                               "maxDepth " + std::to_string(kRelaxedDepth) + ": " + second_error);
  }
}

// The spatial-split trial (BvhBuildOptions::split_trial_triangles): every 16th triangle of the
// scene (sparser past split_trial_max_sample) is built both ways, and the result is the relative
// SAH gain of the splits. Spatial splits pay where triangles are large against the nodes they
// land in (long walls, floors, slivers across a room), and a sparse sample keeps the triangles'
// sizes against the scene's extent. Its triangles lie further apart than the scene's, so the
// sample over-states the gain rather than missing it. A compact sample (a subtree of the binned
// tree) was tried first: it missed atrium's 12% gain, which lives in its top levels.
double sampled_split_gain(const TriangleSource& triangles, const BvhBuildOptions& options,
                          unsigned int sah_block, std::size_t& sampled) {
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
  if (triangles.size() >= PX_NO_HIT)
    throw std::runtime_error("BVH: too many triangles for 32-bit indices");
  if (options.max_leaf_size < 1 || options.max_leaf_size > PX_BVH_MAX_LEAF_SIZE)
    throw std::invalid_argument("BVH: max_leaf_size must be in 1.." +
                                std::to_string(PX_BVH_MAX_LEAF_SIZE));
  if (!(options.split_min_gain >= 0.0 && options.split_min_gain <= 1.0))
    throw std::invalid_argument("BVH: split_min_gain must be in [0, 1]");
  for (std::size_t i = 0; i < triangles.size(); ++i)
    for (int c = 0; c < 3; ++c)
      if (const glm::vec3& p = triangles.p(i)[c]; !std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        throw std::runtime_error("BVH: triangle " + std::to_string(i) +
                                 " has a non-finite vertex");

  FlatBvh bvh;
  // Leaves sized for the wide layouts' 4-triangle blocks (BvhBuildOptions::block_leaves_from):
  // Embree's SAH then counts a leaf's intersection cost per started block of 4 triangles.
  const bool block_leaves = options.block_leaves(triangles.size());
  const unsigned int sah_block = block_leaves ? 4u : 1u;
  const bool trial = options.spatial_splits && options.split_trial_triangles > 0 &&
                     triangles.size() >= options.split_trial_triangles;
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

  compute_bvh_stats(bvh);
  bvh.stats.scene_triangles = triangles.size();
  bvh.stats.block_leaves = block_leaves;
  // The wide nodes the kernels traverse (when the caller's layout is a wide one).
  if (layout && *layout != BvhLayout::Binary) bvh.stats.collapse_ms = ensure_layout(bvh, *layout);
  bvh.stats.build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
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

}  // namespace px
