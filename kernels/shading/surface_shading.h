/* How a surface hit is shaded, whoever shades it: the path tracers at every vertex
 * (pathtrace/path_vertex.h) and ReSTIR DI at the first (restir/shading_point.h), so that the
 * light ReSTIR adds at a pixel's first vertex is the light next-event estimation would add there. */
#ifndef PARALLAX_SURFACE_SHADING_H
#define PARALLAX_SURFACE_SHADING_H

#include "scene/scene_view.h"
#include "shading/bsdf.h"
#include "shading/material.h"
#include "shading/normal_map.h"

/* Both normals of *surf turned to the viewer along wo (the winding order's normal is the front;
 * two-sided surfaces face whoever looks), and in *outside the side the viewer is on, for glass:
 * the geometric normal oriented like the vertex normals (outwards on closed meshes), taken before
 * the flips. Returns whether wo sees the front face (emitters light only that side unless
 * two-sided). */
inline int px_face_viewer(const SurfaceHit* surf, float3 wo, float3* ng, float3* ns, int* outside) {
  *ng = surf->ng;
  *ns = surf->ns;
  const int front_face = dot(*ng, wo) > 0.0f;
  *outside = front_face == (dot(*ng, *ns) >= 0.0f);
  if (!front_face) *ng = -*ng;
  if (dot(*ns, *ng) < 0.0f) *ns = -*ns;
  return front_face;
}

/* The BSDF at `hit` on *surf seen along wo: the diffuse colour times its texture and the vertex
 * colours; the normal map, if any, bends *ns (px_face_viewer's) first. */
inline Bsdf px_surface_bsdf(const SceneView* scene, const SurfaceHit* surf, Hit hit, float3 wo, int outside,
                            float3* ns) {
  const global GpuMaterial* mat = surf->mat;
  float3 albedo = px_load3(mat->diffuse);
  if (PX_HAS(PX_FEATURE_TEXTURES) && mat->diffuse_texture >= 0)
    albedo *= px_texture_bilinear(scene, mat->diffuse_texture, px_interpolate_uv(surf->sh, hit.u, hit.v)).xyz;
  if (PX_HAS(PX_FEATURE_VERTEX_COLOURS)) albedo *= px_vertex_colour(scene, surf->prim, hit.u, hit.v);
  const float2 uv = px_interpolate_uv(surf->sh, hit.u, hit.v);
  if (PX_HAS(PX_FEATURE_NORMAL_MAP) && mat->normal_texture >= 0)
    *ns = px_normal_mapped(scene, mat, surf->sh, surf->v0, surf->v1, surf->v2, uv, *ns, wo);
  return px_material_bsdf(scene, mat, albedo, uv, outside);
}

#endif
