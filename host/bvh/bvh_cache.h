// A disk cache of built BVHs. Building a large scene's BVH with spatial splits takes seconds
// (atrium's 550k triangles: ~6 s on 2 cores, several times Embree's own build), and the same
// scene is loaded again and again; the flattened BVH is a few tens of MB to read back.
//
// Key: a 64-bit ContentHash (io/content_hash.h) of everything the build reads — every triangle's vertices and
// material, the build options — and of the builder itself (a SHA-1 of its sources, set by
// CMake, and the layouts' sizes), so an edited scene, another option or a changed builder is
// simply a miss. A file holds a
// header (the key, the counts, the build's statistics), the nodes, the triangles and a
// checksum of all that; a truncated, corrupted or foreign file is a miss too, never an error.
// Files are written atomically (temporary + rename), so concurrent runs never read half a file.
//
// Validated when written: a tree is stored only after validate_bvh passed on it and on the wide
// nodes it carried, and the header records which layouts those were. Collapsing is
// deterministic and its sources (wide_bvh.cpp, compressed_bvh.cpp) are in the key, as is the
// validator's, so the wide nodes collapsed again from a tree read back are the very nodes that
// were validated: a start that reads the tree need not validate them again.
#pragma once

#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace px {

std::uint64_t bvh_input_hash(const TriangleSource& triangles, const BvhBuildOptions& options);

// A layout's bit in BvhCache's validated-layouts mask.
std::uint32_t bvh_layout_bit(BvhLayout layout);

class BvhCache {
 public:
  // $PARALLAX_CACHE_DIR, else $XDG_CACHE_HOME/parallax, else $HOME/.cache/parallax; "" when
  // none is set or PARALLAX_BVH_CACHE=off.
  static std::string default_dir();

  explicit BvhCache(std::string dir) : dir_(std::move(dir)) {}

  // The cached BVH for these triangles and options, or nullopt (miss, or an unreadable file).
  // `validated_layouts` (if given): the bvh_layout_bit of each wide layout validated with the
  // tree before it was stored (0 on a miss).
  // `key` (if given): the file's key (bvh_input_hash), for a store after a miss.
  std::optional<FlatBvh> load(const TriangleSource& triangles, const BvhBuildOptions& options,
                              std::uint32_t* validated_layouts = nullptr, std::uint64_t* key = nullptr) const;
  // Stores `bvh` (built from these triangles and options), which must have passed validate_bvh
  // with the wide nodes it carries (recorded as validated). Returns the file written, or "" with
  // `why` set when it could not be (a cache never fails a run).
  std::string store(const FlatBvh& bvh, const TriangleSource& triangles, const BvhBuildOptions& options,
                    std::string* why = nullptr) const;
  // What a file holds of a tree: the binary nodes and leaf triangles (as built: flags 0), its
  // statistics and the wide layouts validated with it (bvh_layout_bit). It points into the
  // tree's arrays: a write on another thread (scene_setup.cpp) holds no copy of them.
  struct Contents {
    const BvhNode* nodes = nullptr;
    std::size_t node_count = 0;
    const BvhTriangle* triangles = nullptr;
    std::size_t triangle_count = 0;
    BvhBuildStats stats;
    std::uint32_t validated_layouts = 0;
  };
  static Contents contents_of(const FlatBvh& bvh);
  // store() with the key load() gave on its miss (the triangles are not read again: they may be
  // gone), and the scene's triangle count.
  std::string store(const Contents& tree, std::uint64_t key, std::size_t scene_triangles,
                    std::string* why = nullptr) const;
  std::string path_for(std::uint64_t key) const;

 private:
  std::string dir_;
};

}  // namespace px
