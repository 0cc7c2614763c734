/* The motion pass of an animated scene: where each G-buffer texel's surface point was in the
 * previous frame, in world space, so that the denoiser's temporal passes follow a moving object
 * and not only the camera (svgf_temporal, svgf_antialias).
 *
 * `tri_motion` holds per scene triangle its three vertices now (0..2) and in the previous frame
 * (3..5) (DeviceSceneBuffers::motion). The point's barycentrics in the current triangle carry
 * it to the previous one: prev = pos + the barycentric blend of the vertices' displacements, so
 * a triangle that did not move gives pos back exactly. Output w: PX_MOTION_MOVED on a surface
 * whose triangle or instance moved, PX_MOTION_STILL on one that did not, PX_MOTION_MISS on a
 * miss (whose pos is a direction, left as it is). An instance's mesh triangles move with their
 * instance instead (below); their entries in tri_motion are not read. */
#include "shared/types.h"
#include "pipeline/texel_motion.h"

/* A 3x4 row-major affine matrix applied to a point. */
inline float3 px_motion_xform(const global float* m, float3 p) {
  return (float3)(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                  m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]);
}

/* `instances`: the scene's instance buffer (types.h), or null for a scene without. A texel on an
 * instance's mesh moves with the instance: back into the mesh's space by this frame's
 * world_to_object, out again by the last frame's object_to_world. */
kernel void gbuffer_motion(global float4* out, const global GBufferTexel* gbuf, const global float4* tri_motion,
                           const global SceneInstances* instances, uint row0, uint rows, uint width) {
  const uint gid = get_global_id(0);
  if (gid >= rows * width) return;
  const uint i = row0 * width + gid; /* full-frame buffers */
  const global GBufferTexel* g = gbuf + i;
  const float3 pos = (float3)(g->pos[0], g->pos[1], g->pos[2]);
  if (g->material_class == PX_CLASS_MISS || g->prim == PX_NO_HIT) {
    out[i] = (float4)(pos, PX_MOTION_MISS);
    return;
  }
  if (instances && g->inst != PX_NO_INSTANCE && g->inst < instances->count) {
    const global SceneInstance* in =
        (const global SceneInstance*)((const global uchar*)instances + 16 * (size_t)instances->records) + g->inst;
    const float3 moved = px_motion_xform(in->previous_object_to_world, px_motion_xform(in->world_to_object, pos));
    out[i] = (float4)(isfinite(moved.x) && isfinite(moved.y) && isfinite(moved.z) ? moved : pos,
                      px_texel_moved(tri_motion, instances, g) ? PX_MOTION_MOVED : PX_MOTION_STILL);
    return;
  }
  const global float4* v = tri_motion + 6 * (size_t)g->prim;
  const float3 a = v[0].xyz, e1 = v[1].xyz - a, e2 = v[2].xyz - a, ep = pos - a;
  const float d11 = dot(e1, e1), d12 = dot(e1, e2), d22 = dot(e2, e2);
  const float p1 = dot(ep, e1), p2 = dot(ep, e2);
  const float den = d11 * d22 - d12 * d12;
  float3 prev = pos;
  if (den > 0.0f) {
    const float u = (d22 * p1 - d12 * p2) / den, w = (d11 * p2 - d12 * p1) / den;
    const float3 m0 = v[3].xyz - a, m1 = v[4].xyz - v[1].xyz, m2 = v[5].xyz - v[2].xyz;
    const float3 moved = pos + (1.0f - u - w) * m0 + u * m1 + w * m2;
    if (isfinite(moved.x) && isfinite(moved.y) && isfinite(moved.z)) prev = moved;
  }
  out[i] = (float4)(prev, px_texel_moved(tri_motion, instances, g) ? PX_MOTION_MOVED : PX_MOTION_STILL);
}
