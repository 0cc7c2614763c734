/* Tangent-space normal maps (OBJ `norm`, or `bump` naming a normal map).
 *
 * The tangent frame is the triangle's own: T and B are the directions in which the texture's
 * u and v grow across the triangle (dp/du and dp/dv, solved from its positions and uvs), made
 * orthogonal to the interpolated normal N. A texel (r, g, b) encodes the normal
 * 2 (r, g, b) - 1 in that frame (OpenGL convention: green points towards +v), so
 * (0.5, 0.5, 1) leaves N unchanged. One frame per triangle rather than per vertex: exact on
 * flat, uniformly mapped surfaces; across a curved mesh the frame turns at triangle edges. */
#ifndef PARALLAX_NORMAL_MAP_H
#define PARALLAX_NORMAL_MAP_H

#include "scene/scene_view.h"

/* Smallest cosine a mapped normal keeps with the outgoing direction: a map can tilt the
 * normal away from the viewer, where every BSDF is zero and the pixel would turn black. */
#define PX_NORMAL_MAP_MIN_COS 0.05f

/* The shading normal ns (unit, facing wo) perturbed by the material's normal map at uv.
 * v0..v2 are the triangle's positions; returns ns itself where the triangle's uvs give no
 * frame (all equal or collinear) or the texel decodes to no direction. */
inline float3 px_normal_mapped(const SceneView* s, const global GpuMaterial* mat, const global PxTriangleShading* sh,
                               float3 v0, float3 v1, float3 v2, float2 uv, float3 ns, float3 wo) {
  const float3 e1 = v1 - v0, e2 = v2 - v0;
  const float2 d1 = px_shading_uv(sh, 1) - px_shading_uv(sh, 0);
  const float2 d2 = px_shading_uv(sh, 2) - px_shading_uv(sh, 0);
  const float det = d1.x * d2.y - d1.y * d2.x;
  if (!(fabs(det) > 1e-20f)) return ns;
  const float3 dpdu = (e1 * d2.y - e2 * d1.y) / det;
  const float3 dpdv = (e2 * d1.x - e1 * d2.x) / det;
  float3 t = dpdu - ns * dot(ns, dpdu);
  const float t_len = length(t);
  if (!(t_len > 0.0f) || !isfinite(t_len)) return ns;
  t /= t_len;
  float3 b = cross(ns, t);
  if (dot(b, dpdv) < 0.0f) b = -b; /* mirrored uvs: the map's +v is the other way */

  const float3 c = 2.0f * px_texture_bilinear(s, mat->normal_texture, uv).xyz - 1.0f;
  float3 m = (c.x * mat->normal_scale) * t + (c.y * mat->normal_scale) * b + c.z * ns;
  const float m_len = length(m);
  if (!(m_len > 0.0f) || !isfinite(m_len)) return ns;
  m /= m_len;
  /* Tilt a normal that (nearly) faces away back towards the viewer, continuously. */
  const float cos_o = dot(m, wo);
  if (cos_o < PX_NORMAL_MAP_MIN_COS) m = normalize(m + (PX_NORMAL_MAP_MIN_COS - cos_o) * wo);
  return m;
}

#endif
