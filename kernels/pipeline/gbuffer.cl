/* Stage 3: G-buffer of one eye's rows. The primary ray through each pixel centre: hit point,
 * depth, shading normal facing the eye, and the material class that
 * decides whether reprojection may reuse the pixel (only view-independent, diffuse surfaces). */
#include "shared/types.h"
#include "render/camera.h"
#include "scene/scene_view.h"
#include "trace/traverse.h"

kernel void gbuffer(global GBufferTexel* out, uint row0, uint rows, CameraParams cam, PX_SCENE_PARAMS) {
  const uint gid = get_global_id(0);
  if (gid >= rows * cam.width) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint i = row0 * cam.width + gid; /* out is a full-frame buffer */
  const uint x = i % cam.width, y = i / cam.width;
  const float3 org = px_camera_origin(&cam);
  const float3 dir = px_camera_dir(&cam, x, y, 0.5f, 0.5f);
  const Hit hit = px_trace_closest_leaf(&scene, org, dir, 0.0f, INFINITY);
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
    out[i] = g;
    return;
  }
  const global BvhTriangle* tri = scene.tris + hit.prim;
  const uint prim = tri->prim;
  const global TriangleShading* sh = scene.shading + prim;
  const global GpuMaterial* m = scene.materials + sh->material;
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
  out[i] = g;
}
