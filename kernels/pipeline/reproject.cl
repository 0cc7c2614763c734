/* Stage 4: spatial reprojection left -> right, and the hole list for stage 5.
 *
 * Parallel stereo cameras have horizontal epipolar lines: the left-eye image of a right-eye
 * pixel's surface point lies on the same row. So each right pixel gathers from its own row of
 * the left eye, which the same device owns: no data crosses devices. The two left pixels
 * around the projected position are linearly weighted; both must see the same surface as the
 * right pixel (normal, tangent-plane distance and footprint tolerances) and be diffuse.
 * Otherwise — a silhouette, a disocclusion, the image border, or a right pixel that is not
 * diffuse — the pixel is a hole.
 *
 * Pure footprints. A pixel's radiance is the mean over sample positions jittered across its
 * whole footprint, while the G-buffer describes only its centre. A left pixel whose centre
 * sees the sky (or a wall) may owe part of its radiance to an object that covers a corner of
 * its footprint; copying it into the right eye paints the object's left-eye outline where the
 * right eye sees background (a "ghost silhouette"). So every pixel involved — the right pixel
 * and both left taps — must be pure: the centres of its 3x3 neighbourhood, which surround the
 * footprint, all see the same surface (or all miss). Only a feature thinner than a pixel can
 * slip between those centres. The neighbourhood reaches one row beyond the strip, which the
 * G-buffer stage covers (its margin is at least one row).
 *
 * Background pixels (the right pixel's and the left pixel's neighbourhoods all miss) are
 * copied from the same left pixel: the environment is at infinity, so parallel eyes see it at
 * zero disparity. */
#include "shared/types.h"
#include "parallel/group_scan.h"
#include "render/camera.h"
#include "scene/scene_view.h"

/* Same surface: normals agree, the tap lies on p's tangent plane (within a fraction of the
 * depth), and within `footprints` pixel footprints of p along the plane. The footprint grows as
 * the surface turns away from the eye (1 / cos), which a plain distance threshold ignores. */
inline int px_same_surface(const global GBufferTexel* a, float3 p, float3 n, float depth, float cos_view,
                           float footprint, float min_cos, float footprints) {
  if (a->material_class != PX_CLASS_DIFFUSE) return 0;
  const float3 q = px_load3(a->pos);
  const float3 m = px_load3(a->normal);
  const float3 d = q - p;
  const float in_plane_limit = footprints * footprint / fmax(cos_view, 0.1f);
  return dot(m, n) > min_cos && fabs(dot(d, n)) < PX_REPROJECT_REL_DIST * depth && length(d) < in_plane_limit;
}

/* Does every texel of the 3-row window x in [x0, x1], rows y-1..y+1 (clipped to the image) see
 * the surface (p, n)? The neighbours are a pixel or two away, so the tolerances are looser than
 * for the taps: this looks for another surface, not for the exact point. */
inline int px_window_on_surface(const global GBufferTexel* g, int x0, int x1, int y, uint width, uint height, float3 p,
                                float3 n, float depth, float cos_view, float footprint) {
  for (int ty = max(y - 1, 0); ty <= min(y + 1, (int)height - 1); ++ty)
    for (int tx = max(x0, 0); tx <= min(x1, (int)width - 1); ++tx)
      if (!px_same_surface(g + (uint)ty * width + (uint)tx, p, n, depth, cos_view, footprint,
                           PX_REPROJECT_NEIGHBOUR_MIN_COS, PX_REPROJECT_FOOTPRINTS + 2.0f))
        return 0;
  return 1;
}

/* Does every texel of the 3x3 window around (x, y) (clipped to the image) miss the scene? */
inline int px_window_misses(const global GBufferTexel* g, int x, int y, uint width, uint height) {
  for (int ty = max(y - 1, 0); ty <= min(y + 1, (int)height - 1); ++ty)
    for (int tx = max(x - 1, 0); tx <= min(x + 1, (int)width - 1); ++tx)
      if (g[(uint)ty * width + (uint)tx].material_class != PX_CLASS_MISS) return 0;
  return 1;
}

/* Rows [row0, row0 + rows). All images are full-frame. right_radiance / right_albedo: written
 * for reprojected pixels (holes get 0 and are filled by stage 5); the albedo is the
 * demodulation albedo SVGF divides by, resampled with the same weights as the radiance so
 * that the two stay consistent. holes/hole_count: the compacted list of hole pixel indices
 * (hole_count must be zero before the launch).
 *
 * The hole list keeps scanline order within each work-group: the group's holes are counted
 * with a prefix sum in local memory and written to one contiguous range reserved with a
 * single atomic_add. Stage 5 then traces neighbouring pixels in neighbouring work-items
 * (coherent primary rays and memory) instead of the scattered order per-item atomic_inc gave.
 * Ranges of different groups still land in whatever order the groups finish. */
#define PX_REPROJECT_GROUP PX_LOCAL_SIZE
__attribute__((reqd_work_group_size(PX_REPROJECT_GROUP, 1, 1))) kernel void reproject(
    global float4* right_radiance, global float4* right_albedo, global uint* holes, volatile global uint* hole_count,
    const global float4* left_radiance, const global float4* left_albedo, const global GBufferTexel* left_g,
    const global GBufferTexel* right_g, uint row0, uint rows, CameraParams left_cam) {
  local uint scan[PX_REPROJECT_GROUP];
  local uint group_base;
  const uint gid = get_global_id(0), lid = get_local_id(0);
  const uint width = left_cam.width, height = left_cam.height;
  /* No early return: every work-item of the group takes part in the prefix sum below. */
  const int active = gid < rows * width;
  const uint i = row0 * width + (active ? gid : 0u);
  const int px = (int)(i % width), py = (int)(i / width);
  const uint row_start = (uint)py * width;
  const global GBufferTexel* g = right_g + i;
  float4 result = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  float4 albedo = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  int ok = 0;
  if (!active) {
    /* outside the launch's rows: neither written nor a hole */
  } else if (g->material_class == PX_CLASS_MISS) {
    /* The environment is at infinity: zero disparity, and with parallel eyes the same pixel
     * looks in the same direction, so the left eye's estimate for that pixel is exact reuse —
     * provided neither footprint holds anything but the environment. */
    if (px_window_misses(right_g, px, py, width, height) && px_window_misses(left_g, px, py, width, height)) {
      result = left_radiance[i];
      albedo = left_albedo[i];
      ok = 1;
    }
  } else if (g->material_class == PX_CLASS_DIFFUSE) {
    const float3 p = px_load3(g->pos);
    const float3 n = px_load3(g->normal);
    /* Project p into the left camera: image-plane coordinates along right/forward. */
    const float3 d = p - px_camera_origin(&left_cam);
    /* Size of one pixel at this depth, and how obliquely the left eye sees the surface. */
    const float footprint = g->depth * 2.0f * left_cam.tan_half_fov_y / (float)height;
    const float cos_view = fabs(dot(normalize(d), n));
    const float zf = dot(d, (float3)(left_cam.forward[0], left_cam.forward[1], left_cam.forward[2]));
    if (zf > 0.0f &&
        px_window_on_surface(right_g, px - 1, px + 1, py, width, height, p, n, g->depth, cos_view, footprint)) {
      const float sx = dot(d, (float3)(left_cam.right[0], left_cam.right[1], left_cam.right[2])) / zf;
      /* p lies at the right pixel's jitter position, and every left texel at the same position in
       * its own pixel (both eyes share the frame's jitter): subtracting it gives the left pixel
       * grid coordinate of the right pixel, whose two nearest left pixels are the taps. */
      const float fx =
          (sx / (left_cam.tan_half_fov_y * left_cam.aspect) + 1.0f) * 0.5f * (float)width - left_cam.jitter[0];
      const float x0f = floor(fx);
      const float a = fx - x0f;
      const int x0 = (int)x0f;
      float wsum = 0.0f;
      float3 acc = (float3)(0.0f, 0.0f, 0.0f);
      float3 acc_albedo = (float3)(0.0f, 0.0f, 0.0f);
      int rejected = 0;
      for (int k = 0; k < 2; ++k) {
        const int x = x0 + k;
        const float w = k == 0 ? 1.0f - a : a;
        if (w <= 0.0f) continue;
        if (x < 0 || x >= (int)width) {
          rejected = 1;
          continue;
        }
        const uint j = row_start + (uint)x;
        /* Conservative at silhouettes: if either neighbour sees another surface, the exact point
         * may be hidden from the left eye (a disocclusion edge), so the pixel is a hole. */
        if (!px_same_surface(left_g + j, p, n, g->depth, cos_view, footprint, PX_REPROJECT_MIN_COS,
                             PX_REPROJECT_FOOTPRINTS)) {
          rejected = 1;
          continue;
        }
        acc += w * left_radiance[j].xyz;
        acc_albedo += w * left_albedo[j].xyz;
        wsum += w;
      }
      /* Both taps' footprints must be pure as well (x0 - 1 .. x0 + 2 covers both windows). */
      if (!rejected && wsum > 0.0f &&
          px_window_on_surface(left_g, x0 - 1, x0 + 2, py, width, height, p, n, g->depth, cos_view, footprint)) {
        result = (float4)(acc / wsum, 1.0f);
        albedo = (float4)(acc_albedo / wsum, 1.0f);
        ok = 1;
      }
    }
  }
  if (active) {
    right_radiance[i] = result;
    right_albedo[i] = albedo;
  }
  const uint hole = active && !ok ? 1u : 0u;
  const uint before_and_mine = px_group_inclusive_scan(hole, scan);
  if (lid == PX_REPROJECT_GROUP - 1) group_base = before_and_mine ? atomic_add(hole_count, before_and_mine) : 0u;
  barrier(CLK_LOCAL_MEM_FENCE);
  if (hole) holes[group_base + before_and_mine - 1u] = i;
}
