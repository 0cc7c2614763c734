// The scene's tables as the kernels read them, made on the host: per-triangle shading, materials,
// the light table and its sampling parameters, triangle flags (scene_tables.cpp).
#pragma once

#include "scene/scene.h"
#include "shared/types.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace px {

// One triangle's shading record (normals, uvs, material), and its flat form (one normal; for a
// scene whose triangles all have_flat_shading).
TriangleShading shading_of(const SceneTriangle& t);
FlatTriangleShading flat_shading_of(const SceneTriangle& t);

// Host-side conversions to the kernel layouts (also used by tests).
std::vector<TriangleShading> make_triangle_shading(const Scene& scene);
// Whether every triangle's three vertex normals are the same bits and its texture coordinates
// all +0 (a mesh loaded without NORMAL and TEXCOORD_0): its shading records can be
// FlatTriangleShading (types.h) and say the same.
bool has_flat_shading(const std::vector<SceneTriangle>& triangles);
std::vector<GpuMaterial> make_gpu_materials(const Scene& scene);
std::vector<LightTriangle> make_light_table(const Scene& scene);
// PX_TRI_* flags of every scene triangle, from its material (alpha-tested, emissive).
std::vector<std::uint32_t> triangle_flags(const Scene& scene);
// The same flags per material (a triangle's are its material's), and all that the scene's
// triangles carry, or-ed: what a static scene keeps instead of a word per triangle.
std::vector<std::uint32_t> material_triangle_flags(const Scene& scene);
std::uint32_t used_triangle_flags(const Scene& scene, const std::vector<std::uint32_t>& flags_per_material);

// How next-event estimation picks a light type, and the sun/sky constants, as FrameParams
// fields (the per-launch fields are left for the caller).
void fill_light_params(const Scene& scene, std::size_t light_count, FrameParams& params);

}  // namespace px
