/* The scene as kernels see it: every replicated buffer, gathered in one private struct so
 * helper functions take one argument instead of seven. */
#ifndef PARALLAX_SCENE_VIEW_H
#define PARALLAX_SCENE_VIEW_H

#include "shared/types.h"

typedef struct SceneView {
  const global BvhNode* nodes;
  const global BvhTriangle* tris;
  const global TriangleShading* shading;
  const global GpuMaterial* materials;
  const global TextureInfo* textures;
  const global float4* texels;
  const global LightTriangle* lights;
} SceneView;

/* Kernel parameter list for the scene buffers, always in this order and always last; the host
 * binds them with DeviceSceneBuffers::bind (host/render/device_scene.h). */
#define PX_SCENE_PARAMS                                                                       \
  const global BvhNode *scene_nodes, const global BvhTriangle *scene_tris,                    \
      const global TriangleShading *scene_shading, const global GpuMaterial *scene_materials, \
      const global TextureInfo *scene_textures, const global float4 *scene_texels,            \
      const global LightTriangle *scene_lights

inline SceneView px_scene_view(const global BvhNode* nodes, const global BvhTriangle* tris,
                               const global TriangleShading* shading,
                               const global GpuMaterial* materials,
                               const global TextureInfo* textures, const global float4* texels,
                               const global LightTriangle* lights) {
  SceneView s;
  s.nodes = nodes;
  s.tris = tris;
  s.shading = shading;
  s.materials = materials;
  s.textures = textures;
  s.texels = texels;
  s.lights = lights;
  return s;
}

#define PX_SCENE_VIEW()                                                                     \
  px_scene_view(scene_nodes, scene_tris, scene_shading, scene_materials, scene_textures, \
                scene_texels, scene_lights)

inline float3 px_load3(const global float* p) { return (float3)(p[0], p[1], p[2]); }
inline float3 px_load3_private(const float* p) { return (float3)(p[0], p[1], p[2]); }

/* Bilinear lookup with wrap-around addressing; v = 0 is the image's bottom row (OBJ
 * convention), stored rows run top to bottom. */
inline float4 px_texture_bilinear(const SceneView* s, int index, float2 uv) {
  const TextureInfo ti = s->textures[index];
  const float fx = (uv.x - floor(uv.x)) * (float)ti.width - 0.5f;
  const float fy = (1.0f - (uv.y - floor(uv.y))) * (float)ti.height - 0.5f;
  const float x0f = floor(fx), y0f = floor(fy);
  const float ax = fx - x0f, ay = fy - y0f;
  const int w = (int)ti.width, h = (int)ti.height;
  int x0 = (int)x0f % w, y0 = (int)y0f % h;
  if (x0 < 0) x0 += w;
  if (y0 < 0) y0 += h;
  const int x1 = x0 + 1 == w ? 0 : x0 + 1, y1 = y0 + 1 == h ? 0 : y0 + 1;
  const global float4* t = s->texels + ti.offset;
  const float4 top = mix(t[y0 * w + x0], t[y0 * w + x1], ax);
  const float4 bottom = mix(t[y1 * w + x0], t[y1 * w + x1], ax);
  return mix(top, bottom, ay);
}

inline float2 px_interpolate_uv(const global TriangleShading* sh, float u, float v) {
  const float w = 1.0f - u - v;
  return w * (float2)(sh->uv0[0], sh->uv0[1]) + u * (float2)(sh->uv1[0], sh->uv1[1]) +
         v * (float2)(sh->uv2[0], sh->uv2[1]);
}

/* Alpha cut-outs (OBJ map_d): a hit on a texel with alpha < 0.5 does not count. */
inline int px_alpha_visible(const SceneView* s, uint prim, float u, float v) {
  const global TriangleShading* sh = s->shading + prim;
  const int tex = s->materials[sh->material].alpha_texture;
  if (tex < 0) return 1;
  return px_texture_bilinear(s, tex, px_interpolate_uv(sh, u, v)).w >= 0.5f;
}

#endif
