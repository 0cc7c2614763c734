/* Temporal gradients, the filtering half: the strata's sparse differences (temporal_gradient.cl)
 * spread over their neighbours by PX_GRADIENT_STEPS edge-stopped a-trous steps on the strata
 * grid, so that a stratum whose pick saw no change, or had none to see, still learns that the
 * light around it changed, and one noisy difference does not drop a history alone.
 *
 * Each stratum holds its pick's (shade now, shade last frame, the larger, |difference|), zeros
 * without a valid pick, and a step averages them over its neighbours. A step is a
 * 3x3 B-spline kernel (1 2 1) at spacing `step` strata, weighted by how alike the strata's centre
 * texels are (normal and depth; the environment only with the environment), normalised by the
 * weights of the taps present. svgf_common.h reads the result: the ratio of the first two (how
 * the light changed) and of the last two (lambda: the share of the history to drop). Ratios of
 * weighted sums, so strata without a valid pick count for nothing. */
#include "shared/types.h"
#include "denoise/svgf_constants.h"

/* The G-buffer texel at the centre of stratum (sx, sy), clamped into the readable rows. */
inline const global GBufferTexel* px_stratum_texel(const global GBufferTexel* gbuf, uint sx, uint sy,
                                                   const GradientParams* gp) {
  const uint x = min(sx * PX_GRADIENT_STRATUM + 1u, gp->width - 1u);
  const uint y = clamp(sy * PX_GRADIENT_STRATUM + 1u, gp->lo_row, gp->hi_row - 1u);
  return gbuf + y * gp->width + x;
}

/* How much stratum q's gradient says about stratum c's surface: 1 for the same plane, falling
 * with the angle between the normals and the relative distance between the depths. */
inline float px_gradient_geometry_weight(const global GBufferTexel* c, const global GBufferTexel* q) {
  const int cm = c->material_class == PX_CLASS_MISS, qm = q->material_class == PX_CLASS_MISS;
  if (cm || qm) return cm && qm ? 1.0f : 0.0f;
  const float cosine =
      fmax(0.0f, c->normal[0] * q->normal[0] + c->normal[1] * q->normal[1] + c->normal[2] * q->normal[2]);
  float wn = cosine * cosine; /* cos^32 by five squarings (PX_GRADIENT_SIGMA_N) */
  wn *= wn;
  wn *= wn;
  wn *= wn;
  wn *= wn;
  const float dz = fabs(c->depth - q->depth) / (PX_GRADIENT_REL_DEPTH * fmax(fmin(c->depth, q->depth), 1e-6f));
  return dz < 1.0f ? wn * (1.0f - dz) : 0.0f;
}

/* One a-trous step over strata rows [s_row0, s_row0 + s_rows), reading `in` within [s_lo, s_hi). */
kernel void gradient_atrous(global float4* out, const global float4* in, const global GBufferTexel* gbuf,
                            GradientParams gp) {
  const uint gid = get_global_id(0);
  if (gid >= gp.s_rows * gp.strata_w) return;
  const uint sx = gid % gp.strata_w, sy = gp.s_row0 + gid / gp.strata_w;
  const global GBufferTexel* c = px_stratum_texel(gbuf, sx, sy, &gp);
  float4 sum = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  float wsum = 0.0f;
  for (int dy = -1; dy <= 1; ++dy) {
    const int ty = (int)sy + dy * (int)gp.step;
    if (ty < (int)gp.s_lo || ty >= (int)gp.s_hi) continue;
    for (int dx = -1; dx <= 1; ++dx) {
      const int tx = (int)sx + dx * (int)gp.step;
      if (tx < 0 || tx >= (int)gp.strata_w) continue;
      const float k = (dx == 0 ? 2.0f : 1.0f) * (dy == 0 ? 2.0f : 1.0f);
      const float w = k * px_gradient_geometry_weight(c, px_stratum_texel(gbuf, (uint)tx, (uint)ty, &gp));
      if (w <= 0.0f) continue;
      sum += w * in[(uint)ty * gp.strata_w + (uint)tx];
      wsum += w;
    }
  }
  out[sy * gp.strata_w + sx] = wsum > 0.0f ? sum / wsum : (float4)(0.0f, 0.0f, 0.0f, 0.0f);
}
