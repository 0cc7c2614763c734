// The trees a scene needs: one over its world triangles and, for a scene with instances
// (Scene::instancing), one per instanced mesh over the mesh's own triangles in its own space.
// Each tree's BvhTriangle::prim counts from its own first triangle (a mesh tree's 0 is the
// mesh's first triangle); DeviceScene places them in the scene's buffers.
#pragma once

#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"
#include "scene/scene.h"

#include <vector>

namespace px {

// Triangles [first, first + count) of the scene, copied.
std::vector<SceneTriangle> triangle_range(const Scene& scene, std::size_t first, std::size_t count);

// The world tree: over every triangle of a scene without instances (build_bvh), over the world
// part of one with instances; empty (no nodes) when that part is empty.
FlatBvh build_world_bvh(const Scene& scene, const BvhBuildOptions& options = {});

// One tree per instanced mesh (none without instances), each validated, with the nodes of
// `layout` collapsed. Throws std::runtime_error if a tree fails validation.
std::vector<FlatBvh> build_mesh_bvhs(const Scene& scene, BvhLayout layout, const BvhBuildOptions& options = {});

}  // namespace px
