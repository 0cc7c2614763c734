#include "scene/instancing.h"

#include "scene/scene_loader.h"
#include "util/parallel_parts.h"

#include <glm/gtc/matrix_inverse.hpp>

#include <cmath>
#include <stdexcept>
#include <string>

namespace px {

SceneTriangle place_triangle(const SceneTriangle& t, const glm::mat4& object_to_world) {
  const glm::mat3 normal_matrix = glm::inverseTranspose(glm::mat3(object_to_world));
  SceneTriangle out = t;
  for (int c = 0; c < 3; ++c) {
    out.p[c] = glm::vec3(object_to_world * glm::vec4(t.p[c], 1.0f));
    const glm::vec3 n = normal_matrix * t.n[c];
    const float len = glm::length(n);
    out.n[c] = len > 0.0f && std::isfinite(len) ? n / len : t.n[c];
  }
  return out;
}

std::size_t drawn_triangle_count(const Scene& scene) {
  const SceneInstancing& in = scene.instancing;
  if (in.empty()) return scene.triangles.size();
  std::size_t n = in.world_triangles;
  for (const MeshInstance& inst : in.instances) n += in.meshes.at(inst.mesh).count;
  return n;
}

void flatten_instances(Scene& scene) {
  SceneInstancing& in = scene.instancing;
  if (in.empty()) {
    in = SceneInstancing{};
    return;
  }
  check_instancing(scene);
  const bool colours = !scene.vertex_colours.empty();
  std::vector<SceneTriangle> tris(scene.triangles.begin(),
                                  scene.triangles.begin() + std::ptrdiff_t(in.world_triangles));
  std::vector<std::array<glm::vec3, 3>> cols;
  if (colours)
    cols.assign(scene.vertex_colours.begin(), scene.vertex_colours.begin() + std::ptrdiff_t(in.world_triangles));
  tris.reserve(drawn_triangle_count(scene));
  for (const MeshInstance& inst : in.instances) {
    const InstancedMesh& m = in.meshes[inst.mesh];
    for (std::size_t i = m.first; i < m.first + m.count; ++i) {
      tris.push_back(place_triangle(scene.triangles[i], inst.object_to_world));
      if (colours) cols.push_back(scene.vertex_colours[i]);
    }
  }
  scene.triangles = std::move(tris);
  scene.vertex_colours = std::move(cols);
  in = SceneInstancing{};
}

void check_instancing(const Scene& scene) {
  const SceneInstancing& in = scene.instancing;
  if (in.empty()) return;
  const auto fail = [](const std::string& what) { throw std::logic_error("scene instancing: " + what); };
  if (in.world_triangles > scene.triangles.size()) fail("more world triangles than triangles");
  std::size_t next = in.world_triangles;
  for (std::size_t k = 0; k < in.meshes.size(); ++k) {
    const InstancedMesh& m = in.meshes[k];
    if (m.first != next || m.count == 0 || m.first + m.count > scene.triangles.size())
      fail("mesh " + std::to_string(k) + " is not the next run of triangles after the world's");
    next = m.first + m.count;
  }
  if (next != scene.triangles.size()) fail("triangles after the last mesh");
  for (std::size_t i = 0; i < in.instances.size(); ++i) {
    const MeshInstance& inst = in.instances[i];
    if (inst.mesh >= in.meshes.size()) fail("instance " + std::to_string(i) + " names no mesh");
    const glm::mat4& m = inst.object_to_world;
    const bool affine = m[0][3] == 0.0f && m[1][3] == 0.0f && m[2][3] == 0.0f && m[3][3] == 1.0f;
    const float det = glm::determinant(glm::mat3(m));
    if (!affine || !(det > 0.0f) || !std::isfinite(det))
      fail("instance " + std::to_string(i) + "'s matrix is not affine with a positive determinant");
  }
}

namespace {
void add_to_bounds(DrawnBounds& b, const glm::vec3* ps) {
  b.any = true;
  for (int c = 0; c < 3; ++c) {
    const glm::vec3& p = ps[c];
    b.in_range &= std::abs(p.x) <= kMaxSceneCoordinate && std::abs(p.y) <= kMaxSceneCoordinate &&
                  std::abs(p.z) <= kMaxSceneCoordinate;
    b.lo = glm::min(b.lo, p);
    b.hi = glm::max(b.hi, p);
  }
}
}  // namespace

DrawnBounds drawn_bounds(const Scene& scene) {
  const SceneInstancing& in = scene.instancing;
  const std::size_t world = in.empty() ? scene.triangles.size() : in.world_triangles;
  const unsigned parts = parallel_parts(world, std::size_t{1} << 20);
  std::vector<DrawnBounds> part_bounds(parts);
  run_parts(parts, [&](unsigned part) {
    // Each part's bounds on its own thread's stack until the end: side by side in the vector
    // they would share a cache line between the cores.
    DrawnBounds b;
    const PartRange r = part_range(world, part, parts);
    for (std::size_t i = r.begin; i < r.end; ++i) add_to_bounds(b, scene.triangles[i].p);
    part_bounds[part] = b;
  });
  DrawnBounds out;
  for (const DrawnBounds& b : part_bounds) {
    out.in_range &= b.in_range;
    out.any |= b.any;
    out.lo = glm::min(out.lo, b.lo);
    out.hi = glm::max(out.hi, b.hi);
  }
  for (const MeshInstance& inst : in.instances) {  // as for_each_drawn_triangle places them
    const InstancedMesh& m = in.meshes[inst.mesh];
    for (std::size_t i = m.first; i < m.first + m.count; ++i) {
      glm::vec3 p[3];
      for (int c = 0; c < 3; ++c) p[c] = glm::vec3(inst.object_to_world * glm::vec4(scene.triangles[i].p[c], 1.0f));
      add_to_bounds(out, p);
    }
  }
  return out;
}

}  // namespace px
