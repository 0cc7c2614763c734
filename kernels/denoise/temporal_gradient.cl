/* Temporal gradients, the shading half: one work-item per stratum of 3x3 pixels, for GPUs (CPUs
 * shade the strata in path_trace.cl's `path_trace_pixels`, whose code they share). What a stratum's
 * two shades are and why: denoise/gradient_stratum.h. */
#include "denoise/gradient_stratum.h"

/* Strata rows [s_row0, s_row0 + s_rows): px_gradient_stratum for each. */
kernel void gradient_shade(global float4* raw, global float4* ref, const global float4* prev_ref,
                           const global GBufferTexel* gbuf, const global GBufferTexel* prev_gbuf,
                           volatile global uint* nonfinite, const global float4* tri_motion, FrameParams fp,
                           CameraParams cam, GradientParams gp, PX_SCENE_PARAMS) {
  const uint gid = get_global_id(0);
  if (gid >= gp.s_rows * gp.strata_w) return;
  const SceneView scene = PX_SCENE_VIEW();
  px_gradient_stratum(&scene, gid, raw, ref, prev_ref, gbuf, prev_gbuf, nonfinite, tri_motion, &fp, &cam, &gp);
}
