// A disk cache of built BVHs. Building a large scene's BVH with spatial splits takes seconds
// (atrium's 550k triangles: ~6 s on 2 cores, several times Embree's own build), and the same
// scene is loaded again and again; the flattened BVH is a few tens of MB to read back.
//
// Key: a 64-bit FNV-1a hash of everything the build reads — every triangle's vertices and
// material, the build options — and of the builder itself (a SHA-1 of its sources, set by
// CMake, and the layouts' sizes), so an edited scene, another option or a changed builder is
// simply a miss. A file holds a
// header (the key, the counts, the build's statistics), the nodes, the triangles and a
// checksum of all that; a truncated, corrupted or foreign file is a miss too, never an error.
// Files are written atomically (temporary + rename), so concurrent runs never read half a file.
#pragma once

#include "bvh/flat_bvh.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace px {

std::uint64_t bvh_input_hash(const std::vector<SceneTriangle>& triangles, const BvhBuildOptions& options);

class BvhCache {
 public:
  // $PARALLAX_CACHE_DIR, else $XDG_CACHE_HOME/parallax, else $HOME/.cache/parallax; "" when
  // none is set or PARALLAX_BVH_CACHE=off.
  static std::string default_dir();

  explicit BvhCache(std::string dir) : dir_(std::move(dir)) {}

  // The cached BVH for these triangles and options, or nullopt (miss, or an unreadable file).
  std::optional<FlatBvh> load(const std::vector<SceneTriangle>& triangles, const BvhBuildOptions& options) const;
  // Stores `bvh` (built from these triangles and options). Returns the file written, or "" with
  // `why` set when it could not be (a cache never fails a run).
  std::string store(const FlatBvh& bvh, const std::vector<SceneTriangle>& triangles, const BvhBuildOptions& options,
                    std::string* why = nullptr) const;
  std::string path_for(std::uint64_t key) const;

 private:
  std::string dir_;
};

}  // namespace px
