/* A material's BSDF at a surface point: its specular texture looked up (map_Ks scales the
 * specular colour), or for glass the dielectric seen from the side the path arrives from. */
#ifndef PARALLAX_MATERIAL_H
#define PARALLAX_MATERIAL_H

#include "scene/scene_view.h"
#include "shading/bsdf.h"

/* albedo: the diffuse albedo, textured (the caller has it already: the G-buffer and the
 * path tracer both report it). outside: the path arrives from the surface's outer side. */
inline Bsdf px_material_bsdf(const SceneView* s, const global GpuMaterial* mat, float3 albedo, float2 uv, int outside) {
  if (PX_HAS(PX_FEATURE_DIELECTRIC) && (mat->flags & PX_MAT_DIELECTRIC))
    return px_make_dielectric_bsdf((float3)(1.0f, 1.0f, 1.0f), px_load3(mat->transmission), mat->ior, outside);
  float3 specular = px_load3(mat->specular);
  if (PX_HAS(PX_FEATURE_TEXTURES) && mat->specular_texture >= 0)
    specular *= px_texture_bilinear(s, mat->specular_texture, uv).xyz;
  return px_make_bsdf(albedo, specular, mat->roughness, (mat->flags & PX_MAT_MIRROR) != 0u);
}

#endif
