/* Preview shading of primary hits: material albedo (texture included) lit by a head light
 * (|cos| between shading normal and view ray), plus emission. Not light transport — a quick,
 * noise-free look at geometry, materials and both eyes' framing. */
#include "shared/types.h"
#include "render/camera.h"
#include "scene/scene_view.h"
#include "trace/traverse.h"

kernel void primary_preview(global float* out_rgb, uint row0, uint rows, CameraParams cam, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= rows * cam.width) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint x = i % cam.width;
  const uint y = row0 + i / cam.width;
  const float3 org = px_camera_origin(&cam);
  const float3 dir = px_camera_dir(&cam, x, y, 0.5f, 0.5f);
  const Hit hit = px_trace_closest_leaf(&scene, org, dir, 0.0f, INFINITY);
  float3 c = (float3)(0.0f, 0.0f, 0.0f);
  if (hit.prim != PX_NO_HIT) {
    /* The shading normal in world space (an instance's mesh keeps its own). */
    const SurfaceHit surf = px_surface_hit(&scene, hit);
    const global PxTriangleShading* s = surf.sh;
    const float3 n = surf.ns;
    const global GpuMaterial* m = surf.mat;
    float3 albedo = px_load3(m->diffuse);
    if (PX_HAS(PX_FEATURE_TEXTURES) && m->diffuse_texture >= 0)
      albedo *= px_texture_bilinear(&scene, m->diffuse_texture, px_interpolate_uv(s, hit.u, hit.v)).xyz;
    if (PX_HAS(PX_FEATURE_VERTEX_COLOURS)) albedo *= px_vertex_colour(&scene, surf.prim, hit.u, hit.v);
    albedo += px_load3(m->specular);
    c = albedo * (0.15f + 0.85f * fabs(dot(n, dir))) + px_load3(m->emission);
  }
  out_rgb[3 * i + 0] = c.x;
  out_rgb[3 * i + 1] = c.y;
  out_rgb[3 * i + 2] = c.z;
}
