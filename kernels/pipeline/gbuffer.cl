/* Stage 3: G-buffer of one eye's rows, from the primary ray through each pixel's point at the
 * frame's jitter position (CameraParams::jitter; gbuffer_texel.h). Where a device path traces the same eye's rows in
 * the same frame, the path tracer writes those texels itself and this pass covers only the rest (the margin rows the
 * denoiser and reprojection read beyond the strip, and the eyes nobody path traces in full).
 * `hits`: null, or a full-frame Hit buffer that receives each ray's hit, where hole filling
 * (stage 5) starts its pixels' first sample (the G-buffer's ray) instead of tracing the same ray again. */
#include "shared/types.h"
#include "pipeline/gbuffer_texel.h"
#include "render/camera.h"
#include "scene/scene_view.h"
#include "trace/traverse.h"

kernel void gbuffer(global GBufferTexel* out, global Hit* hits, uint row0, uint rows, CameraParams cam,
                    PX_SCENE_PARAMS) {
  const uint gid = get_global_id(0);
  if (gid >= rows * cam.width) return;
  const SceneView scene = PX_SCENE_VIEW();
  const uint i = row0 * cam.width + gid; /* out is a full-frame buffer */
  const uint x = i % cam.width, y = i / cam.width;
  const float3 dir = px_camera_dir(&cam, x, y, cam.jitter[0], cam.jitter[1]);
  const Hit hit = px_trace_closest_leaf(&scene, px_camera_origin(&cam), dir, 0.0f, INFINITY);
  out[i] = px_gbuffer_texel(&scene, dir, hit);
  if (hits) hits[i] = hit;
}

/* gbuffer, two pixels a work-item (2g and 2g + 1 of the rows, neighbours in a row), their rays'
 * walks in step (px_trace_closest_leaf_pair): the same texels and hits to the bit, with two
 * chains of loads in flight. Launched over half the pixels, rounded up, on CPU devices
 * (GBufferStage); GPUs keep one pixel a work-item. */
kernel void gbuffer_pairs(global GBufferTexel* out, global Hit* hits, uint row0, uint rows, CameraParams cam,
                          PX_SCENE_PARAMS) {
  const uint g = 2u * get_global_id(0);
  const uint n = rows * cam.width;
  if (g >= n) return;
  const SceneView scene = PX_SCENE_VIEW();
  const float3 org = px_camera_origin(&cam);
  const uint i0 = row0 * cam.width + g; /* out is a full-frame buffer */
  const float3 dir0 = px_camera_dir(&cam, i0 % cam.width, i0 / cam.width, cam.jitter[0], cam.jitter[1]);
  if (g + 1u == n) {
    const Hit hit = px_trace_closest_leaf(&scene, org, dir0, 0.0f, INFINITY);
    out[i0] = px_gbuffer_texel(&scene, dir0, hit);
    if (hits) hits[i0] = hit;
    return;
  }
  const uint i1 = i0 + 1u;
  const float3 dir1 = px_camera_dir(&cam, i1 % cam.width, i1 / cam.width, cam.jitter[0], cam.jitter[1]);
  Hit h0, h1;
  px_trace_closest_leaf_pair(&scene, org, dir0, 0.0f, INFINITY, org, dir1, 0.0f, INFINITY, &h0, &h1);
  out[i0] = px_gbuffer_texel(&scene, dir0, h0);
  out[i1] = px_gbuffer_texel(&scene, dir1, h1);
  if (hits) {
    hits[i0] = h0;
    hits[i1] = h1;
  }
}
