#include "bvh/bvh_validator.h"
#include "bvh/scene_bvhs.h"
#include "bvh/wide_bvh.h"

#include <stdexcept>
#include <string>

namespace px {

std::vector<SceneTriangle> triangle_range(const Scene& scene, std::size_t first, std::size_t count) {
  if (first + count > scene.triangles.size()) throw std::out_of_range("triangle_range beyond the scene's triangles");
  return std::vector<SceneTriangle>(scene.triangles.begin() + std::ptrdiff_t(first),
                                    scene.triangles.begin() + std::ptrdiff_t(first + count));
}

FlatBvh build_world_bvh(const Scene& scene, const BvhBuildOptions& options) {
  if (scene.instancing.empty()) return build_bvh(scene.triangles, options);
  if (scene.instancing.world_triangles == 0) return FlatBvh{};
  return build_bvh(triangle_range(scene, 0, scene.instancing.world_triangles), options);
}

std::vector<FlatBvh> build_mesh_bvhs(const Scene& scene, BvhLayout layout, const BvhBuildOptions& options) {
  std::vector<FlatBvh> out;
  out.reserve(scene.instancing.meshes.size());
  for (std::size_t k = 0; k < scene.instancing.meshes.size(); ++k) {
    const InstancedMesh& m = scene.instancing.meshes[k];
    const std::vector<SceneTriangle> tris = triangle_range(scene, m.first, m.count);
    FlatBvh tree = build_bvh(tris, options);
    ensure_layout(tree, layout);
    const BvhValidation check = validate_bvh(tree, tris);
    if (!check.ok)
      throw std::runtime_error("internal error: the BVH of instanced mesh " + std::to_string(k) +
                               " failed validation: " + (check.errors.empty() ? "" : check.errors.front()));
    out.push_back(std::move(tree));
  }
  return out;
}

}  // namespace px
