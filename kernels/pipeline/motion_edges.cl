/* The pixels of an animated frame that get extra samples before denoising
 * (DenoiseStage::Options::motion_edge_samples, path_trace_list_more): where a moving object's
 * silhouette crosses the pixel, and the still background within two pixels of it, which the
 * object is uncovering or about to cover.
 *
 * Why: a still pixel's anti-aliasing averages many frames' jitter positions, so an edge
 * converges to its coverage; a pixel on a moving object keeps at most half of that history
 * (svgf_antialias), and its one sample per frame, on one side of the edge or the other, shows.
 * Every pixel of the frame shares one jitter position, so all of an edge's pixels err the
 * same way at once. A pixel the object uncovered has no history at all. More samples there give
 * each frame's pixel its coverage and a less noisy restart: the MotionTrail test's error where a
 * sliding cube went falls with their count (docs/measurements.md, motion-edge samples).
 *
 * A pixel qualifies if its G-buffer texel lies on a still surface and one within its 5x5
 * neighbourhood lies on a moving object (px_texel_moved), or if its texel lies on a moving object,
 * one of its 3x3 neighbours on a still surface and none on the environment. Not the environment
 * (its history is kept by direction, svgf_temporal: the object's samples entering it would stay
 * behind as the object moves on), nor an object's edge against it: there the escaping samples
 * count as albedo 1 in the mean the filter demodulates by, and the sky's light entered the
 * object's own history along its silhouette (Khronos's RiggedSimple, whose arm moves against
 * the sky; docs/measurements.md, motion-edge samples).
 * Neighbours are read only in rows [lo_row, hi_row) (the G-buffer rows valid on this device),
 * so the list does not depend on how the image is split where those rows cover the reach. The
 * list's order depends on the device's scheduling, its contents do not; each listed pixel's
 * samples depend on the pixel alone. */
#include "shared/types.h"
#include "pipeline/texel_motion.h"

kernel void motion_edge_list(global uint* list, volatile global uint* count, const global GBufferTexel* gbuf,
                             const global float4* tri_motion, const global SceneInstances* instances, uint row0,
                             uint rows, uint width, uint height, uint lo_row, uint hi_row) {
  const uint gid = get_global_id(0);
  if (gid >= rows * width) return;
  const uint i = row0 * width + gid; /* full-frame buffers */
  const int x = (int)(i % width), y = (int)(i / width);
  if (gbuf[i].material_class == PX_CLASS_MISS) return;
  const int moved = px_texel_moved(tri_motion, instances, gbuf + i);
  const int reach = moved ? 1 : 2;
  int wanted = 0;
  for (int dy = -reach; dy <= reach; ++dy) {
    const int ty = y + dy;
    if (ty < (int)lo_row || ty >= (int)hi_row || ty < 0 || ty >= (int)height) continue;
    for (int dx = -reach; dx <= reach; ++dx) {
      const int tx = x + dx;
      if ((dx == 0 && dy == 0) || tx < 0 || tx >= (int)width) continue;
      const global GBufferTexel* q = gbuf + (uint)ty * width + (uint)tx;
      if (moved && q->material_class == PX_CLASS_MISS) return;
      if (px_texel_moved(tri_motion, instances, q) != moved) wanted = 1;
    }
  }
  if (wanted) list[atomic_inc(count)] = i;
}
