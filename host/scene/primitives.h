// Closed and open meshes appended to a triangle list: the building blocks of the built-in
// scenes and of tests that need geometry with known properties.
//
// Conventions shared by every function here:
//   - front faces are counter-clockwise seen from the outside, so the geometric normal
//     normalize(cross(p1 - p0, p2 - p0)) points outwards on closed meshes;
//   - a vertex shared by neighbouring triangles is computed once and copied, so shared
//     positions are bit-identical (watertight meshes stay watertight through the BVH and
//     the watertight intersection test);
//   - shading normals are unit length; flat pieces get their face normal, curved ones
//     (spheres, lathes) the normal of the surface they approximate.
#pragma once

#include "scene/scene.h"

#include <glm/glm.hpp>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace px {

// Unit normal of the triangle's plane, oriented by its winding; (0, 0, 0) for a degenerate
// (zero-area or non-finite) triangle. Computed in double so that tiny and huge triangles both
// give a finite answer.
glm::vec3 geometric_normal(const SceneTriangle& tri);

// Area in double precision (0 for degenerate, NaN/Inf propagate).
double triangle_area(const SceneTriangle& tri);

// True when every coordinate of the three positions is finite.
bool has_finite_positions(const SceneTriangle& tri);

// True when the triangle has zero area (collinear or coincident vertices). Non-finite
// triangles are not "degenerate" by this test; check has_finite_positions first.
bool is_degenerate(const SceneTriangle& tri);
// is_degenerate and geometric_normal from one cross product: true and *normal =
// geometric_normal(tri) for a triangle that is not degenerate; false (normal untouched) else.
bool normal_unless_degenerate(const SceneTriangle& tri, glm::vec3* normal);

// One flat triangle; uvs (0,0), (1,0), (0,1).
void append_triangle(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2,
                     std::uint32_t material);

// Texture coordinates of a quad's corners, in the order of its points.
using QuadUv = std::array<glm::vec2, 4>;
inline constexpr QuadUv kUnitQuadUv = {glm::vec2(0, 0), glm::vec2(1, 0), glm::vec2(1, 1), glm::vec2(0, 1)};

// Planar quad p0 p1 p2 p3 (counter-clockwise seen from its front), split along p0-p2.
void append_quad(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3,
                 std::uint32_t material, const QuadUv& uv = kUnitQuadUv);

// The same quad with its winding chosen so that its normal points along `facing` (the quad's
// corners may be given in either order). For geometry written from published data or built
// in a local frame where working out the winding by hand is error-prone.
void append_quad_facing(std::vector<SceneTriangle>& tris, glm::vec3 p0, glm::vec3 p1, glm::vec3 p2, glm::vec3 p3,
                        glm::vec3 facing, std::uint32_t material, const QuadUv& uv = kUnitQuadUv);

// Axis-aligned box, 12 triangles, normals outward.
void append_box(std::vector<SceneTriangle>& tris, glm::vec3 min, glm::vec3 max, std::uint32_t material);

// The box [min, max] of local space mapped by an affine `transform` (rotation, scale,
// translation; a mirroring transform is handled, normals stay outward).
void append_oriented_box(std::vector<SceneTriangle>& tris, glm::vec3 min, glm::vec3 max, const glm::mat4& transform,
                         std::uint32_t material);

// n overlapping slivers through the unit cube: each joins two random points on the cube's
// surface (at least 0.25 apart) and is 1e-3 wide at one end, so every box covers a large part
// of the cube and no partition of whole triangles separates them: the worst case of a
// spatial-split BVH build (tests and bench_bvh_build). Deterministic for a given seed.
void append_slivers(std::vector<SceneTriangle>& tris, std::size_t n, unsigned seed, std::uint32_t material = 0);

// Sphere from a subdivided icosahedron: 20 * 4^subdivisions triangles, closed, vertices on
// the sphere, smooth normals.
void append_icosphere(std::vector<SceneTriangle>& tris, glm::vec3 center, float radius, int subdivisions,
                      std::uint32_t material);

// Which ends of a lathe are closed with a flat disc.
struct LatheCaps {
  bool bottom = false;
  bool top = false;
};

// Surface of revolution around the vertical axis through `base`: `profile` lists
// (radius, height above base) from bottom to top; `segments` facets around. Profile points with
// radius 0 close the surface on the axis without degenerate triangles. Normals are smooth
// around the axis and flat along each profile segment (so a profile corner stays sharp).
void append_lathe(std::vector<SceneTriangle>& tris, glm::vec3 base, std::span<const glm::vec2> profile, int segments,
                  std::uint32_t material, LatheCaps caps = {});

// Vertical faceted cylinder standing on `base_center`; with caps it is closed.
void append_cylinder(std::vector<SceneTriangle>& tris, glm::vec3 base_center, float radius, float height, int segments,
                     std::uint32_t material, bool caps = true);

}  // namespace px
