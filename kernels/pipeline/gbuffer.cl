/* Stage 3: G-buffer of one eye's rows, from the primary ray through each pixel's point at the
 * frame's jitter position (CameraParams::jitter; gbuffer_texel.h). Where a device path traces the same eye's rows in
 * the same frame, the path tracer writes those texels itself and this pass covers only the rest (the margin rows the
 * denoiser and reprojection read beyond the strip, and the eyes nobody path traces in full). CPU devices run this
 * pass in the path tracer's kernel instead (path_trace.cl, path_trace_pixels), which a frame compiles anyway.
 * `hits`: null, or a full-frame Hit buffer that receives each ray's hit, where hole filling
 * (stage 5) starts its pixels' first sample (the G-buffer's ray) instead of tracing the same ray again. */
#include "shared/types.h"
#include "pipeline/gbuffer_pixel.h"

kernel void gbuffer(global GBufferTexel* out, global Hit* hits, uint row0, uint rows, CameraParams cam,
                    PX_SCENE_PARAMS) {
  const uint gid = get_global_id(0);
  if (gid >= rows * cam.width) return;
  const SceneView scene = PX_SCENE_VIEW();
  px_gbuffer_pixel(&scene, &cam, row0 * cam.width + gid, out, hits); /* full-frame buffers */
}
