/* One camera path's radiance (px_trace_path), shared by the path tracers (path_trace.cl) and
 * the temporal gradients' re-shading (denoise/temporal_gradient.cl), which must trace the very
 * path the image's samples do. */
#ifndef PARALLAX_TRACE_PATH_H
#define PARALLAX_TRACE_PATH_H

#include "shared/types.h"
#include "pathtrace/path_vertex.h"
#include "pipeline/gbuffer_texel.h"
#include "trace/traverse.h"

/* Radiance along one camera path from org along dir, its vertices in a loop (path_vertex.h);
 * *primary_albedo receives PathVertex::primary_albedo; `restir_first_vertex` as px_camera_path's.
 * The camera ray's hit, if the caller has traced it already: *first (private) or *first_global;
 * with neither (null), the loop traces it as it traces every later ray. If `gbuffer_texel` is not
 * null, the camera ray's texel (gbuffer_texel.h) goes there. The loop holds the path's only
 * closest-hit query, so that a GPU build inlines one traversal (its stacks, its registers) for the
 * camera ray and the bounces alike, and the given hit is read where it is used, so that it does not
 * stay in registers through the bounces (docs/measurements.md, "GPU registers from ptxas"). */
inline float3 px_trace_path_vertices(const SceneView* scene, const FrameParams* fp, float3 org, float3 dir,
                                     SampleKey key, const Hit* first, const global Hit* first_global,
                                     int restir_first_vertex, float4* primary_albedo,
                                     global GBufferTexel* gbuffer_texel) {
  PathVertex v = px_camera_path(org, dir, restir_first_vertex);
  for (uint bounce = 0; bounce <= fp->max_bounces; ++bounce) {
    Hit hit;
    if (bounce == 0u && first)
      hit = *first;
    else if (bounce == 0u && first_global)
      hit = *first_global;
    else
      hit = px_trace_closest_leaf(scene, v.org, v.dir, 0.0f, INFINITY);
    /* At bounce 0, v.dir is the camera ray's direction. */
    if (bounce == 0u && gbuffer_texel) *gbuffer_texel = px_gbuffer_texel(scene, v.dir, hit);
    ShadowRay shadow;
    const int goes_on = px_path_vertex(scene, fp, key, bounce, hit, &v, &shadow);
    if (shadow.valid && !px_trace_any(scene, shadow.org, shadow.dir, 0.0f, shadow.tmax))
      v.radiance += shadow.contribution;
    if (!goes_on) break;
  }
  *primary_albedo = v.primary_albedo;
  return v.radiance;
}

/* Radiance along one camera path whose first hit is `first` (already traced by the caller). The
 * temporal gradients' re-shading calls it with the hit it checked (and next-event estimation at
 * every vertex: it compares the lighting of two frames, which ReSTIR's reuse would blur). */
inline float3 px_trace_path_from_hit(const SceneView* scene, const FrameParams* fp, float3 org, float3 dir,
                                     SampleKey key, Hit first, int restir_first_vertex, float4* primary_albedo) {
  return px_trace_path_vertices(scene, fp, org, dir, key, &first, 0, restir_first_vertex, primary_albedo, 0);
}

/* Radiance along one camera path (px_trace_path_vertices). If `gbuffer_hit` is not null, it is the
 * camera ray's hit, already traced (by the G-buffer pass, for the same ray). */
inline float3 px_trace_path(const SceneView* scene, const FrameParams* fp, float3 org, float3 dir, SampleKey key,
                            int restir_first_vertex, float4* primary_albedo, global GBufferTexel* gbuffer_texel,
                            const global Hit* gbuffer_hit) {
  return px_trace_path_vertices(scene, fp, org, dir, key, 0, gbuffer_hit, restir_first_vertex, primary_albedo,
                                gbuffer_texel);
}

#endif
