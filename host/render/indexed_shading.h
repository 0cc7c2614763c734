// Indexed shading records for smooth meshes (types.h: IndexedTriangleShading, ShadingVertex):
// a 16-byte record per triangle pointing to its vertices' normal and uv, each distinct one
// stored once, where a full record (TriangleShading, 64 bytes) repeats a vertex's for every
// triangle that shares it. On a grid-like mesh (a vertex shared by six triangles) that is about
// 26 bytes a triangle instead of 64.
#pragma once

#include "bvh/flat_bvh.h"
#include "render/device_buffers.h"
#include "scene/scene.h"
#include "shared/types.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace px {

// Makes the records one triangle at a time, in scene order (DeviceScene's host part adds them
// as it reads the triangles it packs into build corners). A vertex is found again by its bits
// (normal and uv): first in a small direct-mapped table of the vertices made lately (meshes list
// a vertex's triangles near one another as a rule, and that table stays in a core's cache), then
// in a hash table of every vertex (8 bytes a slot, at most half full; gone at the end).
// The block holds the records, then the vertex table (one buffer: the kernels reach the table
// by each record's relative offsets). It is sized for the worst case (three entries of its own
// per triangle) without being touched; the pages past the table go back at the end.
class IndexedShadingBuilder {
 public:
  explicit IndexedShadingBuilder(std::size_t triangles);
  void add(const SceneTriangle& t);
  struct Result {
    SceneBytes bytes;      // records then table; element 16 (IndexedTriangleShading), or 64
    bool indexed = false;  // false: full TriangleShading records (the vertices shared too little)
    std::size_t vertices = 0;
  };
  // Once every triangle is added. Where the records and table would not be smaller than full
  // records (triangles that share no normal and uv: faceted normals with uvs), full records.
  Result finish();

 private:
  std::size_t triangles_ = 0, added_ = 0, vertices_ = 0;
  std::shared_ptr<std::vector<std::uint32_t, UninitializedAllocator<std::uint32_t>>> block_;
  // Slots: an entry's index + 1, 32 bits of its hash above; 0: none.
  std::vector<std::uint64_t> recent_;  // the latest entry of each hash (2^17 slots)
  std::vector<std::uint64_t> all_;     // every entry, open addressing, at most half full
  // A triangle waiting for its lookups (add): its corners' bits and their hashes.
  struct Pending {
    std::size_t triangle = 0;
    std::uint32_t material = 0;
    std::uint32_t w[3][5];
    std::uint64_t h[3];
  };
  static constexpr std::size_t kPending = 16;
  Pending pending_[kPending];
  std::uint32_t entry(const std::uint32_t* w, std::uint64_t h);
  void resolve(const Pending& p);
};

// Record `i` of an indexed block (records and table) as the full record a kernel would read in
// its place: the host's reading of the relative offsets (tests; the cache's checks).
TriangleShading expand_indexed_shading(const void* block, std::size_t i);

}  // namespace px
