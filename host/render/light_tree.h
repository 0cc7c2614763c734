// The light tree: a bounding volume hierarchy over the emissive triangles that next-event
// estimation walks to pick a light in proportion to its estimated contribution at the shading
// point (Conty Estevez and Kulla 2018, "Importance Sampling of Many Lights with Adaptive Tree
// Splitting"; the importance and the split cost follow pbrt-v4's LightBounds and
// BVHLightSampler, the importance's cosine at the shading point one-sided). The kernels' half is
// kernels/shading/light_tree.h; the buffer layout (LightTreeNode, the trails) is documented in kernels/shared/types.h.
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <cstdint>
#include <vector>

namespace px {

// What the tree knows of one light: its box, power and cone of emission (a LightTreeNode's
// fields, in float as the kernels read them).
struct LightBounds {
  float lo[3] = {0.0f, 0.0f, 0.0f};
  float hi[3] = {0.0f, 0.0f, 0.0f};
  float phi = 0.0f;
  float axis[3] = {0.0f, 0.0f, 1.0f};
  float cos_theta_o = 1.0f;
  float cos_theta_e = 0.0f;  // cos(pi/2): a Lambertian emitter
};

// An emissive triangle's bounds: its box, its geometric normal (front face: the winding order's),
// theta_o = 0 (pi if `two_sided`), theta_e = pi/2.
LightBounds triangle_light_bounds(const LightTriangle& light, bool two_sided);

// A point or spot light's bounds (types.h, LightTriangle: prim >= PX_LIGHT_PUNCTUAL): its point,
// phi the luminance of its intensity, the whole sphere (a spot: its axis and outer cone),
// theta_e pi/2.
LightBounds punctual_light_bounds(const LightTriangle& light);
// Either, by the entry's prim (`two_sided` matters to triangles only).
LightBounds light_bounds(const LightTriangle& light, bool two_sided);

// The union of two bounds: the box around both, the summed power, the smallest cone (of the
// kind pbrt-v4's DirectionCone::Union makes) holding both cones, the wider theta_e.
LightBounds union_of(const LightBounds& a, const LightBounds& b);

class LightTree {
 public:
  // The tree over `lights` (the light table, in its order: the leaves reference table indices),
  // two_sided[i] whether light i emits from both faces. Binned split on the three axes by pbrt-v4's
  // surface area x orientation x power cost; deeper than the trail's bits allow, a median split by
  // count, so that no leaf is deeper than 32.
  static LightTree build(const std::vector<LightTriangle>& lights, const std::vector<std::uint8_t>& two_sided);

  // The same topology, bounds, cones and power recomputed bottom-up from `lights` (the same lights
  // in the same order, moved or changed): false, and nothing changed, if the count differs.
  bool refit(const std::vector<LightTriangle>& lights, const std::vector<std::uint8_t>& two_sided);

  const std::vector<LightTreeNode>& nodes() const { return nodes_; }
  // Per light: bit i set = the path from the root takes child[1] at depth i.
  const std::vector<std::uint32_t>& trails() const { return trails_; }
  // Per light: how many choices lead from the root to its leaf.
  const std::vector<std::uint8_t>& depths() const { return depths_; }
  std::size_t light_count() const { return trails_.size(); }
  unsigned depth() const;

 private:
  std::vector<LightTreeNode> nodes_;  // root first, each node before its children
  std::vector<std::uint32_t> trails_;
  std::vector<std::uint8_t> depths_;
};

// Whether each light of `lights` (a table make_light_table made from `scene`) emits from both faces.
std::vector<std::uint8_t> light_two_sidedness(const Scene& scene, const std::vector<LightTriangle>& lights);

// The tree as the kernels walk it: two levels of the binary tree to a node (types.h,
// LightTreeWideNode), root first. Empty for fewer than two lights.
std::vector<LightTreeWideNode> wide_light_nodes(const LightTree& tree);

// The scene's `lights` buffer: the table, then the tree's trails padded to 64 bytes, then its
// wide nodes (types.h, LightTreeWideNode), as 64-byte records. Empty for an empty table.
std::vector<LightTriangle> light_buffer(const std::vector<LightTriangle>& lights, const LightTree& tree);

// make_light_table, its tree built, packed by light_buffer; `tree`, if not null, receives the tree.
std::vector<LightTriangle> make_light_buffer(const Scene& scene, std::size_t& light_count, LightTree* tree = nullptr);

}  // namespace px
