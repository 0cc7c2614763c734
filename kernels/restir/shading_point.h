/* A primary hit as ReSTIR DI shades it: position, both normals facing the viewer, the offset
 * origin of its shadow rays and its BSDF, built exactly as px_path_vertex builds a vertex
 * (textures, vertex colours, normal maps), so that the direct light ReSTIR adds at the first
 * vertex is the light next-event estimation would have added there. A pixel's hit is re-shaded
 * from its Hit record (prim, instance, barycentrics) wherever a reservoir is evaluated: at the
 * pixel itself, at a neighbour (spatial reuse) and at last frame's pixel (temporal reuse), which
 * is what lets every pass work from 16 bytes a pixel instead of a stored BSDF. */
#ifndef PARALLAX_RESTIR_SHADING_POINT_H
#define PARALLAX_RESTIR_SHADING_POINT_H

#include "shared/types.h"
#include "scene/scene_view.h"
#include "shading/bsdf.h"
#include "shading/surface_shading.h"
#include "trace/ray_offset.h"

typedef struct ShadingPoint {
  float3 p, ng, ns, wo;
  float3 origin; /* shadow rays start here (offset along ng) */
  float depth;   /* distance to the viewer (the reuse tests compare it) */
  Bsdf bsdf;
  int valid; /* a surface with a non-delta lobe: the only ones direct light sampling serves */
} ShadingPoint;

/* The hit `hit` seen from `eye` (the camera's origin of the frame the hit belongs to). The view
 * direction is taken from the point, not from the ray, so that any pass rebuilds the same point
 * from the same 16 bytes. */
inline ShadingPoint px_shading_point(const SceneView* scene, Hit hit, float3 eye) {
  ShadingPoint sp;
  sp.valid = 0;
  sp.depth = 0.0f;
  sp.p = sp.ng = sp.ns = sp.wo = sp.origin = (float3)(0.0f, 0.0f, 0.0f);
  if (hit.prim == PX_NO_HIT) return sp;
  const SurfaceHit surf = px_surface_hit(scene, hit);
  const float3 to_eye = eye - surf.p;
  sp.depth = length(to_eye);
  if (!(sp.depth > 0.0f)) return sp;
  const float3 wo = to_eye / sp.depth;
  float3 ng, ns;
  int outside;
  px_face_viewer(&surf, wo, &ng, &ns, &outside);
  sp.bsdf = px_surface_bsdf(scene, &surf, hit, wo, outside, &ns);
  sp.p = surf.p;
  sp.ng = ng;
  sp.ns = ns;
  sp.wo = wo;
  sp.origin = px_offset_ray_origin(surf.p, ng);
  sp.valid = sp.bsdf.p_specular < 1.0f || !sp.bsdf.mirror;
  return sp;
}

/* A Hit as ReSTIR's passes keep it: (prim, instance, u, v) in a uint4. */
inline uint4 px_pack_hit(Hit h) { return (uint4)(h.prim, h.inst, as_uint(h.u), as_uint(h.v)); }
inline Hit px_unpack_hit(uint4 v) {
  Hit h;
  h.t = 0.0f;
  h.prim = v.x;
  h.inst = v.y;
  h.u = as_float(v.z);
  h.v = as_float(v.w);
  return h;
}

#endif
