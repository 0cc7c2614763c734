// The BVH disk cache: what comes back is byte for byte what was built (and passes the
// validator), and anything that is not exactly that file for exactly these triangles and
// options — another scene, another option, a truncated or corrupted file — is a miss, never
// an error or a wrong tree.
#include "bvh/bvh_cache.h"
#include "bvh/bvh_validator.h"
#include "bvh/wide_bvh.h"
#include "scene/primitives.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

namespace px {
namespace {

std::vector<SceneTriangle> slivers(std::size_t n, unsigned seed) {
  std::vector<SceneTriangle> tris;
  append_slivers(tris, n, seed, 3);
  return tris;
}

bool same_tree(const FlatBvh& a, const FlatBvh& b) {
  return a.nodes.size() == b.nodes.size() && a.triangles.size() == b.triangles.size() &&
         std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(BvhNode)) == 0 &&
         std::memcmp(a.triangles.data(), b.triangles.data(), a.triangles.size() * sizeof(BvhTriangle)) == 0;
}

TEST(BvhCache, ReadsBackExactlyWhatWasBuilt) {
  test::TempDir dir;
  const BvhCache cache(dir.path().string());
  const auto tris = slivers(3000, 1);
  const BvhBuildOptions options;
  EXPECT_FALSE(cache.load(tris, options).has_value()) << "empty cache";
  const FlatBvh built = build_bvh(tris, options);
  const std::string path = cache.store(built, tris, options);
  ASSERT_FALSE(path.empty());
  EXPECT_TRUE(std::filesystem::exists(path));
  const auto loaded = cache.load(tris, options);
  ASSERT_TRUE(loaded.has_value());
  EXPECT_TRUE(same_tree(built, *loaded));
  EXPECT_EQ(loaded->stats.nodes, built.stats.nodes);
  EXPECT_EQ(loaded->stats.depth, built.stats.depth);
  EXPECT_DOUBLE_EQ(loaded->stats.sah_cost, built.stats.sah_cost);
  EXPECT_TRUE(validate_bvh(*loaded, tris).ok);
}

// A start that reads a tree back skips validating the wide nodes recorded as validated with it:
// sound only if collapsing the tree read back gives the very nodes that were validated. Checked
// here byte for byte for each wide layout, and the record itself: what the stored tree carried.
TEST(BvhCache, RecordsTheValidatedLayoutsWhoseNodesCollapseAgainToTheSameBytes) {
  test::TempDir dir;
  const BvhCache cache(dir.path().string());
  const auto tris = slivers(3000, 4);
  const BvhBuildOptions options;
  FlatBvh built = build_bvh(tris, options);
  for (const BvhLayout l : {BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8}) ensure_layout(built, l);
  ASSERT_TRUE(validate_bvh(built, tris).ok);
  ASSERT_FALSE(cache.store(built, tris, options).empty());
  std::uint32_t validated = 0;
  auto loaded = cache.load(tris, options, &validated);
  ASSERT_TRUE(loaded.has_value());
  EXPECT_EQ(validated, bvh_layout_bit(BvhLayout::Wide4) | bvh_layout_bit(BvhLayout::Wide8) |
                           bvh_layout_bit(BvhLayout::Compressed8));
  EXPECT_TRUE(loaded->nodes8.empty()) << "the file holds the binary tree only";
  for (const BvhLayout l : {BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8}) ensure_layout(*loaded, l);
  ASSERT_EQ(loaded->nodes4.size(), built.nodes4.size());
  ASSERT_EQ(loaded->nodes8.size(), built.nodes8.size());
  ASSERT_EQ(loaded->cnodes.size(), built.cnodes.size());
  EXPECT_EQ(std::memcmp(loaded->nodes4.data(), built.nodes4.data(), built.nodes4.size() * sizeof(Bvh4Node)), 0);
  EXPECT_EQ(std::memcmp(loaded->nodes8.data(), built.nodes8.data(), built.nodes8.size() * sizeof(Bvh8Node)), 0);
  EXPECT_EQ(std::memcmp(loaded->cnodes.data(), built.cnodes.data(), built.cnodes.size() * sizeof(CompressedBvh8Node)),
            0);
  EXPECT_EQ(loaded->cleaf_first, built.cleaf_first);
  // A tree stored with its binary nodes alone records no layout: the next start validates.
  const auto other = slivers(2000, 5);
  FlatBvh binary_only = build_bvh(other, options);
  binary_only.nodes4.clear();
  binary_only.nodes8.clear();
  binary_only.cnodes.clear();
  binary_only.cleaf_first.clear();
  ASSERT_FALSE(cache.store(binary_only, other, options).empty());
  ASSERT_TRUE(cache.load(other, options, &validated).has_value());
  EXPECT_EQ(validated, 0u);
  EXPECT_FALSE(cache.load(slivers(2000, 6), options, &validated).has_value());
  EXPECT_EQ(validated, 0u) << "a miss records nothing";
}

TEST(BvhCache, AnotherSceneOrOptionIsAMiss) {
  test::TempDir dir;
  const BvhCache cache(dir.path().string());
  auto tris = slivers(2000, 2);
  const BvhBuildOptions options;
  cache.store(build_bvh(tris, options), tris, options);
  ASSERT_TRUE(cache.load(tris, options).has_value());
  BvhBuildOptions binned;
  binned.spatial_splits = false;
  EXPECT_FALSE(cache.load(tris, binned).has_value());
  auto moved = tris;
  moved[1234].p[2].y += 1e-6f;  // one vertex of one triangle, slightly
  EXPECT_FALSE(cache.load(moved, options).has_value());
  auto remat = tris;
  remat[7].material = 9;
  EXPECT_FALSE(cache.load(remat, options).has_value());
  auto fewer = tris;
  fewer.pop_back();
  EXPECT_FALSE(cache.load(fewer, options).has_value());
}

TEST(BvhCache, DamagedFilesAreMisses) {
  test::TempDir dir;
  const BvhCache cache(dir.path().string());
  const auto tris = slivers(1500, 3);
  const BvhBuildOptions options;
  const std::string path = cache.store(build_bvh(tris, options), tris, options);
  ASSERT_FALSE(path.empty());
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  auto write = [&](const std::string& b) { std::ofstream(path, std::ios::binary | std::ios::trunc) << b; };
  write(bytes.substr(0, bytes.size() / 2));  // truncated
  EXPECT_FALSE(cache.load(tris, options).has_value());
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x40;  // one bit in the nodes or triangles
  write(flipped);
  EXPECT_FALSE(cache.load(tris, options).has_value());
  write(bytes + "x");  // trailing garbage
  EXPECT_FALSE(cache.load(tris, options).has_value());
  write("not a cache file at all");
  EXPECT_FALSE(cache.load(tris, options).has_value());
  write(bytes);  // intact again
  EXPECT_TRUE(cache.load(tris, options).has_value());
}

TEST(BvhCache, NoFolderMeansNoCacheAndNoError) {
  const auto tris = slivers(100, 4);
  const BvhCache none("");
  std::string why;
  EXPECT_TRUE(none.store(build_bvh(tris), tris, {}, &why).empty());
  EXPECT_FALSE(why.empty());
  EXPECT_FALSE(none.load(tris, {}).has_value());
  // A folder that cannot be made (under a file): store says why, load misses.
  test::TempDir dir;
  const auto file = dir.write("plain-file", "x");
  const BvhCache blocked((file / "sub").string());
  why.clear();
  EXPECT_TRUE(blocked.store(build_bvh(tris), tris, {}, &why).empty());
  EXPECT_FALSE(why.empty());
  EXPECT_FALSE(blocked.load(tris, {}).has_value());
}

}  // namespace
}  // namespace px
