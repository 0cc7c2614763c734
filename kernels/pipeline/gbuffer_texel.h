/* The G-buffer texel of a primary ray (org, dir) that found `hit`: hit point, depth, shading
 * normal facing the eye, and the material class that decides whether reprojection may reuse
 * the pixel (only view-independent, diffuse surfaces). Two writers share it, so their texels
 * are the same to the last bit: the G-buffer pass (gbuffer.cl), which traces the ray through
 * each pixel's point at the frame's jitter position, and the path tracers, whose first sample of a frame is that same
 * ray (px_sample_camera_dir) and which write the texel from its first hit instead of a second trace. */
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
    g.inst = PX_NO_INSTANCE;
    return g;
  }
  const SurfaceHit s = px_surface_hit(scene, hit);
  const global GpuMaterial* m = s.mat;
  /* Both normals facing the eye (the vertex normal of a degenerate triangle is ng either way). */
  const float3 ng = dot(s.ng, dir) > 0.0f ? -s.ng : s.ng;
  const float3 n = dot(s.ns, ng) < 0.0f ? -s.ns : s.ns;
  g.pos[0] = s.p.x;
  g.pos[1] = s.p.y;
  g.pos[2] = s.p.z;
  g.depth = hit.t;
  g.normal[0] = n.x;
  g.normal[1] = n.y;
  g.normal[2] = n.z;
  g.prim = s.prim;
  g.inst = hit.inst;
  g.material_class = (m->flags & PX_MAT_EMISSIVE)     ? PX_CLASS_EMISSIVE
                     : (m->flags & PX_MAT_DIELECTRIC) ? PX_CLASS_DIELECTRIC
                     : (m->flags & PX_MAT_MIRROR)     ? PX_CLASS_MIRROR
                     : (m->flags & PX_MAT_GLOSSY)     ? PX_CLASS_GLOSSY
                                                      : PX_CLASS_DIFFUSE;
  return g;
}

#endif
