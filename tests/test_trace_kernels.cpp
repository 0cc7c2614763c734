// The trace kernels (watertight triangle test, conservative box test, BVH traversal, origin
// offset) checked against independent host code: a double-precision brute-force loop over all
// triangles, Embree, and analytic answers.
#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/bvh_validator.h"
#include "bvh/embree_reference.h"
#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"
#include "support/brute_force.h"
#include "support/bvh_layout_test.h"
#include "trace/ray_batch_tracer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <optional>
#include <memory>
#include <random>

namespace px {
namespace {

using test::brute_force_closest;
using test::make_ray;

// A scene uploaded to a device set, with a tracer.
struct TraceFixture {
  Scene scene;
  FlatBvh bvh;
  std::unique_ptr<DeviceScene> device_scene;
  std::unique_ptr<RayBatchTracer> tracer;
  // The geometric comparisons strip alpha textures: the brute-force reference knows no
  // textures, and cut-outs have their own test (AlphaCutoutsPassThroughTransparentTexels).
  TraceFixture(DeviceSet& devices, Scene s, bool spatial_splits = true, bool keep_alpha = false) : scene(std::move(s)) {
    if (!keep_alpha)
      for (auto& m : scene.materials) m.alpha_texture = -1;
    BvhBuildOptions opt;
    opt.spatial_splits = spatial_splits;
    bvh = build_bvh(scene.triangles, opt, devices.bvh_layout());
    auto check = validate_bvh(bvh, scene.triangles);
    EXPECT_TRUE(check.ok) << (check.errors.empty() ? "" : check.errors.front());
    device_scene = std::make_unique<DeviceScene>(devices, scene, bvh);
    tracer = std::make_unique<RayBatchTracer>(devices, *device_scene);
  }
};

// Every trace test runs once per BVH node layout (binary, 4-wide, 8-wide, compressed 8-wide), on a
// device set asked for it (layout_device(), layout_options()).
class TraceKernels : public test::BvhLayoutTest {};

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

Scene scene_from(std::vector<SceneTriangle> tris) {
  Scene s;
  s.name = "test";
  s.triangles = std::move(tris);
  s.materials.resize(1);
  return s;
}

std::vector<SceneTriangle> random_soup(int count, std::uint32_t seed, float extent = 10.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-extent, extent), off(-1.0f, 1.0f);
  std::vector<SceneTriangle> tris;
  while (static_cast<int>(tris.size()) < count) {
    glm::vec3 c(pos(rng), pos(rng), pos(rng));
    append_triangle(tris, c + glm::vec3(off(rng), off(rng), off(rng)), c + glm::vec3(off(rng), off(rng), off(rng)),
                    c + glm::vec3(off(rng), off(rng), off(rng)), 0);
  }
  return tris;
}

struct BoundsF {
  glm::vec3 lo{1e30f}, hi{-1e30f};
};
BoundsF bounds_of(const std::vector<SceneTriangle>& tris) {
  BoundsF b;
  for (auto& t : tris)
    for (auto& p : t.p) {
      b.lo = glm::min(b.lo, p);
      b.hi = glm::max(b.hi, p);
    }
  return b;
}

// Random rays from inside (and a bit beyond) the scene's bounds in random directions.
std::vector<Ray> random_rays(const std::vector<SceneTriangle>& tris, int count, std::uint32_t seed) {
  auto b = bounds_of(tris);
  glm::vec3 c = 0.5f * (b.lo + b.hi), h = 0.6f * (b.hi - b.lo);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays;
  for (int i = 0; i < count; ++i)
    rays.push_back(make_ray(c + h * glm::vec3(u(rng), u(rng), u(rng)), test::random_unit(rng)));
  return rays;
}

// Compares kernel hits to the brute-force loop. A different triangle is accepted only where
// the answer is ambiguous: the reference hit grazes an edge (both neighbours own it) or two
// surfaces lie at the same distance (coplanar overlap); t must then still agree.
void expect_matches_brute_force(const std::vector<SceneTriangle>& tris, const std::vector<Ray>& rays,
                                const std::vector<Hit>& hits) {
  ASSERT_EQ(rays.size(), hits.size());
  // Float t carries the rounding of coordinates of the scene's magnitude, not only of t.
  const auto bb = bounds_of(tris);
  const double extent = std::max({std::abs(bb.lo.x), std::abs(bb.lo.y), std::abs(bb.lo.z), std::abs(bb.hi.x),
                                  std::abs(bb.hi.y), std::abs(bb.hi.z)});
  int hit_count = 0, mismatches = 0, ambiguous = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const auto ref = brute_force_closest(tris, rays[i]);
    const Hit& h = hits[i];
    const bool near_edge = ref.prim != PX_NO_HIT && ref.edge_distance < 1e-5;
    if (ref.prim == PX_NO_HIT) {
      if (h.prim != PX_NO_HIT) {
        // The kernel may only "hit" where the reference grazes: check it is at an edge.
        ++mismatches;
        ADD_FAILURE() << "ray " << i << ": kernel hit prim " << h.prim << " t=" << h.t << ", reference missed";
      }
      continue;
    }
    ++hit_count;
    if (h.prim == PX_NO_HIT) {
      if (near_edge) {
        ++ambiguous;
        continue;
      }
      ++mismatches;
      ADD_FAILURE() << "ray " << i << ": kernel missed, reference hit prim " << ref.prim << " t=" << ref.t;
      continue;
    }
    ASSERT_TRUE(std::isfinite(h.t));
    const double tol = 1e-5 * std::max(1.0, ref.t) + 4e-7 * extent;
    if (h.prim != ref.prim) {
      if (near_edge || std::abs(h.t - ref.t) <= tol) {
        ++ambiguous;
        continue;
      }
      ++mismatches;
      ADD_FAILURE() << "ray " << i << ": kernel prim " << h.prim << " t=" << h.t << ", reference prim " << ref.prim
                    << " t=" << ref.t;
      continue;
    }
    EXPECT_NEAR(h.t, ref.t, tol) << "ray " << i;
    EXPECT_NEAR(h.u, ref.u, 1e-3) << "ray " << i;
    EXPECT_NEAR(h.v, ref.v, 1e-3) << "ray " << i;
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(hit_count, static_cast<int>(rays.size()) / 10) << "too few hits to say anything";
  EXPECT_LE(ambiguous, static_cast<int>(rays.size()) / 100) << "too many ambiguous rays";
}

TEST_P(TraceKernels, ClosestHitMatchesBruteForceOnRandomSoup) {
  for (bool splits : {false, true}) {
    TraceFixture f(layout_device(), scene_from(random_soup(3000, 7)), splits);
    auto rays = random_rays(f.scene.triangles, 3000, 11);
    expect_matches_brute_force(f.scene.triangles, rays, f.tracer->closest(rays));
  }
}

TEST_P(TraceKernels, ClosestHitMatchesBruteForceOnCornell) {
  TraceFixture f(layout_device(), make_builtin_scene("cornell"));
  auto rays = random_rays(f.scene.triangles, 4000, 3);
  expect_matches_brute_force(f.scene.triangles, rays, f.tracer->closest(rays));
}

TEST_P(TraceKernels, ClosestHitMatchesBruteForceOnAtrium) {
  // Reduced detail keeps the O(rays x triangles) reference affordable; the full-size atrium is
  // checked against Embree below.
  TraceFixture f(layout_device(), make_builtin_scene("atrium", {{"detail", 0.05}}));
  ASSERT_GT(f.scene.triangles.size(), 1000u);
  auto rays = random_rays(f.scene.triangles, 1500, 5);
  expect_matches_brute_force(f.scene.triangles, rays, f.tracer->closest(rays));
}

TEST_P(TraceKernels, ClosestHitMatchesEmbreeOnFullAtrium) {
  TraceFixture f(layout_device(), make_builtin_scene("atrium"));
  EmbreeReference embree(f.scene.triangles);
  auto rays = random_rays(f.scene.triangles, 20000, 9);
  auto hits = f.tracer->closest(rays);
  int disagree = 0, hits_seen = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    Hit e = embree.intersect(rays[i]);
    if ((e.prim == PX_NO_HIT) != (hits[i].prim == PX_NO_HIT)) {
      ++disagree;
      continue;
    }
    if (e.prim == PX_NO_HIT) continue;
    ++hits_seen;
    if (e.prim != hits[i].prim && std::abs(e.t - hits[i].t) > 1e-4f * std::max(1.0f, e.t)) ++disagree;
  }
  EXPECT_GT(hits_seen, 1000);
  // Embree is not watertight: it may differ on rays through edges; those are rare.
  EXPECT_LE(disagree, 5) << "of " << rays.size();
}

TEST_P(TraceKernels, TinyScenesWithAOneLeafTree) {
  // A scene that fits one leaf has a root with an absent child (inverted box): traversal must
  // skip it rather than take it for an interior node (which once looped forever).
  for (int count : {1, 2, 3}) {
    std::vector<SceneTriangle> tris;
    for (int i = 0; i < count; ++i)
      append_triangle(tris, {-1.0f, -1.0f, float(i)}, {1.0f, -1.0f, float(i)}, {0.0f, 1.0f, float(i)}, 0);
    TraceFixture f(layout_device(), scene_from(tris));
    std::vector<Ray> rays{make_ray({0.0f, 0.0f, -5.0f}, {0.0f, 0.0f, 1.0f}),
                          make_ray({5.0f, 5.0f, -5.0f}, {0.0f, 0.0f, 1.0f})};
    auto hits = f.tracer->closest(rays);
    ASSERT_EQ(hits[0].prim, 0u) << count << " triangles";
    EXPECT_FLOAT_EQ(hits[0].t, 5.0f);
    EXPECT_EQ(hits[1].prim, PX_NO_HIT);
    auto occ = f.tracer->occluded(rays);
    EXPECT_TRUE(occ[0]);
    EXPECT_FALSE(occ[1]);
  }
}

TEST_P(TraceKernels, AnyHitAgreesWithClosestHit) {
  TraceFixture f(layout_device(), scene_from(random_soup(2000, 21)));
  auto rays = random_rays(f.scene.triangles, 3000, 22);
  // Half the rays get a finite tmax so occlusion is decided by the interval, not just hit/miss.
  for (std::size_t i = 0; i < rays.size(); i += 2) rays[i].tmax = 3.0f;
  auto hits = f.tracer->closest(rays);
  auto occ = f.tracer->occluded(rays);
  for (std::size_t i = 0; i < rays.size(); ++i) EXPECT_EQ(occ[i] != 0, hits[i].prim != PX_NO_HIT) << "ray " << i;
}

// Rays aimed exactly at every vertex and edge midpoint of a closed mesh, from outside and from
// inside, never miss: the watertight test leaves no crack between neighbours.
void expect_watertight(DeviceSet& devices, const std::vector<SceneTriangle>& mesh, glm::vec3 inside) {
  TraceFixture f(devices, scene_from(mesh));
  auto b = bounds_of(mesh);
  const float radius = 2.0f * glm::length(b.hi - b.lo);
  std::vector<Ray> rays;
  std::vector<float> target_dist;
  for (const auto& t : mesh) {
    const glm::vec3 targets[6] = {
        t.p[0], t.p[1], t.p[2], 0.5f * (t.p[0] + t.p[1]), 0.5f * (t.p[1] + t.p[2]), 0.5f * (t.p[2] + t.p[0])};
    for (const auto& target : targets) {
      // From inside: the ray must leave through the closed surface. From outside: on the line
      // from the inside point through the target, so the ray enters the mesh exactly there (a
      // ray aimed at a silhouette vertex from an arbitrary side could rightly graze past it).
      const glm::vec3 out_dir = glm::normalize(target - inside);
      for (glm::vec3 o : {inside, target + radius * out_dir}) {
        rays.push_back(make_ray(o, glm::normalize(target - o)));
        target_dist.push_back(glm::length(target - o));
      }
    }
  }
  auto hits = f.tracer->closest(rays);
  int misses = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    if (hits[i].prim == PX_NO_HIT) {
      ++misses;
      if (misses < 4) {
        auto ref = brute_force_closest(mesh, rays[i]);
        ADD_FAILURE() << "miss: ray " << i << " org " << rays[i].org[0] << "," << rays[i].org[1] << ","
                      << rays[i].org[2] << " dir " << rays[i].dir[0] << "," << rays[i].dir[1] << "," << rays[i].dir[2]
                      << " ref prim " << ref.prim << " t " << ref.t << " edge " << ref.edge_distance;
      }
      continue;
    }
    // The first surface is at or before the target point.
    EXPECT_LE(hits[i].t, target_dist[i] * (1.0f + 1e-4f)) << "ray " << i;
  }
  EXPECT_EQ(misses, 0) << "of " << rays.size() << " rays";
}

TEST_P(TraceKernels, WatertightIcosphere) {
  std::vector<SceneTriangle> m;
  append_icosphere(m, glm::vec3(0.3f, -0.2f, 0.1f), 1.7f, 3, 0);
  expect_watertight(layout_device(), m, glm::vec3(0.3f, -0.2f, 0.1f));
}

TEST_P(TraceKernels, WatertightCube) {
  std::vector<SceneTriangle> m;
  append_box(m, glm::vec3(-1.0f), glm::vec3(1.0f, 2.0f, 0.5f), 0);
  expect_watertight(layout_device(), m, glm::vec3(0.1f, 0.2f, -0.1f));
}

TEST_P(TraceKernels, WatertightCornellRoom) {
  // The Cornell room is closed but for its front (z = 0, towards the camera). From a point
  // inside, a ray aimed at any vertex, edge midpoint or centroid of a wall (corners where three
  // walls meet included) must end on a surface. (Aiming at the blocks' convex corners from
  // outside them would be ill-posed: such a ray may rightly graze past.)
  Scene s = make_builtin_scene("cornell");
  auto b = bounds_of(s.triangles);
  const glm::vec3 inside = glm::mix(b.lo, b.hi, glm::vec3(0.3f, 0.8f, 0.5f));
  auto on_wall = [&](const SceneTriangle& t) {
    auto all = [&](auto pred) { return pred(t.p[0]) && pred(t.p[1]) && pred(t.p[2]); };
    return all([&](glm::vec3 p) { return p.x == b.lo.x; }) || all([&](glm::vec3 p) { return p.y == b.hi.y; }) ||
           all([&](glm::vec3 p) { return p.z == b.hi.z; }) || all([&](glm::vec3 p) { return p.x >= 549.0f; }) ||
           (all([&](glm::vec3 p) { return p.y == b.lo.y; }) && triangle_area(t) > 1e4);
  };
  TraceFixture f(layout_device(), s);
  std::vector<Ray> rays;
  for (const auto& t : s.triangles) {
    if (!on_wall(t)) continue;
    for (int k = 0; k < 3; ++k)
      for (const auto& target : {t.p[k], 0.5f * (t.p[k] + t.p[(k + 1) % 3]), (t.p[0] + t.p[1] + t.p[2]) / 3.0f})
        if (target.z > b.lo.z) rays.push_back(make_ray(inside, glm::normalize(target - inside)));
  }
  ASSERT_GT(rays.size(), 50u);
  auto hits = f.tracer->closest(rays);
  int misses = 0;
  for (auto& h : hits) misses += h.prim == PX_NO_HIT;
  EXPECT_EQ(misses, 0) << "of " << rays.size();
}

TEST_P(TraceKernels, AxisAlignedAndGrazingRays) {
  std::vector<SceneTriangle> m;
  append_box(m, glm::vec3(-1.0f), glm::vec3(1.0f), 0);
  TraceFixture f(layout_device(), scene_from(m));
  std::vector<Ray> rays;
  std::vector<float> expect_t;
  // Zero direction components: axis-parallel rays at face interiors have exact answers.
  for (int axis = 0; axis < 3; ++axis)
    for (float sign : {-1.0f, 1.0f}) {
      glm::vec3 o(0.25f, -0.5f, 0.125f), d(0.0f);
      o[axis] = -5.0f * sign;
      d[axis] = sign;
      rays.push_back(make_ray(o, d));
      expect_t.push_back(4.0f);
    }
  auto hits = f.tracer->closest(rays);
  for (std::size_t i = 0; i < rays.size(); ++i) {
    ASSERT_NE(hits[i].prim, PX_NO_HIT) << "axis ray " << i;
    EXPECT_FLOAT_EQ(hits[i].t, expect_t[i]);
  }
  // Grazing: rays lying in a face's plane and along edges. Either answer is geometrically
  // defensible; what must hold is no NaN/Inf, and t inside the ray interval. Of the nine rays
  // along +x, (y, z) = (0, 0.3) is no grazing ray: it lies in no face's plane (y, z = +-1) and
  // on neither diagonal of the x = -1 face (y = +-z), so it enters that face's interior at
  // (-1, 0, 0.3), t = 4, and must hit it there, with barycentrics that rebuild that point.
  std::vector<Ray> graze;
  std::size_t clean = 0;
  for (float y : {-1.0f, 1.0f, 0.0f})
    for (float z : {-1.0f, 1.0f, 0.3f}) {
      if (y == 0.0f && z == 0.3f) clean = graze.size();
      graze.push_back(make_ray({-5.0f, y, z}, {1.0f, 0.0f, 0.0f}));
    }
  graze.push_back(make_ray({-5.0f, 1.0f, -5.0f}, glm::normalize(glm::vec3(1.0f, 0.0f, 1.0f))));
  auto gh = f.tracer->closest(graze);
  ASSERT_NE(gh[clean].prim, PX_NO_HIT) << "the interior ray (y, z) = (0, 0.3) missed the box";
  EXPECT_FLOAT_EQ(gh[clean].t, 4.0f);
  {
    const SceneTriangle& t = m[gh[clean].prim];
    for (const auto& p : t.p) EXPECT_EQ(p.x, -1.0f) << "hit prim " << gh[clean].prim << " is not on the x = -1 face";
    const glm::vec3 at = (1.0f - gh[clean].u - gh[clean].v) * t.p[0] + gh[clean].u * t.p[1] + gh[clean].v * t.p[2];
    EXPECT_NEAR(at.x, -1.0f, 1e-6f);
    EXPECT_NEAR(at.y, 0.0f, 1e-6f);
    EXPECT_NEAR(at.z, 0.3f, 1e-6f);
    // Embree, independent of our kernels, agrees on the triangle and the distance.
    const Hit ref = EmbreeReference(m).intersect(graze[clean]);
    EXPECT_EQ(ref.prim, gh[clean].prim);
    EXPECT_FLOAT_EQ(ref.t, 4.0f);
  }
  for (std::size_t i = 0; i < graze.size(); ++i) {
    if (gh[i].prim == PX_NO_HIT) continue;
    EXPECT_TRUE(std::isfinite(gh[i].t) && gh[i].t >= 0.0f) << "grazing ray " << i;
    EXPECT_TRUE(std::isfinite(gh[i].u) && std::isfinite(gh[i].v)) << "grazing ray " << i;
  }
  // A ray inside the box along the x axis through its centre must hit the +x face at t = 1.
  auto c = f.tracer->closest({make_ray({0.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f})});
  ASSERT_NE(c[0].prim, PX_NO_HIT);
  EXPECT_FLOAT_EQ(c[0].t, 1.0f);
}

TEST_P(TraceKernels, DegenerateTrianglesAreNeverHit) {
  std::vector<SceneTriangle> m;
  append_box(m, glm::vec3(-1.0f), glm::vec3(1.0f), 0);
  const std::uint32_t first_degenerate = static_cast<std::uint32_t>(m.size());
  // Collinear, coincident, and needle triangles placed in front of the box faces.
  append_triangle(m, {-2, 0, 0}, {2, 0, 0}, {0, 0, 0}, 0);
  append_triangle(m, {0, 0, -1.5f}, {0, 0, -1.5f}, {0, 0, -1.5f}, 0);
  append_triangle(m, {-0.5f, -0.5f, -1.2f}, {0.5f, 0.5f, -1.2f}, {0.0f, 0.0f, -1.2f}, 0);
  TraceFixture f(layout_device(), scene_from(m));
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.6f, 0.6f);
  std::vector<Ray> rays;
  for (int i = 0; i < 2000; ++i) {
    glm::vec3 target(u(rng), u(rng), -1.0f);
    glm::vec3 o(u(rng), u(rng), -4.0f);
    // Some rays aimed exactly at the degenerate triangles' points.
    if (i % 4 == 0) target = {0.0f, 0.0f, -1.2f};
    rays.push_back(make_ray(o, glm::normalize(target - o)));
  }
  auto hits = f.tracer->closest(rays);
  for (std::size_t i = 0; i < hits.size(); ++i) {
    ASSERT_NE(hits[i].prim, PX_NO_HIT) << "ray " << i << " should reach the box";
    EXPECT_LT(hits[i].prim, first_degenerate) << "ray " << i << " hit a degenerate triangle";
  }
}

// Secondary rays leave from the offset hit point. At 1e5 and 1e6 units a fixed epsilon would be
// far below one ULP; the ULP-space offset must still keep rays off their own surface.
TEST_P(TraceKernels, NoSelfIntersectionFarFromOrigin) {
  for (float offset : {0.0f, 1e5f, 1e6f}) {
    const float scale = offset >= 1e6f ? 100.0f : 10.0f;  // keep triangles many ULPs wide
    const glm::vec3 shift(offset, -0.5f * offset, 0.25f * offset);
    std::vector<SceneTriangle> m;
    append_icosphere(m, shift, 1.0f * scale, 3, 0);
    append_box(m, shift + glm::vec3(2.0f, -1.0f, -1.0f) * scale, shift + glm::vec3(3.0f, 1.0f, 1.0f) * scale, 0);
    TraceFixture f(layout_device(), scene_from(m));
    std::mt19937 rng(static_cast<std::uint32_t>(offset) + 1);
    std::vector<Ray> primary;
    for (int i = 0; i < 2000; ++i) {
      const glm::vec3 o = shift + 6.0f * scale * test::random_unit(rng);
      const glm::vec3 target = shift + 0.5f * scale * test::random_unit(rng);
      primary.push_back(make_ray(o, glm::normalize(target - o)));
    }
    auto hits = f.tracer->closest(primary);
    std::vector<glm::vec3> points, normals;
    std::vector<std::uint32_t> prims;
    for (std::size_t i = 0; i < hits.size(); ++i) {
      if (hits[i].prim == PX_NO_HIT) continue;
      const auto& t = m[hits[i].prim];
      const float w = 1.0f - hits[i].u - hits[i].v;
      points.push_back(w * t.p[0] + hits[i].u * t.p[1] + hits[i].v * t.p[2]);
      glm::vec3 n = geometric_normal(t);
      const glm::vec3 d(primary[i].dir[0], primary[i].dir[1], primary[i].dir[2]);
      if (glm::dot(n, d) > 0.0f) n = -n;  // leave on the side the ray came from
      normals.push_back(n);
      prims.push_back(hits[i].prim);
    }
    ASSERT_GT(points.size(), 1000u);
    auto origins = f.tracer->offset_origins(points, normals);
    std::vector<Ray> secondary;
    for (std::size_t i = 0; i < origins.size(); ++i) {
      // The offset point lies strictly on the outer side of the surface's plane.
      const auto& t = m[prims[i]];
      const double side = glm::dot(glm::dvec3(origins[i]) - glm::dvec3(t.p[0]), glm::dvec3(normals[i]));
      EXPECT_GT(side, 0.0) << "offset " << offset << " point " << i;
      // Directions in the outer hemisphere: a convex closed mesh is never hit again.
      glm::vec3 d = test::random_unit(rng);
      if (glm::dot(d, normals[i]) < 0.0f) d = -d;
      secondary.push_back(make_ray(origins[i], d));
    }
    auto again = f.tracer->closest(secondary);
    int self_hits = 0;
    for (std::size_t i = 0; i < again.size(); ++i) self_hits += again[i].prim == prims[i];
    EXPECT_EQ(self_hits, 0) << "at offset " << offset;
  }
}

// Hits count in the open interval (tmin, tmax), as in Embree. A ray that starts exactly on a
// triangle (in its plane inside it, or at one of its vertices) computes t = +0 or -0 there;
// with tmin = 0 a closed lower end made that a hit at distance zero, so such a ray never left
// its surface. Offset origins hide this in the renderer, but not for every leaf layout.
TEST_P(TraceKernels, RaysStartingOnATriangleDoNotHitItAtZeroDistance) {
  // In the plane: a floor at z = 0 and a ceiling at z = 1 above it.
  std::vector<SceneTriangle> planes;
  append_triangle(planes, {-1.0f, -1.0f, 0.0f}, {3.0f, -1.0f, 0.0f}, {-1.0f, 3.0f, 0.0f}, 0);
  append_triangle(planes, {-9.0f, -9.0f, 1.0f}, {27.0f, -9.0f, 1.0f}, {-9.0f, 27.0f, 1.0f}, 0);
  {
    TraceFixture f(layout_device(), scene_from(planes));
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> in(-0.5f, 0.5f);
    std::vector<Ray> rays;
    for (int i = 0; i < 400; ++i) {
      // z dominant: the shear then keeps the floor's z differences exactly 0, so t is exactly
      // +-0 (with another dominant axis t is the rounding noise of a ray in the plane, ~1e-7
      // either way, which is what offset origins exist for).
      glm::vec3 d = test::random_unit(rng);
      d.z = std::copysign(std::max(std::abs(d.z), 1.01f * std::max(std::abs(d.x), std::abs(d.y))), d.z);
      rays.push_back(make_ray({in(rng), in(rng), 0.0f}, glm::normalize(d)));
    }
    auto hits = f.tracer->closest(rays);
    auto occ = f.tracer->occluded(rays);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const bool up = rays[i].dir[2] > 0.0f;
      const auto ref = brute_force_closest(f.scene.triangles, rays[i]);
      EXPECT_EQ(hits[i].prim, up ? 1u : PX_NO_HIT) << "ray " << i << " t=" << hits[i].t;
      EXPECT_EQ(ref.prim, up ? 1u : PX_NO_HIT) << "reference, ray " << i;
      EXPECT_EQ(static_cast<bool>(occ[i]), up) << "any hit, ray " << i;
    }
  }
  // At a vertex: rays leave each vertex of a convex icosphere radially outwards and hit
  // nothing; the vertex is on five or six triangles, every one of which computes t = 0.
  std::vector<SceneTriangle> sphere;
  const glm::vec3 centre(0.3f, -0.2f, 0.1f);
  append_icosphere(sphere, centre, 1.5f, 2, 0);
  TraceFixture f(layout_device(), scene_from(sphere));
  std::vector<Ray> rays;
  for (const auto& t : sphere)
    for (const auto& p : t.p) rays.push_back(make_ray(p, glm::normalize(p - centre)));
  auto hits = f.tracer->closest(rays);
  auto occ = f.tracer->occluded(rays);
  int zero_hits = 0, blocked = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    zero_hits += hits[i].prim != PX_NO_HIT;
    blocked += occ[i] != 0;
  }
  EXPECT_EQ(zero_hits, 0) << "of " << rays.size() << " rays from vertices";
  EXPECT_EQ(blocked, 0) << "of " << rays.size() << " rays from vertices";
}

TEST_P(TraceKernels, AlphaCutoutsPassThroughTransparentTexels) {
  Scene s;
  s.materials.resize(2);
  Texture alpha;
  alpha.width = 4;
  alpha.height = 1;
  // Texels left to right: transparent, transparent, opaque, opaque.
  alpha.rgba = {1, 1, 1, 0, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1, 1, 1};
  s.textures.push_back(alpha);
  s.materials[1].alpha_texture = 0;
  // A card in the z = 0 plane, u along x, and a wall behind it at z = 5.
  append_quad(s.triangles, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, 1);
  append_quad(s.triangles, {-3, -3, 5}, {3, -3, 5}, {3, 3, 5}, {-3, 3, 5}, 0);
  TraceFixture f(layout_device(), s, true, /*keep_alpha=*/true);
  std::vector<Ray> rays;
  for (float y : {-0.7f, 0.0f, 0.6f})
    for (float u : {0.05f, 0.15f, 0.3f, 0.7f, 0.85f, 0.95f})
      rays.push_back(make_ray({2.0f * u - 1.0f, y, -2.0f}, {0, 0, 1}));
  auto hits = f.tracer->closest(rays);
  auto occ = f.tracer->occluded(rays);
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const float u = 0.5f * (rays[i].org[0] + 1.0f);
    ASSERT_NE(hits[i].prim, PX_NO_HIT);
    EXPECT_TRUE(occ[i]);
    if (u < 0.5f) {
      EXPECT_GE(hits[i].prim, 2u) << "u=" << u << ": should pass the cut-out and reach the wall";
      EXPECT_FLOAT_EQ(hits[i].t, 7.0f);
    } else {
      EXPECT_LT(hits[i].prim, 2u) << "u=" << u << ": opaque texel should stop the ray";
      EXPECT_FLOAT_EQ(hits[i].t, 2.0f);
    }
  }
  // Occlusion rays that end before the wall: blocked only by opaque texels.
  for (auto& r : rays) r.tmax = 4.0f;
  occ = f.tracer->occluded(rays);
  for (std::size_t i = 0; i < rays.size(); ++i)
    EXPECT_EQ(occ[i] != 0, 0.5f * (rays[i].org[0] + 1.0f) >= 0.5f) << "ray " << i;
}

// The image (here: the hit list) must not depend on how many devices shared the work, nor on
// how those devices were made.
TEST_P(TraceKernels, SameHitsWithOneTwoAndFourDevices) {
  Scene s = make_builtin_scene("cornell-glossy");
  auto rays = random_rays(s.triangles, 5000, 77);
  std::vector<Hit> reference;
  for (auto [count, mode] : {std::pair{1, DeviceMode::Auto},
                             {2, DeviceMode::Auto},
                             {4, DeviceMode::Auto},
                             {2, DeviceMode::SharedQueues},
                             {3, DeviceMode::SharedQueues}}) {
    DeviceSet set = DeviceSet::create(layout_options(count, mode));
    ASSERT_EQ(set.size(), count);
    TraceFixture f(set, s);
    auto hits = f.tracer->closest(rays);
    if (reference.empty()) {
      reference = hits;
      continue;
    }
    ASSERT_EQ(hits.size(), reference.size());
    EXPECT_EQ(0, std::memcmp(hits.data(), reference.data(), hits.size() * sizeof(Hit)))
        << count << " devices (" << to_string(set.mode()) << ") differ from 1 device";
  }
}

// trace_closest_pairs walks two rays a work-item in step (RayBatchTracer::closest); each walk must
// be the one-ray kernel's, so every hit is the same to the bit. The rays mix long and short
// walks (inside the atrium, and from outside pointing away: a pair whose walks end far apart),
// finite tmax, and an odd count (the last work-item has one ray).
TEST_P(TraceKernels, TwoRaysAWorkItemGiveTheOneRayKernelsHits) {
  for (bool splits : {false, true}) {
    TraceFixture f(layout_device(), make_builtin_scene("atrium", {{"detail", 0.05}}), splits);
    auto rays = random_rays(f.scene.triangles, 3001, 21);
    const auto bb = bounds_of(f.scene.triangles);
    for (std::size_t i = 0; i < rays.size(); i += 3) {
      if (i % 2 == 0) {
        rays[i].tmax = 0.05f * (1.0f + static_cast<float>(i % 7));
      } else {  // from beyond the box, away from it: no node but the root is entered
        const glm::vec3 far = bb.hi + glm::vec3(1.0f + static_cast<float>(i % 5));
        rays[i] = make_ray(far, glm::normalize(glm::vec3(1.0f, 0.5f, 0.25f)));
      }
    }
    const auto paired = f.tracer->closest(rays);
    const auto single = f.tracer->closest_one_per_item(rays);
    ASSERT_EQ(paired.size(), single.size());
    int differ = 0, hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      differ += std::memcmp(&paired[i], &single[i], sizeof(Hit)) != 0;
      hits += single[i].prim != PX_NO_HIT;
    }
    EXPECT_EQ(differ, 0) << (splits ? "with" : "without") << " spatial splits";
    EXPECT_GT(hits, static_cast<int>(rays.size()) / 4) << "too few hits to say anything";
  }
}

// An alpha-tested leaf is tested lane-wise, its geometric hits then tried nearest first through
// their cut-outs; a build with PX_ALPHA_LEAVES_ONE_BY_ONE tests such leaves triangle by triangle
// as before (px_intersect_leaf). Both must give every ray the same hit to the bit, closest and
// any, on the atrium's foliage: clouds of alpha-masked cards, where a ray's nearest geometric
// hit in a leaf is often cut away and the next one is not.
TEST_P(TraceKernels, AlphaLeavesTestedByLaneGiveTheOneByOneHits) {
  TraceFixture f(layout_device(), make_builtin_scene("atrium", {{"detail", 0.05}}), true, /*keep_alpha=*/true);
  RayBatchTracer one_by_one(layout_device(), *f.device_scene, "-DPX_ALPHA_LEAVES_ONE_BY_ONE=1");
  TraceFixture opaque(layout_device(), f.scene);  // the same cards with their cut-outs dropped
  // Rays from points on the foliage cards into random directions (short ones too), and random
  // rays through the whole scene.
  std::vector<Ray> rays = random_rays(f.scene.triangles, 2001, 31);
  std::mt19937 rng(32);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<std::size_t> cards;
  for (std::size_t i = 0; i < f.scene.triangles.size(); ++i)
    if (f.scene.materials[f.scene.triangles[i].material].alpha_texture >= 0) cards.push_back(i);
  ASSERT_GT(cards.size(), 100u) << "the scene has too few foliage cards to say anything";
  for (int i = 0; i < 6000; ++i) {
    const SceneTriangle& t = f.scene.triangles[cards[rng() % cards.size()]];
    const float a = unit(rng), b = unit(rng) * (1.0f - a);
    const glm::vec3 p = t.p[0] + a * (t.p[1] - t.p[0]) + b * (t.p[2] - t.p[0]);
    Ray r = make_ray(p + 0.05f * test::random_unit(rng), test::random_unit(rng));
    if (i % 3 == 0) r.tmax = 0.5f;
    rays.push_back(r);
  }
  const auto lanes = f.tracer->closest(rays);
  const auto reference = one_by_one.closest(rays);
  const auto lanes_single = f.tracer->closest_one_per_item(rays);
  const auto lanes_any = f.tracer->occluded(rays);
  const auto reference_any = one_by_one.occluded(rays);
  const auto without_cutouts = opaque.tracer->closest(rays);
  int differ = 0, differ_single = 0, differ_any = 0, cut = 0, hits = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    differ += std::memcmp(&lanes[i], &reference[i], sizeof(Hit)) != 0;
    differ_single += std::memcmp(&lanes_single[i], &reference[i], sizeof(Hit)) != 0;
    differ_any += lanes_any[i] != reference_any[i];
    cut += without_cutouts[i].prim != reference[i].prim;
    hits += reference[i].prim != PX_NO_HIT;
  }
  EXPECT_EQ(differ, 0) << "closest hits (pairs on CPUs) of " << rays.size() << " rays";
  EXPECT_EQ(differ_single, 0) << "closest hits, one ray a work-item, of " << rays.size() << " rays";
  EXPECT_EQ(differ_any, 0) << "any hits of " << rays.size() << " rays";
  // The cut-outs decide many of these rays' hits, so the comparison above is not vacuous.
  EXPECT_GT(cut, static_cast<int>(rays.size()) / 10) << "rays whose hit a cut-out changed";
  EXPECT_GT(hits, static_cast<int>(rays.size()) / 2);
}

TEST(BvhLayoutChoice, EachDeviceTypeHasItsDefaultUnlessALayoutIsRequested) {
  EXPECT_EQ(bvh_layout_for(false), BvhLayout::Wide8);
  EXPECT_EQ(bvh_layout_for(true), BvhLayout::Binary);
  DeviceSet& set = one_device();
  const bool gpus =
      std::all_of(set.devices().begin(), set.devices().end(), [](const ComputeDevice& d) { return d.is_gpu(); });
  EXPECT_FALSE(set.bvh_layout_requested());
  EXPECT_EQ(set.bvh_layout(), gpus ? BvhLayout::Binary : BvhLayout::Wide8);
  const DeviceSet binary = DeviceSet::create(test::options_in_layout(BvhLayout::Binary));
  EXPECT_TRUE(binary.bvh_layout_requested());
  EXPECT_EQ(binary.bvh_layout(), BvhLayout::Binary);
}

// A DeviceScene may get a tree made for another layout (load_and_build collapses for CPUs) and
// makes the nodes its set traverses: here a binary-only tree uploaded to a set asked for cwbvh.
TEST(BvhLayoutChoice, DeviceSceneMakesTheNodesItsSetTraverses) {
  Scene scene = scene_from(random_soup(2000, 5));
  const FlatBvh bvh = build_bvh(scene.triangles, {}, BvhLayout::Binary);
  ASSERT_TRUE(bvh.nodes8.empty() && bvh.cnodes.empty());
  DeviceSet& cwbvh = test::device_in_layout(BvhLayout::Compressed8);
  DeviceScene device_scene(cwbvh, scene, bvh);
  EXPECT_EQ(device_scene.layout(), BvhLayout::Compressed8);
  RayBatchTracer tracer(cwbvh, device_scene);
  const auto rays = random_rays(scene.triangles, 2000, 9);
  expect_matches_brute_force(scene.triangles, rays, tracer.closest(rays));
}

INSTANTIATE_TEST_SUITE_P(Layouts, TraceKernels, test::all_bvh_layouts(), test::bvh_layout_name);

}  // namespace
}  // namespace px
