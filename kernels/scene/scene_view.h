/* The scene as kernels see it: every replicated buffer, gathered in one private struct so
 * helper functions take one argument instead of eight. */
#ifndef PARALLAX_SCENE_VIEW_H
#define PARALLAX_SCENE_VIEW_H

#include "shared/types.h"

typedef struct SceneView {
  const global BvhNode* nodes;
  const global PxLeafTriangle* tris; /* leaf order: BvhTriangle, or BvhLeafRef (PX_LEAF_REFS) */
  /* TriangleShading, FlatTriangleShading (PX_FLAT_SHADING) or IndexedTriangleShading with its
   * vertex table after the records (PX_INDEXED_SHADING) */
  const global PxTriangleShading* shading;
  const global GpuMaterial* materials;
  const global TextureInfo* textures;
  const global float4* texels;
  const global LightTriangle* lights;
  /* Per scene triangle three float4: its vertices' linear RGB colours (glTF COLOR_0) with w 1,
   * read only in kernels built with PX_FEATURE_VERTEX_COLOURS; without colours one placeholder
   * (1, 1, 1, 0). */
  const global float4* colours;
  /* The instance buffer (types.h: SceneInstances, its top level and SceneInstance records),
   * read only in kernels built with PX_FEATURE_INSTANCES. */
  const global SceneInstances* instances;
} SceneView;

/* Kernel parameter list for the nine scene buffers, always in this order and always last; the host
 * binds them with DeviceSceneBuffers::bind (host/render/device_scene.h). */
#define PX_SCENE_PARAMS                                                                         \
  const global BvhNode *scene_nodes, const global PxLeafTriangle *scene_tris,                   \
      const global PxTriangleShading *scene_shading, const global GpuMaterial *scene_materials, \
      const global TextureInfo *scene_textures, const global float4 *scene_texels,              \
      const global LightTriangle *scene_lights, const global float4 *scene_colours,             \
      const global SceneInstances *scene_instances

inline SceneView px_scene_view(const global BvhNode* nodes, const global PxLeafTriangle* tris,
                               const global PxTriangleShading* shading, const global GpuMaterial* materials,
                               const global TextureInfo* textures, const global float4* texels,
                               const global LightTriangle* lights, const global float4* colours,
                               const global SceneInstances* instances) {
  SceneView s;
  s.nodes = nodes;
  s.tris = tris;
  s.shading = shading;
  s.materials = materials;
  s.textures = textures;
  s.texels = texels;
  s.lights = lights;
  s.colours = colours;
  s.instances = instances;
  return s;
}

#define PX_SCENE_VIEW()                                                                                              \
  px_scene_view(scene_nodes, scene_tris, scene_shading, scene_materials, scene_textures, scene_texels, scene_lights, \
                scene_colours, scene_instances)

inline float3 px_load3(const global float* p) { return (float3)(p[0], p[1], p[2]); }
inline float3 px_load3_private(const float* p) { return (float3)(p[0], p[1], p[2]); }

/* Vertex k's shading normal and texture coordinates in a scene triangle's shading record. A
 * flat record (PX_FLAT_SHADING) has one normal for the three and no texture coordinates; an
 * indexed one (PX_INDEXED_SHADING) points to its vertices' entries. */
#if defined(PX_FLAT_SHADING) && PX_FLAT_SHADING
inline float3 px_shading_normal(const global PxTriangleShading* sh, int k) { return px_load3(sh->n); }
inline float2 px_shading_uv(const global PxTriangleShading* sh, int k) { return (float2)(0.0f, 0.0f); }
#elif defined(PX_INDEXED_SHADING) && PX_INDEXED_SHADING
/* An indexed record (types.h: IndexedTriangleShading): vertex k's ShadingVertex lies sh->v[k]
 * floats past the record. */
inline float3 px_shading_normal(const global PxTriangleShading* sh, int k) {
  return px_load3((const global float*)sh + sh->v[k]);
}
inline float2 px_shading_uv(const global PxTriangleShading* sh, int k) {
  const global float* e = (const global float*)sh + sh->v[k];
  return (float2)(e[3], e[4]);
}
#else
inline float3 px_shading_normal(const global PxTriangleShading* sh, int k) {
  return px_load3(k == 0 ? sh->n0 : k == 1 ? sh->n1 : sh->n2);
}
inline float2 px_shading_uv(const global PxTriangleShading* sh, int k) {
  const global float* uv = k == 0 ? sh->uv0 : k == 1 ? sh->uv1 : sh->uv2;
  return (float2)(uv[0], uv[1]);
}
#endif

/* Instance `k`'s record (types.h: the instance buffer's layout). */
inline const global SceneInstance* px_instance(const SceneView* scene, uint k) {
  const global uchar* base = (const global uchar*)scene->instances;
  return (const global SceneInstance*)(base + 16 * (size_t)scene->instances->records) + k;
}

/* A 3x4 row-major affine matrix applied to a point, and to a direction. */
inline float3 px_xform_point(const global float* m, float3 p) {
  return (float3)(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                  m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]);
}
inline float3 px_xform_dir(const global float* m, float3 d) {
  return (float3)(m[0] * d.x + m[1] * d.y + m[2] * d.z, m[4] * d.x + m[5] * d.y + m[6] * d.z,
                  m[8] * d.x + m[9] * d.y + m[10] * d.z);
}
/* A normal by the transpose of m's 3x3 (m = world_to_object: the inverse transpose of
 * object_to_world, as normals need), normalised; `fallback` where that degenerates. */
inline float3 px_xform_normal(const global float* m, float3 n, float3 fallback) {
  const float3 w = (float3)(m[0] * n.x + m[4] * n.y + m[8] * n.z, m[1] * n.x + m[5] * n.y + m[9] * n.z,
                            m[2] * n.x + m[6] * n.y + m[10] * n.z);
  const float len = length(w);
  return len > 0.0f && isfinite(len) ? w / len : fallback;
}

/* What a closest hit (hit.prim != PX_NO_HIT) found, before anything is faced towards the ray:
 * the scene triangle `prim` with its shading record and material, its vertices, the hit point,
 * the winding order's unit normal `ng`, and the interpolated vertex normal `ns` (ng where that
 * degenerates). The path tracer's vertex and the G-buffer texel both start from it. */
typedef struct SurfaceHit {
  uint prim;
  const global PxTriangleShading* sh;
  const global GpuMaterial* mat;
  float3 v0, v1, v2;
  float3 p, ng, ns;
} SurfaceHit;

inline SurfaceHit px_surface_hit(const SceneView* scene, Hit hit) {
  SurfaceHit s;
  const global PxLeafTriangle* tri = scene->tris + hit.prim;
  s.prim = tri->prim;
  s.sh = scene->shading + s.prim;
  s.mat = scene->materials + s.sh->material;
#if defined(PX_LEAF_REFS) && PX_LEAF_REFS
  /* The vertices are in the leaf's block (types.h: BvhLeafBlock rows, lane = this triangle). */
  const global float* b = (const global float*)scene->nodes + 4 * (size_t)tri->block;
  const uint lane = hit.prim - ((const global uint*)(b + 36))[0];
  s.v0 = (float3)(b[lane], b[4 + lane], b[8 + lane]);
  s.v1 = (float3)(b[12 + lane], b[16 + lane], b[20 + lane]);
  s.v2 = (float3)(b[24 + lane], b[28 + lane], b[32 + lane]);
#else
  s.v0 = px_load3(tri->v0);
  s.v1 = px_load3(tri->v1);
  s.v2 = px_load3(tri->v2);
#endif
  float3 n0 = px_shading_normal(s.sh, 0), n1 = px_shading_normal(s.sh, 1), n2 = px_shading_normal(s.sh, 2);
  if (PX_HAS(PX_FEATURE_INSTANCES) && hit.inst != PX_NO_INSTANCE) {
    /* A mesh's vertices and normals are in its own space: placed as a flat copy of the mesh
     * would place them (instancing.cpp, place_triangle), vertex by vertex. */
    const global SceneInstance* in = px_instance(scene, hit.inst);
    s.v0 = px_xform_point(in->object_to_world, s.v0);
    s.v1 = px_xform_point(in->object_to_world, s.v1);
    s.v2 = px_xform_point(in->object_to_world, s.v2);
    n0 = px_xform_normal(in->world_to_object, n0, n0);
    n1 = px_xform_normal(in->world_to_object, n1, n1);
    n2 = px_xform_normal(in->world_to_object, n2, n2);
  }
  const float w = 1.0f - hit.u - hit.v;
  s.p = w * s.v0 + hit.u * s.v1 + hit.v * s.v2;
  s.ng = normalize(cross(s.v1 - s.v0, s.v2 - s.v0));
  const float3 n = w * n0 + hit.u * n1 + hit.v * n2;
  const float len = length(n);
  s.ns = len > 0.0f && isfinite(len) ? n / len : s.ng;
  return s;
}

/* Bilinear lookup with wrap-around addressing; v = 0 is the image's bottom row (OBJ
 * convention), stored rows run top to bottom. */
inline float4 px_texture_bilinear(const SceneView* s, int index, float2 uv) {
  const TextureInfo ti = s->textures[index];
  const float fx = (uv.x - floor(uv.x)) * (float)ti.width - 0.5f;
  const float fy = (1.0f - (uv.y - floor(uv.y))) * (float)ti.height - 0.5f;
  const float x0f = floor(fx), y0f = floor(fy);
  const float ax = fx - x0f, ay = fy - y0f;
  const int w = (int)ti.width, h = (int)ti.height;
  /* The fractions above keep fx in [-0.5, w - 0.5] and fy in [-0.5, h - 0.5] for any finite uv,
   * so x0f and y0f are -1 at the least and w - 1, h - 1 at the most: wrapping -1 is all a
   * remainder would do, without its two integer divisions (the alpha cut-outs run this for
   * every geometric hit on foliage). The clamp only keeps a non-finite uv's index in bounds. */
  int x0 = (int)x0f, y0 = (int)y0f;
  x0 = clamp(x0 < 0 ? x0 + w : x0, 0, w - 1);
  y0 = clamp(y0 < 0 ? y0 + h : y0, 0, h - 1);
  const int x1 = x0 + 1 == w ? 0 : x0 + 1, y1 = y0 + 1 == h ? 0 : y0 + 1;
  const global float4* t = s->texels + ti.offset;
  const float4 top = mix(t[y0 * w + x0], t[y0 * w + x1], ax);
  const float4 bottom = mix(t[y1 * w + x0], t[y1 * w + x1], ax);
  return mix(top, bottom, ay);
}

inline float2 px_interpolate_uv(const global PxTriangleShading* sh, float u, float v) {
  const float w = 1.0f - u - v;
  return w * px_shading_uv(sh, 0) + u * px_shading_uv(sh, 1) + v * px_shading_uv(sh, 2);
}

/* Alpha cut-outs (OBJ map_d): a hit on a texel with alpha < 0.5 does not count. */
inline int px_alpha_visible(const SceneView* s, uint prim, float u, float v) {
  const global PxTriangleShading* sh = s->shading + prim;
  const int tex = s->materials[sh->material].alpha_texture;
  if (tex < 0) return 1;
  return px_texture_bilinear(s, tex, px_interpolate_uv(sh, u, v)).w >= 0.5f;
}

/* The vertex colour at barycentrics (u, v) of scene triangle `prim`: white without
 * PX_FEATURE_VERTEX_COLOURS, or when the scene has none (kernels built with every feature: the
 * one-element placeholder's w is 0, a real entry's 1). */
inline float3 px_vertex_colour(const SceneView* scene, uint prim, float u, float v) {
  if (!PX_HAS(PX_FEATURE_VERTEX_COLOURS) || !(scene->colours[0].w > 0.0f)) return (float3)(1.0f, 1.0f, 1.0f);
  const global float4* c = scene->colours + 3 * (size_t)prim;
  return (1.0f - u - v) * c[0].xyz + u * c[1].xyz + v * c[2].xyz;
}

#endif
