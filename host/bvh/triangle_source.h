// The triangles a BVH is built over, as its builder, validator and cache read them: each
// triangle's three corners and its material, wherever they lie. Either the scene's own
// SceneTriangles (100 bytes apart) or BuildTriangles (40 bytes): a static scene that goes
// to the devices turns its triangles into shading records before its tree is built, and keeps
// for the build only the corners and the materials, packed where the triangles were
// (DeviceScene::prepare_host_before_tree), so that the build's arrays never stand beside the 100-byte
// triangles. Both read the same floats, so the trees and the cache keys are the same.
#pragma once

#include "scene/scene.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace px {

struct BuildTriangle {
  glm::vec3 p[3];
  std::uint32_t material = 0;
};
static_assert(sizeof(BuildTriangle) == 40, "BuildTriangle: three corners and a material, packed");

// A view; what it reads must outlive it. Implicit from the scene's triangles, so that a caller
// holding those passes them as before.
class TriangleSource {
 public:
  TriangleSource(const std::vector<SceneTriangle>& triangles)  // NOLINT: implicit on purpose
      : base_(reinterpret_cast<const unsigned char*>(triangles.data())),
        stride_(sizeof(SceneTriangle)),
        material_offset_(offsetof(SceneTriangle, material)),
        size_(triangles.size()) {}
  TriangleSource(const BuildTriangle* triangles, std::size_t count)
      : base_(reinterpret_cast<const unsigned char*>(triangles)),
        stride_(sizeof(BuildTriangle)),
        material_offset_(offsetof(BuildTriangle, material)),
        size_(count) {}
  TriangleSource(const std::vector<BuildTriangle>& triangles) : TriangleSource(triangles.data(), triangles.size()) {}

  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  // Triangle i's corners p[0], p[1], p[2] (both layouts begin with them).
  const glm::vec3* p(std::size_t i) const { return reinterpret_cast<const glm::vec3*>(base_ + i * stride_); }
  std::uint32_t material(std::size_t i) const {
    return *reinterpret_cast<const std::uint32_t*>(base_ + i * stride_ + material_offset_);
  }
  BuildTriangle operator[](std::size_t i) const {
    const glm::vec3* c = p(i);
    return BuildTriangle{{c[0], c[1], c[2]}, material(i)};
  }

 private:
  const unsigned char* base_;
  std::size_t stride_, material_offset_, size_;
};

}  // namespace px
