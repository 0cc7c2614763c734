// The top level of the two-level BVH: binary nodes over the world boxes of a scene's instances,
// and the instance buffer the kernels read (types.h: SceneInstances, BvhNode[], SceneInstance[]).
// Rebuilt from scratch whenever instances move: a median split over a few thousand boxes takes
// well under a millisecond per thousand instances.
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <cstdint>
#include <vector>

namespace px {

struct InstanceBox {
  glm::vec3 lo{0.0f}, hi{0.0f};
};

struct TopLevelBvh {
  std::vector<BvhNode> nodes;        // nodes[0] the root; empty for no instances
  std::vector<std::uint32_t> order;  // leaf order: order[i] is the input index of instance i
  int depth = 0;                     // levels of nodes (a single root: 1)
};

// Median splits on the longest axis of the boxes' centres, at most PX_TLAS_MAX_LEAF instances a
// leaf. A leaf child's `left` / `right` is the first of its `count` instances in `order`.
TopLevelBvh build_top_level(const std::vector<InstanceBox>& boxes);

// The world box of mesh-space box [lo, hi] placed by `m` (its eight corners transformed).
InstanceBox place_box(const glm::vec3& lo, const glm::vec3& hi, const glm::mat4& m);

// Where each instanced mesh lies in the node and triangle buffers (DeviceScene decides).
struct MeshPlacement {
  std::uint32_t node_offset = 0;      // in 4-byte words
  std::uint32_t triangle_offset = 0;  // in BvhTriangle entries
};

// The instance buffer of `scene` as 4-byte words (types.h: SceneInstances): the header, the top
// level over its instances, the leaf order and their records in the scene's instance order. A
// scene without instances gets the header alone (count 0, world_triangles = every triangle).
// `world_triangles`: how many triangles the world tree holds (0 = none: the kernels skip it).
// `previous`: each instance's matrix in the last frame (the motion pass), or null (not moving).
std::vector<std::uint32_t> instance_buffer_words(const Scene& scene, const std::vector<MeshPlacement>& meshes,
                                                 std::size_t world_triangles, TopLevelBvh* top = nullptr,
                                                 const std::vector<glm::mat4>* previous = nullptr);

}  // namespace px
