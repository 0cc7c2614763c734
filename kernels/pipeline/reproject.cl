/* Stage 4: spatial reprojection left -> right, and the hole list for stage 5.
 *
 * Parallel stereo cameras have horizontal epipolar lines: the left-eye image of a right-eye
 * pixel's surface point lies on the same row. So each right pixel gathers from its own row of
 * the left eye, which the same device owns: no data crosses devices. The two left pixels
 * around the projected position are linearly weighted; both must see the same surface as the
 * right pixel (normal, tangent-plane distance and footprint tolerances) and be diffuse.
 * Otherwise — a silhouette, a disocclusion, the image border, or a right pixel that is not
 * diffuse — the pixel is a hole. Background pixels
 * (both eyes miss the scene) are copied from the same left pixel. */
#include "shared/types.h"
#include "render/camera.h"
#include "scene/scene_view.h"

/* Same surface: normals agree, the tap lies on p's tangent plane (within a fraction of the
 * depth), and within a few pixel footprints of p along the plane. The footprint grows as the
 * surface turns away from the eye (1 / cos), which a plain distance threshold ignores. */
inline int px_same_surface(const global GBufferTexel* a, float3 p, float3 n, float depth, float cos_view,
                           float footprint) {
  if (a->material_class != PX_CLASS_DIFFUSE) return 0;
  const float3 q = px_load3(a->pos);
  const float3 m = px_load3(a->normal);
  const float3 d = q - p;
  const float in_plane_limit = PX_REPROJECT_FOOTPRINTS * footprint / fmax(cos_view, 0.1f);
  return dot(m, n) > PX_REPROJECT_MIN_COS && fabs(dot(d, n)) < PX_REPROJECT_REL_DIST * depth &&
         length(d) < in_plane_limit;
}

/* Rows [row0, row0 + rows). All images are full-frame. right_radiance: written for reprojected
 * pixels (holes get 0 and are filled by stage 5). holes/hole_count: the compacted list of hole
 * pixel indices (hole_count must be zero before the launch). */
kernel void reproject(global float4* right_radiance, global uint* holes, volatile global uint* hole_count,
                      const global float4* left_radiance, const global GBufferTexel* left_g,
                      const global GBufferTexel* right_g, uint row0, uint rows, CameraParams left_cam) {
  const uint gid = get_global_id(0);
  const uint width = left_cam.width;
  if (gid >= rows * width) return;
  const uint i = row0 * width + gid;
  const uint row_start = (i / width) * width;
  const global GBufferTexel* g = right_g + i;
  float4 result = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  int ok = 0;
  if (g->material_class == PX_CLASS_MISS && left_g[i].material_class == PX_CLASS_MISS) {
    /* The environment is at infinity: zero disparity, and with parallel eyes the same pixel
     * looks in the same direction, so the left eye's estimate for that pixel is exact reuse. */
    result = left_radiance[i];
    ok = 1;
  } else if (g->material_class == PX_CLASS_DIFFUSE) {
    const float3 p = px_load3(g->pos);
    const float3 n = px_load3(g->normal);
    /* Project p into the left camera: image-plane coordinates along right/forward. */
    const float3 d = p - px_camera_origin(&left_cam);
    /* Size of one pixel at this depth, and how obliquely the left eye sees the surface. */
    const float footprint = g->depth * 2.0f * left_cam.tan_half_fov_y / (float)left_cam.height;
    const float cos_view = fabs(dot(normalize(d), n));
    const float zf = dot(d, (float3)(left_cam.forward[0], left_cam.forward[1], left_cam.forward[2]));
    if (zf > 0.0f) {
      const float sx = dot(d, (float3)(left_cam.right[0], left_cam.right[1], left_cam.right[2])) / zf;
      const float fx = (sx / (left_cam.tan_half_fov_y * left_cam.aspect) + 1.0f) * 0.5f * (float)width - 0.5f;
      const float x0f = floor(fx);
      const float a = fx - x0f;
      const int x0 = (int)x0f;
      float wsum = 0.0f;
      float3 acc = (float3)(0.0f, 0.0f, 0.0f);
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
        if (!px_same_surface(left_g + j, p, n, g->depth, cos_view, footprint)) {
          rejected = 1;
          continue;
        }
        acc += w * left_radiance[j].xyz;
        wsum += w;
      }
      if (!rejected && wsum > 0.0f) {
        result = (float4)(acc / wsum, 1.0f);
        ok = 1;
      }
    }
  }
  right_radiance[i] = result;
  if (!ok) holes[atomic_inc(hole_count)] = i;
}
