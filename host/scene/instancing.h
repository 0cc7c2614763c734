// Instances in the host scene (Scene::instancing): meshes stored once in their own space and
// placed by several nodes. Most of the host reads a scene as world-space triangles; these are
// the ways to do so whether or not it has instances.
#pragma once

#include "scene/scene.h"

#include <cstddef>
#include <limits>

namespace px {

// The mesh-space triangle `t` placed by `object_to_world` (normals by its inverse transpose).
SceneTriangle place_triangle(const SceneTriangle& t, const glm::mat4& object_to_world);

// Triangles the scene draws: its world triangles plus every instance's mesh.
std::size_t drawn_triangle_count(const Scene& scene);

// Replaces the instances by copies of their meshes in world space (appended after the world's
// triangles, instance by instance), so that `scene` has no instancing left. Vertex colours
// follow. A scene without instances is left as it is.
void flatten_instances(Scene& scene);

// Calls fn(const glm::vec3 (&p)[3], std::size_t index) for every drawn triangle in world space,
// in flatten_instances' order (index counts in that order).
template <typename Fn>
void for_each_drawn_triangle(const Scene& scene, Fn&& fn) {
  const SceneInstancing& in = scene.instancing;
  const std::size_t world = in.empty() ? scene.triangles.size() : in.world_triangles;
  std::size_t index = 0;
  for (std::size_t i = 0; i < world; ++i) fn(scene.triangles[i].p, index++);
  for (const MeshInstance& inst : in.instances) {
    const InstancedMesh& m = in.meshes[inst.mesh];
    for (std::size_t i = m.first; i < m.first + m.count; ++i) {
      const SceneTriangle& t = scene.triangles[i];
      glm::vec3 p[3];
      for (int c = 0; c < 3; ++c) p[c] = glm::vec3(inst.object_to_world * glm::vec4(t.p[c], 1.0f));
      fn(p, index++);
    }
  }
}

// The drawn triangles' bounding box (NaN coordinates passed over) and whether every coordinate
// lies within +-kMaxSceneCoordinate (NaN does not). A large scene's world triangles are read in
// parts side by side: a start asks for this several times (the loader's range check, load_scene's,
// the start's bounds) and 4M triangles are 400 MB to read. Where a bound is zero, its sign may
// differ from a one-by-one pass's (the parts are joined by min and max).
struct DrawnBounds {
  glm::vec3 lo{std::numeric_limits<float>::max()}, hi{-std::numeric_limits<float>::max()};
  bool in_range = true;  // every coordinate within +-kMaxSceneCoordinate
  bool any = false;      // a triangle is drawn
};
DrawnBounds drawn_bounds(const Scene& scene);

// Throws std::logic_error when the instancing does not describe the triangles (meshes out of
// range or overlapping the world part, instances naming no mesh, a matrix that is not affine
// with a positive determinant).
void check_instancing(const Scene& scene);

}  // namespace px
