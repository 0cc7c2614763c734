/* The seam filter of independently denoised strips (svgf_common.h for its edge-stopping weights). */
#include "denoise/svgf_common.h"

/* The paper's optional seam filter ("--seams bilateral"): after independent per-strip
 * denoising, a 5x5 bilateral (normal, depth, luminance) blur of the rows within `band` rows of
 * a seam. Rows across the seam were copied in beforehand. */
kernel void seam_bilateral(global float4* out_color, const global float4* color, const global float4* guide,
                           SvgfParams p, int seam_above, int seam_below, int band) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  const int near_above = seam_above >= 0 && abs(y - seam_above) < band;
  const int near_below = seam_below >= 0 && abs(y - seam_below) < band;
  if (!(near_above || near_below) || !px_guide_filtered(guide[i])) {
    out_color[i] = color[i];
    return;
  }
  const FilterCentre fc = px_filter_centre(guide, x, y, color[i].xyz, &p);
  float wsum = 0.0f;
  float3 csum = (float3)(0.0f, 0.0f, 0.0f);
  for (int dy = -2; dy <= 2; ++dy) {
    const int ty = y + dy;
    if (ty < 0 || ty >= (int)p.height || !px_row_readable(ty, &p)) continue;
    for (int dx = -2; dx <= 2; ++dx) {
      const int tx = x + dx;
      if (tx < 0 || tx >= (int)p.width) continue;
      const uint j = (uint)ty * p.width + (uint)tx;
      const float3 t = color[j].xyz;
      float w = px_exp(-(float)(dx * dx + dy * dy) / 4.0f);
      if (dx != 0 || dy != 0)
        w *= px_geometry_weight(guide[j], fc.n, fc.z, fc.grad, (float)dx, (float)dy, &p) *
             px_exp(-fabs(fc.l - px_luminance(t)) / (0.25f * fc.l + 1e-3f));
      wsum += w;
      csum += w * t;
    }
  }
  out_color[i] = (float4)(csum / wsum, 1.0f);
}
