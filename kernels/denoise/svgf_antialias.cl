/* SVGF's last pass (svgf_common.h): temporal anti-aliasing of the remodulated result. */
#include "denoise/svgf_common.h"
#include "pipeline/texel_motion.h"

/* Temporal anti-aliasing of the remodulated radiance `color`, rows [p.row0, p.row0 + p.rows).
 *
 * Each frame samples every pixel once at the frame's jitter position; SVGF's history is kept
 * per surface, so a pixel on an edge (an emitter's rim, a silhouette) restarts it whenever its
 * sample lands on the other side, and shows one side or the other: jagged edges and, at 1 spp,
 * a light whose visible area changes by whole rows and columns with the jitter (cornell's
 * mean came out too bright in one frame; docs/measurements.md, temporal anti-aliasing). Here the final radiance itself
 * is averaged over frames, whatever surface each sample saw: last frame's result, reprojected through the G-buffer
 * point (or the direction of a miss) into the previous camera with the jitter taken out (px_previous_pixel) and read
 * with 2x2 bilinear taps, is blended as mix(history, color, max(alpha, 1 / history length, PX_TAA_MOTION_ALPHA x the
 * pixels moved (at most PX_TAA_MOTION_ALPHA_MAX))): a still pixel averages its jitter positions over many frames, a
 * moving one keeps less of a history that each bilinear read blurs and that lags behind the view (docs/measurements.md,
 * temporal anti-aliasing). The history is first clipped to mean +- PX_TAA_CLIP_SIGMA standard deviations of the current
 * 3x3 neighbourhood per YCoCg axis, so that what moved or was disoccluded cannot leave a trail: on an edge the
 * neighbourhood holds both sides and the average passes. Reads `color` in rows y - 1 .. y + 1 (readable ones) and
 * `prev` within temporal_rows rows. Writes the result to `resolved` (w = 1) and the new history (rgb, length) to
 * `history`. */
/* Luma and two chroma differences (YCoCg): the history is clipped in these axes, not in R, G
 * and B. A box per RGB channel around a grey neighbourhood still holds a saturated colour's
 * brightest and darkest channels, so a red object that moved on left a reddish trail on a grey
 * edge behind it (the range of R and that of B each pass); in YCoCg the neighbourhood's narrow
 * chroma range removes the hue. */
inline float3 px_ycocg(float3 c) {
  return (float3)(0.25f * c.x + 0.5f * c.y + 0.25f * c.z, 0.5f * c.x - 0.5f * c.z,
                  -0.25f * c.x + 0.5f * c.y - 0.25f * c.z);
}
inline float3 px_from_ycocg(float3 c) { return (float3)(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z); }
kernel void svgf_antialias(global float4* resolved, global float4* history, const global float4* color,
                           const global float4* prev, const global GBufferTexel* gbuf, SvgfParams p,
                           CameraParams prev_cam, uint have_history, float alpha, const global float4* motion,
                           const global GBufferTexel* prev_gbuf, const global float4* tri_motion,
                           const global SceneInstances* instances, const global float4* gradient) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  const float3 c = color[i].xyz;
  float3 out = c;
  float len = 1.0f;
  if (have_history) {
    const global GBufferTexel* g = gbuf + i;
    const float3 at = motion && motion[i].w > 0.0f ? motion[i].xyz : px_load3(g->pos);
    const float3 d = g->material_class == PX_CLASS_MISS ? px_load3(g->pos) : at - px_camera_origin(&prev_cam);
    float fx, fy;
    int found = px_previous_pixel(d, &prev_cam, &p, &fx, &fy);
    /* Around a moving object (animated scenes), a pixel whose sample saw the still background
     * cannot trust the history at its own place when a moving object was within a texel of
     * it last frame: that history holds the object, which has gone (behind its trailing edge)
     * or is arriving. Such a pixel, and one whose texel there was the moving object (on the
     * edge then as well), takes its history from where the object's edge was: the front-most
     * moving neighbour's motion, less the neighbour's offset (Karis 2014's velocity dilation).
     * Under a rigid motion the pixel covers the object now as much as that place did then, so
     * a moving edge anti-aliases and no object colour stays behind. A pixel with a stale
     * history and no moving neighbour now (the object left it altogether) starts over, as
     * SVGF's history does where the surface changed. Only those: when every background pixel
     * beside the object followed it, the image as a whole got worse. Following only the object's
     * texels left the trailing column with the cube's colour (docs/measurements.md, velocity
     * dilation). */
    if (motion && tri_motion && found && motion[i].w != PX_MOTION_MOVED) {
      int own_stale = 0;
      const int ox = (int)floor(fx + 0.5f), oy = (int)floor(fy + 0.5f);
      for (int sy = -1; sy <= 1; ++sy)
        for (int sx = -1; sx <= 1; ++sx)
          if (px_history_tap_readable(ox + sx, oy + sy, y, &p) &&
              px_texel_moved(tri_motion, instances, prev_gbuf + (uint)(oy + sy) * p.width + (uint)(ox + sx)))
            own_stale = 1;
      int bx = x, by = y;
      float nearest = g->material_class == PX_CLASS_MISS ? INFINITY : g->depth;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int tx = x + dx, ty = y + dy;
          if ((dx == 0 && dy == 0) || !px_pixel_readable(tx, ty, &p)) continue;
          const global GBufferTexel* q = gbuf + (uint)ty * p.width + (uint)tx;
          if (q->material_class != PX_CLASS_MISS && q->depth < nearest &&
              motion[(uint)ty * p.width + (uint)tx].w == PX_MOTION_MOVED) {
            nearest = q->depth;
            bx = tx;
            by = ty;
          }
        }
      int dilated = 0;
      if (bx != x || by != y) {
        const uint b = (uint)by * p.width + (uint)bx;
        float gx, gy;
        if (motion[b].w > 0.0f &&
            px_previous_pixel(motion[b].xyz - px_camera_origin(&prev_cam), &prev_cam, &p, &gx, &gy)) {
          gx -= (float)(bx - x);
          gy -= (float)(by - y);
          const int cx = (int)floor(gx + 0.5f), cy = (int)floor(gy + 0.5f);
          if (px_history_tap_readable(cx, cy, y, &p) &&
              (own_stale || px_texel_moved(tri_motion, instances, prev_gbuf + (uint)cy * p.width + (uint)cx))) {
            fx = gx;
            fy = gy;
            dilated = 1;
          }
        }
      }
      if (own_stale && !dilated) found = 0;
    }
    if (found) {
      float3 hist = (float3)(0.0f, 0.0f, 0.0f);
      float hist_len = 0.0f, wsum = 0.0f;
      for (int k = 0; k < 4; ++k) {
        uint j;
        float w;
        if (!px_bilinear_history_tap(fx, fy, k, y, &p, &j, &w)) continue;
        const float4 h = prev[j];
        hist += w * h.xyz;
        hist_len += w * h.w;
        wsum += w;
      }
      if (wsum > 0.0f) {
        hist /= wsum;
        /* The current 3x3 neighbourhood's mean and spread, per channel. */
        float3 m1 = (float3)(0.0f, 0.0f, 0.0f), m2 = m1;
        float count = 0.0f;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int tx = x + dx, ty = y + dy;
            if (!px_pixel_readable(tx, ty, &p)) continue;
            const float3 t = px_ycocg(color[(uint)ty * p.width + (uint)tx].xyz);
            m1 += t;
            m2 += t * t;
            count += 1.0f;
          }
        m1 /= count;
        const float3 sigma = sqrt(fmax(m2 / count - m1 * m1, (float3)(0.0f, 0.0f, 0.0f)));
        /* Temporal gradients, as in svgf_temporal (not on an object that moved). */
        const global float4* grad = motion && motion[i].w == PX_MOTION_MOVED ? 0 : gradient;
        hist *= px_gradient_ratio(grad, (uint)x, (uint)y, p.width);
        hist = px_from_ycocg(clamp(px_ycocg(hist), m1 - PX_TAA_CLIP_SIGMA * sigma, m1 + PX_TAA_CLIP_SIGMA * sigma));
        len = fmin((float)p.max_history, floor(hist_len / wsum + 0.5f) + 1.0f);
        /* Motion: resampled history blurs a little more with every bilinear read and lags behind
         * what the view now shows, so a pixel that moved trusts it less. */
        const float moved = length((float2)(fx - (float)x, fy - (float)y));
        float a = fmax(fmax(alpha, 1.0f / len), fmin(PX_TAA_MOTION_ALPHA_MAX, PX_TAA_MOTION_ALPHA * moved));
        const float lambda = fmin(1.0f, PX_GRADIENT_TAA_GAIN * px_gradient_lambda(grad, (uint)x, (uint)y, p.width));
        if (lambda > 0.0f) {
          a = mix(a, 1.0f, lambda);
          len = fmax(1.0f, floor(len * (1.0f - lambda) + 0.5f)); /* a whole count, as everywhere */
        }
        out = mix(hist, c, a);
        if (!(isfinite(out.x) && isfinite(out.y) && isfinite(out.z))) {
          out = c;
          len = 1.0f;
        }
      }
    }
  }
  resolved[i] = (float4)(out, 1.0f);
  history[i] = (float4)(out, len);
}
