// The scene's device layout on disk, memory-mapped at the next start: for a static scene
// without instances, the three large scene buffers exactly as DeviceScene makes them for one
// node layout (the node buffer: wide nodes and leaf blocks, or binary nodes; the leaf-order
// triangles with their flags; the shading records). A warm start maps the file and hands the
// mapping to the devices: CPU devices read it in place (CL_MEM_USE_HOST_PTR), GPUs are written
// from it. No tree is read, collapsed, laid out or validated: the 10M-triangle heightfield's
// warm start had spent 2.4 s reading the binary tree back and 6.8 s laying it out again.
//
// Key: a ContentHash of every scene triangle (vertices, normals, uvs, material), of each
// material's triangle flags (alpha-tested, emissive), of the build options and the node layout,
// and of the sources of the builder, the collapser, the validator and the device layout (set by
// CMake), so an edited scene or a changed builder is a miss.
//
// Validated when written: a file is stored only from a tree that passed validate_bvh with the
// wide nodes laid out from it (scene_setup.cpp), and the layout is a function of those. A start
// does not read the whole file: it checks the header (its own checksum, the key, the sizes,
// the file's length) and a sample of the payload (the first 4 KiB of every MiB) against
// checksums written with it, so a truncated, foreign or overwritten file is a miss, never an
// error; verify_payload() checks every byte (the tests do). Files are written atomically
// (temporary + rename).
//
// File layout (little-endian; every section starts on a 4096-byte boundary, so the mapped
// arrays are page-aligned as CL_MEM_USE_HOST_PTR wants them):
//   0       DeviceLayoutHeader (below), zero-padded to 4096 bytes
//   nodes   the node buffer's bytes (uint words)
//   tris    the leaf triangles, triangle_count records of triangle_size bytes: BvhTriangle, or
//           BvhLeafRef in the Wide4 and Wide8 layouts (DeviceScene::leaf_refs)
//   shading shading_count records of shading_size bytes (scene order): TriangleShading,
//           FlatTriangleShading for a scene of flat, untextured triangles (DeviceScene::flat_shading),
//           or IndexedTriangleShading and then its vertex table for a smooth mesh
//           (DeviceScene::indexed_shading): shading_bytes in all, the header's shading_records
//           says which
#pragma once

#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"
#include "scene/scene.h"
#include "shared/types.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace px {

// The shading buffer's records (types.h): TriangleShading (64 bytes), FlatTriangleShading (16:
// every triangle flat and untextured), or IndexedTriangleShading (16) followed by its table of
// ShadingVertex (20 bytes each: a smooth mesh's vertices).
enum class ShadingRecords : std::uint32_t { Full = 0, Flat = 1, Indexed = 2 };
const char* to_string(ShadingRecords records);  // "full", "flat", "indexed"
std::size_t record_size(ShadingRecords records);

// A hash of what the device layout of `scene` depends on, whatever the node layout: its
// triangles (all attributes) and each material's triangle flags. device_layout_key() adds the
// layout and the build options.
std::uint64_t scene_content_key(const Scene& scene);
std::uint64_t device_layout_key(std::uint64_t content_key, BvhLayout layout, const BvhBuildOptions& options);

// A file of the cache, mapped read-only. The arrays live as long as the object.
class MappedDeviceLayout {
 public:
  MappedDeviceLayout(const MappedDeviceLayout&) = delete;
  MappedDeviceLayout& operator=(const MappedDeviceLayout&) = delete;
  ~MappedDeviceLayout();

  BvhLayout layout() const { return layout_; }
  // The tree's statistics as built (nodes, leaf triangles, depth, SAH cost, build time), and its
  // node count in the layout (wide nodes; binary: nodes).
  const BvhBuildStats& stats() const { return stats_; }
  std::size_t layout_nodes() const { return layout_nodes_; }

  const void* node_bytes() const { return at(nodes_offset_); }
  std::size_t node_byte_count() const { return node_bytes_; }
  // The leaf triangles: triangle_count records of triangle_size bytes (BvhTriangle or BvhLeafRef).
  const void* triangles() const { return at(triangles_offset_); }
  std::size_t triangle_count() const { return triangle_count_; }
  std::size_t triangle_size() const { return triangle_size_; }
  // The shading records: shading_count of shading_size bytes (ShadingRecords says which), and
  // for indexed records their vertex table after them: shading_bytes in all.
  const void* shading() const { return at(shading_offset_); }
  std::size_t shading_count() const { return shading_count_; }
  std::size_t shading_size() const { return shading_size_; }
  std::size_t shading_bytes() const { return shading_bytes_; }
  ShadingRecords shading_records() const { return shading_records_; }
  std::size_t file_bytes() const { return length_; }
  const std::string& path() const { return path_; }

  // Reads every byte of the payload against its checksum (a start checks a sample only).
  bool verify_payload() const;

 private:
  friend class DeviceLayoutCache;
  MappedDeviceLayout() = default;
  const void* at(std::size_t offset) const { return static_cast<const unsigned char*>(base_) + offset; }

  void* base_ = nullptr;
  std::size_t length_ = 0;
  std::string path_;
  BvhLayout layout_ = BvhLayout::Binary;
  BvhBuildStats stats_;
  std::size_t layout_nodes_ = 0;
  std::size_t nodes_offset_ = 0, node_bytes_ = 0;
  std::size_t triangles_offset_ = 0, triangle_count_ = 0, triangle_size_ = sizeof(BvhTriangle);
  std::size_t shading_offset_ = 0, shading_count_ = 0, shading_size_ = sizeof(TriangleShading), shading_bytes_ = 0;
  ShadingRecords shading_records_ = ShadingRecords::Full;
  std::uint64_t payload_checksum_ = 0;
};

// What DeviceScene stores: the three buffers of one layout, and the tree's statistics.
struct DeviceLayoutParts {
  BvhLayout layout = BvhLayout::Binary;
  BvhBuildStats stats;
  std::size_t layout_nodes = 0;
  const void* nodes = nullptr;
  std::size_t node_bytes = 0;
  const void* triangles = nullptr;  // triangle_count records of triangle_size bytes
  std::size_t triangle_count = 0;
  std::size_t triangle_size = sizeof(BvhTriangle);  // or sizeof(BvhLeafRef) (Wide4, Wide8)
  const void* shading = nullptr;                    // shading_count records of shading_size bytes (scene order)
  std::size_t shading_count = 0;
  std::size_t shading_size = sizeof(TriangleShading);  // or sizeof(FlatTriangleShading)
  ShadingRecords shading_records = ShadingRecords::Full;
  // The shading section's bytes: the records, and for indexed ones their vertex table (0: the
  // records alone, shading_count * shading_size).
  std::size_t shading_bytes = 0;
};

class DeviceLayoutCache {
 public:
  // The BVH cache's folder (BvhCache::default_dir: "" when PARALLAX_BVH_CACHE=off); "" = none.
  static std::string default_dir();

  explicit DeviceLayoutCache(std::string dir) : dir_(std::move(dir)) {}
  bool enabled() const { return !dir_.empty(); }

  // The file for `content_key` (scene_content_key) in `layout`, mapped, or null (a miss, or a
  // file that fails a check). `scene_triangles`: the scene's count, checked against the file's.
  std::shared_ptr<const MappedDeviceLayout> open(std::uint64_t content_key, BvhLayout layout,
                                                 const BvhBuildOptions& options, std::size_t scene_triangles) const;
  // Writes `parts`; returns the file written, or "" with `why` set (a cache never fails a run).
  std::string store(std::uint64_t content_key, const BvhBuildOptions& options, std::size_t scene_triangles,
                    const DeviceLayoutParts& parts, std::string* why = nullptr) const;
  std::string path_for(std::uint64_t key) const;

 private:
  std::string dir_;
};

}  // namespace px
