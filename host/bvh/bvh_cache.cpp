#include "bvh/bvh_cache.h"
#include "bvh/wide_bvh.h"

#include "io/atomic_file.h"
#include "io/content_hash.h"
#include "io/environment.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace px {

namespace {

constexpr char kMagic[8] = {'P', 'X', 'B', 'V', 'H', 'C', '0', '1'};
constexpr std::uint32_t kFormatVersion = 3;  // 2: validated_layouts; 3: ContentHash, not FNV-1a
#ifndef PX_BVH_BUILDER_SHA
#define PX_BVH_BUILDER_SHA "unknown"
#endif
// SHA-1 of the builder's sources (set by CMake): a rebuilt builder never reads an old file.
constexpr const char* kBuilderSha = PX_BVH_BUILDER_SHA;

// Fixed-size header (all fields 8 bytes wide: no padding, same on every platform we build for).
struct Header {
  char magic[8];
  std::uint64_t format, node_size, triangle_size, key;
  std::uint64_t scene_triangles, nodes, triangles;
  std::uint64_t depth, split_budget_exceeded, split_calls;
  double build_ms, sah_cost;
  std::uint64_t validated_layouts;  // bvh_layout_bit of each wide layout the tree carried when stored
};

std::uint64_t payload_checksum(const Header& h, const BvhNode* nodes, const BvhTriangle* triangles) {
  ContentHash f(3);
  f.value(h);
  f.bytes(nodes, h.nodes * sizeof(BvhNode));
  f.bytes(triangles, h.triangles * sizeof(BvhTriangle));
  return f.digest();
}

}  // namespace

std::uint64_t bvh_input_hash(const TriangleSource& triangles, const BvhBuildOptions& options) {
  ContentHash f(4);
  f.value(kFormatVersion);
  f.bytes(kBuilderSha, std::strlen(kBuilderSha));
  f.value(static_cast<std::uint64_t>(sizeof(BvhNode)));
  f.value(static_cast<std::uint64_t>(sizeof(BvhTriangle)));
  f.value(static_cast<std::uint8_t>(options.spatial_splits));
  f.value(options.max_leaf_size);
  f.value(options.split_calls_per_triangle);
  f.value(static_cast<std::uint64_t>(options.split_trial_triangles));
  f.value(options.split_min_gain);
  f.value(static_cast<std::uint64_t>(options.split_trial_max_sample));
  f.value(static_cast<std::uint64_t>(options.block_leaves_from));
  f.value(static_cast<std::uint64_t>(triangles.size()));
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    f.bytes(triangles.p(i), 3 * sizeof(glm::vec3));
    f.value(triangles.material(i));
  }
  return f.digest();
}

std::string BvhCache::default_dir() {
  if (!environment().bvh_cache) return "";
  if (const std::string& d = environment().cache_dir; !d.empty()) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::string(x) + "/parallax";
  if (const char* home = std::getenv("HOME"); home && *home) return std::string(home) + "/.cache/parallax";
  return "";
}

std::string BvhCache::path_for(std::uint64_t key) const {
  char name[40];
  std::snprintf(name, sizeof name, "bvh-%016llx.bin", static_cast<unsigned long long>(key));
  return dir_ + "/" + name;
}

std::uint32_t bvh_layout_bit(BvhLayout layout) { return 1u << static_cast<unsigned>(bvh_layout_width(layout)); }

std::optional<FlatBvh> BvhCache::load(const TriangleSource& triangles, const BvhBuildOptions& options,
                                      std::uint32_t* validated_layouts, std::uint64_t* key_out) const {
  if (validated_layouts) *validated_layouts = 0;
  if (dir_.empty()) return std::nullopt;
  const std::uint64_t key = bvh_input_hash(triangles, options);
  if (key_out) *key_out = key;
  std::ifstream in(path_for(key), std::ios::binary);
  if (!in) return std::nullopt;
  Header h{};
  if (!in.read(reinterpret_cast<char*>(&h), sizeof h)) return std::nullopt;
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0 || h.format != kFormatVersion ||
      h.node_size != sizeof(BvhNode) || h.triangle_size != sizeof(BvhTriangle) || h.key != key ||
      h.scene_triangles != triangles.size())
    return std::nullopt;
  // Bound the sizes before allocating: a leaf triangle list is at most a few times the scene
  // (spatial splits), a binary tree has fewer nodes than leaf triangles.
  if (h.nodes == 0 || h.triangles == 0 || h.triangles > 16 * triangles.size() + 16 || h.nodes > 2 * h.triangles + 1)
    return std::nullopt;
  FlatBvh bvh;
  bvh.nodes.resize(h.nodes);
  bvh.triangles.resize(h.triangles);
  std::uint64_t checksum = 0;
  if (!in.read(reinterpret_cast<char*>(bvh.nodes.data()), h.nodes * sizeof(BvhNode)) ||
      !in.read(reinterpret_cast<char*>(bvh.triangles.data()), h.triangles * sizeof(BvhTriangle)) ||
      !in.read(reinterpret_cast<char*>(&checksum), sizeof checksum) || in.peek() != std::ifstream::traits_type::eof())
    return std::nullopt;
  if (checksum != payload_checksum(h, bvh.nodes.data(), bvh.triangles.data())) return std::nullopt;
  bvh.stats.scene_triangles = h.scene_triangles;
  bvh.stats.leaf_triangles = h.triangles;
  bvh.stats.nodes = h.nodes;
  bvh.stats.depth = static_cast<int>(h.depth);
  bvh.stats.split_budget_exceeded = h.split_budget_exceeded != 0;
  bvh.stats.split_calls = h.split_calls;
  bvh.stats.build_ms = h.build_ms;
  bvh.stats.sah_cost = h.sah_cost;
  if (validated_layouts) *validated_layouts = static_cast<std::uint32_t>(h.validated_layouts);
  return bvh;
}

BvhCache::Contents BvhCache::contents_of(const FlatBvh& bvh) {
  Contents c;
  c.nodes = bvh.nodes.data();
  c.node_count = bvh.nodes.size();
  c.triangles = bvh.triangles.data();
  c.triangle_count = bvh.triangles.size();
  c.stats = bvh.stats;
  for (const BvhLayout l : {BvhLayout::Wide4, BvhLayout::Wide8, BvhLayout::Compressed8})
    if (has_layout(bvh, l)) c.validated_layouts |= bvh_layout_bit(l);
  return c;
}

std::string BvhCache::store(const FlatBvh& bvh, const TriangleSource& triangles, const BvhBuildOptions& options,
                            std::string* why) const {
  if (dir_.empty()) {
    if (why) *why = "no cache folder";
    return "";
  }
  return store(contents_of(bvh), bvh_input_hash(triangles, options), triangles.size(), why);
}

std::string BvhCache::store(const Contents& tree, std::uint64_t key, std::size_t scene_triangles,
                            std::string* why) const {
  if (dir_.empty()) {
    if (why) *why = "no cache folder";
    return "";
  }
  try {
    std::filesystem::create_directories(dir_);
    Header h{};
    std::memcpy(h.magic, kMagic, sizeof kMagic);
    h.format = kFormatVersion;
    h.node_size = sizeof(BvhNode);
    h.triangle_size = sizeof(BvhTriangle);
    h.key = key;
    h.scene_triangles = scene_triangles;
    h.nodes = tree.node_count;
    h.triangles = tree.triangle_count;
    h.depth = static_cast<std::uint64_t>(tree.stats.depth);
    h.split_budget_exceeded = tree.stats.split_budget_exceeded;
    h.split_calls = tree.stats.split_calls;
    h.build_ms = tree.stats.build_ms;
    h.sah_cost = tree.stats.sah_cost;
    h.validated_layouts = tree.validated_layouts;
    const std::uint64_t checksum = payload_checksum(h, tree.nodes, tree.triangles);
    const std::string path = path_for(h.key);
    AtomicFileWriter out(path);
    out.write({reinterpret_cast<const char*>(&h), sizeof h});
    out.write({reinterpret_cast<const char*>(tree.nodes), tree.node_count * sizeof(BvhNode)});
    out.write({reinterpret_cast<const char*>(tree.triangles), tree.triangle_count * sizeof(BvhTriangle)});
    out.write({reinterpret_cast<const char*>(&checksum), sizeof checksum});
    out.commit();
    return path;
  } catch (const std::exception& e) {
    if (why) *why = e.what();
    return "";
  }
}

}  // namespace px
