// Instances and the two-level BVH: a mesh drawn by several nodes is stored once and traversed
// through a top level. Every check compares with a second code path: the same scene flattened
// into world-space copies (flatten_instances, or the loader without instancing), traced by
// Embree or by the one-level kernels, rendered by the same path tracer.
#include "bvh/bvh_builder.h"
#include "bvh/embree_reference.h"
#include "bvh/flat_bvh.h"
#include "bvh/scene_bvhs.h"
#include "bvh/top_level_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "scene/instancing.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"
#include "support/brute_force.h"
#include "support/bvh_layout_test.h"
#include "support/gltf_builder.h"
#include "support/test_support.h"
#include "trace/ray_batch_tracer.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

namespace px {
namespace {

using nlohmann::json;

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

// A random placement: rotation about a random axis, non-uniform scale, translation in a box.
glm::mat4 random_placement(std::mt19937& rng, float spread) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), s(0.5f, 1.5f);
  glm::mat4 m = glm::translate(glm::mat4(1.0f), spread * glm::vec3(u(rng), u(rng), u(rng)));
  m = glm::rotate(m, 3.14159265f * u(rng), test::random_unit(rng));
  return glm::scale(m, glm::vec3(s(rng), s(rng), s(rng)));
}

// A ground quad (the world's own triangles, unless `with_world` is false) and `count` instances
// of an icosphere with a bump (so that it is not symmetric), all diffuse, under a sky.
Scene instanced_scene(int count, bool with_world, std::uint32_t seed, int subdivisions = 2) {
  Scene s;
  s.name = "instances";
  Material grey, red;
  grey.diffuse = glm::vec3(0.6f);
  red.diffuse = glm::vec3(0.7f, 0.3f, 0.2f);
  s.materials = {grey, red};
  if (with_world)
    append_quad(s.triangles, {-8.0f, -3.0f, -8.0f}, {8.0f, -3.0f, -8.0f}, {8.0f, -3.0f, 8.0f}, {-8.0f, -3.0f, 8.0f}, 0);
  SceneInstancing in;
  in.world_triangles = s.triangles.size();
  InstancedMesh mesh;
  mesh.first = s.triangles.size();
  append_icosphere(s.triangles, glm::vec3(0.0f), 0.6f, subdivisions, 1);
  append_triangle(s.triangles, {0.0f, 0.5f, 0.0f}, {0.9f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.9f}, 1);
  mesh.count = s.triangles.size() - mesh.first;
  in.meshes.push_back(mesh);
  std::mt19937 rng(seed);
  for (int i = 0; i < count; ++i) in.instances.push_back({0, random_placement(rng, 5.0f)});
  s.instancing = std::move(in);
  s.sky.enabled = true;
  s.sky.zenith = glm::vec3(1.0f);
  s.sky.horizon = glm::vec3(0.8f);
  s.sky.ground = glm::vec3(0.3f);
  s.camera.position = glm::vec3(0.0f, 4.0f, 14.0f);
  s.camera.target = glm::vec3(0.0f);
  s.camera.vfov_deg = 50.0f;
  return s;
}

Scene flattened(Scene s) {
  flatten_instances(s);
  return s;
}

std::vector<Ray> rays_through(const Scene& flat, int count, std::uint32_t seed) {
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const SceneTriangle& t : flat.triangles)
    for (const glm::vec3& p : t.p) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  const glm::vec3 c = 0.5f * (lo + hi), h = 0.6f * (hi - lo);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays;
  for (int i = 0; i < count; ++i)
    rays.push_back(test::make_ray(c + h * glm::vec3(u(rng), u(rng), u(rng)), test::random_unit(rng)));
  return rays;
}

// ---------------------------------------------------------------------------------------------

TEST(TopLevelBvh, EveryInstanceLiesInOneLeafInsideEveryBoxAboveIt) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100.0f, 100.0f), e(0.1f, 5.0f);
  for (int n : {1, 2, 3, 1000}) {
    std::vector<InstanceBox> boxes(static_cast<std::size_t>(n));
    for (auto& b : boxes) {
      const glm::vec3 c(u(rng), u(rng), u(rng));
      b.lo = c - glm::vec3(e(rng));
      b.hi = c + glm::vec3(e(rng));
    }
    const TopLevelBvh top = build_top_level(boxes);
    ASSERT_FALSE(top.nodes.empty());
    ASSERT_EQ(top.order.size(), boxes.size());
    std::vector<int> seen(boxes.size(), 0);
    // Walk from the root; every leaf instance must lie inside the box of its slot.
    std::vector<std::uint32_t> stack{0};
    std::size_t visited_nodes = 0;
    while (!stack.empty()) {
      const BvhNode node = top.nodes.at(stack.back());
      stack.pop_back();
      ++visited_nodes;
      const auto slot = [&](const float* lo, const float* hi, std::uint32_t index, std::uint32_t count) {
        if (count == 0 && index == 0 && is_absent_box(lo, hi)) return;
        if (count == 0) {
          ASSERT_LT(index, top.nodes.size());
          // A child node's own boxes lie inside this slot's box.
          const BvhNode& c = top.nodes[index];
          for (int a = 0; a < 3; ++a) {
            EXPECT_LE(lo[a], c.lmin[a]);
            EXPECT_GE(hi[a], c.lmax[a]);
            if (!(c.right_count == 0 && c.right == 0 && is_absent_box(c.rmin, c.rmax))) {
              EXPECT_LE(lo[a], c.rmin[a]);
              EXPECT_GE(hi[a], c.rmax[a]);
            }
          }
          stack.push_back(index);
          return;
        }
        EXPECT_LE(count, std::uint32_t(PX_TLAS_MAX_LEAF));
        for (std::uint32_t k = index; k < index + count; ++k) {
          ASSERT_LT(k, top.order.size());
          const InstanceBox& b = boxes[top.order[k]];
          ++seen[top.order[k]];
          for (int a = 0; a < 3; ++a) {
            EXPECT_LE(lo[a], b.lo[a]);
            EXPECT_GE(hi[a], b.hi[a]);
          }
        }
      };
      slot(node.lmin, node.lmax, node.left, node.left_count);
      slot(node.rmin, node.rmax, node.right, node.right_count);
    }
    EXPECT_EQ(visited_nodes, top.nodes.size()) << n << " instances: every node reached once";
    for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_EQ(seen[i], 1) << "instance " << i << " of " << n;
    // Median splits: depth ceil(log2(n / 2)) + 1 at most.
    const int bound = n <= 2 ? 1 : int(std::ceil(std::log2(double(n) / 2.0))) + 1;
    EXPECT_LE(top.depth, bound) << n << " instances";
  }
}

TEST(Instancing, FlattenedTrianglesAreTheMeshPlacedByEachMatrix) {
  const Scene s = instanced_scene(5, true, 3);
  check_instancing(s);
  const Scene flat = flattened(s);
  EXPECT_TRUE(flat.instancing.empty());
  ASSERT_EQ(flat.triangles.size(), drawn_triangle_count(s));
  const InstancedMesh& m = s.instancing.meshes[0];
  // Triangle j of instance i, placed by hand (double precision), against the flat copy.
  for (std::size_t i = 0; i < s.instancing.instances.size(); ++i)
    for (std::size_t j = 0; j < m.count; j += 7) {
      const glm::dmat4 w(s.instancing.instances[i].object_to_world);
      const SceneTriangle& src = s.triangles[m.first + j];
      const SceneTriangle& got = flat.triangles[s.instancing.world_triangles + i * m.count + j];
      for (int c = 0; c < 3; ++c) {
        const glm::dvec3 p(w * glm::dvec4(glm::dvec3(src.p[c]), 1.0));
        const glm::dvec3 n = glm::normalize(glm::transpose(glm::inverse(glm::dmat3(w))) * glm::dvec3(src.n[c]));
        for (int a = 0; a < 3; ++a) {
          EXPECT_NEAR(got.p[c][a], p[a], 1e-5);
          EXPECT_NEAR(got.n[c][a], n[a], 1e-5);
        }
      }
    }
  // The world bounds seen through for_each_drawn_triangle are the flat copy's.
  glm::vec3 lo(1e30f), hi(-1e30f), flo(1e30f), fhi(-1e30f);
  for_each_drawn_triangle(s, [&](const glm::vec3* p, std::size_t) {
    for (int c = 0; c < 3; ++c) lo = glm::min(lo, p[c]), hi = glm::max(hi, p[c]);
  });
  for (const SceneTriangle& t : flat.triangles)
    for (const glm::vec3& p : t.p) flo = glm::min(flo, p), fhi = glm::max(fhi, p);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(lo[a], flo[a], 1e-5f);
    EXPECT_NEAR(hi[a], fhi[a], 1e-5f);
  }
}

TEST(Instancing, DrawnBoundsInPartsAreTheBoundsOfEveryDrawnTriangle) {
  // The one-by-one pass over for_each_drawn_triangle is the reference: the bounds (NaN passed
  // over), whether every coordinate is in range, and whether anything is drawn.
  const auto one_by_one = [](const Scene& s) {
    DrawnBounds b;
    for_each_drawn_triangle(s, [&](const glm::vec3* p, std::size_t) {
      b.any = true;
      for (int c = 0; c < 3; ++c) {
        for (int a = 0; a < 3; ++a) b.in_range &= std::abs(p[c][a]) <= kMaxSceneCoordinate;
        b.lo = glm::min(b.lo, p[c]);
        b.hi = glm::max(b.hi, p[c]);
      }
    });
    return b;
  };
  const auto expect_same = [](const DrawnBounds& got, const DrawnBounds& want, const char* label) {
    EXPECT_EQ(got.any, want.any) << label;
    EXPECT_EQ(got.in_range, want.in_range) << label;
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(got.lo[a], want.lo[a]) << label << " axis " << a;
      EXPECT_EQ(got.hi[a], want.hi[a]) << label << " axis " << a;
    }
  };
  // Instances placed by their matrices (one part: a small world).
  const Scene instanced = instanced_scene(5, true, 3);
  expect_same(drawn_bounds(instanced), one_by_one(instanced), "instanced");
  // A world large enough to be read in parts, with its extremes in the last part.
  Scene big;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  big.triangles.resize((std::size_t{1} << 20) + 4097);
  for (SceneTriangle& t : big.triangles)
    for (glm::vec3& p : t.p) p = {u(rng), u(rng), u(rng)};
  big.triangles.back().p[1] = {-7.0f, 9.0f, 6.5f};
  expect_same(drawn_bounds(big), one_by_one(big), "large world");
  EXPECT_EQ(drawn_bounds(big).lo.x, -7.0f);
  EXPECT_EQ(drawn_bounds(big).hi.y, 9.0f);
  // A coordinate beyond the range in the last part, a NaN in the first.
  big.triangles[big.triangles.size() - 10].p[2].z = 3e11f;
  big.triangles[3].p[0].y = std::nanf("");
  const DrawnBounds out = drawn_bounds(big);
  expect_same(out, one_by_one(big), "out of range and NaN");
  EXPECT_FALSE(out.in_range);
  EXPECT_EQ(out.hi.z, 3e11f);
  // Nothing drawn.
  expect_same(drawn_bounds(Scene{}), one_by_one(Scene{}), "empty");
  EXPECT_FALSE(drawn_bounds(Scene{}).any);
}

TEST(Instancing, BadInstancingIsRefused) {
  Scene s = instanced_scene(2, true, 1);
  s.instancing.instances[1].object_to_world = glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, 1.0f, 1.0f));
  EXPECT_THROW(check_instancing(s), std::logic_error) << "a mirroring matrix";
  s = instanced_scene(2, true, 1);
  s.instancing.instances[0].mesh = 3;
  EXPECT_THROW(check_instancing(s), std::logic_error) << "no such mesh";
  s = instanced_scene(2, true, 1);
  s.instancing.meshes[0].count += 1;
  EXPECT_THROW(check_instancing(s), std::logic_error) << "a mesh beyond the triangles";
}

// ---------------------------------------------------------------------------------------------
// The loader: a mesh drawn by several nodes is stored once.

using Gltf = test::GltfBuilder;

// Three meshes: 0 (a quad and a triangle) drawn by three nodes, one of them mirrored; 1 drawn
// once; 2 (emissive) drawn twice.
std::filesystem::path write_shared_meshes(const test::TempDir& dir) {
  Gltf g;
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0, 3, 0, 0, 2, 1, 0};
  const std::vector<std::uint16_t> idx = {0, 1, 2, 0, 2, 3, 4, 5, 6};
  const int p = g.floats(pos, "VEC3", pos.size() / 3);
  const int i = g.uint16s(idx, "SCALAR", idx.size());
  const json prim0 = {{"attributes", {{"POSITION", p}}}, {"indices", i}, {"material", 0}};
  const json prim2 = {{"attributes", {{"POSITION", p}}}, {"indices", i}, {"material", 1}};
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1.0}}}}});
  g.add("materials", {{"emissiveFactor", {1.0, 1.0, 1.0}}});
  g.add("meshes", {{"primitives", json::array({prim0})}});
  g.add("meshes", {{"primitives", json::array({prim0})}});
  g.add("meshes", {{"primitives", json::array({prim2})}});
  const double h = std::sqrt(0.5);
  g.add("nodes", {{"mesh", 0}, {"translation", {0, 0, 0}}});
  g.add("nodes", {{"mesh", 0}, {"translation", {5, 0, 0}}, {"rotation", {0, h, 0, h}}, {"scale", {2, 1, 3}}});
  g.add("nodes", {{"mesh", 0}, {"translation", {0, 5, 0}}, {"scale", {-1, 1, 1}}});
  g.add("nodes", {{"mesh", 1}, {"translation", {0, 0, 5}}});
  g.add("nodes", {{"mesh", 2}, {"translation", {0, -5, 0}}});
  g.add("nodes", {{"mesh", 2}, {"translation", {0, -9, 0}}});
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", json::array({0, 1, 2, 3, 4, 5})}}});
  g.doc["buffers"] = json::array(
      {{{"byteLength", g.bin.size()}, {"uri", "data:application/octet-stream;base64," + test::base64(g.bin)}}});
  return dir.write("shared.gltf", g.doc.dump());
}

// The drawn triangles' corners in a canonical order (sorted), for comparing two scenes whose
// triangle order differs.
std::vector<std::array<float, 9>> sorted_corners(const Scene& s) {
  std::vector<std::array<float, 9>> out;
  for_each_drawn_triangle(s, [&](const glm::vec3* p, std::size_t) {
    std::array<float, 9> t{};
    for (int c = 0; c < 3; ++c)
      for (int a = 0; a < 3; ++a) t[std::size_t(3 * c + a)] = std::round(p[c][a] * 1e4f) / 1e4f;
    out.push_back(t);
  });
  std::sort(out.begin(), out.end());
  return out;
}

TEST(Instancing, TheLoaderStoresASharedMeshOnceAndDrawsWhatAFlatLoadDraws) {
  test::TempDir dir;
  const auto path = write_shared_meshes(dir);
  const Scene s = load_gltf(path.string());
  check_instancing(s);
  // Mesh 0 is instanced by its two unmirrored nodes; its mirrored node, mesh 1 (drawn once) and
  // the emissive mesh 2 are flat: 3 + 3 + 2 x 3 world triangles, then mesh 0 once (3).
  ASSERT_EQ(s.instancing.meshes.size(), 1u);
  EXPECT_EQ(s.instancing.instances.size(), 2u);
  EXPECT_EQ(s.instancing.world_triangles, 12u);
  EXPECT_EQ(s.triangles.size(), 15u);
  EXPECT_EQ(drawn_triangle_count(s), 18u);
  SceneLoadOptions flat;
  flat.instancing = false;
  const Scene flat_load = load_gltf(path.string(), flat);
  EXPECT_TRUE(flat_load.instancing.empty());
  EXPECT_EQ(flat_load.triangles.size(), 18u);
  const auto a = sorted_corners(s), b = sorted_corners(flat_load), c = sorted_corners(flattened(s));
  EXPECT_EQ(a, b) << "the instanced scene draws the triangles a flat load draws";
  EXPECT_EQ(c, b) << "flatten_instances gives them back";
}

// ---------------------------------------------------------------------------------------------
// Traversal, in every node layout.

class InstancedTrace : public test::BvhLayoutTest {};

// Closest hits and occlusion of the instanced scene on the device against Embree on its flat
// copy: the same distance where both hit, the same answer nearly everywhere (a ray that grazes
// an edge may see it on one side and not the other, as transformed vertices round differently).
void expect_traces_like_embree(DeviceSet& devices, const Scene& scene, const char* label) {
  const Scene flat = flattened(scene);
  DeviceScene device_scene(devices, scene, build_world_bvh(scene));
  EXPECT_NE(device_scene.kernel_features() & PX_FEATURE_INSTANCES, 0u);
  RayBatchTracer tracer(devices, device_scene);
  const std::vector<Ray> rays = rays_through(flat, 20000, 11);
  const std::vector<Hit> hits = tracer.closest(rays);
  const std::vector<std::uint32_t> occluded = tracer.occluded(rays);
  const EmbreeReference embree(flat.triangles);
  int disagree = 0, hits_both = 0, occl_disagree = 0;
  const std::size_t stored = scene.triangles.size();
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const Hit ref = embree.intersect(rays[i]);
    const Hit& h = hits[i];
    if ((ref.prim == PX_NO_HIT) != (h.prim == PX_NO_HIT)) {
      ++disagree;
      continue;
    }
    if (occluded[i] != (ref.prim != PX_NO_HIT ? 1u : 0u)) ++occl_disagree;
    if (ref.prim == PX_NO_HIT) continue;
    ++hits_both;
    ASSERT_LT(h.prim, stored) << label << ": hit.prim indexes the stored triangles";
    // Instance hits name an instance and a mesh triangle; world hits name no instance.
    const bool on_mesh = h.prim >= scene.instancing.world_triangles;
    EXPECT_EQ(on_mesh, h.inst != PX_NO_INSTANCE) << label << " ray " << i;
    if (on_mesh) {
      EXPECT_LT(h.inst, scene.instancing.instances.size()) << label;
    }
    EXPECT_NEAR(h.t, ref.t, 1e-4 * std::max(1.0f, ref.t)) << label << " ray " << i;
  }
  EXPECT_GT(hits_both, 2000) << label << ": the rays must find the geometry";
  EXPECT_LE(disagree, 4) << label << ": hit / miss differs from Embree on the flat copy";
  EXPECT_LE(occl_disagree, 4) << label << ": occlusion differs from Embree on the flat copy";
}

TEST_P(InstancedTrace, HitsWhatEmbreeHitsInTheSceneFlattened) {
  expect_traces_like_embree(layout_device(), instanced_scene(60, true, 5), "instances over a ground quad");
  expect_traces_like_embree(layout_device(), instanced_scene(60, false, 6), "instances only (no world triangles)");
  expect_traces_like_embree(layout_device(), instanced_scene(1, true, 7), "one instance");
}

INSTANTIATE_TEST_SUITE_P(Layouts, InstancedTrace, test::all_bvh_layouts(), test::bvh_layout_name);

// ---------------------------------------------------------------------------------------------
// Images and memory.

double psnr(const ImageRGB& a, const ImageRGB& b) {
  double peak = 0.0, se = 0.0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    peak = std::max(peak, double(b.rgb[i]));
    se += (double(a.rgb[i]) - b.rgb[i]) * (double(a.rgb[i]) - b.rgb[i]);
  }
  const double mse = se / double(a.rgb.size());
  return mse > 0.0 ? 10.0 * std::log10(peak * peak / mse) : 200.0;
}

double mean(const ImageRGB& img) {
  double s = 0;
  for (float v : img.rgb) s += v;
  return s / double(img.rgb.size());
}

TEST(Instancing, RendersTheImageOfTheSceneFlattened) {
  // The same path tracer, the same samples: geometry placed on the device (instances) or on
  // the host (flat copy) differs by rounding only, so a path may rarely part ways at an edge.
  const Scene scene = instanced_scene(40, true, 9);
  const Scene flat = flattened(scene);
  DeviceScene inst_dev(one_device(), scene, build_world_bvh(scene));
  DeviceScene flat_dev(one_device(), flat, build_bvh(flat.triangles));
  PathTracer inst_tracer(one_device(), inst_dev, scene);
  PathTracer flat_tracer(one_device(), flat_dev, flat);
  PathTracer::Options opt;
  opt.spp = 4;
  const auto a = inst_tracer.render_stereo(0.0f, 0, 96, 64, opt);
  const auto b = flat_tracer.render_stereo(0.0f, 0, 96, 64, opt);
  for (int eye = 0; eye < 2; ++eye) {
    EXPECT_GT(psnr(a[eye], b[eye]), 45.0) << "eye " << eye;
    EXPECT_NEAR(mean(a[eye]), mean(b[eye]), 1e-3 * mean(b[eye])) << "eye " << eye;
  }
  EXPECT_EQ(inst_tracer.nonfinite_paths(), 0u);
}

TEST(Instancing, AThousandInstancesCostLittleMoreDeviceMemoryThanOne) {
  // A 5k-triangle mesh: 1,024 instances add their records and top level, not their triangles.
  const Scene one = instanced_scene(1, false, 2, 4);
  const Scene many = instanced_scene(1024, false, 2, 4);
  ASSERT_GT(one.triangles.size(), 5000u);
  DeviceScene one_dev(one_device(), one, build_world_bvh(one));
  DeviceScene many_dev(one_device(), many, build_world_bvh(many));
  EXPECT_EQ(many_dev.instance_count(), 1024u);
  EXPECT_LE(double(many_dev.bytes_in_context()), 1.5 * double(one_dev.bytes_in_context()))
      << one_dev.bytes_in_context() << " bytes for one instance, " << many_dev.bytes_in_context() << " for 1,024";
}

}  // namespace
}  // namespace px
