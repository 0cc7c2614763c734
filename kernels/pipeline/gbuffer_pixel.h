/* One pixel of the G-buffer pass (stage 3): the camera ray through pixel p's point at the frame's
 * jitter position (CameraParams::jitter), its texel to out[p] and, where `hits` is not null, its
 * hit to hits[p] (full-frame buffers). Shared by gbuffer.cl's `gbuffer` (GPUs) and path_trace.cl's
 * `path_trace_pixels` in its G-buffer mode (CPUs), so both write the same bits. */
#ifndef PARALLAX_GBUFFER_PIXEL_H
#define PARALLAX_GBUFFER_PIXEL_H

#include "shared/types.h"
#include "pipeline/gbuffer_texel.h"
#include "render/camera.h"
#include "scene/scene_view.h"
#include "trace/traverse.h"

inline void px_gbuffer_pixel(const SceneView* scene, const CameraParams* cam, uint p, global GBufferTexel* out,
                             global Hit* hits) {
  const float3 dir = px_camera_dir(cam, p % cam->width, p / cam->width, cam->jitter[0], cam->jitter[1]);
  const Hit hit = px_trace_closest_leaf(scene, px_camera_origin(cam), dir, 0.0f, INFINITY);
  out[p] = px_gbuffer_texel(scene, dir, hit);
  if (hits) hits[p] = hit;
}

#endif
