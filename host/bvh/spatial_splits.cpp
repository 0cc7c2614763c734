// split_primitive(): exact clipped boxes for Embree's spatial splits, with a per-thread cache of
// the clipped polygons and the split-call budget.
#include "bvh/spatial_splits.h"

#include "bvh/embree_build_tree.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>

namespace px::embree_build {

namespace {

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
float outward_step(float f) { return std::max(std::abs(f) * 0x1p-23f, std::numeric_limits<float>::min()); }
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
    return build_id == id && prim == p && box[0] == lo[0] && box[1] == lo[1] && box[2] == lo[2] && box[3] == hi[0] &&
           box[4] == hi[1] && box[5] == hi[2];
  }
  void store(std::uint64_t id, std::uint32_t p, const float lo[3], const float hi[3], const Point3d* polygon,
             int count) {
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

}  // namespace

void split_primitive(const RTCBuildPrimitive* primitive, unsigned int dim, float pos, RTCBounds* left, RTCBounds* right,
                     void* user) {
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
    if (context->split_calls.fetch_add(kSplitCountBatch, std::memory_order_relaxed) + kSplitCountBatch >
        context->split_budget)
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

}  // namespace px::embree_build
