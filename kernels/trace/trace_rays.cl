/* Ray-buffer kernels: trace a list of rays against the BVH. Used by the tests (against a
 * brute-force host loop) and by bench_trace (against Embree's rtcIntersect1). RayBatchTracer
 * runs trace_closest_pairs on CPU devices and trace_closest on GPUs. */
#include "shared/types.h"
#include "scene/scene_view.h"
#include "trace/traverse.h"
#include "trace/ray_offset.h"

kernel void trace_closest(const global Ray* rays, global Hit* hits, uint count, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const Ray r = rays[i];
  hits[i] = px_trace_closest(&scene, (float3)(r.org[0], r.org[1], r.org[2]), (float3)(r.dir[0], r.dir[1], r.dir[2]),
                             r.tmin, r.tmax);
}

/* trace_closest two rays a work-item, rays 2i and 2i + 1 (their walks interleaved: the same hits,
 * more memory loads in flight; traverse.h, px_tree_closest_pair). Launched over (count + 1) / 2. */
kernel void trace_closest_pairs(const global Ray* rays, global Hit* hits, uint count, PX_SCENE_PARAMS) {
  const uint i = 2u * get_global_id(0);
  if (i >= count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const Ray r0 = rays[i];
  if (i + 1u == count) {
    hits[i] = px_trace_closest(&scene, (float3)(r0.org[0], r0.org[1], r0.org[2]),
                               (float3)(r0.dir[0], r0.dir[1], r0.dir[2]), r0.tmin, r0.tmax);
    return;
  }
  const Ray r1 = rays[i + 1u];
  Hit h0, h1;
  px_trace_closest_pair(&scene, (float3)(r0.org[0], r0.org[1], r0.org[2]), (float3)(r0.dir[0], r0.dir[1], r0.dir[2]),
                        r0.tmin, r0.tmax, (float3)(r1.org[0], r1.org[1], r1.org[2]),
                        (float3)(r1.dir[0], r1.dir[1], r1.dir[2]), r1.tmin, r1.tmax, &h0, &h1);
  hits[i] = h0;
  hits[i + 1u] = h1;
}

kernel void trace_any(const global Ray* rays, global uint* occluded, uint count, PX_SCENE_PARAMS) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const SceneView scene = PX_SCENE_VIEW();
  const Ray r = rays[i];
  occluded[i] = (uint)px_trace_any(&scene, (float3)(r.org[0], r.org[1], r.org[2]),
                                   (float3)(r.dir[0], r.dir[1], r.dir[2]), r.tmin, r.tmax);
}

/* Offsets hit points off their surfaces (Wächter & Binder) — exposed so the tests can check
 * the very function the path tracer uses. points/normals: 4 floats each (xyz, unused w). */
kernel void offset_origins(const global float4* points, const global float4* normals, global float4* out, uint count) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  out[i] = (float4)(px_offset_ray_origin(points[i].xyz, normals[i].xyz), 0.0f);
}
