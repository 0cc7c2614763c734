// The device layout cache (render/device_layout_cache.h): a start maps the scene's three large
// buffers from disk instead of reading, collapsing and laying out its tree. What is mapped must
// be byte for byte what the layout code makes from the tree (made again here, apart from the
// cache), must trace like it (closest hits against a brute-force loop, through a DeviceScene
// made from the mapping), and anything that is not exactly that file (another scene, another
// material flag, another layout, a cut or damaged file) must be a miss, never an error. Also
// ContentHash, the key's hash: independent of how its input is split, and sensitive to a bit.
#include "app/scene_setup.h"
#include "bvh/bvh_cache.h"
#include "bvh/wide_bvh.h"
#include "render/device_layout_cache.h"
#include "render/device_scene.h"
#include "render/indexed_shading.h"
#include "render/path_tracer.h"
#include "io/background_writes.h"
#include "io/content_hash.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"
#include "support/brute_force.h"
#include "support/bvh_layout_test.h"
#include "support/scoped_env.h"
#include "support/test_support.h"
#include "trace/ray_batch_tracer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <random>
#include <thread>

namespace px {
namespace {

TEST(ContentHash, DoesNotDependOnHowTheInputIsSplitAndSeesEveryBit) {
  std::mt19937 rng(7);
  std::vector<unsigned char> bytes(1000);
  for (auto& b : bytes) b = static_cast<unsigned char>(rng());
  const std::uint64_t whole = content_hash(bytes.data(), bytes.size());
  for (const std::size_t cut : {0, 1, 7, 31, 32, 33, 500, 999, 1000}) {
    for (const std::size_t cut2 : {cut, std::min<std::size_t>(1000, cut + 5), std::min<std::size_t>(1000, cut + 64)}) {
      ContentHash h;
      h.bytes(bytes.data(), cut);
      h.bytes(bytes.data() + cut, cut2 - cut);
      h.bytes(bytes.data() + cut2, bytes.size() - cut2);
      EXPECT_EQ(h.digest(), whole) << "split at " << cut << " and " << cut2;
    }
  }
  // One bit anywhere, the length, or the seed: another value (2,000 flips, no collision).
  std::vector<std::uint64_t> seen{whole};
  for (std::size_t i = 0; i < bytes.size(); i += 1)
    for (const int bit : {0, 7}) {
      auto flipped = bytes;
      flipped[i] ^= static_cast<unsigned char>(1u << bit);
      seen.push_back(content_hash(flipped.data(), flipped.size()));
    }
  seen.push_back(content_hash(bytes.data(), bytes.size() - 1));
  seen.push_back(content_hash(bytes.data(), bytes.size(), 1));
  std::sort(seen.begin(), seen.end());
  EXPECT_EQ(std::adjacent_find(seen.begin(), seen.end()), seen.end()) << "two inputs hashed alike";
}

// Enough triangles for several leaves per node level, with two materials: one plain, one
// emissive (its triangles carry PX_TRI_EMISSIVE in the leaf triangles and leaf blocks).
Scene test_scene() {
  Scene s;
  s.name = "slivers and spheres";
  Material plain;
  Material lamp;
  lamp.emission = glm::vec3(4.0f);
  s.materials = {plain, lamp};
  append_slivers(s.triangles, 3000, 11, 0);
  append_icosphere(s.triangles, {0.0f, 2.0f, 0.0f}, 0.5f, 2, 1);
  return s;
}

// The three buffers as the device layout code makes them, made here from the tree apart from
// any cache: flags from the materials, the node words of `layout`, the shading records.
struct ExpectedLayout {
  std::vector<std::uint8_t> nodes;
  std::vector<BvhTriangle> triangles;
  std::vector<TriangleShading> shading;
};
ExpectedLayout expected_layout(const Scene& scene, const FlatBvh& built, BvhLayout layout) {
  FlatBvh tree = built;
  set_triangle_flags(tree, triangle_flags(scene));
  ensure_layout(tree, layout);
  ExpectedLayout e;
  if (layout == BvhLayout::Binary) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(tree.nodes.data());
    e.nodes.assign(p, p + tree.nodes.size() * sizeof(BvhNode));
  } else {
    const auto words = device_wide_nodes(tree, layout);
    const auto* p = reinterpret_cast<const std::uint8_t*>(words.data());
    e.nodes.assign(p, p + words.size() * 4);
  }
  e.triangles = tree.triangles;
  e.shading = make_triangle_shading(scene);
  return e;
}

bool same_bytes(const void* a, const void* b, std::size_t n) { return std::memcmp(a, b, n) == 0; }

// A cache in a fresh folder and the test scene with its tree and key.
struct Stored {
  test::TempDir dir;
  DeviceLayoutCache cache{dir.path().string()};
  Scene scene = test_scene();
  FlatBvh built = build_bvh(scene.triangles);
  std::uint64_t key = scene_content_key(scene);
};

// A DeviceScene on `set` stores the layout; the cache maps back exactly the expected bytes.
std::shared_ptr<const MappedDeviceLayout> store_and_open(DeviceSet& set, const Scene& scene, const FlatBvh& built,
                                                         const DeviceLayoutCache& cache, std::uint64_t key) {
  DeviceLayoutStore store;
  store.cache = &cache;
  store.content_key = key;
  DeviceScene stored(set, scene, built, {}, store);
  EXPECT_FALSE(stored.layout_from_cache());
  return cache.open(key, set.bvh_layout(), BvhBuildOptions{}, scene.triangles.size());
}

TEST(DeviceLayoutCache, MapsBackExactlyTheLayoutOfEachNodeLayout) {
  const Stored f;
  const DeviceLayoutCache& cache = f.cache;
  const Scene& scene = f.scene;
  const FlatBvh& built = f.built;
  const std::uint64_t key = f.key;
  for (const BvhLayout layout : {BvhLayout::Binary, BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8}) {
    SCOPED_TRACE(to_string(layout));
    DeviceSet set = DeviceSet::create(test::options_in_layout(layout));
    ASSERT_EQ(set.bvh_layout(), layout);
    EXPECT_EQ(cache.open(key, layout, BvhBuildOptions{}, scene.triangles.size()), nullptr) << "nothing stored yet";
    const auto mapped = store_and_open(set, scene, built, cache, key);
    ASSERT_NE(mapped, nullptr);
    const ExpectedLayout e = expected_layout(scene, built, layout);
    EXPECT_EQ(mapped->layout(), layout);
    ASSERT_EQ(mapped->node_byte_count(), e.nodes.size());
    EXPECT_TRUE(same_bytes(mapped->node_bytes(), e.nodes.data(), e.nodes.size()));
    ASSERT_EQ(mapped->triangle_count(), e.triangles.size());
    EXPECT_TRUE(same_bytes(mapped->triangles(), e.triangles.data(), e.triangles.size() * sizeof(BvhTriangle)));
    ASSERT_EQ(mapped->shading_count(), e.shading.size());
    EXPECT_TRUE(same_bytes(mapped->shading(), e.shading.data(), e.shading.size() * sizeof(TriangleShading)));
    EXPECT_EQ(mapped->stats().nodes, built.stats.nodes);
    EXPECT_EQ(mapped->stats().depth, built.stats.depth);
    EXPECT_DOUBLE_EQ(mapped->stats().sah_cost, built.stats.sah_cost);
    EXPECT_TRUE(mapped->verify_payload());
    // The sections are page-aligned (CL_MEM_USE_HOST_PTR).
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(mapped->node_bytes()) % 4096, 0u);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(mapped->triangles()) % 4096, 0u);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(mapped->shading()) % 4096, 0u);
  }
}

// A DeviceScene made from the mapping traces as the scene's triangles say: closest hits of rays
// from inside and outside the scene against a brute-force loop over every triangle, and the same
// hits as the DeviceScene laid out from the tree.
TEST(DeviceLayoutCache, ASceneMadeFromTheMappingTracesLikeTheBruteForceLoop) {
  const Stored f;
  const DeviceLayoutCache& cache = f.cache;
  const Scene& scene = f.scene;
  const FlatBvh& built = f.built;
  const std::uint64_t key = f.key;
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  auto mapped = store_and_open(set, scene, built, cache, key);
  ASSERT_NE(mapped, nullptr);
  DeviceScene laid_out(set, scene, built);
  DeviceScene from_file(set, scene, mapped);
  EXPECT_TRUE(from_file.layout_from_cache());
  EXPECT_EQ(from_file.bytes_in_context(), laid_out.bytes_in_context());
  EXPECT_EQ(from_file.scene_features(), laid_out.scene_features());
  EXPECT_EQ(from_file.light_count(), laid_out.light_count());
  mapped.reset();  // the DeviceScene keeps the mapping alive
  // Rays from far away at a random point of a random triangle, and rays in random directions
  // from a random triangle's centre.
  std::mt19937 rng(3);
  std::uniform_int_distribution<std::size_t> pick(0, scene.triangles.size() - 1);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<Ray> rays;
  for (int i = 0; i < 600; ++i) {
    const SceneTriangle& t = scene.triangles[pick(rng)];
    float a = u01(rng), b = u01(rng);
    if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
    const glm::vec3 target = t.p[0] + a * (t.p[1] - t.p[0]) + b * (t.p[2] - t.p[0]);
    const glm::vec3 centre = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    if (i % 2)
      rays.push_back(test::make_ray(centre, test::random_unit(rng), 1e-3f));
    else {
      const glm::vec3 o = target + 20.0f * test::random_unit(rng);
      rays.push_back(test::make_ray(o, glm::normalize(target - o)));
    }
  }
  RayBatchTracer a(set, laid_out), b(set, from_file);
  const std::vector<Hit> ha = a.closest(rays), hb = b.closest(rays);
  int hits = 0, agreed = 0, checked = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    EXPECT_EQ(ha[i].prim, hb[i].prim) << "ray " << i;
    EXPECT_EQ(ha[i].t, hb[i].t) << "ray " << i;
    const test::BruteHit ref = test::brute_force_closest(scene.triangles, rays[i]);
    if (ref.edge_distance < 1e-4) continue;  // grazing an edge: either triangle may claim it
    ++checked;
    hits += ref.prim != PX_NO_HIT;
    // The same triangle (or both a miss); or, where slivers cross, another triangle at the same
    // distance to float precision.
    const bool both_hit = hb[i].prim != PX_NO_HIT && ref.prim != PX_NO_HIT;
    agreed += hb[i].prim == ref.prim || (both_hit && std::abs(hb[i].t - ref.t) <= 1e-4 * ref.t);
  }
  EXPECT_GT(hits, 200) << "the rays must mostly hit something to test anything";
  EXPECT_EQ(agreed, checked);
}

TEST(DeviceLayoutCache, AnotherSceneFlagOrLayoutIsAMiss) {
  const Stored f;
  const DeviceLayoutCache& cache = f.cache;
  const Scene& scene = f.scene;
  const FlatBvh& built = f.built;
  const std::uint64_t key = f.key;
  DeviceSet set = DeviceSet::create(test::options_in_layout(BvhLayout::Wide8));
  ASSERT_NE(store_and_open(set, scene, built, cache, key), nullptr);
  const std::size_t n = scene.triangles.size();
  EXPECT_EQ(cache.open(key, BvhLayout::Wide4, BvhBuildOptions{}, n), nullptr) << "another layout";
  BvhBuildOptions binned;
  binned.spatial_splits = false;
  EXPECT_EQ(cache.open(key, BvhLayout::Wide8, binned, n), nullptr) << "other build options";
  EXPECT_EQ(cache.open(key, BvhLayout::Wide8, BvhBuildOptions{}, n + 1), nullptr) << "another triangle count";
  // The key sees what the layout holds: a normal (shading), a uv, a material's flags.
  Scene normal = scene;
  normal.triangles[1234].n[2].x += 1e-3f;
  EXPECT_NE(scene_content_key(normal), key);
  Scene uv = scene;
  uv.triangles[5].uv[0].y = 0.25f;
  EXPECT_NE(scene_content_key(uv), key);
  Scene cut_out = scene;
  cut_out.materials[0].alpha_texture = 0;
  EXPECT_NE(scene_content_key(cut_out), key);
  Scene dark = scene;
  dark.materials[1].emission = glm::vec3(0.0f);
  EXPECT_NE(scene_content_key(dark), key);
  // ... but not what it does not hold: a material's colour.
  Scene red = scene;
  red.materials[0].diffuse = glm::vec3(0.9f, 0.1f, 0.1f);
  EXPECT_EQ(scene_content_key(red), key);
}

TEST(DeviceLayoutCache, DamagedFilesAreMissesAndVerifyPayloadFindsAnyChangedByte) {
  const Stored f;
  const DeviceLayoutCache& cache = f.cache;
  const Scene& scene = f.scene;
  const FlatBvh& built = f.built;
  const std::uint64_t key = f.key;
  DeviceSet set = DeviceSet::create(test::options_in_layout(BvhLayout::Wide8));
  const auto mapped = store_and_open(set, scene, built, cache, key);
  ASSERT_NE(mapped, nullptr);
  const std::string path = mapped->path();
  const std::size_t length = mapped->file_bytes();
  ASSERT_EQ(std::filesystem::file_size(path), length);
  std::ifstream in(path, std::ios::binary);
  const std::string original((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(original.size(), length);
  const auto write = [&](const std::string& bytes) {
    std::filesystem::remove(path);  // a new file: the mapping above keeps the old one
    std::ofstream(path, std::ios::binary) << bytes;
  };
  const auto open = [&] { return cache.open(key, BvhLayout::Wide8, BvhBuildOptions{}, scene.triangles.size()); };
  write(original.substr(0, length - 100));
  EXPECT_EQ(open(), nullptr) << "truncated";
  write(original + std::string(4096, '\0'));
  EXPECT_EQ(open(), nullptr) << "grown";
  for (const std::size_t at : {std::size_t(0), std::size_t(8), std::size_t(100), std::size_t(200)}) {
    std::string bad = original;
    bad[at] ^= 0x10;
    write(bad);
    EXPECT_EQ(open(), nullptr) << "header byte " << at;
  }
  // The first payload page is always among the samples a start checks.
  {
    std::string bad = original;
    bad[4096 + 17] ^= 0x01;
    write(bad);
    EXPECT_EQ(open(), nullptr) << "a sampled payload byte";
  }
  // The payload's second page: with more than 64 payload pages the samples (the first page of
  // every 64th of the payload) are at least two pages apart, so a start maps the file;
  // verify_payload reads every byte and finds it.
  ASSERT_GT(length, 4096u * 70) << "the scene is too small for the samples to skip a page";
  {
    std::string bad = original;
    bad[2 * 4096 + 100] ^= 0x01;
    write(bad);
    const auto damaged = open();
    ASSERT_NE(damaged, nullptr) << "an unsampled page is not read at the start";
    EXPECT_FALSE(damaged->verify_payload());
  }
  write(original);
  const auto intact = open();
  ASSERT_NE(intact, nullptr);
  EXPECT_TRUE(intact->verify_payload());
}

// A start through SceneOnDevices, as `render` makes it: the first fills the cache, the second
// maps the layout. A cache that holds another layout only (a GPU set's) is mapped by the
// loader (it cannot know the devices yet) and then set aside for a tree: the start still traces
// the scene's triangles, and stores its own layout for the next one.
TEST(DeviceLayoutCache, StartsMapTheSetsLayoutAndSetAnotherLayoutAside) {
  test::TempDir dir;
  const test::ScopedEnv cache_dir("PARALLAX_CACHE_DIR", (dir.path() / "cache").string());
  const test::ScopedEnv cache_on("PARALLAX_BVH_CACHE", std::nullopt);
  // A 120 x 100 grid of quads, 24,000 triangles: past the cache's threshold of 20,000.
  std::string obj;
  const int nx = 120, ny = 100;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i)
      obj += "v " + std::to_string(0.05 * i) + " " + std::to_string(0.3 * std::sin(0.2 * i) * std::cos(0.3 * j)) + " " +
             std::to_string(0.05 * j) + "\n";
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i + 1, b = a + 1, c = a + nx + 1, d = c + 1;
      obj += "f " + std::to_string(a) + " " + std::to_string(c) + " " + std::to_string(b) + "\n";
      obj += "f " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d) + "\n";
    }
  const std::string spec = dir.write("grid.obj", obj).string();
  const DeviceOptions one{1, DeviceMode::Auto, "", std::nullopt};
  // Rays down onto the grid from above, and the hits of a start without any cache to match.
  std::vector<Ray> rays;
  for (int k = 0; k < 200; ++k)
    rays.push_back(test::make_ray({0.03f * (k % 20) + 0.1f, 2.0f, 0.025f * (k / 10) + 0.1f}, {0.0f, -1.0f, 0.0f}));
  const auto hits_of = [&](SceneOnDevices& s) { return RayBatchTracer(s.devices, s.device_scene).closest(rays); };
  const auto device_layout_files = [&] {
    int files = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir.path() / "cache"))
      files += e.path().filename().string().rfind("device-layout-", 0) == 0;
    return files;
  };
  std::vector<Hit> expected;
  {
    std::optional<SceneOnDevices> none_start;
    {
      const test::ScopedEnv cache_off("PARALLAX_BVH_CACHE", "off");
      none_start.emplace(spec, one, /*quiet=*/true);
    }
    SceneOnDevices& none = *none_start;
    EXPECT_FALSE(none.device_scene.layout_from_cache());
    expected = hits_of(none);
  }
  const auto same_hits = [&](const std::vector<Hit>& h) {
    int hits = 0;
    for (std::size_t i = 0; i < h.size(); ++i) {
      if (h[i].prim != expected[i].prim || h[i].t != expected[i].t) return false;
      hits += h[i].prim != PX_NO_HIT;
    }
    return hits == static_cast<int>(h.size());  // every ray comes down on the grid
  };
  {
    SceneOnDevices fill(spec, one, true);
    EXPECT_FALSE(fill.device_scene.layout_from_cache());
    // Written on a thread of its own once the first frame is on its way (none here).
    EXPECT_EQ(device_layout_files(), 0) << "held for the first frame";
    fill.wait_for_cache_writes();
    EXPECT_EQ(device_layout_files(), 1) << "the first start stored its layout";
    EXPECT_TRUE(same_hits(hits_of(fill)));
  }
  {
    SceneOnDevices warm(spec, one, true);
    EXPECT_TRUE(warm.device_scene.layout_from_cache());
    EXPECT_TRUE(warm.loaded.times.device_layout_from_cache);
    EXPECT_TRUE(same_hits(hits_of(warm)));
  }
  // Only a GPU set's layout in the cache (binary, bvh_layout_for(true)): the wide8 file goes, a
  // binary one is made. The loader maps it (it cannot know the devices yet); the wide8 set sets
  // it aside.
  for (const auto& e : std::filesystem::directory_iterator(dir.path() / "cache"))
    if (e.path().filename().string().rfind("device-layout-", 0) == 0) std::filesystem::remove(e.path());
  const BvhLayout gpu_layout = bvh_layout_for(/*all_gpus=*/true);
  ASSERT_NE(gpu_layout, bvh_layout_for(/*all_gpus=*/false)) << "the test needs the two device types' layouts to differ";
  { SceneOnDevices gpu_like(spec, test::options_in_layout(gpu_layout), true); }
  EXPECT_EQ(device_layout_files(), 1) << "the GPU-layout start stored its layout";
  {
    testing::internal::CaptureStderr();
    SceneOnDevices other(spec, one, /*quiet=*/false);
    const std::string said = testing::internal::GetCapturedStderr();
    EXPECT_NE(said.find(to_string(gpu_layout)), std::string::npos) << said;
    EXPECT_NE(said.find("not in this device set's wide8 layout"), std::string::npos) << said;
    EXPECT_FALSE(other.device_scene.layout_from_cache()) << "a GPU set's file for a wide8 set";
    EXPECT_FALSE(other.loaded.times.device_layout_from_cache);
    EXPECT_TRUE(same_hits(hits_of(other)));
  }
  {
    SceneOnDevices again(spec, one, true);
    EXPECT_TRUE(again.device_scene.layout_from_cache()) << "the last start stored its own layout";
    EXPECT_TRUE(same_hits(hits_of(again)));
  }
}

// The cache files of a start through SceneOnDevices are written on a thread of their own: the
// BVH cache at once, the device layout once the first frame is on its way (render says when);
// a start that ends without saying so (an error, an interrupt, a bench) still waits for both
// as it goes. What they hold is read back by the next starts: the layout mapped, the tree read
// for another layout, every hit the same as a start without any cache.
TEST(DeviceLayoutCache, CacheWritesRunOffTheStartAndAreCompleteWhenItEnds) {
  test::TempDir dir;
  const std::filesystem::path cache_dir = dir.path() / "cache";
  const test::ScopedEnv cache_env("PARALLAX_CACHE_DIR", cache_dir.string());
  const test::ScopedEnv cache_on("PARALLAX_BVH_CACHE", std::nullopt);
  // A 120 x 100 grid, 24,000 triangles: past the caches' threshold of 20,000.
  std::string obj;
  const int nx = 120, ny = 100;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i)
      obj += "v " + std::to_string(0.05 * i) + " " + std::to_string(0.2 * std::sin(0.3 * i + 0.1 * j)) + " " +
             std::to_string(0.05 * j) + "\n";
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i + 1, b = a + 1, c = a + nx + 1, d = c + 1;
      obj += "f " + std::to_string(a) + " " + std::to_string(c) + " " + std::to_string(b) + "\n";
      obj += "f " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d) + "\n";
    }
  const std::string spec = dir.write("grid.obj", obj).string();
  const DeviceOptions one{1, DeviceMode::Auto, "", std::nullopt};
  std::vector<Ray> rays;
  for (int k = 0; k < 200; ++k)
    rays.push_back(test::make_ray({0.03f * (k % 20) + 0.1f, 2.0f, 0.025f * (k / 10) + 0.1f}, {0.0f, -1.0f, 0.0f}));
  const auto hits_of = [&](SceneOnDevices& s) { return RayBatchTracer(s.devices, s.device_scene).closest(rays); };
  const auto files = [&](const char* prefix) {
    int n = 0;
    if (std::filesystem::exists(cache_dir))
      for (const auto& e : std::filesystem::directory_iterator(cache_dir))
        n += e.path().filename().string().rfind(prefix, 0) == 0;
    return n;
  };
  std::vector<Hit> expected;
  {
    const test::ScopedEnv cache_off("PARALLAX_BVH_CACHE", "off");
    SceneOnDevices none(spec, one, /*quiet=*/true);
    expected = hits_of(none);
  }
  const auto same_hits = [&](const std::vector<Hit>& h) {
    for (std::size_t i = 0; i < h.size(); ++i)
      if (h[i].prim != expected[i].prim || h[i].t != expected[i].t || h[i].prim == PX_NO_HIT) return false;
    return h.size() == expected.size();
  };
  {
    SceneOnDevices cold(spec, one, true);
    ASSERT_NE(cold.loaded.cache_writes, nullptr);
    EXPECT_TRUE(cold.loaded.cache_writes->any());
    EXPECT_TRUE(cold.loaded.tree_write.has_value()) << "the tree was built, so its write was queued";
    EXPECT_EQ(files("device-layout-"), 0) << "held for the first frame";
    EXPECT_EQ(cold.device_scene.layout_store_ms(), 0.0) << "not written by the start itself";
    EXPECT_TRUE(same_hits(hits_of(cold)));
  }  // no wait_for_cache_writes: the start's end waits
  EXPECT_EQ(files("bvh-"), 1);
  EXPECT_EQ(files("device-layout-"), 1);
  EXPECT_EQ(files("."), 0) << "no temporary file left behind";
  {
    const Scene scene = load_scene(spec);
    const auto mapped =
        DeviceLayoutCache(cache_dir.string())
            .open(scene_content_key(scene), bvh_layout_for(false), BvhBuildOptions{}, scene.triangles.size());
    ASSERT_NE(mapped, nullptr);
    EXPECT_TRUE(mapped->verify_payload());
    EXPECT_TRUE(BvhCache(cache_dir.string()).load(TriangleSource(scene.triangles), BvhBuildOptions{}).has_value());
  }
  {
    SceneOnDevices warm(spec, one, true);
    EXPECT_TRUE(warm.device_scene.layout_from_cache());
    EXPECT_TRUE(same_hits(hits_of(warm)));
    warm.wait_for_cache_writes();
    EXPECT_EQ(files("device-layout-"), 1) << "nothing new to write";
    EXPECT_EQ(files("bvh-"), 1);
  }
  {
    // Another layout: no device layout of it in the cache, the tree read from the BVH cache.
    SceneOnDevices other(spec, test::options_in_layout(bvh_layout_for(/*all_gpus=*/true)), true);
    EXPECT_FALSE(other.device_scene.layout_from_cache());
    EXPECT_TRUE(other.loaded.times.bvh_from_cache);
    EXPECT_TRUE(same_hits(hits_of(other)));
    // Checked before the first frame lets it go (after, it may be written at once).
    EXPECT_EQ(files("device-layout-"), 1) << "its own layout held for the first frame";
    other.first_frame_on_its_way();
    other.wait_for_cache_writes();
    EXPECT_EQ(files("device-layout-"), 2) << "its own layout written";
  }
  EXPECT_EQ(files("device-layout-"), 2);
  EXPECT_EQ(files("."), 0) << "no temporary file left behind";
}

// Waiting for a write that is still running (DeviceScene waits for the BVH cache's before it
// changes the tree) runs the jobs up to it, and only those: a job queued after it for the first
// frame (the device layout's write) is still held until first_frame_on_its_way(). It had opened the
// gate for good, and the layout's write then ran during the start whenever the BVH cache's write
// had outlasted the tree's collapse. (The pauses order the threads; no time is measured.)
TEST(BackgroundWrites, WaitingForARunningWriteDoesNotReleaseTheWritesHeldForTheFirstFrame) {
  BackgroundWrites writes;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<bool> tree_written{false}, layout_written{false};
  const auto tree = writes.submit(
      [released, &tree_written] {
        released.wait();
        tree_written = true;
      },
      BackgroundWrites::Start::Now);
  std::thread waiter([&] { writes.wait_for(tree); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the waiter is waiting, as a rule
  release.set_value();
  waiter.join();
  EXPECT_TRUE(tree_written);
  writes.submit([&layout_written] { layout_written = true; }, BackgroundWrites::Start::AfterFirstFrame);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // time enough to run, were it let
  EXPECT_FALSE(layout_written) << "held for the first frame";
  writes.first_frame_on_its_way();
  writes.wait();
  EXPECT_TRUE(layout_written);
}

TEST(DeviceLayoutCache, NoFolderMeansNoCacheAndNoError) {
  const DeviceLayoutCache cache("");
  EXPECT_FALSE(cache.enabled());
  const Scene scene = test_scene();
  EXPECT_EQ(cache.open(scene_content_key(scene), BvhLayout::Wide8, BvhBuildOptions{}, scene.triangles.size()), nullptr);
  std::string why;
  DeviceLayoutParts parts;
  EXPECT_EQ(cache.store(1, BvhBuildOptions{}, 1, parts, &why), "");
  EXPECT_FALSE(why.empty());
  // A folder that cannot be made: a miss and a reason, no exception.
  test::TempDir dir;
  const auto file = dir.write("plain-file", "x");
  const DeviceLayoutCache blocked((file / "sub").string());
  EXPECT_EQ(blocked.open(1, BvhLayout::Wide8, BvhBuildOptions{}, 1), nullptr);
  const std::vector<BvhTriangle> tris(1);
  const std::vector<TriangleShading> shading(1);
  const std::uint32_t word = 0;
  parts.nodes = &word;
  parts.node_bytes = 4;
  parts.triangles = tris.data();
  parts.triangle_count = tris.size();
  parts.shading = shading.data();
  parts.shading_count = shading.size();
  why.clear();
  EXPECT_EQ(blocked.store(1, BvhBuildOptions{}, 1, parts, &why), "");
  EXPECT_FALSE(why.empty());
}

// A scene of flat, untextured triangles (a mesh without normals or uvs) is laid out with
// 16-byte FlatTriangleShading records (DeviceScene::flat_shading); its cache file holds them, a
// start maps them as such, and the mapped scene renders what the full records render.
// A smooth scene's indexed records (DeviceScene::indexed_shading) and their vertex table are
// one shading section: stored with the kind in the header, mapped back byte for byte, and a
// device scene made from the mapping builds the same kernels; a header that says another kind
// for those bytes is a miss.
TEST(DeviceLayoutCache, ASmoothSceneIsStoredAndMappedWithItsIndexedRecords) {
  test::TempDir dir;
  const DeviceLayoutCache cache{dir.path().string()};
  Scene scene;  // icospheres: vertices shared by their triangles, as a smooth mesh's are
  Material lamp;
  lamp.emission = glm::vec3(4.0f);
  scene.materials = {Material{}, lamp};
  for (int i = 0; i < 4; ++i) append_icosphere(scene.triangles, {1.5f * i, 0.0f, 0.0f}, 0.6f, 3, i == 3 ? 1 : 0);
  for (SceneTriangle& t : scene.triangles)
    for (int k = 0; k < 3; ++k) t.uv[k] = glm::vec2(t.p[k].x, t.p[k].z);
  ASSERT_FALSE(has_flat_shading(scene.triangles));
  const std::uint64_t key = scene_content_key(scene);
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  DeviceLayoutStore store;
  store.cache = &cache;
  store.content_key = key;
  Scene handed = scene;
  const auto host = DeviceScene::prepare_host(handed, [&handed] { return std::exchange(handed.triangles, {}); });
  const DeviceScene stored(set, host, handed, build_bvh(scene.triangles, {}, /*layout=*/std::nullopt), store);
  ASSERT_TRUE(stored.indexed_shading());
  auto mapped = cache.open(key, set.bvh_layout(), BvhBuildOptions{}, scene.triangles.size());
  ASSERT_NE(mapped, nullptr);
  EXPECT_EQ(mapped->shading_records(), ShadingRecords::Indexed);
  EXPECT_EQ(mapped->shading_size(), sizeof(IndexedTriangleShading));
  EXPECT_EQ(mapped->shading_count(), scene.triangles.size());
  EXPECT_GT(mapped->shading_bytes(), scene.triangles.size() * sizeof(IndexedTriangleShading));
  EXPECT_TRUE(mapped->verify_payload());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const TriangleShading got = expand_indexed_shading(mapped->shading(), i), want = shading_of(scene.triangles[i]);
    bad += std::memcmp(&got, &want, sizeof got) != 0;
  }
  EXPECT_EQ(bad, 0u);
  const DeviceScene from_file(set, scene, mapped);
  EXPECT_TRUE(from_file.indexed_shading());
  EXPECT_EQ(from_file.kernel_options(), stored.kernel_options());
  EXPECT_EQ(from_file.bytes_in_context(), stored.bytes_in_context());
}

TEST(DeviceLayoutCache, AFlatSceneIsStoredAndMappedWithItsSixteenByteRecords) {
  test::TempDir dir;
  const DeviceLayoutCache cache{dir.path().string()};
  Scene scene = test_scene();
  for (SceneTriangle& t : scene.triangles) {
    const glm::vec3 n = glm::normalize(glm::cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
    for (int k = 0; k < 3; ++k) {
      t.n[k] = n;
      t.uv[k] = glm::vec2(0.0f);
    }
  }
  ASSERT_TRUE(has_flat_shading(scene.triangles));
  scene.sky.enabled = true;  // lit from everywhere, not only by the lamp
  scene.sky.zenith = glm::vec3(0.5f, 0.6f, 0.9f);
  scene.sky.horizon = glm::vec3(0.9f);
  scene.sky.ground = glm::vec3(0.2f);
  const std::uint64_t key = scene_content_key(scene);
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  DeviceLayoutStore store;
  store.cache = &cache;
  store.content_key = key;
  Scene handed = scene;
  const auto host = DeviceScene::prepare_host(handed, [&handed] { return std::exchange(handed.triangles, {}); });
  const DeviceScene stored(set, host, handed, build_bvh(scene.triangles, {}, /*layout=*/std::nullopt), store);
  ASSERT_TRUE(stored.flat_shading());
  auto mapped = cache.open(key, set.bvh_layout(), BvhBuildOptions{}, scene.triangles.size());
  ASSERT_NE(mapped, nullptr);
  EXPECT_EQ(mapped->shading_size(), sizeof(FlatTriangleShading));
  EXPECT_EQ(mapped->shading_count(), scene.triangles.size());
  EXPECT_TRUE(mapped->verify_payload());
  const FlatTriangleShading* records = static_cast<const FlatTriangleShading*>(mapped->shading());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i)
    bad += records[i].n[0] != scene.triangles[i].n[0].x || records[i].n[2] != scene.triangles[i].n[0].z ||
           records[i].material != scene.triangles[i].material;
  EXPECT_EQ(bad, 0u);
  const DeviceScene from_file(set, scene, mapped);
  mapped.reset();
  EXPECT_TRUE(from_file.layout_from_cache());
  EXPECT_TRUE(from_file.flat_shading());
  EXPECT_EQ(from_file.kernel_options(), stored.kernel_options());
  EXPECT_EQ(from_file.bytes_in_context(), stored.bytes_in_context());
  const DeviceScene full(set, scene, build_bvh(scene.triangles));
  EXPECT_FALSE(full.flat_shading());
  PathTracer::Options opt;
  opt.spp = 2;
  opt.bounces = 3;
  const auto want = PathTracer(set, full, scene).render_stereo(0.0f, 1, 40, 30, opt);
  const auto got = PathTracer(set, from_file, scene).render_stereo(0.0f, 1, 40, 30, opt);
  for (int e = 0; e < 2; ++e)
    EXPECT_EQ(std::memcmp(want[e].rgb.data(), got[e].rgb.data(), want[e].rgb.size() * sizeof(float)), 0) << "eye " << e;
  double sum = 0.0;
  for (float v : want[0].rgb) sum += v;
  EXPECT_GT(sum, 0.0) << "a picture, not a black frame";
}

}  // namespace
}  // namespace px
