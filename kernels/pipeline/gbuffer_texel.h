/* The G-buffer texel of a primary ray (org, dir) that found `hit`: hit point, depth, shading
 * normal facing the eye, and the material class that decides whether reprojection may reuse
 * the pixel (only view-independent, diffuse surfaces). Two writers share it, so their texels
 * are the same to the last bit: the G-buffer pass (gbuffer.cl), which traces the ray through
 * each pixel centre, and the path tracers, whose first sample of a frame is that same ray
 * (px_sample_camera_dir) and which write the texel from its first hit instead of a second
 * trace. */
#ifndef PARALLAX_GBUFFER_TEXEL_H
#define PARALLAX_GBUFFER_TEXEL_H

#include "shared/types.h"
#include "scene/scene_view.h"

inline GBufferTexel px_gbuffer_texel(const SceneView* scene, float3 dir, Hit hit) {
  GBufferTexel g;
  if (hit.prim == PX_NO_HIT) {
    /* The environment is at infinity: the ray's direction is all there is to its "position"
     * (SVGF reprojects the environment's history by direction). */
    g.pos[0] = dir.x;
    g.pos[1] = dir.y;
    g.pos[2] = dir.z;
    g.depth = 0.0f;
    g.normal[0] = g.normal[1] = g.normal[2] = 0.0f;
    g.material_class = PX_CLASS_MISS;
    g.prim = PX_NO_HIT;
    return g;
  }
  const global BvhTriangle* tri = scene->tris + hit.prim;
  const uint prim = tri->prim;
  const global TriangleShading* sh = scene->shading + prim;
  const global GpuMaterial* m = scene->materials + sh->material;
  const float3 v0 = px_load3(tri->v0), v1 = px_load3(tri->v1), v2 = px_load3(tri->v2);
  const float w = 1.0f - hit.u - hit.v;
  const float3 p = w * v0 + hit.u * v1 + hit.v * v2;
  float3 ng = normalize(cross(v1 - v0, v2 - v0));
  if (dot(ng, dir) > 0.0f) ng = -ng;
  float3 n = w * px_load3(sh->n0) + hit.u * px_load3(sh->n1) + hit.v * px_load3(sh->n2);
  const float len = length(n);
  n = len > 0.0f && isfinite(len) ? n / len : ng;
  if (dot(n, ng) < 0.0f) n = -n;
  g.pos[0] = p.x; g.pos[1] = p.y; g.pos[2] = p.z;
  g.depth = hit.t;
  g.normal[0] = n.x; g.normal[1] = n.y; g.normal[2] = n.z;
  g.prim = prim;
  g.material_class = (m->flags & PX_MAT_EMISSIVE)     ? PX_CLASS_EMISSIVE
                     : (m->flags & PX_MAT_DIELECTRIC) ? PX_CLASS_DIELECTRIC
                     : (m->flags & PX_MAT_MIRROR)  ? PX_CLASS_MIRROR
                     : (m->flags & PX_MAT_GLOSSY)  ? PX_CLASS_GLOSSY
                                                   : PX_CLASS_DIFFUSE;
  return g;
}

#endif
