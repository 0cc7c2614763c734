// The scene on the devices (render/device_scene.h): one copy per OpenCL context, whatever the
// number of devices, and a buffer too large for one allocation refused with an error that
// names it and both sizes (PARALLAX_MAX_ALLOC_BYTES lowers the device's limit for the test).
#include "app/scene_setup.h"
#include "bvh/bvh_cache.h"
#include "bvh/bvh_validator.h"
#include "render/device_scene.h"
#include "render/indexed_shading.h"
#include "render/path_tracer.h"
#include "render/scene_tables.h"
#include "scene/scene_loader.h"
#include "scene/primitives.h"
#include "scene/scene_rig.h"
#include "support/bvh_layout_test.h"
#include "support/gltf_builder.h"
#include "support/scoped_env.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace px {
namespace {

Scene spheres() {
  Scene s;
  s.name = "spheres";
  s.materials = {Material{}};
  for (int i = 0; i < 6; ++i) append_icosphere(s.triangles, {1.5f * i, 0.0f, 0.0f}, 0.6f, 3, 0);
  return s;
}

std::size_t size_of(const cl::Buffer& b) { return b.getInfo<CL_MEM_SIZE>(); }

// Both eyes of two renders the same to the bit.
void expect_identical_eyes(const std::array<ImageRGB, 2>& a, const std::array<ImageRGB, 2>& b) {
  for (int e = 0; e < 2; ++e) {
    ASSERT_EQ(a[e].rgb.size(), b[e].rgb.size());
    EXPECT_EQ(std::memcmp(a[e].rgb.data(), b[e].rgb.data(), a[e].rgb.size() * sizeof(float)), 0) << "eye " << e;
  }
}

std::size_t total_size(const DeviceSceneBuffers& b) {
  return size_of(b.nodes) + size_of(b.triangles) + size_of(b.shading) + size_of(b.materials) + size_of(b.textures) +
         size_of(b.texels) + size_of(b.lights) + size_of(b.colours) + size_of(b.instances);
}

TEST(DeviceScene, OneCopyPerContextServesEveryDevice) {
  const Scene scene = spheres();
  const FlatBvh bvh = build_bvh(scene.triangles);
  DeviceSet set = DeviceSet::create({3, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, scene, bvh);
  for (int d = 1; d < set.size(); ++d) {
    EXPECT_EQ(ds.on(d).triangles(), ds.on(0).triangles()) << "device " << d << " has its own triangle buffer";
    EXPECT_EQ(ds.on(d).nodes(), ds.on(0).nodes()) << "device " << d;
    EXPECT_EQ(ds.on(d).texels(), ds.on(0).texels()) << "device " << d;
  }
  // What the context holds is what the scene reports, once.
  EXPECT_EQ(ds.bytes_in_context(), total_size(ds.on(0)));
  EXPECT_GE(size_of(ds.on(0).triangles), scene.triangles.size() * sizeof(BvhTriangle));
}

TEST(DeviceScene, ABufferOverTheAllocationLimitIsRefusedNamingItAndTheSizes) {
  const Scene scene = spheres();
  const FlatBvh bvh = build_bvh(scene.triangles);
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  // The first buffer written is the BVH's nodes (with the wide layouts their leaf blocks too):
  // a limit one byte below it must stop the upload there, naming it.
  std::size_t nodes = 0;
  {
    DeviceScene ds(set, scene, bvh);
    nodes = size_of(ds.on(0).nodes);
  }
  {
    const test::ScopedEnv limit("PARALLAX_MAX_ALLOC_BYTES", std::to_string(nodes - 1));
    try {
      DeviceScene ds(set, scene, bvh);
      ADD_FAILURE() << "a " << nodes << "-byte node buffer was accepted under a " << nodes - 1 << "-byte limit";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("BVH node buffer needs"), std::string::npos) << what;
      EXPECT_NE(what.find("(" + std::to_string(nodes) + " bytes)"), std::string::npos) << what;
      EXPECT_NE(what.find("(" + std::to_string(nodes - 1) + " bytes)"), std::string::npos) << what;
      EXPECT_NE(what.find("CL_DEVICE_MAX_MEM_ALLOC_SIZE"), std::string::npos) << what;
    }
  }
  // At exactly its size it fits (every other buffer of this scene is smaller).
  const test::ScopedEnv exact("PARALLAX_MAX_ALLOC_BYTES", std::to_string(nodes));
  EXPECT_NO_THROW(DeviceScene(set, scene, bvh));
}

std::vector<std::uint8_t> read_back(DeviceSet& set, const cl::Buffer& b) {
  std::vector<std::uint8_t> out(size_of(b));
  set.devices().front().queue.enqueueReadBuffer(b, CL_TRUE, 0, out.size(), out.data());
  return out;
}

// A caller that hands its triangles over (take_triangles: SceneOnDevices for a static scene)
// gets the shading records made in the triangles' own memory, with the pages behind them given
// back: the buffers must hold the very bytes of a scene whose triangles stay with the caller,
// and the shading records those make_triangle_shading makes. 300k triangles: the released tail
// (36 bytes a triangle) passes the 8 MiB from which pages are handed back.
TEST(DeviceScene, ShadingMadeInTheHandedOverTrianglesIsTheSameBuffer) {
  Scene scene;
  scene.name = "soup";
  scene.materials = {Material{}, Material{}};
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 300000; ++i) {
    SceneTriangle t;
    const glm::vec3 c(50.0f * u(rng), 50.0f * u(rng), 50.0f * u(rng));
    for (int k = 0; k < 3; ++k) {
      t.p[k] = c + glm::vec3(u(rng), u(rng), u(rng));
      t.n[k] = glm::normalize(glm::vec3(u(rng), u(rng), 1.5f));
      t.uv[k] = glm::vec2(u(rng), u(rng));
    }
    t.material = static_cast<std::uint32_t>(i % 2);
    scene.triangles.push_back(t);
  }
  const std::vector<TriangleShading> want = make_triangle_shading(scene);
  const FlatBvh bvh = build_bvh(scene.triangles);
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  const DeviceScene kept(set, scene, bvh);
  Scene handed = scene;
  const DeviceScene taken(set, handed, bvh, {}, {}, [&handed] { return std::exchange(handed.triangles, {}); });
  EXPECT_TRUE(handed.triangles.empty()) << "the triangles were handed over";
  const auto shading = read_back(set, taken.on(0).shading);
  ASSERT_EQ(shading.size(), want.size() * sizeof(TriangleShading));
  EXPECT_EQ(std::memcmp(shading.data(), want.data(), shading.size()), 0) << "the records make_triangle_shading makes";
  EXPECT_EQ(shading, read_back(set, kept.on(0).shading));
  const auto nodes = read_back(set, taken.on(0).nodes);
  EXPECT_EQ(nodes, read_back(set, kept.on(0).nodes)) << "node words";
  // The CPU set's wide layout: the handed-over scene's leaf triangles are BvhLeafRef records,
  // each the kept scene's triangle without its vertices, which its block holds.
  ASSERT_TRUE(taken.leaf_refs());
  EXPECT_FALSE(kept.leaf_refs());
  EXPECT_NE(taken.kernel_options().find("-DPX_LEAF_REFS=1"), std::string::npos);
  const auto kept_tris = read_back(set, kept.on(0).triangles);
  const auto refs = read_back(set, taken.on(0).triangles);
  const std::size_t n = kept_tris.size() / sizeof(BvhTriangle);
  ASSERT_EQ(refs.size(), n * sizeof(BvhLeafRef));
  std::size_t bad = 0;
  for (std::size_t i = 0; i < n && bad < 5; ++i) {
    BvhTriangle t;
    BvhLeafRef r;
    BvhLeafBlock b;
    std::memcpy(&t, kept_tris.data() + i * sizeof t, sizeof t);
    std::memcpy(&r, refs.data() + i * sizeof r, sizeof r);
    ASSERT_LE(std::size_t{r.block} * 16 + sizeof b, nodes.size());
    std::memcpy(&b, nodes.data() + std::size_t{r.block} * 16, sizeof b);
    bool ok =
        r.prim == t.prim && r.flags == t.flags && r.material == t.material && b.first <= i && i < b.first + b.count;
    for (int k = 0; k < 3 && ok; ++k)
      ok = b.v[k][i - b.first] == t.v0[k] && b.v[3 + k][i - b.first] == t.v1[k] && b.v[6 + k][i - b.first] == t.v2[k];
    if (!ok) ++bad, ADD_FAILURE() << "leaf triangle " << i;
  }
  // A tree handed over without its wide nodes (load_and_build's for SceneOnDevices): they are
  // made after the shading records, validated against the leaf triangles, and the same words.
  Scene late = scene;
  const DeviceScene collapsed_late(set, late, build_bvh(scene.triangles, {}, /*layout=*/std::nullopt), {}, {},
                                   [&late] { return std::exchange(late.triangles, {}); });
  EXPECT_EQ(read_back(set, collapsed_late.on(0).nodes), nodes);
  EXPECT_EQ(read_back(set, collapsed_late.on(0).triangles), refs);
  // Handing over another number of triangles than the scene's is a caller's error.
  Scene short_scene = scene;
  EXPECT_THROW(DeviceScene(set, short_scene, bvh, {}, {},
                           [&short_scene] {
                             short_scene.triangles.pop_back();
                             return std::exchange(short_scene.triangles, {});
                           }),
               std::logic_error);
}

// The two steps SceneOnDevices takes for a static scene (prepare_host before the devices are
// made, then the layout of the set) give the buffers of the one-step constructor, in every node
// layout; in the layouts without leaf blocks in leaf order (binary, cwbvh) the leaf triangles
// stay BvhTriangle, byte for byte those of a scene that keeps its triangles. Trees come without
// the layout's nodes, as load_and_build leaves them: made here, validated against the leaves.
TEST(DeviceScene, TwoStepsBeforeTheDevicesGiveTheOneStepBuffers) {
  const Scene scene = spheres();
  for (const BvhLayout layout : {BvhLayout::Binary, BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8}) {
    SCOPED_TRACE(to_string(layout));
    Scene first = scene;
    const auto host = DeviceScene::prepare_host(first, [&first] { return std::exchange(first.triangles, {}); });
    EXPECT_TRUE(first.triangles.empty()) << "handed over before any device exists";
    DeviceSet set = DeviceSet::create(test::options_in_layout(layout, 2));
    ASSERT_EQ(set.bvh_layout(), layout);
    const DeviceScene two(set, host, first, build_bvh(scene.triangles, {}, /*layout=*/std::nullopt));
    Scene second = scene;
    const DeviceScene one(set, second, build_bvh(scene.triangles, {}, layout), {}, {},
                          [&second] { return std::exchange(second.triangles, {}); });
    const DeviceScene kept(set, scene, build_bvh(scene.triangles, {}, layout));
    EXPECT_EQ(two.leaf_refs(), layout == BvhLayout::Wide4 || layout == BvhLayout::Wide8);
    EXPECT_EQ(one.leaf_refs(), two.leaf_refs());
    EXPECT_EQ(two.kernel_options(), one.kernel_options());
    EXPECT_EQ(two.scene_features(), kept.scene_features());
    EXPECT_EQ(two.light_count(), kept.light_count());
    for (const auto member : {&DeviceSceneBuffers::nodes, &DeviceSceneBuffers::triangles, &DeviceSceneBuffers::shading,
                              &DeviceSceneBuffers::materials})  // lights: a placeholder (no emitter)
      EXPECT_EQ(read_back(set, two.on(1).*member), read_back(set, one.on(0).*member));
    EXPECT_EQ(read_back(set, two.on(0).nodes), read_back(set, kept.on(0).nodes));
    // The spheres are smooth: indexed records in two steps, which read as the full ones.
    ASSERT_TRUE(two.indexed_shading());
    const auto indexed = read_back(set, two.on(0).shading), full = read_back(set, kept.on(0).shading);
    ASSERT_EQ(full.size(), scene.triangles.size() * sizeof(TriangleShading));
    for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
      const TriangleShading r = expand_indexed_shading(indexed.data(), i);
      ASSERT_EQ(std::memcmp(&r, full.data() + i * sizeof r, sizeof r), 0) << "triangle " << i;
    }
    if (!two.leaf_refs()) {
      EXPECT_EQ(read_back(set, two.on(0).triangles), read_back(set, kept.on(0).triangles));
    }
  }
  Scene animated = scene;
  animated.rig = std::make_shared<SceneRig>();
  EXPECT_THROW(DeviceScene::prepare_host(animated, [&animated] { return std::exchange(animated.triangles, {}); }),
               std::logic_error)
      << "an animated scene keeps its triangles";
}

// A scene of flat, untextured triangles (what a mesh without NORMAL and TEXCOORD_0 loads as)
// goes to the devices with 16-byte FlatTriangleShading records where the full records take 64,
// and renders the same image to the bit: the kernels built with PX_FLAT_SHADING compute what
// the full records' kernels compute. The full records come from the one-step constructor (a
// scene that keeps its triangles), the flat ones from the two steps SceneOnDevices takes.
// The Cornell box and a sliver field inside it (thin triangles at every orientation), every
// triangle's normal its geometric one as the loaders give a mesh without normals, no uvs.
Scene flat_cornell_with_slivers() {
  Scene scene = make_builtin_scene("cornell");
  std::vector<SceneTriangle> slivers;
  append_slivers(slivers, 400, 5, 0);
  for (SceneTriangle& t : slivers)
    for (glm::vec3& p : t.p) p = 0.2f * p + glm::vec3(0.0f, 0.5f, 0.0f);
  scene.triangles.insert(scene.triangles.end(), slivers.begin(), slivers.end());
  EXPECT_FALSE(has_flat_shading(scene.triangles)) << "the box's sphere has vertex normals";
  for (SceneTriangle& t : scene.triangles) {
    glm::vec3 n = glm::normalize(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
    if (glm::dot(n, t.n[0]) < 0.0f) n = -n;  // facing as the vertex normals did
    for (int k = 0; k < 3; ++k) {
      t.n[k] = n;
      t.uv[k] = glm::vec2(0.0f);
    }
  }
  return scene;
}

TEST(DeviceScene, AFlatUntexturedSceneGetsSixteenByteRecordsAndTheSameImage) {
  const Scene scene = flat_cornell_with_slivers();
  ASSERT_TRUE(has_flat_shading(scene.triangles));
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  const DeviceScene full(set, scene, build_bvh(scene.triangles));
  Scene handed = scene;
  const auto host = DeviceScene::prepare_host(handed, [&handed] { return std::exchange(handed.triangles, {}); });
  const DeviceScene flat(set, host, handed, build_bvh(scene.triangles, {}, /*layout=*/std::nullopt));
  EXPECT_FALSE(full.flat_shading());
  ASSERT_TRUE(flat.flat_shading());
  EXPECT_NE(flat.kernel_options().find("-DPX_FLAT_SHADING=1"), std::string::npos);
  EXPECT_EQ(full.kernel_options().find("PX_FLAT_SHADING"), std::string::npos);
  // The records: each triangle's normal and material, 16 bytes.
  const auto records = read_back(set, flat.on(0).shading);
  ASSERT_EQ(records.size(), scene.triangles.size() * sizeof(FlatTriangleShading));
  std::size_t bad = 0;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    FlatTriangleShading r;
    std::memcpy(&r, records.data() + i * sizeof r, sizeof r);
    const SceneTriangle& t = scene.triangles[i];
    bad += r.n[0] != t.n[0].x || r.n[1] != t.n[0].y || r.n[2] != t.n[0].z || r.material != t.material;
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(size_of(full.on(0).shading) - records.size(), 48 * scene.triangles.size());
  // The same picture: two eyes, the light, four bounces, the slivers' edges.
  PathTracer::Options opt;
  opt.spp = 4;
  opt.bounces = 4;
  PathTracer a(set, full, scene), b(set, flat, scene);
  const auto ia = a.render_stereo(0.0f, 2, 48, 32, opt), ib = b.render_stereo(0.0f, 2, 48, 32, opt);
  expect_identical_eyes(ia, ib);
  double sum = 0.0;
  for (float v : ia[0].rgb) sum += v;
  EXPECT_GT(sum, 0.0) << "a picture, not a black frame";
  // What is not flat stays full: one vertex normal a bit off, or a texture coordinate of -0.
  std::vector<SceneTriangle> tris = scene.triangles;
  tris[7].n[2] = glm::vec3(std::nextafter(tris[7].n[2].x, 2.0f), tris[7].n[2].y, tris[7].n[2].z);
  EXPECT_FALSE(has_flat_shading(tris));
  tris = scene.triangles;
  tris.back().uv[1].y = -0.0f;
  EXPECT_FALSE(has_flat_shading(tris));
  Scene smooth = spheres();
  EXPECT_FALSE(has_flat_shading(smooth.triangles)) << "an icosphere's normals are per vertex";
  const auto smooth_host = DeviceScene::prepare_host(smooth, [&smooth] { return std::exchange(smooth.triangles, {}); });
  const Scene spheres_scene = spheres();
  const DeviceScene smooth_ds(set, smooth_host, smooth, build_bvh(spheres_scene.triangles, {}, std::nullopt));
  EXPECT_FALSE(smooth_ds.flat_shading());
}

// A smooth scene (per-vertex normals and texture coordinates, a texture read through them)
// goes to the devices with indexed records: 16 bytes a triangle beside each distinct vertex's
// normal and uv once (types.h: IndexedTriangleShading), and renders the full records' image to
// the bit, since the kernels built with PX_INDEXED_SHADING read the same floats. The records
// read back as the full ones (the host's reading of their relative offsets against shading_of),
// the table holds each distinct vertex once; PARALLAX_INDEXED_SHADING=off keeps full records
// (the second code path), and so does a mesh whose vertices share nothing (faceted normals).
TEST(DeviceScene, ASmoothSceneGetsIndexedRecordsAndTheSameImage) {
  Scene scene = make_builtin_scene("cornell");
  for (int i = 0; i < 3; ++i) append_icosphere(scene.triangles, {-0.5f + 0.5f * i, 0.3f, 0.2f}, 0.15f, 3, 0);
  // A checker texture on every material, read through uvs made from the positions.
  Texture checker;
  checker.width = checker.height = 4;
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x)
      for (const float c : {(x + y) % 2 ? 0.9f : 0.2f, 0.5f, (x + y) % 2 ? 0.1f : 0.8f, 1.0f})
        checker.rgba.push_back(c);
  scene.textures.push_back(checker);
  for (Material& m : scene.materials)
    if (!m.is_emissive()) m.diffuse_texture = 0;
  for (SceneTriangle& t : scene.triangles)
    for (int k = 0; k < 3; ++k) t.uv[k] = glm::vec2(2.0f * t.p[k].x + 0.3f * t.p[k].y, 2.0f * t.p[k].z);
  ASSERT_FALSE(has_flat_shading(scene.triangles));
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  const auto two_steps = [&set](const Scene& s) {
    Scene handed = s;
    const auto host = DeviceScene::prepare_host(handed, [&handed] { return std::exchange(handed.triangles, {}); });
    return DeviceScene(set, host, handed, build_bvh(s.triangles, {}, /*layout=*/std::nullopt));
  };
  const DeviceScene full(set, scene, build_bvh(scene.triangles));
  const DeviceScene indexed = two_steps(scene);
  EXPECT_EQ(full.shading_records(), ShadingRecords::Full);
  ASSERT_TRUE(indexed.indexed_shading());
  EXPECT_NE(indexed.kernel_options().find("-DPX_INDEXED_SHADING=1"), std::string::npos);
  EXPECT_EQ(full.kernel_options().find("PX_INDEXED_SHADING"), std::string::npos);
  // The records against shading_of, byte for byte, and the table: each distinct vertex once.
  const auto bytes = read_back(set, indexed.on(0).shading);
  const std::size_t n = scene.triangles.size();
  ASSERT_GE(bytes.size(), n * sizeof(IndexedTriangleShading));
  std::size_t bad = 0;
  std::vector<std::array<std::uint32_t, 5>> distinct;
  for (std::size_t i = 0; i < n; ++i) {
    const TriangleShading got = expand_indexed_shading(bytes.data(), i), want = shading_of(scene.triangles[i]);
    bad += std::memcmp(&got, &want, sizeof got) != 0;
    for (int k = 0; k < 3; ++k) {
      std::array<std::uint32_t, 5> v;
      std::memcpy(v.data(), &scene.triangles[i].n[k], 12);
      std::memcpy(v.data() + 3, &scene.triangles[i].uv[k], 8);
      distinct.push_back(v);
    }
  }
  EXPECT_EQ(bad, 0u);
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  EXPECT_EQ(bytes.size(), n * sizeof(IndexedTriangleShading) + distinct.size() * sizeof(ShadingVertex));
  EXPECT_LT(bytes.size(), n * sizeof(TriangleShading) / 2) << "the icospheres' vertices are shared";
  // The same picture: two eyes, textures, four bounces.
  PathTracer::Options opt;
  opt.spp = 4;
  opt.bounces = 4;
  PathTracer a(set, full, scene), b(set, indexed, scene);
  const auto ia = a.render_stereo(0.0f, 2, 48, 32, opt), ib = b.render_stereo(0.0f, 2, 48, 32, opt);
  expect_identical_eyes(ia, ib);
  double sum = 0.0;
  for (float v : ia[0].rgb) sum += v;
  EXPECT_GT(sum, 0.0) << "a picture, not a black frame";
  {
    const test::ScopedEnv off("PARALLAX_INDEXED_SHADING", "off");
    const DeviceScene kept = two_steps(scene);
    EXPECT_EQ(kept.shading_records(), ShadingRecords::Full);
    PathTracer c(set, kept, scene);
    expect_identical_eyes(ia, c.render_stereo(0.0f, 2, 48, 32, opt));
  }
  // Faceted normals with uvs: no vertex is shared, indexed records would not be smaller.
  Scene faceted = scene;
  for (SceneTriangle& t : faceted.triangles) {
    const glm::vec3 g = glm::normalize(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
    for (int k = 0; k < 3; ++k) t.n[k] = g + glm::vec3(0.0f, 1e-3f * float(k), 0.0f);
  }
  EXPECT_EQ(two_steps(faceted).shading_records(), ShadingRecords::Full);
}

// A static scene keeps its triangle flags per material (they follow from the material alone):
// set on the leaf triangles by material they are the flags triangle_flags gives each triangle,
// and the flags the scene uses, or-ed, leave out a material no triangle has (which would otherwise
// compile alpha testing into the kernels for nothing).
TEST(DeviceScene, TriangleFlagsByMaterialAreThePerTriangleFlags) {
  Scene scene = make_builtin_scene("cornell");
  Texture cutout;
  cutout.width = cutout.height = 1;
  cutout.rgba = {1.0f, 1.0f, 1.0f, 0.5f};
  scene.textures.push_back(cutout);
  Material leaves;
  leaves.diffuse = glm::vec3(0.3f, 0.6f, 0.2f);
  leaves.alpha_texture = 0;
  scene.materials.push_back(leaves);
  scene.materials.push_back(leaves);  // never used
  const auto used_material = static_cast<std::uint32_t>(scene.materials.size() - 2);
  for (std::size_t i = 0; i < scene.triangles.size(); i += 7) scene.triangles[i].material = used_material;
  const std::vector<std::uint32_t> per_triangle = triangle_flags(scene), per_material = material_triangle_flags(scene);
  FlatBvh a = build_bvh(scene.triangles), b = a;
  set_triangle_flags(a, per_triangle);
  set_triangle_flags_by_material(b, per_material);
  std::uint32_t any = 0, differ = 0;
  for (std::size_t i = 0; i < a.triangles.size(); ++i) {
    differ += a.triangles[i].flags != b.triangles[i].flags;
    any |= a.triangles[i].flags;
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_EQ(any, std::uint32_t{PX_TRI_ALPHA_TESTED | PX_TRI_EMISSIVE}) << "both kinds present";
  std::uint32_t used = 0;
  for (const std::uint32_t f : per_triangle) used |= f;
  EXPECT_EQ(used_triangle_flags(scene, per_material), used);
  for (SceneTriangle& t : scene.triangles)
    if (t.material == used_material) t.material = 0;
  EXPECT_EQ(used_triangle_flags(scene, per_material) & PX_TRI_ALPHA_TESTED, 0u)
      << "the cut-out materials are on no triangle now";
  b.triangles[0].material = static_cast<std::uint32_t>(per_material.size());
  EXPECT_THROW(set_triangle_flags_by_material(b, per_material), std::out_of_range);
}

// A large scene's triangles hand their pages back as the pass that makes its records and corners
// over them reads them (records_in_place, from 8 MiB: here 26 MB of triangles, several hand-backs),
// never a page that is still to be read or already holds corners: every corner is its triangle's
// to the bit and every record the one shading_of / flat_shading_of makes of it, smooth (indexed
// records beside the vertices' table) and flat.
TEST(DeviceScene, ALargeScenesTrianglesGoBackAsTheyAreReadAndItsCornersAndRecordsStayWhole) {
  const int n = 360;  // 259,200 triangles
  Scene smooth;
  smooth.materials.push_back(Material{});
  struct Vertex {
    glm::vec3 p, n;
    glm::vec2 uv;
  };
  const auto vertex = [n](int x, int z) {
    Vertex v;
    v.p = {x / float(n) * 2.0f - 1.0f, 0.1f * std::sin(0.37f * x) * std::cos(0.23f * z), z / float(n) * 2.0f - 1.0f};
    v.n = glm::normalize(glm::vec3(-0.037f * std::cos(0.37f * x), 1.0f, 0.023f * std::sin(0.23f * z)));
    v.uv = {x / float(n), z / float(n)};
    return v;
  };
  for (int z = 0; z < n; ++z)
    for (int x = 0; x < n; ++x) {
      const Vertex a = vertex(x, z), b = vertex(x + 1, z), c = vertex(x, z + 1), d = vertex(x + 1, z + 1);
      for (const std::array<const Vertex*, 3>& t : {std::array{&a, &c, &b}, std::array{&b, &c, &d}}) {
        SceneTriangle tri;
        for (int k = 0; k < 3; ++k) {
          tri.p[k] = t[k]->p;
          tri.n[k] = t[k]->n;
          tri.uv[k] = t[k]->uv;
        }
        smooth.triangles.push_back(tri);
      }
    }
  ASSERT_GE(smooth.triangles.size() * sizeof(SceneTriangle), std::size_t{24} << 20);
  Scene flat = smooth;
  for (SceneTriangle& t : flat.triangles) {
    const glm::vec3 g = glm::normalize(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
    for (int k = 0; k < 3; ++k) {
      t.n[k] = g;
      t.uv[k] = glm::vec2(0.0f);
    }
  }
  ASSERT_TRUE(has_flat_shading(flat.triangles));
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  for (const Scene* scene : {&smooth, &flat}) {
    Scene handed = *scene;
    DeviceScene::BuildCorners corners;
    const auto host = DeviceScene::prepare_host_before_tree(
        handed, [&handed] { return std::exchange(handed.triangles, {}); }, corners);
    ASSERT_TRUE(host);
    const std::size_t count = scene->triangles.size();
    ASSERT_EQ(corners.count, count);
    std::size_t bad_corners = 0;
    for (std::size_t i = 0; i < count; ++i)
      bad_corners += std::memcmp(corners.data[i].p, scene->triangles[i].p, sizeof corners.data[i].p) != 0 ||
                     corners.data[i].material != scene->triangles[i].material;
    EXPECT_EQ(bad_corners, 0u);
    const DeviceScene on(set, host, handed, build_bvh(corners.source(), {}, /*layout=*/std::nullopt));
    ASSERT_EQ(scene == &flat, on.flat_shading());
    ASSERT_EQ(scene == &smooth, on.indexed_shading());
    const auto bytes = read_back(set, on.on(0).shading);
    std::size_t bad_records = 0;
    for (std::size_t i = 0; i < count; ++i) {
      if (scene == &flat) {
        const FlatTriangleShading want = flat_shading_of(scene->triangles[i]);
        bad_records += std::memcmp(bytes.data() + i * sizeof want, &want, sizeof want) != 0;
      } else {
        const TriangleShading got = expand_indexed_shading(bytes.data(), i), want = shading_of(scene->triangles[i]);
        bad_records += std::memcmp(&got, &want, sizeof got) != 0;
      }
    }
    EXPECT_EQ(bad_records, 0u) << (scene == &flat ? "flat" : "smooth");
  }
}

// SceneOnDevices has the scene's kernels built while it lays the scene out (DeviceSet::prebuild),
// with the options DeviceScene::kernel_options_for reads from the host part before the device
// scene exists. Those must be the device scene's own kernel_options(), or the start builds the
// kernels twice: for flat and smooth scenes (flat and indexed records), in every node layout, for
// both kernel choices; and SceneOnDevices' devices hold that build when the start ends.
TEST(DeviceScene, TheKernelOptionsKnownFromTheHostPartAreTheDeviceScenesOwn) {
  for (const BvhLayout layout : {BvhLayout::Binary, BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8}) {
    DeviceSet set = DeviceSet::create(test::options_in_layout(layout, 2));
    for (const Scene& scene : {flat_cornell_with_slivers(), spheres()})
      for (const KernelChoice choice : {KernelChoice::Scene, KernelChoice::General}) {
        SCOPED_TRACE(std::string(to_string(layout)) + ", " + scene.name +
                     (choice == KernelChoice::General ? ", general" : ""));
        Scene handed = scene;
        DeviceScene::BuildCorners corners;
        const auto host = DeviceScene::prepare_host_before_tree(
            handed, [&handed] { return std::exchange(handed.triangles, {}); }, corners);
        ASSERT_TRUE(host);
        const std::string predicted = DeviceScene::kernel_options_for(*host, set.bvh_layout(), choice);
        DeviceScene device_scene(set, host, handed, build_bvh(corners.source(), {}, /*layout=*/std::nullopt));
        device_scene.set_kernel_choice(choice);
        EXPECT_EQ(predicted, device_scene.kernel_options());
      }
  }
  const SceneOnDevices start("cornell", {2, DeviceMode::Auto, "", std::nullopt}, /*quiet=*/true);
  ASSERT_TRUE(start.device_scene.flat_shading() || start.device_scene.indexed_shading());
  EXPECT_TRUE(start.devices.has_program("pathtrace/path_trace.cl", start.device_scene.kernel_options()))
      << "the start built (or is building) the scene's kernels";
  EXPECT_FALSE(start.devices.has_program("pipeline/reproject.cl")) << "no frame kernels asked for";
  // A start that renders frames builds the frame's kernels too (the program the stages ask for).
  SceneOnDevices frames("cornell", {2, DeviceMode::Auto, "", std::nullopt}, /*quiet=*/true, {}, KernelChoice::Scene,
                        StartBuilds::Frames);
  EXPECT_TRUE(frames.devices.has_program("pathtrace/path_trace.cl", frames.device_scene.kernel_options()));
  EXPECT_TRUE(frames.devices.has_program("pipeline/reproject.cl"));
  EXPECT_TRUE(frames.devices.has_program("pipeline/tonemap.cl"));
  EXPECT_NO_THROW(cl::Kernel(frames.devices.program("pipeline/tonemap.cl"), "tonemap"));
}

// A flat static scene that goes to the devices makes its records before its tree
// (prepare_host_before_tree): the tree is then built, validated and keyed in the cache from the corners
// packed where the triangles were, and comes out the same tree, under the same cache key, as
// one built from the scene's triangles; the device scene renders the one-step constructor's
// image. A scene that is not flat is left alone. And the start that does it: load_and_build
// for the devices on a glTF mesh without normals or uvs.
TEST(DeviceScene, AFlatSceneBuildsItsTreeFromCornersPackedWhereItsTrianglesWere) {
  const Scene scene = flat_cornell_with_slivers();
  Scene handed = scene;
  DeviceScene::BuildCorners corners;
  const auto host = DeviceScene::prepare_host_before_tree(
      handed, [&handed] { return std::exchange(handed.triangles, {}); }, corners);
  ASSERT_TRUE(host);
  EXPECT_TRUE(handed.triangles.empty());
  ASSERT_EQ(corners.count, scene.triangles.size());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const SceneTriangle& t = scene.triangles[i];
    const BuildTriangle& c = corners.data[i];
    bad += std::memcmp(c.p, t.p, sizeof t.p) != 0 || c.material != t.material;
  }
  EXPECT_EQ(bad, 0u);
  const BvhBuildOptions options;
  EXPECT_EQ(bvh_input_hash(corners.source(), options), bvh_input_hash(scene.triangles, options));
  FlatBvh from_corners = build_bvh(corners.source(), options, /*layout=*/std::nullopt);
  const FlatBvh from_triangles = build_bvh(scene.triangles, options, /*layout=*/std::nullopt);
  ASSERT_EQ(from_corners.nodes.size(), from_triangles.nodes.size());
  ASSERT_EQ(from_corners.triangles.size(), from_triangles.triangles.size());
  EXPECT_EQ(std::memcmp(from_corners.nodes.data(), from_triangles.nodes.data(),
                        from_triangles.nodes.size() * sizeof(BvhNode)),
            0);
  EXPECT_EQ(std::memcmp(from_corners.triangles.data(), from_triangles.triangles.data(),
                        from_triangles.triangles.size() * sizeof(BvhTriangle)),
            0);
  EXPECT_TRUE(validate_bvh(from_corners, corners.source()).ok);
  // A corner moved by one ulp is caught by the validator (the corners are what it checks against).
  {
    std::vector<BuildTriangle> moved(corners.data, corners.data + corners.count);
    moved[from_corners.triangles[0].prim].p[1].x = std::nextafter(moved[from_corners.triangles[0].prim].p[1].x, 1e9f);
    EXPECT_FALSE(validate_bvh(from_corners, TriangleSource(moved)).ok);
  }
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  const DeviceScene full(set, scene, build_bvh(scene.triangles));
  const DeviceScene flat(set, host, handed, std::move(from_corners));
  ASSERT_TRUE(flat.flat_shading());
  PathTracer::Options opt;
  opt.spp = 2;
  opt.bounces = 3;
  PathTracer a(set, full, scene), b(set, flat, scene);
  expect_identical_eyes(a.render_stereo(0.0f, 1, 40, 28, opt), b.render_stereo(0.0f, 1, 40, 28, opt));
  // Not flat, with its 64-byte records kept (PARALLAX_INDEXED_SHADING=off): nothing taken, no
  // host part.
  const test::ScopedEnv full_records("PARALLAX_INDEXED_SHADING", "off");
  Scene smooth = spheres();
  bool taken = false;
  DeviceScene::BuildCorners none;
  EXPECT_FALSE(DeviceScene::prepare_host_before_tree(
      smooth,
      [&] {
        taken = true;
        return std::exchange(smooth.triangles, {});
      },
      none));
  EXPECT_FALSE(taken);
  EXPECT_EQ(none.data, nullptr);
  EXPECT_FALSE(smooth.triangles.empty());

  // The start: a 32 x 32 quad grid without NORMAL or TEXCOORD_0 is flat; loaded for the devices,
  // its triangles are gone when load_and_build returns and its host part waits for the devices;
  // loaded for anything else, it keeps them. Both give the same tree and the same image.
  const test::TempDir dir;
  test::GltfBuilder g;
  const int n = 32;
  std::vector<float> pos;
  std::vector<std::uint16_t> idx;
  for (int z = 0; z <= n; ++z)
    for (int x = 0; x <= n; ++x) {
      pos.insert(pos.end(), {x / float(n) * 2.0f - 1.0f, 0.1f * std::sin(0.7f * x) * std::cos(0.5f * z),
                             z / float(n) * 2.0f - 1.0f});
    }
  for (int z = 0; z < n; ++z)
    for (int x = 0; x < n; ++x) {
      const auto a0 = std::uint16_t(z * (n + 1) + x), b0 = std::uint16_t(a0 + 1), c0 = std::uint16_t(a0 + n + 1),
                 d0 = std::uint16_t(c0 + 1);
      idx.insert(idx.end(), {a0, c0, b0, b0, c0, d0});
    }
  g.add("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.7, 0.7, 0.7, 1}}, {"metallicFactor", 0}}}});
  const int p_acc = g.floats(pos, "VEC3", pos.size() / 3);
  const int i_acc = g.uint16s(idx, "SCALAR", idx.size());
  g.add("meshes",
        {{"primitives",
          nlohmann::json::array({{{"attributes", {{"POSITION", p_acc}}}, {"indices", i_acc}, {"material", 0}}})}});
  g.add("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}});
  g.doc["scene"] = 0;
  g.doc["scenes"] = nlohmann::json::array({{{"nodes", {0, 1}}}});
  g.doc["nodes"] = nlohmann::json::array(
      {{{"mesh", 0}}, {{"camera", 0}, {"translation", {0, 1.5, 2.5}}, {"rotation", {-0.27, 0, 0, 0.963}}}});
  const std::string file = dir.write("grid.gltf", g.text()).string();
  LoadedScene for_devices = load_and_build(file, /*quiet=*/true, {}, /*map_device_layout=*/true);
  const LoadedScene kept = load_and_build(file, true);
  ASSERT_TRUE(for_devices.host_part) << "records made before the tree";
  EXPECT_TRUE(for_devices.scene.triangles.empty());
  EXPECT_EQ(for_devices.triangle_count, std::size_t(2 * n * n));
  EXPECT_FALSE(kept.host_part);
  ASSERT_EQ(kept.scene.triangles.size(), std::size_t(2 * n * n));
  ASSERT_EQ(for_devices.bvh.nodes.size(), kept.bvh.nodes.size());
  EXPECT_EQ(std::memcmp(for_devices.bvh.nodes.data(), kept.bvh.nodes.data(), kept.bvh.nodes.size() * sizeof(BvhNode)),
            0);
  SceneOnDevices on(std::move(for_devices), {2, DeviceMode::Auto, "", std::nullopt});
  EXPECT_TRUE(on.device_scene.flat_shading());
  const DeviceScene kept_ds(on.devices, kept.scene, kept.bvh);
  PathTracer c(on.devices, on.device_scene, on.loaded.scene), d(on.devices, kept_ds, kept.scene);
  const auto ic = c.render_stereo(0.0f, 0, 40, 28, opt), id = d.render_stereo(0.0f, 0, 40, 28, opt);
  expect_identical_eyes(ic, id);
  double sum = 0.0;
  for (int e = 0; e < 2; ++e)
    for (float v : ic[e].rgb) sum += v;
  EXPECT_GT(sum, 0.0) << "a picture, not a black frame";
}

}  // namespace
}  // namespace px
