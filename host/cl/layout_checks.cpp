// Compile-time proof that the host sees kernels/shared/types.h with the byte layout that the
// header documents (and that OpenCL C gives it: 4-byte scalars only, no implicit padding).
#include "restir/restir_params.h"
#include "shared/types.h"

#include <cstddef>

namespace px {

static_assert(sizeof(BvhNode) == 64);
static_assert(offsetof(BvhNode, left) == 12 && offsetof(BvhNode, lmax) == 16);
static_assert(offsetof(BvhNode, left_count) == 28 && offsetof(BvhNode, rmin) == 32);
static_assert(offsetof(BvhNode, right) == 44 && offsetof(BvhNode, rmax) == 48);
static_assert(offsetof(BvhNode, right_count) == 60);

static_assert(sizeof(Bvh8Node) == 256);
static_assert(offsetof(Bvh8Node, hi_x) == 32 && offsetof(Bvh8Node, lo_y) == 64);
static_assert(offsetof(Bvh8Node, hi_y) == 96 && offsetof(Bvh8Node, lo_z) == 128);
static_assert(offsetof(Bvh8Node, hi_z) == 160 && offsetof(Bvh8Node, child) == 192);
static_assert(offsetof(Bvh8Node, count) == 224);
static_assert(sizeof(Bvh4Node) == 128);
static_assert(offsetof(Bvh4Node, hi_x) == 16 && offsetof(Bvh4Node, lo_y) == 32);
static_assert(offsetof(Bvh4Node, hi_y) == 48 && offsetof(Bvh4Node, lo_z) == 64);
static_assert(offsetof(Bvh4Node, hi_z) == 80 && offsetof(Bvh4Node, child) == 96);
static_assert(offsetof(Bvh4Node, count) == 112);

static_assert(sizeof(CompressedBvh8Node) == 80 && offsetof(CompressedBvh8Node, e) == 12);
static_assert(offsetof(CompressedBvh8Node, imask) == 15 && offsetof(CompressedBvh8Node, child_base) == 16);
static_assert(offsetof(CompressedBvh8Node, leaf_base) == 20 && offsetof(CompressedBvh8Node, meta) == 24);
static_assert(offsetof(CompressedBvh8Node, qlo_x) == 32 && offsetof(CompressedBvh8Node, qlo_y) == 40);
static_assert(offsetof(CompressedBvh8Node, qlo_z) == 48 && offsetof(CompressedBvh8Node, qhi_x) == 56);
static_assert(offsetof(CompressedBvh8Node, qhi_y) == 64 && offsetof(CompressedBvh8Node, qhi_z) == 72);
static_assert(sizeof(BvhLeafBlock) == PX_LEAF_BLOCK_UNITS * 16);

static_assert(sizeof(BvhLeafBlock) == 160 && offsetof(BvhLeafBlock, first) == 144);
static_assert(offsetof(BvhLeafBlock, count) == 148 && offsetof(BvhLeafBlock, flags) == 152);

static_assert(sizeof(BvhTriangle) == 48);
static_assert(offsetof(BvhTriangle, prim) == 12 && offsetof(BvhTriangle, v1) == 16);
static_assert(offsetof(BvhTriangle, flags) == 28 && offsetof(BvhTriangle, v2) == 32);
static_assert(offsetof(BvhTriangle, material) == 44);
static_assert(sizeof(BvhLeafRef) == 16 && offsetof(BvhLeafRef, flags) == 4);
static_assert(offsetof(BvhLeafRef, material) == 8 && offsetof(BvhLeafRef, block) == 12);

static_assert(sizeof(Ray) == 32 && offsetof(Ray, tmin) == 12 && offsetof(Ray, tmax) == 28);
static_assert(sizeof(Hit) == 20 && offsetof(Hit, prim) == 12 && offsetof(Hit, inst) == 16);

static_assert(sizeof(SceneInstances) == 32 && offsetof(SceneInstances, world_triangles) == 12);
static_assert(offsetof(SceneInstances, order) == 16);
static_assert(sizeof(SceneInstance) == 160 && offsetof(SceneInstance, object_to_world) == 48);
static_assert(offsetof(SceneInstance, previous_object_to_world) == 96 && offsetof(SceneInstance, node_offset) == 144);
static_assert(offsetof(SceneInstance, triangle_offset) == 148);

static_assert(sizeof(TriangleShading) == 64);
static_assert(offsetof(TriangleShading, uv0) == 12 && offsetof(TriangleShading, n1) == 20);
static_assert(offsetof(TriangleShading, uv1) == 32 && offsetof(TriangleShading, n2) == 40);
static_assert(offsetof(TriangleShading, uv2) == 52 && offsetof(TriangleShading, material) == 60);
static_assert(sizeof(FlatTriangleShading) == 16 && offsetof(FlatTriangleShading, material) == 12);
static_assert(sizeof(IndexedTriangleShading) == 16 && offsetof(IndexedTriangleShading, material) == 12);
static_assert(sizeof(ShadingVertex) == 20 && offsetof(ShadingVertex, uv) == 12);

static_assert(sizeof(GpuMaterial) == 80);
static_assert(offsetof(GpuMaterial, diffuse_texture) == 12 && offsetof(GpuMaterial, roughness) == 28);
static_assert(offsetof(GpuMaterial, alpha_texture) == 44 && offsetof(GpuMaterial, flags) == 48);
static_assert(offsetof(GpuMaterial, specular_texture) == 52 && offsetof(GpuMaterial, normal_texture) == 56);
static_assert(offsetof(GpuMaterial, ior) == 60 && offsetof(GpuMaterial, transmission) == 64);
static_assert(offsetof(GpuMaterial, normal_scale) == 76);

static_assert(sizeof(CameraParams) == 80);
static_assert(offsetof(CameraParams, jitter) == 64);
static_assert(offsetof(CameraParams, tan_half_fov_y) == 12 && offsetof(CameraParams, aspect) == 28);
static_assert(offsetof(CameraParams, width) == 44 && offsetof(CameraParams, height) == 60);

static_assert(sizeof(TextureInfo) == 16);
static_assert(sizeof(LightTriangle) == 64);
static_assert(offsetof(LightTriangle, area) == 28 && offsetof(LightTriangle, cdf) == 44);
static_assert(offsetof(LightTriangle, emission) == 48 && offsetof(LightTriangle, pdf_select) == 60);
static_assert(sizeof(LightTreeNode) == 64 && sizeof(LightTreeNode) == sizeof(LightTriangle));
static_assert(offsetof(LightTreeNode, bounds_max) == 12 && offsetof(LightTreeNode, phi) == 24);
static_assert(offsetof(LightTreeNode, axis) == 28 && offsetof(LightTreeNode, cos_theta_o) == 40);
static_assert(offsetof(LightTreeNode, cos_theta_e) == 44 && offsetof(LightTreeNode, child) == 48);
static_assert(offsetof(LightTreeNode, sin_theta_o) == 56 && offsetof(LightTreeNode, radius) == 60);
static_assert(sizeof(LightTreeWideNode) == 4 * sizeof(LightTriangle) && offsetof(LightTreeWideNode, bounds_max) == 48);
static_assert(offsetof(LightTreeWideNode, axis) == 96 && offsetof(LightTreeWideNode, phi) == 144);
static_assert(offsetof(LightTreeWideNode, cos_theta_o) == 160 && offsetof(LightTreeWideNode, sin_theta_o) == 176);
static_assert(offsetof(LightTreeWideNode, cos_theta_e) == 192 && offsetof(LightTreeWideNode, radius) == 208);
static_assert(offsetof(LightTreeWideNode, child) == 224 && offsetof(LightTreeWideNode, by_power) == 240);
static_assert(sizeof(FrameParams) == 128);
static_assert(offsetof(FrameParams, p_sun) == 28 && offsetof(FrameParams, light_count) == 76);
static_assert(offsetof(FrameParams, frame) == 80 && offsetof(FrameParams, rr_start_bounce) == 104);
static_assert(offsetof(FrameParams, row0) == 108 && offsetof(FrameParams, rows) == 112);
static_assert(offsetof(FrameParams, sample_offset) == 116 && offsetof(FrameParams, gbuffer_ray_samples) == 120);
static_assert(offsetof(FrameParams, direct_light) == 124);
static_assert(sizeof(RestirParams) == 64);
static_assert(offsetof(RestirParams, candidates) == 24 && offsetof(RestirParams, max_history) == 40);
static_assert(offsetof(RestirParams, tag) == 44 && offsetof(RestirParams, temporal_rows) == 52);
static_assert(offsetof(GBufferTexel, depth) == 12 && offsetof(GBufferTexel, material_class) == 28);
static_assert(offsetof(GBufferTexel, prim) == 32 && offsetof(GBufferTexel, inst) == 36 && sizeof(GBufferTexel) == 40);
static_assert(sizeof(SvgfParams) == 64);
static_assert(offsetof(SvgfParams, jitter) == 56);
static_assert(offsetof(SvgfParams, temporal_rows) == 24 && offsetof(SvgfParams, lo_row) == 40);
static_assert(offsetof(SvgfParams, width) == 48 && offsetof(SvgfParams, height) == 52);

}  // namespace px
