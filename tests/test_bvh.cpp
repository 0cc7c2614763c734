// BVH module: build_bvh (Embree builder + flattening), validate_bvh, EmbreeReference.
//
// The trees are checked three ways: the validator (structure and boxes), a host traversal of
// the flat arrays against a brute-force loop over all triangles (both in double precision, so
// they must agree exactly), and Embree's own ray tracer (float, so agreement within tolerance).
#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/bvh_validator.h"
#include "bvh/compressed_bvh.h"
#include "bvh/embree_reference.h"
#include "bvh/flat_bvh.h"
#include "bvh/wide_bvh.h"
#include "scene/primitives.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace px {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

// ---------------------------------------------------------------------------------------------
// Scenes

SceneTriangle make_triangle(glm::vec3 a, glm::vec3 b, glm::vec3 c, std::uint32_t material = 0) {
  SceneTriangle t{};
  t.p[0] = a, t.p[1] = b, t.p[2] = c;
  const glm::vec3 n = glm::cross(b - a, c - a);
  const float len = glm::length(n);
  for (auto& normal : t.n) normal = len > 0.0f ? n / len : glm::vec3(0, 0, 1);
  t.material = material;
  return t;
}

// n triangles with random vertices around random centres in [offset, offset + extent]^3.
std::vector<SceneTriangle> random_soup(std::size_t n, unsigned seed, float extent = 100.0f, float size = 2.0f,
                                       float offset = 0.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<SceneTriangle> tris;
  tris.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const glm::vec3 c = glm::vec3(offset) + extent * glm::vec3(u(rng), u(rng), u(rng));
    auto jitter = [&] { return size * (glm::vec3(u(rng), u(rng), u(rng)) - 0.5f); };
    tris.push_back(make_triangle(c + jitter(), c + jitter(), c + jitter(), static_cast<std::uint32_t>(i % 7)));
  }
  return tris;
}

// Long thin triangles (length ~60, width ~0.5) in random diagonal directions.
std::vector<SceneTriangle> long_thin_soup(std::size_t n, unsigned seed, float length = 60.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<SceneTriangle> tris;
  for (std::size_t i = 0; i < n; ++i) {
    const glm::vec3 c = 100.0f * glm::vec3(u(rng), u(rng), u(rng));
    const glm::vec3 d =
        glm::normalize(glm::vec3(u(rng) < 0.5f ? -1 : 1, u(rng) < 0.5f ? -1 : 1, u(rng) < 0.5f ? -1 : 1));
    const glm::vec3 side = glm::normalize(glm::cross(d, glm::vec3(u(rng), u(rng), u(rng)) - 0.5f));
    const glm::vec3 a = c - 0.5f * length * d;
    tris.push_back(make_triangle(a, c + 0.5f * length * d, a + 0.5f * side));
  }
  return tris;
}

// Parallel strips along the diagonal of a slanted square: every strip's box covers most of the
// square, so no partition of whole triangles separates them — the case spatial splits exist for.
std::vector<SceneTriangle> diagonal_strips(int strips) {
  std::vector<SceneTriangle> tris;
  auto slant = [](glm::vec3 p) { return glm::vec3(p.x, p.y, 0.3f * p.x); };
  for (int i = 0; i < strips; ++i) {
    const float o = -100.0f + 200.0f * i / strips, w = 200.0f / strips;
    const glm::vec3 a(std::max(o, 0.0f), std::max(-o, 0.0f), 0.0f);
    const glm::vec3 b = a + glm::vec3(100.0f - std::abs(o), 100.0f - std::abs(o), 0.0f);
    const glm::vec3 off(0.5f * w, -0.5f * w, 0.0f);
    tris.push_back(make_triangle(slant(a), slant(b), slant(b + off)));
    tris.push_back(make_triangle(slant(a), slant(b + off), slant(a + off)));
  }
  return tris;
}

// Triangles whose positions and sizes grow geometrically from 1e-15 to 1e15: every SAH split
// peels off a few of the largest, so an unconstrained SAH tree is hundreds of levels deep.
std::vector<SceneTriangle> geometric_progression(std::size_t n) {
  std::vector<SceneTriangle> tris;
  const double ratio = std::pow(1e30, 1.0 / double(n));
  double x = 1e-15;
  for (std::size_t i = 0; i < n; ++i, x *= ratio) {
    const auto c = float(x), s = float(0.5 * x);
    tris.push_back(make_triangle({c, 0, 0}, {c + s, s, 0}, {c, 0, s}));
  }
  return tris;
}

// ---------------------------------------------------------------------------------------------
// Reference ray tracing in double precision

struct RefHit {
  double t = std::numeric_limits<double>::infinity();
  std::uint32_t prim = PX_NO_HIT;
};

// Möller–Trumbore in double: returns true and t for a hit with tmin <= t <= tmax.
bool intersect_triangle(const Ray& ray, const float* p0, const float* p1, const float* p2, double tmin, double tmax,
                        double& t_out) {
  double o[3], d[3], e1[3], e2[3], tv[3];
  for (int k = 0; k < 3; ++k) {
    o[k] = ray.org[k], d[k] = ray.dir[k];
    e1[k] = double(p1[k]) - p0[k];
    e2[k] = double(p2[k]) - p0[k];
    tv[k] = o[k] - p0[k];
  }
  auto cross = [](const double* a, const double* b, double* r) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
  };
  auto dot = [](const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  double pv[3], qv[3];
  cross(d, e2, pv);
  const double det = dot(e1, pv);
  if (det == 0.0) return false;
  const double inv = 1.0 / det;
  const double u = dot(tv, pv) * inv;
  if (u < 0.0 || u > 1.0) return false;
  cross(tv, e1, qv);
  const double v = dot(d, qv) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  const double t = dot(e2, qv) * inv;
  if (t < tmin || t > tmax) return false;
  t_out = t;
  return true;
}

RefHit brute_force(const std::vector<SceneTriangle>& tris, const Ray& ray) {
  RefHit best;
  double tmax = ray.tmax;
  for (std::size_t i = 0; i < tris.size(); ++i) {
    double t;
    if (intersect_triangle(ray, &tris[i].p[0].x, &tris[i].p[1].x, &tris[i].p[2].x, ray.tmin, tmax, t)) {
      tmax = t;
      best = {t, static_cast<std::uint32_t>(i)};
    }
  }
  return best;
}

// Slab test in double; the interval is widened by a relative 1e-9 so rounding never loses a
// hit that lies exactly on a box face (flat boxes of axis-aligned triangles). Absent children
// are skipped by the caller.
bool hit_box(const Ray& ray, const float* lo, const float* hi, double tmin, double tmax) {
  for (int k = 0; k < 3; ++k) {
    const double o = ray.org[k], d = ray.dir[k];
    if (d == 0.0) {
      if (o < lo[k] || o > hi[k]) return false;
      continue;
    }
    double t0 = (lo[k] - o) / d, t1 = (hi[k] - o) / d;
    if (t0 > t1) std::swap(t0, t1);
    tmin = std::max(tmin, t0);
    tmax = std::min(tmax, t1);
  }
  return tmin <= tmax + 1e-9 * std::abs(tmax) + 1e-300;
}

bool is_absent(const float* lo, const float* hi) { return lo[0] > hi[0]; }

struct TraversalStats {
  std::size_t triangle_tests = 0;
  std::size_t node_visits = 0;
};

// Closest hit by walking the flat arrays the way the kernels will: a stack of node indices,
// leaves test their triangle range.
RefHit traverse(const FlatBvh& bvh, const Ray& ray, TraversalStats* stats = nullptr) {
  RefHit best;
  double tmax = ray.tmax;
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const BvhNode& node = bvh.nodes[stack.back()];
    stack.pop_back();
    if (stats) ++stats->node_visits;
    const float* lo[2] = {node.lmin, node.rmin};
    const float* hi[2] = {node.lmax, node.rmax};
    const std::uint32_t index[2] = {node.left, node.right};
    const std::uint32_t count[2] = {node.left_count, node.right_count};
    for (int side = 0; side < 2; ++side) {
      if (is_absent(lo[side], hi[side]) || !hit_box(ray, lo[side], hi[side], ray.tmin, tmax)) continue;
      if (count[side] == 0) {
        stack.push_back(index[side]);
        continue;
      }
      for (std::uint32_t i = index[side]; i < index[side] + count[side]; ++i) {
        const BvhTriangle& t = bvh.triangles[i];
        if (stats) ++stats->triangle_tests;
        double th;
        if (intersect_triangle(ray, t.v0, t.v1, t.v2, ray.tmin, tmax, th)) {
          tmax = th;
          best = {th, t.prim};
        }
      }
    }
  }
  return best;
}

// Half the rays aim at a random point of a random triangle (so most hit), half go in random
// directions from random origins in and around the scene.
std::vector<Ray> random_rays(const std::vector<SceneTriangle>& tris, std::size_t n, unsigned seed) {
  glm::vec3 lo(kInfinity), hi(-kInfinity);
  for (const auto& t : tris)
    for (const auto& p : t.p) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const glm::vec3 centre = 0.5f * (lo + hi), half = 0.75f * (hi - lo) + 1e-3f;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::uniform_int_distribution<std::size_t> pick(0, tris.size() - 1);
  std::vector<Ray> rays;
  for (std::size_t i = 0; i < n; ++i) {
    const glm::vec3 org = centre + half * (2.0f * glm::vec3(u(rng), u(rng), u(rng)) - 1.0f);
    glm::vec3 dir;
    if (i % 2 == 0) {
      const SceneTriangle& t = tris[pick(rng)];
      float a = u(rng), b = u(rng);
      if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
      dir = (1.0f - a - b) * t.p[0] + a * t.p[1] + b * t.p[2] - org;
    } else {
      dir = glm::vec3(u(rng), u(rng), u(rng)) - 0.5f;
    }
    if (glm::length(dir) == 0.0f) dir = glm::vec3(0, 0, 1);
    dir = glm::normalize(dir);
    rays.push_back({{org.x, org.y, org.z}, 0.0f, {dir.x, dir.y, dir.z}, kInfinity});
  }
  return rays;
}

// Same closest surface: the same triangle, or (coplanar duplicates, a shared edge) the same
// distance.
bool same_hit(double t_a, std::uint32_t prim_a, double t_b, std::uint32_t prim_b, double rel = 1e-4) {
  if (prim_a == PX_NO_HIT || prim_b == PX_NO_HIT) return prim_a == prim_b;
  if (prim_a == prim_b) return true;
  return std::abs(t_a - t_b) <= rel * std::max({std::abs(t_a), std::abs(t_b), 1e-30});
}

// Checks the flat tree against brute force on `rays` rays; returns the average number of
// triangle tests per ray (how much the tree prunes).
double expect_traversal_matches_brute_force(const FlatBvh& bvh, const std::vector<SceneTriangle>& tris,
                                            std::size_t rays, unsigned seed) {
  TraversalStats stats;
  std::size_t mismatches = 0, hits = 0;
  for (const Ray& ray : random_rays(tris, rays, seed)) {
    const RefHit a = traverse(bvh, ray, &stats);
    const RefHit b = brute_force(tris, ray);
    hits += b.prim != PX_NO_HIT;
    if (!same_hit(a.t, a.prim, b.t, b.prim)) {
      if (++mismatches <= 5)
        ADD_FAILURE() << "BVH traversal: prim " << a.prim << " t " << a.t << ", brute force: prim " << b.prim << " t "
                      << b.t;
    }
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_GT(hits, rays / 3) << "too few hits for the comparison to mean much";
  return double(stats.triangle_tests) / double(rays);
}

void expect_valid(const FlatBvh& bvh, const std::vector<SceneTriangle>& tris) {
  const BvhValidation v = validate_bvh(bvh, tris);
  std::string all;
  for (const auto& e : v.errors) all += "\n  " + e;
  EXPECT_TRUE(v.ok) << all;
  EXPECT_TRUE(v.errors.empty());
  EXPECT_EQ(bvh.stats.scene_triangles, tris.size());
  EXPECT_EQ(bvh.stats.nodes, bvh.nodes.size());
  EXPECT_EQ(bvh.stats.leaf_triangles, bvh.triangles.size());
  EXPECT_GE(bvh.stats.leaf_triangles, tris.size());
  EXPECT_GE(bvh.stats.depth, 2);
  EXPECT_LE(bvh.stats.depth, PX_BVH_MAX_DEPTH);
  EXPECT_GE(bvh.stats.sah_cost, 1.0);
}

BvhBuildOptions with_splits(bool spatial_splits) {
  BvhBuildOptions options;
  options.spatial_splits = spatial_splits;
  return options;
}

// ---------------------------------------------------------------------------------------------
// Building

class BuildSoup : public ::testing::TestWithParam<std::tuple<std::size_t, bool>> {};

TEST_P(BuildSoup, ProducesAValidTree) {
  const auto [n, splits] = GetParam();
  const auto tris = random_soup(n, 1234 + unsigned(n));
  const FlatBvh bvh = build_bvh(tris, with_splits(splits));
  expect_valid(bvh, tris);
  // A binary tree with L leaves has L - 1 inner nodes (plus the root of a one-leaf scene).
  EXPECT_GE(bvh.nodes.size(), (bvh.triangles.size() + PX_BVH_MAX_LEAF_SIZE - 1) / PX_BVH_MAX_LEAF_SIZE - 1);
  EXPECT_LE(bvh.nodes.size(), std::max<std::size_t>(bvh.triangles.size(), 2) - 1);
}

INSTANTIATE_TEST_SUITE_P(Sizes, BuildSoup,
                         ::testing::Combine(::testing::Values(1, 2, 3, 4, 5, 17, 1000, 100000), ::testing::Bool()),
                         [](const auto& info) {
                           return std::to_string(std::get<0>(info.param)) +
                                  (std::get<1>(info.param) ? "_splits" : "_binned");
                         });

TEST(Bvh, OneTriangleGivesARootWithOneLeafAndAnAbsentChild) {
  const auto tris = random_soup(1, 7);
  for (bool splits : {false, true}) {
    const FlatBvh bvh = build_bvh(tris, with_splits(splits));
    ASSERT_EQ(bvh.nodes.size(), 1u);
    ASSERT_EQ(bvh.triangles.size(), 1u);
    const BvhNode& root = bvh.nodes[0];
    EXPECT_EQ(root.left, 0u);
    EXPECT_EQ(root.left_count, 1u);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(root.lmin[k], std::min({tris[0].p[0][k], tris[0].p[1][k], tris[0].p[2][k]}));
      EXPECT_EQ(root.lmax[k], std::max({tris[0].p[0][k], tris[0].p[1][k], tris[0].p[2][k]}));
      EXPECT_EQ(root.rmin[k], FLT_MAX);
      EXPECT_EQ(root.rmax[k], -FLT_MAX);
    }
    EXPECT_EQ(root.right, 0u);
    EXPECT_EQ(root.right_count, 0u);
    EXPECT_EQ(bvh.stats.depth, 2);
    expect_valid(bvh, tris);
  }
}

TEST(Bvh, TrianglesCarryTheirSceneData) {
  const auto tris = random_soup(500, 99);
  const FlatBvh bvh = build_bvh(tris, with_splits(false));
  ASSERT_EQ(bvh.triangles.size(), tris.size());
  std::vector<int> seen(tris.size(), 0);
  for (const BvhTriangle& t : bvh.triangles) {
    ASSERT_LT(t.prim, tris.size());
    ++seen[t.prim];
    const SceneTriangle& s = tris[t.prim];
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(t.v0[k], s.p[0][k]);
      EXPECT_EQ(t.v1[k], s.p[1][k]);
      EXPECT_EQ(t.v2[k], s.p[2][k]);
    }
    EXPECT_EQ(t.material, s.material);
    EXPECT_EQ(t.flags, 0u);
  }
  EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](int c) { return c == 1; }));
}

// From 2^18 triangles the build primitives and the leaf triangles are written by one part per
// core: every leaf triangle is still its own scene triangle's (a part one place off would copy a
// neighbour's corners, or leave one unwritten), each scene triangle once, and the boxes Embree
// built from the primitives contain them (the validator).
TEST(Bvh, ALargeScenesTrianglesMadeInPartsCarryTheirSceneData) {
  std::vector<SceneTriangle> tris;
  const int n = 363;  // 2 x 363 x 363 = 263,538 triangles
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto p = [n](int x, int z) {
        return glm::vec3(float(x) / n, 0.05f * std::sin(0.3f * float(x)) * std::cos(0.2f * float(z)), float(z) / n);
      };
      tris.push_back(make_triangle(p(i, j), p(i, j + 1), p(i + 1, j), std::uint32_t(i % 5)));
      tris.push_back(make_triangle(p(i + 1, j), p(i, j + 1), p(i + 1, j + 1), std::uint32_t(j % 7)));
    }
  ASSERT_GE(tris.size(), std::size_t{1} << 18);
  const FlatBvh bvh = build_bvh(tris, with_splits(false));
  expect_valid(bvh, tris);
  ASSERT_EQ(bvh.triangles.size(), tris.size());
  std::vector<std::uint8_t> seen(tris.size(), 0);
  for (std::size_t i = 0; i < bvh.triangles.size(); ++i) {
    const BvhTriangle& t = bvh.triangles[i];
    ASSERT_LT(t.prim, tris.size()) << "leaf triangle " << i;
    ++seen[t.prim];
    const SceneTriangle& s = tris[t.prim];
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(t.v0[k], s.p[0][k]) << "leaf triangle " << i;
      ASSERT_EQ(t.v1[k], s.p[1][k]) << "leaf triangle " << i;
      ASSERT_EQ(t.v2[k], s.p[2][k]) << "leaf triangle " << i;
    }
    ASSERT_EQ(t.material, s.material) << "leaf triangle " << i;
    ASSERT_EQ(t.flags, 0u) << "leaf triangle " << i;
  }
  EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](std::uint8_t c) { return c == 1; }));
}

TEST(Bvh, SetTriangleFlagsCopiesPerSceneTriangleFlags) {
  const auto tris = diagonal_strips(50);  // spatial splits duplicate some triangles
  FlatBvh bvh = build_bvh(tris, with_splits(true));
  std::vector<std::uint32_t> flags(tris.size());
  for (std::size_t i = 0; i < flags.size(); ++i) flags[i] = i % 3 == 0 ? PX_TRI_EMISSIVE : 0u;
  set_triangle_flags(bvh, flags);
  for (const BvhTriangle& t : bvh.triangles) EXPECT_EQ(t.flags, flags[t.prim]);
  EXPECT_THROW(set_triangle_flags(bvh, std::vector<std::uint32_t>(3)), std::out_of_range);
}

TEST(Bvh, RespectsMaxLeafSize) {
  const auto tris = random_soup(3000, 5, 10.0f, 2.0f);  // dense: SAH wants big leaves
  for (int max_leaf : {1, 2, PX_BVH_MAX_LEAF_SIZE}) {
    BvhBuildOptions options;
    options.spatial_splits = false;
    options.max_leaf_size = max_leaf;
    const FlatBvh bvh = build_bvh(tris, options);
    expect_valid(bvh, tris);
    std::uint32_t largest = 0;
    for (const BvhNode& n : bvh.nodes) largest = std::max({largest, n.left_count, n.right_count});
    EXPECT_LE(largest, std::uint32_t(max_leaf));
    if (max_leaf == 1) {
      EXPECT_EQ(bvh.nodes.size(), tris.size() - 1);
    }
  }
}

TEST(Bvh, RejectsBadInput) {
  EXPECT_THROW(build_bvh(std::vector<SceneTriangle>{}), std::runtime_error);
  auto tris = random_soup(10, 3);
  tris[4].p[1].y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(build_bvh(tris), std::runtime_error);
  tris[4].p[1].y = kInfinity;
  EXPECT_THROW(build_bvh(tris), std::runtime_error);
  BvhBuildOptions options;
  options.max_leaf_size = PX_BVH_MAX_LEAF_SIZE + 1;
  EXPECT_THROW(build_bvh(random_soup(10, 3), options), std::invalid_argument);
  options.max_leaf_size = 0;
  EXPECT_THROW(build_bvh(random_soup(10, 3), options), std::invalid_argument);
}

TEST(Bvh, BinnedBuildIsDeterministic) {
  const auto tris = random_soup(20000, 77);
  const FlatBvh a = build_bvh(tris, with_splits(false));
  const FlatBvh b = build_bvh(tris, with_splits(false));
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  EXPECT_EQ(0, std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(BvhNode)));
  EXPECT_EQ(0, std::memcmp(a.triangles.data(), b.triangles.data(), a.triangles.size() * sizeof(BvhTriangle)));
}

// Inputs that break naive builders: degenerate centroid distributions, zero-area and zero-
// thickness triangles, large coordinates.
struct HardScene {
  const char* name;
  std::vector<SceneTriangle> triangles;
};

std::vector<HardScene> hard_scenes() {
  std::vector<HardScene> scenes;
  scenes.push_back({"long_thin", long_thin_soup(2000, 11)});
  {
    // 1000 copies of one triangle: every centroid is the same, binning cannot split.
    std::vector<SceneTriangle> same(1000, make_triangle({0, 0, 0}, {1, 0, 0}, {0, 1, 0}));
    scenes.push_back({"identical", same});
  }
  {
    // Heavily overlapping: 2000 big triangles through one small region.
    scenes.push_back({"overlapping", random_soup(2000, 12, 1.0f, 40.0f)});
  }
  {
    // Axis-aligned triangles (flat boxes), some zero-area ones, and a shared-edge fan.
    std::vector<SceneTriangle> t;
    std::mt19937 rng(13);
    std::uniform_real_distribution<float> u(0.0f, 50.0f);
    for (int i = 0; i < 600; ++i) {
      const glm::vec3 c(u(rng), u(rng), u(rng));
      if (i % 3 == 0) t.push_back(make_triangle(c, c + glm::vec3(3, 0, 0), c + glm::vec3(0, 3, 0)));
      if (i % 3 == 1) t.push_back(make_triangle(c, c + glm::vec3(0, 0, 3), c + glm::vec3(0, 3, 0)));
      if (i % 3 == 2) t.push_back(make_triangle(c, c + glm::vec3(2, 2, 2), c + glm::vec3(4, 4, 4)));
    }
    for (int i = 0; i < 64; ++i) {
      const float a0 = 6.2831853f * i / 64, a1 = 6.2831853f * (i + 1) / 64;
      t.push_back(make_triangle({25, 25, 25}, {25 + 10 * std::cos(a0), 25 + 10 * std::sin(a0), 25},
                                {25 + 10 * std::cos(a1), 25 + 10 * std::sin(a1), 25}));
    }
    scenes.push_back({"flat_degenerate_fan", t});
  }
  scenes.push_back({"huge_coordinates", random_soup(3000, 14, 1000.0f, 20.0f, 1.0e6f)});
  scenes.push_back({"huge_negative_coordinates", random_soup(3000, 15, 1000.0f, 20.0f, -1.0e6f)});
  return scenes;
}

TEST(Bvh, HardInputsBuildValidTreesThatTraceCorrectly) {
  for (const HardScene& scene : hard_scenes()) {
    for (bool splits : {false, true}) {
      SCOPED_TRACE(std::string(scene.name) + (splits ? " with spatial splits" : " binned"));
      const FlatBvh bvh = build_bvh(scene.triangles, with_splits(splits));
      expect_valid(bvh, scene.triangles);
      expect_traversal_matches_brute_force(bvh, scene.triangles, 600, 21);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Traversal of the flat tree

TEST(Bvh, TraversalMatchesBruteForceAndPrunes) {
  for (bool splits : {false, true}) {
    SCOPED_TRACE(splits ? "with spatial splits" : "binned");
    const auto tris = random_soup(4000, 31);
    const FlatBvh bvh = build_bvh(tris, with_splits(splits));
    const double tests_per_ray = expect_traversal_matches_brute_force(bvh, tris, 3000, 32);
    // The tree must actually cull: a ray tests a small fraction of the triangles.
    EXPECT_LT(tests_per_ray, tris.size() / 20.0);
  }
}

TEST(Bvh, TraversalMatchesEmbree) {
  const auto tris = random_soup(20000, 41, 100.0f, 3.0f);
  const EmbreeReference embree(tris);
  for (bool splits : {false, true}) {
    SCOPED_TRACE(splits ? "with spatial splits" : "binned");
    const FlatBvh bvh = build_bvh(tris, with_splits(splits));
    std::size_t mismatches = 0, hits = 0;
    const auto rays = random_rays(tris, 4000, 42);
    for (const Ray& ray : rays) {
      const RefHit a = traverse(bvh, ray);
      const Hit b = embree.intersect(ray);
      hits += b.prim != PX_NO_HIT;
      if (!same_hit(a.t, a.prim, b.t, b.prim)) {
        // Float (Embree) and double (here) may disagree on a ray through an edge; count them.
        if (++mismatches <= 3)
          ADD_FAILURE() << "flat BVH: prim " << a.prim << " t " << a.t << ", Embree: prim " << b.prim << " t " << b.t;
      }
    }
    EXPECT_EQ(mismatches, 0u);
    EXPECT_GT(hits, rays.size() / 3);
  }
}

// ---------------------------------------------------------------------------------------------
// Spatial splits and depth

TEST(Bvh, SpatialSplitsLowerSahOnDiagonalStrips) {
  const auto tris = diagonal_strips(400);
  const FlatBvh binned = build_bvh(tris, with_splits(false));
  const FlatBvh split = build_bvh(tris, with_splits(true));
  expect_valid(binned, tris);
  expect_valid(split, tris);
  // Measured: about 35% lower. Splits must have happened, and paid off clearly.
  EXPECT_FALSE(split.stats.split_budget_exceeded);
  EXPECT_GT(split.stats.leaf_triangles, tris.size());
  EXPECT_LT(split.stats.sah_cost, 0.9 * binned.stats.sah_cost)
      << "binned " << binned.stats.sah_cost << ", split " << split.stats.sah_cost;
  expect_traversal_matches_brute_force(split, tris, 1000, 51);
}

TEST(Bvh, SpatialSplitsDoNotWorsenSahOnLongDiagonalTriangles) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const auto tris = long_thin_soup(3000, seed);
    const FlatBvh binned = build_bvh(tris, with_splits(false));
    const FlatBvh split = build_bvh(tris, with_splits(true));
    expect_valid(split, tris);
    EXPECT_GT(split.stats.leaf_triangles, tris.size());
    EXPECT_LE(split.stats.sah_cost, 1.01 * binned.stats.sah_cost)
        << "binned " << binned.stats.sah_cost << ", split " << split.stats.sah_cost;
  }
}

TEST(Bvh, OverlappingSliversStayWithinTheSplitBudgetAndTraceCorrectly) {
  // Issue 14: on overlapping slivers Embree's spatial binning asks for ~500 splits per triangle
  // (101k slivers: 12 s). The build must stop at its split budget and fall back to binned SAH,
  // and the result must still be a valid tree with exact closest hits.
  std::vector<SceneTriangle> tris;
  append_slivers(tris, 20000, 14);
  const FlatBvh bvh = build_bvh(tris, with_splits(true));
  expect_valid(bvh, tris);
  EXPECT_TRUE(bvh.stats.split_budget_exceeded);
  const std::uint64_t budget = split_call_budget(tris.size());
  // The cancelled attempt stops within a batch of calls per build thread of the budget.
  EXPECT_GE(bvh.stats.split_calls, budget);
  EXPECT_LE(bvh.stats.split_calls, budget + budget / 100);
  EXPECT_EQ(bvh.stats.leaf_triangles, tris.size()) << "the fallback is binned: no fragments";
  const FlatBvh binned = build_bvh(tris, with_splits(false));
  EXPECT_FALSE(binned.stats.split_budget_exceeded);
  EXPECT_EQ(binned.stats.split_calls, 0u);
  EXPECT_DOUBLE_EQ(bvh.stats.sah_cost, binned.stats.sah_cost);
  expect_traversal_matches_brute_force(bvh, tris, 600, 15);
}

TEST(Bvh, SpatialSplitsWithinTheBudgetOnOrdinaryScenes) {
  // A scene of ordinary triangles keeps its spatial splits, well inside the budget.
  const auto tris = random_soup(20000, 16, 100.0f, 3.0f);
  const FlatBvh bvh = build_bvh(tris, with_splits(true));
  EXPECT_FALSE(bvh.stats.split_budget_exceeded);
  EXPECT_GT(bvh.stats.split_calls, 0u);
  EXPECT_LT(bvh.stats.split_calls, split_call_budget(tris.size()) / 2);
}

// The large-scene rule (BvhBuildOptions::split_trial_triangles), forced here on small scenes: a
// binned build, spatial splits tried on every 16th triangle, the scene rebuilt with them only
// where they gain. Each decision is checked against the full builds both ways.
BvhBuildOptions forced_trial() {
  BvhBuildOptions options;
  options.split_trial_triangles = 1;
  return options;
}

// A heightfield of n x n quads: small triangles that share their edges, where splits find
// nothing to gain (the 1M-triangle one: 5x the binned build's time for an equal SAH).
std::vector<SceneTriangle> heightfield(int n) {
  std::vector<SceneTriangle> tris;
  auto p = [n](int i, int j) {
    const float x = float(i) / n, z = float(j) / n;
    return glm::vec3(x, 0.1f * std::sin(9.0f * x) * std::cos(7.0f * z), z);
  };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      tris.push_back(make_triangle(p(i, j), p(i, j + 1), p(i + 1, j)));
      tris.push_back(make_triangle(p(i + 1, j), p(i, j + 1), p(i + 1, j + 1)));
    }
  return tris;
}

// Leaves sized for 4-triangle blocks (BvhBuildOptions::block_leaves_from): from the threshold
// on, leaves hold more triangles (fewer leaves, so fewer nodes and leaf blocks), the tree is
// valid and traces what brute force finds; below it the tree is exactly the per-triangle one.
TEST(Bvh, LeavesSizedForBlocksFromTheirThresholdOnly) {
  const auto tris = heightfield(100);  // 20,000 triangles
  BvhBuildOptions per_triangle = with_splits(false), blocks = with_splits(false);
  per_triangle.block_leaves_from = 0;
  blocks.block_leaves_from = tris.size();
  const FlatBvh a = build_bvh(tris, per_triangle), b = build_bvh(tris, blocks);
  expect_valid(b, tris);
  EXPECT_FALSE(a.stats.block_leaves);
  EXPECT_TRUE(b.stats.block_leaves);
  const double leaf_size_a = double(a.stats.leaf_triangles) / double(a.stats.nodes + 1);
  const double leaf_size_b = double(b.stats.leaf_triangles) / double(b.stats.nodes + 1);
  EXPECT_GT(leaf_size_b, 1.4 * leaf_size_a) << "triangles per leaf: " << leaf_size_a << " -> " << leaf_size_b;
  EXPECT_LT(b.stats.nodes, a.stats.nodes * 3 / 4);
  expect_traversal_matches_brute_force(b, tris, 2000, 71);
  // One triangle short of the threshold: the per-triangle tree, node for node.
  blocks.block_leaves_from = tris.size() + 1;
  const FlatBvh c = build_bvh(tris, blocks);
  EXPECT_FALSE(c.stats.block_leaves);
  ASSERT_EQ(c.nodes.size(), a.nodes.size());
  EXPECT_EQ(std::memcmp(c.nodes.data(), a.nodes.data(), a.nodes.size() * sizeof(BvhNode)), 0);
}

TEST(Bvh, SplitTrialKeepsBinnedSahWhereSplitsGainNothing) {
  const auto tris = heightfield(150);  // 45,000 triangles
  const FlatBvh trial = build_bvh(tris, forced_trial());
  BvhBuildOptions binned_options = with_splits(false), split_options = with_splits(true);
  binned_options.split_trial_triangles = split_options.split_trial_triangles = 0;
  const FlatBvh binned = build_bvh(tris, binned_options);
  const FlatBvh split = build_bvh(tris, split_options);
  expect_valid(trial, tris);
  ASSERT_TRUE(trial.stats.split_trial);
  EXPECT_EQ(trial.stats.split_trial_sampled, (tris.size() + 15) / 16);
  EXPECT_LT(trial.stats.split_trial_gain, BvhBuildOptions{}.split_min_gain);
  EXPECT_FALSE(trial.stats.split_trial_taken);
  EXPECT_EQ(trial.stats.leaf_triangles, tris.size()) << "binned: no fragments";
  EXPECT_DOUBLE_EQ(trial.stats.sah_cost, binned.stats.sah_cost) << "the binned tree itself";
  // The decision was right: the whole scene's splits gain less than the threshold too.
  EXPECT_GT(split.stats.sah_cost, (1.0 - BvhBuildOptions{}.split_min_gain) * binned.stats.sah_cost)
      << "binned " << binned.stats.sah_cost << ", split " << split.stats.sah_cost;
  expect_traversal_matches_brute_force(trial, tris, 500, 52);
}

TEST(Bvh, SplitTrialTakesSplitsWhereTheyPay) {
  auto tris = diagonal_strips(400);  // splits: ~35% lower SAH (SpatialSplitsLowerSahOnDiagonalStrips)
  const FlatBvh trial = build_bvh(tris, forced_trial());
  BvhBuildOptions split_options = with_splits(true);
  split_options.split_trial_triangles = 0;
  const FlatBvh split = build_bvh(tris, split_options);
  expect_valid(trial, tris);
  ASSERT_TRUE(trial.stats.split_trial);
  EXPECT_GE(trial.stats.split_trial_gain, BvhBuildOptions{}.split_min_gain);
  EXPECT_TRUE(trial.stats.split_trial_taken);
  EXPECT_GT(trial.stats.leaf_triangles, tris.size());
  EXPECT_DOUBLE_EQ(trial.stats.sah_cost, split.stats.sah_cost) << "the spatial-split tree itself";
  expect_traversal_matches_brute_force(trial, tris, 500, 53);
}

// Past 16 x split_trial_max_sample triangles the sample thins out to that many: forced here with
// a small cap. It holds exactly ceil(n / stride) triangles and decides as every 16th did, both
// where splits gain nothing and where they pay.
TEST(Bvh, SplitTrialSampleCappedDecidesAsTheFullSample) {
  const auto flat = heightfield(150);        // 45,000 triangles
  const auto strips = diagonal_strips(400);  // splits pay
  for (const auto* tris : {&flat, &strips}) {
    SCOPED_TRACE(tris == &flat ? "heightfield" : "diagonal strips");
    const FlatBvh every16 = build_bvh(*tris, forced_trial());
    BvhBuildOptions capped_options = forced_trial();
    capped_options.split_trial_max_sample = tris->size() / 40;
    const FlatBvh capped = build_bvh(*tris, capped_options);
    const std::size_t stride =
        (tris->size() + capped_options.split_trial_max_sample - 1) / capped_options.split_trial_max_sample;
    ASSERT_GT(stride, 16u);
    EXPECT_EQ(capped.stats.split_trial_sampled, (tris->size() + stride - 1) / stride);
    EXPECT_LE(capped.stats.split_trial_sampled, capped_options.split_trial_max_sample);
    EXPECT_EQ(every16.stats.split_trial_sampled, (tris->size() + 15) / 16);
    EXPECT_EQ(capped.stats.split_trial_taken, every16.stats.split_trial_taken)
        << "gain " << capped.stats.split_trial_gain << " against " << every16.stats.split_trial_gain;
    EXPECT_EQ(capped.stats.split_trial_taken, tris == &strips);
    expect_valid(capped, *tris);
  }
}

TEST(Bvh, SplitTrialOnlyFromItsSizeAndNeverOnOverlappingSlivers) {
  // Below split_trial_triangles the build is as asked: no trial.
  const auto tris = diagonal_strips(50);
  BvhBuildOptions options = with_splits(true);
  options.split_trial_triangles = tris.size() + 1;
  EXPECT_FALSE(build_bvh(tris, options).stats.split_trial);
  options.split_trial_triangles = tris.size();
  EXPECT_TRUE(build_bvh(tris, options).stats.split_trial);
  // Slivers whose splits would run out of budget: the sample runs out too, so the scene is not
  // built a second time only to be cancelled.
  std::vector<SceneTriangle> slivers;
  append_slivers(slivers, 20000, 14);
  const FlatBvh trial = build_bvh(slivers, forced_trial());
  EXPECT_FALSE(trial.stats.split_trial_taken);
  EXPECT_EQ(trial.stats.leaf_triangles, slivers.size());
  expect_valid(trial, slivers);
  BvhBuildOptions bad = forced_trial();
  bad.split_min_gain = -0.1;
  EXPECT_THROW(build_bvh(tris, bad), std::invalid_argument);
}

TEST(Bvh, DepthLimitHoldsOnAGeometricProgression) {
  // Embree alone fails here ("depth limit reached"); build_bvh must still deliver a tree no
  // deeper than the kernels' stack allows, and a correct one.
  for (bool splits : {false, true}) {
    SCOPED_TRACE(splits ? "with spatial splits" : "binned");
    const auto tris = geometric_progression(splits ? 20000 : 100000);
    const FlatBvh bvh = build_bvh(tris, with_splits(splits));
    expect_valid(bvh, tris);
    EXPECT_LE(bvh.stats.depth, PX_BVH_MAX_DEPTH);
    EXPECT_GE(bvh.stats.depth, PX_BVH_MAX_DEPTH - 8) << "the scene is meant to be pathological";
    // Rays along the progression's axis from its small end, and random ones.
    std::vector<Ray> rays;
    for (int i = 0; i < 200; ++i) {
      const float y = 1e-16f * std::pow(1.4f, float(i % 100));
      rays.push_back({{-1.0f, y, y}, 0.0f, {1.0f, 0.0f, 0.0f}, kInfinity});
    }
    std::size_t mismatches = 0;
    for (const Ray& ray : rays) {
      const RefHit a = traverse(bvh, ray), b = brute_force(tris, ray);
      mismatches += !same_hit(a.t, a.prim, b.t, b.prim);
    }
    EXPECT_EQ(mismatches, 0u);
  }
}

// ---------------------------------------------------------------------------------------------
// The validator must catch corruption, each with the error that names it: a validator that
// rejected a corrupt tree only through a side effect (a check that happens to fire for another
// reason) would let that corruption through where the side effect does not occur.

// `v` rejects the tree, at most the first 10 errors and a count are reported, and one of them
// starts with `layout` ("" for the binary tree: its errors carry no prefix, "wide8 ", "cwbvh ")
// and contains `message`.
::testing::AssertionResult has_error(const BvhValidation& v, const std::string& layout, const std::string& message) {
  std::string all;
  for (const auto& e : v.errors) all += "\n  " + e;
  if (v.ok) return ::testing::AssertionFailure() << "the validator accepted the tree";
  if (v.errors.empty() || v.errors.size() > 11)
    return ::testing::AssertionFailure() << v.errors.size() << " errors reported, expected 1..11:" << all;
  for (const auto& e : v.errors)
    if (e.rfind(layout, 0) == 0 && e.find(message) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "no error '" << layout << "... " << message << "' among:" << all;
}

class ValidatorDetects : public ::testing::Test {
 protected:
  void SetUp() override {
    tris_ = random_soup(2000, 61);
    bvh_ = build_bvh(tris_, with_splits(false));
    ASSERT_TRUE(validate_bvh(bvh_, tris_).ok);
    // A leaf with at least two triangles, an inner child slot, and the parent of each. Not the
    // root for the inner slots: a root pointing at itself would be "points at the root" again,
    // not a cycle below it.
    for (std::uint32_t i = 0; i < bvh_.nodes.size(); ++i) {
      const BvhNode& n = bvh_.nodes[i];
      if (big_leaf_node_ == kNone && n.left_count >= 2) big_leaf_node_ = i;
      if (inner_child_node_ == kNone && i > 0 && n.left_count == 0 && n.right_count == 0) inner_child_node_ = i;
    }
    ASSERT_NE(big_leaf_node_, kNone);
    ASSERT_NE(inner_child_node_, kNone);
  }

  // The binary tree's own errors carry no layout prefix, and no wide layout is built here.
  void expect_invalid(const FlatBvh& bvh, const std::string& message, const char* what) {
    EXPECT_TRUE(has_error(validate_bvh(bvh, tris_), "", message)) << what;
  }

  static constexpr std::uint32_t kNone = ~0u;
  std::vector<SceneTriangle> tris_;
  FlatBvh bvh_;
  std::uint32_t big_leaf_node_ = kNone;     // its left child is a leaf of >= 2 triangles
  std::uint32_t inner_child_node_ = kNone;  // not the root; both its children are inner nodes
};

TEST_F(ValidatorDetects, ShrunkLeafBox) {
  FlatBvh bad = bvh_;
  BvhNode& n = bad.nodes[big_leaf_node_];
  n.lmax[0] = 0.5f * (n.lmin[0] + n.lmax[0]);
  expect_invalid(bad, "is not inside the box of its leaf", "leaf box no longer contains its triangles");
}

TEST_F(ValidatorDetects, ShrunkInnerBox) {
  FlatBvh bad = bvh_;
  BvhNode& n = bad.nodes[inner_child_node_];
  n.lmin[1] = 0.5f * (n.lmin[1] + n.lmax[1]);
  expect_invalid(bad, "box is not inside the box its parent stores for it",
                 "inner box no longer contains its children");
}

TEST_F(ValidatorDetects, DroppedLeafTriangle) {
  FlatBvh bad = bvh_;
  bad.nodes[big_leaf_node_].left_count -= 1;
  // The entry left out of its leaf, and (no spatial splits: one entry per triangle) its triangle.
  const std::string entry =
      "triangle entry " + std::to_string(bad.nodes[big_leaf_node_].left + bad.nodes[big_leaf_node_].left_count);
  expect_invalid(bad, entry + " is in 0 leaves (expected 1)", "an entry no longer referenced");
  const std::string prim =
      "scene triangle " +
      std::to_string(bad.triangles[bad.nodes[big_leaf_node_].left + bad.nodes[big_leaf_node_].left_count].prim);
  expect_invalid(bad, prim + " is not referenced by any leaf", "a triangle no longer referenced");
}

TEST_F(ValidatorDetects, Cycle) {
  FlatBvh to_root = bvh_;
  to_root.nodes[inner_child_node_].left = 0;
  expect_invalid(to_root, "node " + std::to_string(inner_child_node_) + " left child index 0 points at the root",
                 "child points at the root");
  FlatBvh to_self = bvh_;
  to_self.nodes[inner_child_node_].right = inner_child_node_;
  const std::string again = "node " + std::to_string(inner_child_node_) + " is reached more than once";
  expect_invalid(to_self, again, "child points at its own node");
  FlatBvh shared = bvh_;
  shared.nodes[inner_child_node_].right = shared.nodes[inner_child_node_].left;
  const std::string twice =
      "node " + std::to_string(shared.nodes[inner_child_node_].left) + " is reached more than once";
  expect_invalid(shared, twice, "two parents share a subtree");
  expect_invalid(shared, "nodes are not reachable from the root", "the subtree it no longer points to");
}

TEST_F(ValidatorDetects, OutOfRangeIndices) {
  FlatBvh node_index = bvh_;
  node_index.nodes[inner_child_node_].left = static_cast<std::uint32_t>(bvh_.nodes.size() + 5);
  expect_invalid(node_index,
                 "node " + std::to_string(inner_child_node_) + " left child index " +
                     std::to_string(bvh_.nodes.size() + 5) + " is out of range",
                 "node index past the end");
  FlatBvh tri_index = bvh_;
  tri_index.nodes[big_leaf_node_].left = static_cast<std::uint32_t>(bvh_.triangles.size() - 1);
  expect_invalid(tri_index, "but there are " + std::to_string(bvh_.triangles.size()), "leaf range past the end");
  FlatBvh prim = bvh_;
  prim.triangles[3].prim = static_cast<std::uint32_t>(tris_.size());
  expect_invalid(prim, "triangle entry 3 has prim " + std::to_string(tris_.size()) + " but the scene has",
                 "prim index past the scene");
}

TEST_F(ValidatorDetects, NanBox) {
  FlatBvh bad = bvh_;
  bad.nodes[0].rmax[2] = std::numeric_limits<float>::quiet_NaN();
  expect_invalid(bad, "node 0 right box has NaN", "NaN in a box");
}

TEST_F(ValidatorDetects, WrongTriangleData) {
  FlatBvh bad = bvh_;
  bad.triangles[10].v1[0] += 0.25f;
  expect_invalid(bad, "triangle entry 10 does not match scene triangle " + std::to_string(bad.triangles[10].prim),
                 "vertex differs from the scene");
}

TEST_F(ValidatorDetects, UnreachableNode) {
  FlatBvh bad = bvh_;
  bad.nodes.push_back(bad.nodes[1]);
  expect_invalid(bad, "1 nodes are not reachable from the root (first: " + std::to_string(bvh_.nodes.size()) + ")",
                 "a node nothing points to");
}

TEST_F(ValidatorDetects, ManyErrorsAreCapped) {
  FlatBvh bad = bvh_;
  for (BvhNode& n : bad.nodes) n.lmax[0] = n.lmin[0];  // flattens every left box
  const BvhValidation v = validate_bvh(bad, tris_);
  EXPECT_FALSE(v.ok);
  EXPECT_LE(v.errors.size(), 11u);
  EXPECT_NE(v.errors.back().find("more"), std::string::npos) << v.errors.back();
}

TEST_F(ValidatorDetects, ATreeReadBackFromTheCacheSkipsOnlyTheBinaryNodes) {
  // validate_bvh(..., binary_tree = false), what a start from the BVH cache runs: the binary
  // nodes (validated before the file was written, guarded by its checksum since) are left out,
  // the wide nodes collapsed from them in this run are still checked.
  FlatBvh bad = bvh_;
  ensure_layout(bad, BvhLayout::Wide8);
  ASSERT_TRUE(validate_bvh(bad, tris_).ok);
  for (BvhNode& n : bad.nodes) n.lmax[0] = n.lmin[0];  // the binary tree broken after the collapse
  EXPECT_FALSE(validate_bvh(bad, tris_).ok);
  EXPECT_TRUE(validate_bvh(bad, tris_, /*binary_tree=*/false).ok);
  bad.nodes8[0].child[0] = static_cast<std::uint32_t>(bad.nodes8.size() + 5);  // a wide node broken too
  EXPECT_FALSE(validate_bvh(bad, tris_, /*binary_tree=*/false).ok);
}

// ---------------------------------------------------------------------------------------------
// Wide layouts (types.h: Bvh4Node, Bvh8Node): the binary tree collapsed, checked by the same
// validator.

template <typename Node>
void expect_wide_tree_sound(const std::vector<Node>& nodes, const FlatBvh& bvh, int width) {
  ASSERT_FALSE(nodes.empty());
  EXPECT_LE(nodes.size(), bvh.nodes.size()) << "every wide node is a binary node";
  // Leaf slots cover the triangle entries exactly once, as the binary leaves do.
  std::vector<int> refs(bvh.triangles.size(), 0);
  std::size_t slots = 0, used = 0;
  for (const Node& n : nodes)
    for (int i = 0; i < width; ++i) {
      ++slots;
      if (n.lo_x[i] > n.hi_x[i]) continue;
      ++used;
      for (std::uint32_t k = 0; k < n.count[i]; ++k) ++refs[n.child[i] + k];
    }
  for (std::size_t i = 0; i < refs.size(); ++i) EXPECT_EQ(refs[i], 1) << "entry " << i;
  if (bvh.triangles.size() > 64) {
    EXPECT_GT(double(used) / double(slots), 0.6) << "slots mostly filled";
  }
}

TEST(WideBvh, CollapsedTreesValidateWithAndWithoutSplits) {
  for (bool splits : {false, true}) {
    const auto tris = random_soup(3000, 91);
    FlatBvh bvh = build_bvh(tris, with_splits(splits));
    collapse_bvh(bvh, 4);
    collapse_bvh(bvh, 8);
    const BvhValidation v = validate_bvh(bvh, tris);
    EXPECT_TRUE(v.ok) << (v.errors.empty() ? "" : v.errors.front());
    expect_wide_tree_sound(bvh.nodes4, bvh, 4);
    expect_wide_tree_sound(bvh.nodes8, bvh, 8);
  }
}

TEST(WideBvh, OneTriangleScene) {
  std::vector<SceneTriangle> tris;
  append_triangle(tris, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0);
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  collapse_bvh(bvh, 4);
  collapse_bvh(bvh, 8);
  ASSERT_EQ(bvh.nodes4.size(), 1u);
  ASSERT_EQ(bvh.nodes8.size(), 1u);
  EXPECT_EQ(bvh.nodes8[0].count[0], 1u);
  EXPECT_GT(bvh.nodes8[0].lo_x[1], bvh.nodes8[0].hi_x[1]) << "unused slots are absent";
  EXPECT_TRUE(validate_bvh(bvh, tris).ok);
}

// The device form (types.h BvhLeafBlock): the wide nodes, then one block per leaf holding its
// triangles structure-of-arrays; leaf slots point at their blocks in 16-byte units.
TEST(WideBvh, DeviceFormHoldsEveryLeafAsABlock) {
  const auto tris = random_soup(1500, 63);
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  collapse_bvh(bvh, 8);
  bvh.triangles[5].flags = PX_TRI_ALPHA_TESTED;
  const std::vector<std::uint32_t> words = device_wide_nodes(bvh, BvhLayout::Wide8);
  const std::size_t node_units = bvh.nodes8.size() * sizeof(Bvh8Node) / 16;
  std::size_t leaves = 0;
  std::vector<int> refs(bvh.triangles.size(), 0);
  for (std::size_t n = 0; n < bvh.nodes8.size(); ++n) {
    Bvh8Node dev;
    std::memcpy(&dev, words.data() + n * sizeof(Bvh8Node) / 4, sizeof dev);
    for (int i = 0; i < 8; ++i) {
      const Bvh8Node& host = bvh.nodes8[n];
      EXPECT_EQ(dev.count[i], host.count[i]);
      if (host.count[i] == 0) {
        EXPECT_EQ(dev.child[i], host.child[i]) << "interior slots keep their node index";
        continue;
      }
      ++leaves;
      EXPECT_EQ(dev.child[i] >> 29, host.count[i]) << "a leaf slot's entry carries its count";
      const std::uint32_t block = dev.child[i] & 0x1fffffffu;
      ASSERT_GE(block, node_units);
      ASSERT_LE((block * 16 + sizeof(BvhLeafBlock)) / 4, words.size());
      BvhLeafBlock b;
      std::memcpy(&b, words.data() + block * 4, sizeof b);
      EXPECT_EQ(b.first, host.child[i]);
      EXPECT_EQ(b.count, host.count[i]);
      std::uint32_t flags = 0;
      for (std::uint32_t j = 0; j < 4; ++j) {
        const BvhTriangle& t = bvh.triangles[b.first + (j < b.count ? j : 0)];
        if (j < b.count) flags |= t.flags, ++refs[b.first + j];
        for (int k = 0; k < 3; ++k) {
          EXPECT_EQ(b.v[k][j], t.v0[k]);
          EXPECT_EQ(b.v[3 + k][j], t.v1[k]);
          EXPECT_EQ(b.v[6 + k][j], t.v2[k]);
        }
      }
      EXPECT_EQ(b.flags, flags);
    }
  }
  EXPECT_EQ(words.size() * 4, bvh.nodes8.size() * sizeof(Bvh8Node) + leaves * sizeof(BvhLeafBlock));
  for (std::size_t i = 0; i < refs.size(); ++i) EXPECT_EQ(refs[i], 1) << "entry " << i;
}

// device_wide_nodes_from (the start's path: it frees the wide nodes as it writes the words, no
// zero fill) against device_wide_nodes (the test above checks that one block by block): the same
// words, for both widths, and the nodes gone afterwards.
TEST(WideBvh, DeviceFormFromFreedNodesIsTheSameWords) {
  const auto tris = random_soup(1500, 64);
  for (int width : {4, 8}) {
    FlatBvh bvh = build_bvh(tris, with_splits(false));
    collapse_bvh(bvh, width);
    bvh.triangles[7].flags = PX_TRI_ALPHA_TESTED | PX_TRI_EMISSIVE;
    const BvhLayout layout = width == 4 ? BvhLayout::Wide4 : BvhLayout::Wide8;
    const std::vector<std::uint32_t> want = device_wide_nodes(bvh, layout);
    const DeviceWords got = device_wide_nodes_from(bvh, layout);
    ASSERT_EQ(got.size(), want.size()) << "width " << width;
    EXPECT_TRUE(std::equal(got.begin(), got.end(), want.begin())) << "width " << width;
    EXPECT_TRUE(width == 4 ? bvh.nodes4.empty() : bvh.nodes8.empty()) << "the wide nodes are freed";
    EXPECT_FALSE(bvh.triangles.empty()) << "the leaf triangles stay";
  }
  FlatBvh binary = build_bvh(tris, with_splits(false));
  binary.nodes4.clear();
  binary.nodes8.clear();
  EXPECT_THROW(device_wide_nodes_from(binary, BvhLayout::Wide8), std::invalid_argument) << "no wide nodes built";
  EXPECT_THROW(device_wide_nodes_from(binary, BvhLayout::Binary), std::invalid_argument);
}

// Leaf blocks go in leaf order, and with LeafRefs the leaf triangles become 16-byte records in
// their own memory: each names its scene triangle, flags and material, and the block whose lane
// holds its very vertices. 200k triangles, so that the 48-byte array (9.6 MB) passes the 8 MiB
// from which its dead pages are handed back while the blocks are written.
TEST(WideBvh, LeafRefsPointAtTheBlocksHoldingTheirVertices) {
  const auto tris = random_soup(200000, 65);
  for (int width : {4, 8}) {
    FlatBvh bvh = build_bvh(tris, with_splits(false));
    collapse_bvh(bvh, width);
    for (std::size_t i = 0; i < bvh.triangles.size(); i += 97) bvh.triangles[i].flags = PX_TRI_ALPHA_TESTED;
    const BvhLayout layout = width == 4 ? BvhLayout::Wide4 : BvhLayout::Wide8;
    const std::vector<BvhTriangle> leaf = bvh.triangles;
    const std::vector<std::uint32_t> want = device_wide_nodes(bvh, layout);
    LeafRefs refs;
    const DeviceWords got = device_wide_nodes_from(bvh, layout, &refs);
    ASSERT_EQ(got.size(), want.size()) << "width " << width;
    EXPECT_TRUE(std::equal(got.begin(), got.end(), want.begin())) << "the same words with or without refs";
    EXPECT_TRUE(bvh.triangles.empty()) << "the leaf triangles were moved into the refs";
    ASSERT_EQ(refs.count, leaf.size());
    std::uint32_t last_first = 0;
    std::size_t last_block = 0, bad = 0;
    for (std::size_t i = 0; i < leaf.size() && bad < 5; ++i) {
      BvhLeafRef r;
      std::memcpy(&r, reinterpret_cast<const unsigned char*>(refs.memory.data()) + i * sizeof r, sizeof r);
      const BvhTriangle& t = leaf[i];
      BvhLeafBlock b;
      ASSERT_LE((std::size_t{r.block} * 16 + sizeof b) / 4, got.size());
      std::memcpy(&b, got.data() + std::size_t{r.block} * 4, sizeof b);
      bool ok =
          r.prim == t.prim && r.flags == t.flags && r.material == t.material && b.first <= i && i < b.first + b.count;
      const std::size_t lane = i - b.first;
      for (int k = 0; k < 3 && ok; ++k)
        ok = b.v[k][lane] == t.v0[k] && b.v[3 + k][lane] == t.v1[k] && b.v[6 + k][lane] == t.v2[k];
      // Leaf order: a later leaf's block lies further on.
      if (b.first != last_first || i == 0) {
        ok = ok && (i == 0 || r.block > last_block);
        last_first = b.first;
        last_block = r.block;
      }
      if (!ok) {
        ++bad;
        ADD_FAILURE() << "width " << width << ": leaf triangle " << i << " and its block disagree";
      }
    }
  }
}

// Wide nodes made after the scene's triangles are gone are validated with the leaf entries'
// own vertices: a correct tree passes (with spatial splits too), a leaf box that misses its
// triangle and a leaf entry dropped from the tree are found.
TEST(Validator, WideNodesCheckedAgainstTheLeafTriangles) {
  const auto tris = diagonal_strips(400);
  for (bool splits : {false, true}) {
    FlatBvh bvh = build_bvh(tris, with_splits(splits), /*layout=*/std::nullopt);
    EXPECT_TRUE(bvh.nodes8.empty() && bvh.nodes4.empty()) << "collapse false: no wide nodes";
    ASSERT_TRUE(validate_bvh(bvh, tris).ok);
    collapse_bvh(bvh, 8);
    collapse_bvh(bvh, 4);
    const BvhValidation good = validate_layout_from_leaves(bvh, tris.size());
    EXPECT_TRUE(good.ok) << (good.errors.empty() ? "" : good.errors.front());
    // A leaf slot's box pulled away from its triangles.
    FlatBvh shrunk = bvh;
    bool done = false;
    for (Bvh8Node& n : shrunk.nodes8)
      for (int i = 0; i < 8 && !done; ++i)
        if (n.count[i] > 0) {
          n.hi_x[i] = n.lo_x[i];
          n.lo_x[i] -= 1.0f;
          done = true;
        }
    ASSERT_TRUE(done);
    shrunk.nodes4.clear();
    EXPECT_FALSE(validate_layout_from_leaves(shrunk, tris.size()).ok) << "splits " << splits;
    // A leaf slot that forgets its last triangle.
    FlatBvh dropped = bvh;
    dropped.nodes8.clear();
    done = false;
    for (Bvh4Node& n : dropped.nodes4)
      for (int i = 0; i < 4 && !done; ++i)
        if (n.count[i] > 1) {
          --n.count[i];
          done = true;
        }
    ASSERT_TRUE(done);
    EXPECT_FALSE(validate_layout_from_leaves(dropped, tris.size()).ok) << "splits " << splits;
  }
  FlatBvh none = build_bvh(tris, with_splits(false), std::nullopt);
  EXPECT_FALSE(validate_layout_from_leaves(none, tris.size()).ok) << "no wide nodes to check";
}

// A triangle that spatial splits put in several leaves is checked against all of their boxes
// (gathered by a second walk of the tree): each must overlap it, and together they must cover it.
TEST(Validator, DetectsALeafBoxThatMissesASplitTriangle) {
  const auto tris = diagonal_strips(400);
  const FlatBvh split = build_bvh(tris, with_splits(true));
  ASSERT_TRUE(validate_bvh(split, tris).ok);
  ASSERT_GT(split.stats.leaf_triangles, tris.size()) << "splits happened";
  // A binary leaf (a left child) holding a reference of a triangle that is referenced more than once.
  std::vector<int> refs(tris.size(), 0);
  for (const BvhTriangle& t : split.triangles) ++refs[t.prim];
  std::uint32_t node = ~0u, prim_index = 0;
  for (std::uint32_t n = 0; n < split.nodes.size() && node == ~0u; ++n)
    for (std::uint32_t i = 0; i < split.nodes[n].left_count && node == ~0u; ++i)
      if (refs[split.triangles[split.nodes[n].left + i].prim] > 1)
        node = n, prim_index = split.triangles[split.nodes[n].left + i].prim;
  ASSERT_NE(node, ~0u);
  const std::string prim = "scene triangle " + std::to_string(prim_index);
  // Moved far away: that box no longer overlaps the triangle (and the part it held is uncovered).
  FlatBvh moved = split;
  for (int k = 0; k < 3; ++k) moved.nodes[node].lmin[k] += 1e4f, moved.nodes[node].lmax[k] += 1e4f;
  const BvhValidation v = validate_bvh(moved, tris);
  EXPECT_FALSE(v.ok);
  EXPECT_TRUE(has_error(v, "", prim + " does not overlap the box of a leaf holding it"));
}

// The validator rejects `bad`, its first error names the layout at fault (`layout`), and one of
// its errors is the one this corruption must cause: `layout` then `message`.
void expect_rejected(const FlatBvh& bad, const std::vector<SceneTriangle>& tris, const char* layout,
                     const std::string& message, const char* what) {
  const BvhValidation v = validate_bvh(bad, tris);
  EXPECT_FALSE(v.ok) << what;
  ASSERT_FALSE(v.errors.empty()) << what;
  EXPECT_NE(v.errors.front().find(layout), std::string::npos) << what << ": " << v.errors.front();
  EXPECT_TRUE(has_error(v, std::string(layout) + " ", message)) << what;
}

// Large trees are validated one layout per thread: each layout's errors must still be found, and
// reported in the layouts' order (binary, then wide8) whichever thread finishes first.
TEST(WideBvh, ValidatorOnThreadsReportsEveryLayoutInOrder) {
  const auto tris = random_soup(120000, 64);  // past the validator's threading threshold
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  collapse_bvh(bvh, 8);
  ASSERT_TRUE(validate_bvh(bvh, tris).ok);
  // One leaf of one triangle in each layout, its box halved: one message each ("not inside the
  // box of its leaf"), so neither is pushed out of the report's first ten.
  std::uint32_t leaf_node = ~0u, binary_node = ~0u;
  int leaf_slot = -1;
  for (std::uint32_t n = 0; n < bvh.nodes8.size() && leaf_slot < 0; ++n)
    for (int i = 0; i < 8 && leaf_slot < 0; ++i)
      if (bvh.nodes8[n].lo_x[i] <= bvh.nodes8[n].hi_x[i] && bvh.nodes8[n].count[i] == 1) leaf_node = n, leaf_slot = i;
  for (std::uint32_t n = bvh.nodes.size(); n-- > 0 && binary_node == ~0u;)
    if (bvh.nodes[n].left_count == 1) binary_node = n;
  ASSERT_GE(leaf_slot, 0);
  ASSERT_NE(binary_node, ~0u);
  Bvh8Node& w = bvh.nodes8[leaf_node];
  w.hi_y[leaf_slot] = 0.5f * (w.lo_y[leaf_slot] + w.hi_y[leaf_slot]);
  BvhNode& b = bvh.nodes[binary_node];
  b.lmax[1] = 0.5f * (b.lmin[1] + b.lmax[1]);
  for (int run = 0; run < 3; ++run) {
    const BvhValidation check = validate_bvh(bvh, tris);
    ASSERT_FALSE(check.ok);
    std::size_t binary_at = check.errors.size(), wide_at = check.errors.size();
    for (std::size_t i = 0; i < check.errors.size(); ++i) {
      if (check.errors[i].find("is not inside the box of its leaf") == std::string::npos) continue;
      if (check.errors[i].rfind("wide8 ", 0) == 0)
        wide_at = std::min(wide_at, i);
      else
        binary_at = std::min(binary_at, i);
    }
    ASSERT_LT(binary_at, check.errors.size()) << "the binary tree's halved leaf box";
    ASSERT_LT(wide_at, check.errors.size()) << "the wide8 tree's halved leaf box";
    EXPECT_LT(binary_at, wide_at);
  }
}

// A single large tree is validated by several threads, each over its own range of the leaf
// entries (validate_tree's parts; this VM's two cores make two). A correct tree passes, with
// spatial splits too, whose triangles are counted by both parts and must be added up, not
// judged twice as single references; corruptions in the last part are found, with the count of
// problems the same as when the tree is checked beside a wide layout (one thread a layout).
TEST(Validator, OneLargeTreeOnSeveralThreadsFindsWhatOneThreadFinds) {
  const auto tris = random_soup(120000, 65);  // past the validator's threading threshold
  for (bool splits : {false, true}) {
    SCOPED_TRACE(splits ? "spatial splits" : "binned");
    const FlatBvh bvh = build_bvh(tris, with_splits(splits), /*layout=*/std::nullopt);
    if (splits) {
      ASSERT_GT(bvh.triangles.size(), tris.size()) << "splits referenced some triangles twice";
    }
    const BvhValidation good = validate_bvh(bvh, tris);
    EXPECT_TRUE(good.ok) << (good.errors.empty() ? "" : good.errors.front());
    FlatBvh with_wide = bvh;
    collapse_bvh(with_wide, 8);
    const BvhValidation good_wide = validate_layout_from_leaves(with_wide, tris.size());
    EXPECT_TRUE(good_wide.ok) << (good_wide.errors.empty() ? "" : good_wide.errors.front());
    // In the last tenth of the entries: one entry whose vertex is not its scene triangle's, and
    // one binary leaf of one triangle whose box no longer holds it.
    FlatBvh bad = bvh;
    const std::size_t entry = bad.triangles.size() - bad.triangles.size() / 20;
    bad.triangles[entry].v0[0] += 1e-3f;
    std::uint32_t leaf_node = ~0u;
    for (std::uint32_t n = 0; n < bad.nodes.size() && leaf_node == ~0u; ++n)
      if (bad.nodes[n].left_count == 1 && bad.nodes[n].left > bad.triangles.size() * 9 / 10 &&
          tris[bad.triangles[bad.nodes[n].left].prim].p[0].y > bad.nodes[n].lmin[1])
        leaf_node = n;
    ASSERT_NE(leaf_node, ~0u);
    BvhNode& b = bad.nodes[leaf_node];
    b.lmax[1] = b.lmin[1];
    const BvhValidation alone = validate_bvh(bad, tris);
    EXPECT_FALSE(alone.ok);
    EXPECT_TRUE(has_error(alone, "", "triangle entry " + std::to_string(entry) + " does not match scene triangle"));
    const std::string moved = "scene triangle " + std::to_string(bad.triangles[b.left].prim);
    EXPECT_TRUE(has_error(alone, "", moved + " is not inside the box of its leaf") ||
                has_error(alone, "", moved + " does not overlap the box of a leaf holding it"));
    // Beside wide8 nodes each layout gets one thread: the binary tree's problems, counted the same.
    FlatBvh bad_wide = bad;
    collapse_bvh(bad_wide, 8);
    const BvhValidation beside = validate_bvh(bad_wide, tris);
    EXPECT_FALSE(beside.ok);
    std::size_t binary_alone = 0, binary_beside = 0;
    for (const std::string& e : alone.errors) binary_alone += e.rfind("wide8 ", 0) != 0 && e.rfind("...", 0) != 0;
    for (const std::string& e : beside.errors) binary_beside += e.rfind("wide8 ", 0) != 0 && e.rfind("...", 0) != 0;
    EXPECT_EQ(binary_alone, binary_beside) << "first: " << alone.errors.front();
  }
}

TEST(WideBvh, ValidatorDetectsCorruptWideNodes) {
  const auto tris = random_soup(2000, 62);
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  collapse_bvh(bvh, 8);
  ASSERT_TRUE(validate_bvh(bvh, tris).ok);
  // A leaf slot and an interior slot of the root's subtree.
  std::uint32_t leaf_node = ~0u, inner_node = ~0u;
  int leaf_slot = -1, inner_slot = -1;
  for (std::uint32_t n = 0; n < bvh.nodes8.size(); ++n)
    for (int i = 0; i < 8; ++i) {
      if (bvh.nodes8[n].lo_x[i] > bvh.nodes8[n].hi_x[i]) continue;
      if (leaf_slot < 0 && bvh.nodes8[n].count[i] >= 2) leaf_node = n, leaf_slot = i;
      if (inner_slot < 0 && n > 0 && bvh.nodes8[n].count[i] == 0) inner_node = n, inner_slot = i;
    }
  ASSERT_GE(leaf_slot, 0);
  ASSERT_GE(inner_slot, 0);
  auto expect_invalid = [&](const FlatBvh& bad, const std::string& message, const char* what) {
    expect_rejected(bad, tris, "wide8", message, what);
  };
  const std::string leaf_at = "node " + std::to_string(leaf_node) + " slot " + std::to_string(leaf_slot);
  FlatBvh shrunk = bvh;
  Bvh8Node& s = shrunk.nodes8[leaf_node];
  s.hi_y[leaf_slot] = 0.5f * (s.lo_y[leaf_slot] + s.hi_y[leaf_slot]);
  expect_invalid(shrunk, " is not inside the box of its leaf", "leaf box no longer contains its triangles");
  FlatBvh inner = bvh;
  Bvh8Node& in = inner.nodes8[inner_node];
  in.lo_z[inner_slot] = 0.5f * (in.lo_z[inner_slot] + in.hi_z[inner_slot]);
  expect_invalid(inner, " box is not inside the box its parent stores for it",
                 "inner box no longer contains its children");
  FlatBvh dropped = bvh;
  dropped.nodes8[leaf_node].count[leaf_slot] -= 1;
  expect_invalid(
      dropped,
      "triangle entry " +
          std::to_string(bvh.nodes8[leaf_node].child[leaf_slot] + bvh.nodes8[leaf_node].count[leaf_slot] - 1) +
          " is in 0 leaves (expected 1)",
      "a triangle entry is no longer referenced");
  FlatBvh cycle = bvh;
  cycle.nodes8[inner_node].child[inner_slot] = inner_node;
  expect_invalid(cycle, "node " + std::to_string(inner_node) + " is reached more than once",
                 "child points at its own node");
  FlatBvh absent = bvh;
  Bvh8Node& a = absent.nodes8[leaf_node];
  a.lo_x[leaf_slot] = a.lo_y[leaf_slot] = a.lo_z[leaf_slot] = std::numeric_limits<float>::max();
  a.hi_x[leaf_slot] = a.hi_y[leaf_slot] = a.hi_z[leaf_slot] = -std::numeric_limits<float>::max();
  expect_invalid(absent, leaf_at + " slot is unused (inverted box) but has a child or count",
                 "an unused slot that still holds a leaf");
}

// ---------------------------------------------------------------------------------------------
// Compressed 8-wide layout (types.h: CompressedBvh8Node): nodes8 with quantized boxes.

// Decodes a plane independently of the validator, in double: p + q * 2^(e - 127).
double decoded_plane(const CompressedBvh8Node& n, int axis, unsigned q) {
  return double(n.p[axis]) + double(q) * std::ldexp(1.0, int(n.e[axis]) - 127);
}

// Walks the compressed tree beside nodes8 and checks, per slot, what the builder promises: the
// same children, each decoded box containing the exact Bvh8Node box, qlo / qhi the tightest
// grid coordinates that do (a real rounding, not 0 / 255 everywhere), every plane a float.
void expect_compressed_matches_wide8(const FlatBvh& bvh) {
  ASSERT_FALSE(bvh.cnodes.empty());
  EXPECT_EQ(bvh.cnodes.size(), bvh.nodes8.size()) << "the same nodes";
  std::vector<std::pair<std::uint32_t, std::uint32_t>> stack{{0u, 0u}};
  std::size_t visited = 0, leaves = 0, tight = 0, planes = 0;
  while (!stack.empty()) {
    const auto [c, w] = stack.back();
    stack.pop_back();
    ++visited;
    ASSERT_LT(c, bvh.cnodes.size());
    const CompressedBvh8Node& n = bvh.cnodes[c];
    const Bvh8Node& r = bvh.nodes8[w];
    const std::uint8_t* qlo[3] = {n.qlo_x, n.qlo_y, n.qlo_z};
    const std::uint8_t* qhi[3] = {n.qhi_x, n.qhi_y, n.qhi_z};
    const float* rlo[3] = {r.lo_x, r.lo_y, r.lo_z};
    const float* rhi[3] = {r.hi_x, r.hi_y, r.hi_z};
    int interior = 0, leaf = 0;
    for (int i = 0; i < 8; ++i) {
      const bool used = !(r.lo_x[i] > r.hi_x[i]);
      ASSERT_EQ(n.meta[i] != 0, used) << "node " << c << " slot " << i;
      if (!used) continue;
      const unsigned count = (n.meta[i] >> 3) & 7u, rank = n.meta[i] & 7u;
      EXPECT_EQ(count, r.count[i]);
      EXPECT_EQ((n.imask >> i) & 1u, count == 0 ? 1u : 0u);
      for (int k = 0; k < 3; ++k) {
        const double lo = decoded_plane(n, k, qlo[k][i]), hi = decoded_plane(n, k, qhi[k][i]);
        EXPECT_LE(lo, double(rlo[k][i])) << "node " << c << " slot " << i << " axis " << k;
        EXPECT_GE(hi, double(rhi[k][i])) << "node " << c << " slot " << i << " axis " << k;
        EXPECT_EQ(double(float(lo)), lo) << "a plane that is not a float";
        EXPECT_EQ(double(float(hi)), hi) << "a plane that is not a float";
        // Tightest: one grid step further in would cut the exact box.
        if (qlo[k][i] < 255) {
          EXPECT_GT(decoded_plane(n, k, qlo[k][i] + 1u), double(rlo[k][i]));
        }
        if (qhi[k][i] > 0) {
          EXPECT_LT(decoded_plane(n, k, qhi[k][i] - 1u), double(rhi[k][i]));
        }
        planes += 2;
        tight += (qhi[k][i] - qlo[k][i] < 255) ? 2 : 0;
      }
      if (count == 0) {
        EXPECT_EQ(rank, unsigned(interior++));
        stack.push_back({n.child_base + rank, r.child[i]});
      } else {
        EXPECT_EQ(rank, unsigned(leaf++));
        ASSERT_LT(n.leaf_base + rank, bvh.cleaf_first.size());
        EXPECT_EQ(bvh.cleaf_first[n.leaf_base + rank], r.child[i]);
        ++leaves;
      }
    }
  }
  EXPECT_EQ(visited, bvh.cnodes.size()) << "every node reached once";
  EXPECT_EQ(leaves, bvh.cleaf_first.size());
  EXPECT_GT(tight, planes / 2) << "most child boxes span less than their node's whole grid";
}

TEST(CompressedBvh, BuiltFromWide8ValidatesAndMatchesIt) {
  for (bool splits : {false, true}) {
    const auto tris = random_soup(3000, 93);
    FlatBvh bvh = build_bvh(tris, with_splits(splits));
    compress_bvh8(bvh);  // collapses nodes8 first
    ASSERT_FALSE(bvh.nodes8.empty());
    const BvhValidation v = validate_bvh(bvh, tris);
    EXPECT_TRUE(v.ok) << (v.errors.empty() ? "" : v.errors.front());
    expect_compressed_matches_wide8(bvh);
  }
}

TEST(CompressedBvh, ExactFarFromTheOriginAndOnTinyOrFlatNodes) {
  // Far from the origin: tiny nodes at 1e5 need a grid no finer than the floats there; a flat
  // scene has zero extent on one axis; a microscopic one needs the smallest scales.
  std::vector<std::vector<SceneTriangle>> scenes{random_soup(800, 7, 4.0f, 0.1f, 1.0e5f),
                                                 random_soup(800, 8, 1.0e-12f, 1.0e-14f, 0.0f)};
  // Flat at y = 3.7: zero extent, and a grid origin that must stay an exact float.
  std::vector<SceneTriangle> flat;
  for (int i = 0; i < 400; ++i)
    flat.push_back(make_triangle({float(i), 3.7f, 0}, {float(i) + 1.0f, 3.7f, 0.5f}, {float(i), 3.7f, 1.0f}));
  scenes.push_back(flat);
  for (const auto& tris : scenes) {
    FlatBvh bvh = build_bvh(tris, with_splits(false));
    compress_bvh8(bvh);
    const BvhValidation v = validate_bvh(bvh, tris);
    EXPECT_TRUE(v.ok) << (v.errors.empty() ? "" : v.errors.front());
    expect_compressed_matches_wide8(bvh);
  }
}

TEST(CompressedBvh, LayoutNameAndKernelSwitch) {
  EXPECT_EQ(parse_bvh_layout("cwbvh"), BvhLayout::Compressed8);
  EXPECT_STREQ(to_string(BvhLayout::Compressed8), "cwbvh");
  EXPECT_EQ(bvh_layout_width(BvhLayout::Compressed8), PX_BVH_COMPRESSED8);
  EXPECT_THROW(parse_bvh_layout("cwbvh4"), std::invalid_argument);
}

TEST(CompressedBvh, OneTriangleScene) {
  std::vector<SceneTriangle> tris;
  append_triangle(tris, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0);
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  compress_bvh8(bvh);
  ASSERT_EQ(bvh.cnodes.size(), 1u);
  ASSERT_EQ(bvh.cleaf_first.size(), 1u);
  EXPECT_EQ(bvh.cnodes[0].meta[0], PX_CWBVH_META_USED | (1u << PX_CWBVH_META_COUNT_SHIFT));
  EXPECT_EQ(bvh.cnodes[0].meta[1], 0u) << "unused slots are marked unused";
  EXPECT_EQ(bvh.cnodes[0].imask, 0u);
  EXPECT_TRUE(validate_bvh(bvh, tris).ok);
}

// Device form: the compressed nodes, then the leaf blocks in cleaf_first order, so a node's
// leaves are contiguous blocks from its leaf_base (in 16-byte units).
TEST(CompressedBvh, DeviceFormPointsLeavesAtTheirBlocks) {
  const auto tris = random_soup(1500, 64);
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  compress_bvh8(bvh);
  bvh.triangles[3].flags = PX_TRI_ALPHA_TESTED;
  const std::vector<std::uint32_t> words = device_wide_nodes(bvh, BvhLayout::Compressed8);
  const std::size_t node_units = bvh.cnodes.size() * sizeof(CompressedBvh8Node) / 16;
  EXPECT_EQ(words.size() * 4,
            bvh.cnodes.size() * sizeof(CompressedBvh8Node) + bvh.cleaf_first.size() * sizeof(BvhLeafBlock));
  std::vector<int> refs(bvh.triangles.size(), 0);
  for (std::size_t n = 0; n < bvh.cnodes.size(); ++n) {
    CompressedBvh8Node dev;
    std::memcpy(&dev, words.data() + n * sizeof dev / 4, sizeof dev);
    const CompressedBvh8Node& host = bvh.cnodes[n];
    EXPECT_EQ(dev.child_base, host.child_base);
    EXPECT_EQ(0, std::memcmp(dev.meta, host.meta, 56)) << "meta and boxes unchanged";
    for (int i = 0; i < 8; ++i) {
      const unsigned count = (host.meta[i] >> 3) & 7u, rank = host.meta[i] & 7u;
      if (host.meta[i] == 0 || count == 0) continue;
      const std::size_t unit = dev.leaf_base + std::size_t{PX_LEAF_BLOCK_UNITS} * rank;
      EXPECT_EQ(unit, node_units + (std::size_t{host.leaf_base} + rank) * PX_LEAF_BLOCK_UNITS);
      ASSERT_LE((unit * 16 + sizeof(BvhLeafBlock)) / 4, words.size());
      BvhLeafBlock b;
      std::memcpy(&b, words.data() + unit * 4, sizeof b);
      EXPECT_EQ(b.first, bvh.cleaf_first[host.leaf_base + rank]);
      EXPECT_EQ(b.count, count);
      std::uint32_t flags = 0;
      for (std::uint32_t j = 0; j < b.count; ++j) {
        const BvhTriangle& t = bvh.triangles[b.first + j];
        flags |= t.flags;
        ++refs[b.first + j];
        EXPECT_EQ(b.v[0][j], t.v0[0]);
        EXPECT_EQ(b.v[8][j], t.v2[2]);
      }
      EXPECT_EQ(b.flags, flags);
    }
  }
  for (std::size_t i = 0; i < refs.size(); ++i) EXPECT_EQ(refs[i], 1) << "entry " << i;
}

TEST(CompressedBvh, ValidatorDetectsCorruptCompressedNodes) {
  const auto tris = random_soup(2000, 65);
  FlatBvh bvh = build_bvh(tris, with_splits(false));
  compress_bvh8(bvh);
  ASSERT_TRUE(validate_bvh(bvh, tris).ok);
  // A leaf slot and an interior slot whose y extent spans more than one grid step.
  std::uint32_t leaf_node = ~0u, inner_node = ~0u;
  int leaf_slot = -1, inner_slot = -1;
  for (std::uint32_t n = 0; n < bvh.cnodes.size(); ++n)
    for (int i = 0; i < 8; ++i) {
      const CompressedBvh8Node& c = bvh.cnodes[n];
      if (c.meta[i] == 0 || c.qhi_y[i] <= c.qlo_y[i] + 1) continue;
      const bool leaf = ((c.meta[i] >> 3) & 7u) > 0;
      if (leaf && leaf_slot < 0) leaf_node = n, leaf_slot = i;
      if (!leaf && inner_slot < 0 && n > 0) inner_node = n, inner_slot = i;
    }
  ASSERT_GE(leaf_slot, 0);
  ASSERT_GE(inner_slot, 0);
  auto expect_invalid = [&](const FlatBvh& bad, const std::string& message, const char* what) {
    expect_rejected(bad, tris, "cwbvh", message, what);
  };
  const std::string leaf_at = "node " + std::to_string(leaf_node) + " slot " + std::to_string(leaf_slot);
  const std::string inner_at = "node " + std::to_string(inner_node) + " slot " + std::to_string(inner_slot);
  // One grid step in on qhi: the decoded box no longer contains its child.
  FlatBvh shrunk_leaf = bvh;
  shrunk_leaf.cnodes[leaf_node].qhi_y[leaf_slot] -= 1;
  expect_invalid(shrunk_leaf, leaf_at + " decoded box does not contain the exact child box on axis 1",
                 "a leaf's qhi one step too low");
  FlatBvh shrunk_inner = bvh;
  shrunk_inner.cnodes[inner_node].qhi_y[inner_slot] -= 1;
  expect_invalid(shrunk_inner, inner_at + " decoded box does not contain the exact child box on axis 1",
                 "an interior child's qhi one step too low");
  FlatBvh raised = bvh;
  raised.cnodes[inner_node].qlo_x[inner_slot] += 1;
  expect_invalid(raised, inner_at + " decoded box does not contain the exact child box on axis 0",
                 "an interior child's qlo one step too high");
  FlatBvh finer = bvh;
  finer.cnodes[inner_node].e[2] -= 1;
  expect_invalid(finer, " decoded box does not contain the exact child box on axis 2", "a halved scale");
  FlatBvh bad_child = bvh;
  bad_child.cnodes[inner_node].child_base = static_cast<std::uint32_t>(bvh.cnodes.size());
  // The walk meets the first of them (child_base + the slot's rank) before the encoding check
  // would name the whole range, and its errors fill the ten reported.
  expect_invalid(
      bad_child,
      inner_at + " child index " +
          std::to_string(bvh.cnodes.size() + (bvh.cnodes[inner_node].meta[inner_slot] & PX_CWBVH_RANK_MASK)) +
          " is out of range",
      "interior children past the node array");
  FlatBvh bad_leaf = bvh;
  bad_leaf.cnodes[leaf_node].leaf_base = static_cast<std::uint32_t>(bvh.cleaf_first.size());
  // The walk decodes a leaf past the table as a start past every triangle (CompressedNodes::slot).
  expect_invalid(bad_leaf, "leaf under node " + std::to_string(leaf_node) + " references triangles 4294967295..",
                 "leaves past the leaf table");
  FlatBvh moved_leaf = bvh;
  moved_leaf.cleaf_first[0] += 1;
  expect_invalid(moved_leaf,
                 " leaf starts at triangle " + std::to_string(bvh.cleaf_first[0] + 1) + ", wide8 at " +
                     std::to_string(bvh.cleaf_first[0]),
                 "a leaf that starts at the wrong triangle");
  FlatBvh dropped = bvh;
  dropped.cnodes[leaf_node].meta[leaf_slot] = 0;
  expect_invalid(dropped, leaf_at + " is unused but its box is not inverted (255, 0)", "a leaf slot marked unused");
  expect_invalid(dropped, leaf_at + " is unused but wide8 node ", "a leaf slot marked unused");
  FlatBvh imask = bvh;
  imask.cnodes[leaf_node].imask ^= static_cast<std::uint8_t>(1u << leaf_slot);
  expect_invalid(imask, leaf_at + ": imask and meta disagree", "imask disagreeing with meta");
}

TEST(Validator, DetectsUncoveredSplitTriangle) {
  // With spatial splits a triangle spans several leaves; moving one of them away must be
  // caught even though the triangle is still referenced.
  const auto tris = diagonal_strips(100);
  FlatBvh bvh = build_bvh(tris, with_splits(true));
  ASSERT_TRUE(validate_bvh(bvh, tris).ok);
  ASSERT_GT(bvh.triangles.size(), tris.size());
  for (BvhNode& n : bvh.nodes) {
    if (n.left_count == 0) continue;
    // Shrink this leaf's box to a corner of itself.
    for (int k = 0; k < 3; ++k) n.lmax[k] = n.lmin[k] + 0.01f * (n.lmax[k] - n.lmin[k]);
    break;
  }
  // The shrunk leaf still holds its pieces of split triangles, and their other leaves do not
  // cover what this one covered.
  EXPECT_TRUE(has_error(validate_bvh(bvh, tris), "", " leaf boxes"));
}

// A chain: node i has a leaf (triangle i) on the left and node i + 1 on the right; the last
// node has two leaves. `inner` nodes give a tree of depth inner + 1.
FlatBvh chain(const std::vector<SceneTriangle>& tris, std::uint32_t inner) {
  FlatBvh bvh;
  auto box_of = [&](std::uint32_t first, std::uint32_t last, float* lo, float* hi) {
    for (int k = 0; k < 3; ++k) lo[k] = FLT_MAX, hi[k] = -FLT_MAX;
    for (std::uint32_t i = first; i <= last; ++i)
      for (const auto& p : tris[i].p)
        for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  };
  for (std::uint32_t i = 0; i < tris.size(); ++i) {
    BvhTriangle t{};
    for (int k = 0; k < 3; ++k) t.v0[k] = tris[i].p[0][k], t.v1[k] = tris[i].p[1][k], t.v2[k] = tris[i].p[2][k];
    t.prim = i;
    t.material = tris[i].material;
    bvh.triangles.push_back(t);
  }
  const auto last = static_cast<std::uint32_t>(tris.size() - 1);
  for (std::uint32_t i = 0; i < inner; ++i) {
    BvhNode n{};
    box_of(i, i, n.lmin, n.lmax);
    n.left = i;
    n.left_count = 1;
    if (i + 1 < inner) {
      box_of(i + 1, last, n.rmin, n.rmax);
      n.right = i + 1;
      n.right_count = 0;
    } else {
      box_of(i + 1, last, n.rmin, n.rmax);
      n.right = i + 1;
      n.right_count = last - i;
    }
    bvh.nodes.push_back(n);
  }
  return bvh;
}

TEST(Validator, DepthAndLeafSizeLimits) {
  const auto tris = random_soup(PX_BVH_MAX_DEPTH + 2, 71);
  // Depth exactly PX_BVH_MAX_DEPTH passes; one more level fails.
  const FlatBvh deepest_allowed =
      chain(std::vector<SceneTriangle>(tris.begin(), tris.begin() + PX_BVH_MAX_DEPTH), PX_BVH_MAX_DEPTH - 1);
  EXPECT_TRUE(
      validate_bvh(deepest_allowed, std::vector<SceneTriangle>(tris.begin(), tris.begin() + PX_BVH_MAX_DEPTH)).ok);
  const std::vector<SceneTriangle> one_more(tris.begin(), tris.begin() + PX_BVH_MAX_DEPTH + 1);
  const BvhValidation too_deep = validate_bvh(chain(one_more, PX_BVH_MAX_DEPTH), one_more);
  EXPECT_FALSE(too_deep.ok);
  ASSERT_FALSE(too_deep.errors.empty());
  EXPECT_NE(too_deep.errors[0].find("depth"), std::string::npos) << too_deep.errors[0];
  EXPECT_TRUE(
      has_error(too_deep, "", "at depth " + std::to_string(PX_BVH_MAX_DEPTH + 1) + " exceeds PX_BVH_MAX_DEPTH"));

  // One inner node whose right leaf holds PX_BVH_MAX_LEAF_SIZE + 1 triangles.
  const std::vector<SceneTriangle> few(tris.begin(), tris.begin() + PX_BVH_MAX_LEAF_SIZE + 2);
  EXPECT_TRUE(
      has_error(validate_bvh(chain(few, 1), few), "",
                "holds " + std::to_string(PX_BVH_MAX_LEAF_SIZE + 1) + " triangles, more than PX_BVH_MAX_LEAF_SIZE"));
  const std::vector<SceneTriangle> fits(tris.begin(), tris.begin() + PX_BVH_MAX_LEAF_SIZE + 1);
  EXPECT_TRUE(validate_bvh(chain(fits, 1), fits).ok);
}

TEST(Validator, EmptyTreeAndAbsentChildRules) {
  const auto tris = random_soup(3, 81);
  EXPECT_TRUE(has_error(validate_bvh(FlatBvh{}, tris), "", "the BVH has no nodes"));
  // An absent child anywhere but the root is an error.
  FlatBvh bvh = build_bvh(random_soup(50, 82), with_splits(false));
  ASSERT_GT(bvh.nodes.size(), 1u);
  BvhNode& n = bvh.nodes[1];
  for (int k = 0; k < 3; ++k) n.rmin[k] = FLT_MAX, n.rmax[k] = -FLT_MAX;
  n.right_count = 0;
  n.right = 0;
  EXPECT_TRUE(has_error(validate_bvh(bvh, random_soup(50, 82)), "",
                        "node 1 right child is absent (inverted box); only the root's may be"));
}

// ---------------------------------------------------------------------------------------------
// EmbreeReference

TEST(EmbreeReference, MatchesBruteForce) {
  const auto tris = random_soup(3000, 91);
  const EmbreeReference embree(tris);
  std::size_t mismatches = 0, hits = 0;
  for (const Ray& ray : random_rays(tris, 3000, 92)) {
    const Hit a = embree.intersect(ray);
    const RefHit b = brute_force(tris, ray);
    hits += b.prim != PX_NO_HIT;
    mismatches += !same_hit(a.t, a.prim, b.t, b.prim);
    if (a.prim != PX_NO_HIT) {
      // (u, v) are the barycentrics of v1 and v2: they rebuild the hit point.
      const SceneTriangle& t = tris[a.prim];
      const glm::vec3 p = (1.0f - a.u - a.v) * t.p[0] + a.u * t.p[1] + a.v * t.p[2];
      const glm::vec3 q =
          glm::vec3(ray.org[0], ray.org[1], ray.org[2]) + a.t * glm::vec3(ray.dir[0], ray.dir[1], ray.dir[2]);
      EXPECT_LT(glm::length(p - q), 1e-5f * std::max(1.0f, glm::length(q)) + 1e-4f * a.t);
    }
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_GT(hits, 1000u);
}

TEST(EmbreeReference, RespectsTheRayIntervalAndOcclusion) {
  const std::vector<SceneTriangle> tris = {make_triangle({-1, -1, 5}, {1, -1, 5}, {0, 1, 5}),
                                           make_triangle({-1, -1, 8}, {1, -1, 8}, {0, 1, 8})};
  const EmbreeReference embree(tris);
  Ray ray{{0, 0, 0}, 0.0f, {0, 0, 1}, kInfinity};
  Hit hit = embree.intersect(ray);
  EXPECT_EQ(hit.prim, 0u);
  EXPECT_NEAR(hit.t, 5.0f, 1e-5f);
  EXPECT_TRUE(embree.occluded(ray));
  ray.tmin = 6.0f;  // skips the first triangle
  hit = embree.intersect(ray);
  EXPECT_EQ(hit.prim, 1u);
  EXPECT_NEAR(hit.t, 8.0f, 1e-5f);
  ray.tmax = 7.0f;  // and now both
  EXPECT_EQ(embree.intersect(ray).prim, PX_NO_HIT);
  EXPECT_FALSE(embree.occluded(ray));
  const Ray away{{0, 0, 0}, 0.0f, {0, 0, -1}, kInfinity};
  EXPECT_EQ(embree.intersect(away).prim, PX_NO_HIT);
  EXPECT_FALSE(embree.occluded(away));
}

TEST(EmbreeReference, IntersectAllMatchesSingleRaysOnAnyThreadCount) {
  const auto tris = random_soup(2000, 101);
  const EmbreeReference embree(tris);
  const auto rays = random_rays(tris, 2001, 102);
  std::vector<Hit> expected;
  for (const Ray& r : rays) expected.push_back(embree.intersect(r));
  for (int threads : {1, 2, 3}) {
    std::vector<Hit> hits;
    embree.intersect_all(rays, hits, threads);
    ASSERT_EQ(hits.size(), rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) {
      EXPECT_EQ(hits[i].prim, expected[i].prim);
      EXPECT_EQ(hits[i].t, expected[i].t);
    }
  }
  // Occlusion agrees with closest hit.
  for (std::size_t i = 0; i < rays.size(); ++i) EXPECT_EQ(embree.occluded(rays[i]), expected[i].prim != PX_NO_HIT);
}

TEST(EmbreeReference, EmptySceneMissesEverything) {
  const EmbreeReference embree(std::vector<SceneTriangle>{});
  const Ray ray{{0, 0, 0}, 0.0f, {0, 0, 1}, kInfinity};
  EXPECT_EQ(embree.intersect(ray).prim, PX_NO_HIT);
  EXPECT_FALSE(embree.occluded(ray));
  std::vector<Hit> hits;
  embree.intersect_all({}, hits, 2);
  EXPECT_TRUE(hits.empty());
}

}  // namespace
}  // namespace px
