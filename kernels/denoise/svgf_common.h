/* SVGF, spatiotemporal variance-guided filtering (Schied et al., HPG 2017): what its passes share.
 * The passes are programs of their own: svgf_temporal.cl (svgf_guide, svgf_temporal,
 * svgf_variance), svgf_atrous.cl (svgf_luma, the three a-trous variants, svgf_remodulate),
 * svgf_antialias.cl; seam_bilateral.cl is the seam filter of independently denoised strips.
 *
 * One eye, rows [p.row0, p.row0 + p.rows) of full-frame buffers. Passes, in order:
 *   svgf_guide      the G-buffer rows the spatial passes read, reduced to a 16-byte guide
 *                   texel per pixel (normal, signed depth);
 *   svgf_temporal   demodulate by albedo, reproject last frame's history through the previous
 *                   camera (2x2 bilinear taps, 3x3 fallback), accumulate colour and luminance
 *                   moments with alpha = max(alpha_min, 1/h) (at least
 *                   PX_SVGF_NEAR_MOTION_ALPHA on a still surface beside a moving object); the
 *                   environment's colour is accumulated too, its history found by direction;
 *   svgf_variance   variance from the moments, or a 7x7 bilateral spatial estimate while h < 4;
 *                   its colour is next frame's colour history (not the first a-trous step's);
 *   svgf_luma       before each a-trous step: the luminance its edge-stopping compares, each
 *                   pixel's prefiltered over its 3x3 same-surface neighbours;
 *   svgf_atrous     5x5 B3-spline a-trous steps (spacing 2^i) with normal, depth and luminance
 *                   edge-stopping; variance propagates as sum w^2 var / (sum w)^2;
 *   svgf_remodulate multiply the albedo back;
 *   svgf_antialias  temporal anti-aliasing of the result (the paper's last step): blend with
 *                   last frame's result, reprojected and clipped to the pixel's 3x3
 *                   neighbourhood, so that the per-frame jitter of the sample position
 *                   (CameraParams::jitter) averages into each pixel's footprint.
 * Every read of another pixel stays inside [lo_row, hi_row) and, for history, within
 * temporal_rows rows of the pixel: with independent seams those bounds are the strip, with
 * halo exchange the neighbours' rows have been copied in and the bounds are the image, and the
 * result does not depend on how the image was split.
 *
 * Buffers: illum float4 (rgb illumination, w = variance); moments float4 (m1, m2, history
 * length, w: 1 if the pixel is filtered, PX_SVGF_BORROWED for a silhouette pixel filtered with
 * a neighbour's geometry, else 0); guide float4 (shading normal, +depth where the
 * filter smooths the pixel, -depth where not: one load per tap where the GBufferTexel was 48
 * bytes, and the filtered flag without a second load from moments). The environment and
 * emitters are not filtered and never serve as taps: emitters pass through with their noisy
 * colour, the environment with its colour accumulated over frames (moments (0, 0, history
 * length, 0)). */
#ifndef PARALLAX_SVGF_COMMON_H
#define PARALLAX_SVGF_COMMON_H

#include "shared/types.h"
#include "denoise/svgf_constants.h"
#include "render/camera.h"
#include "scene/scene_view.h"
#include "math/exp.h"
#include "shading/bsdf.h" /* px_luminance */

/* Albedo used for demodulation: the path tracer's mean primary-hit albedo of the very samples
 * that made the pixel's radiance (the G-buffer's centre albedo is not: where the texture or the
 * surface changes inside a pixel, dividing by it scaled a channel by up to 1/albedo and the
 * filter spread that into neighbours). The floor only keeps the division finite: a channel
 * that dark reflected next to nothing, and multiplying it back gives next to nothing again. */
inline float3 px_demod_albedo(const global float4* albedo, uint i) {
  return fmax(albedo[i].xyz, (float3)(1e-3f, 1e-3f, 1e-3f));
}

inline int px_row_readable(int y, const SvgfParams* p) { return y >= (int)p->lo_row && y < (int)p->hi_row; }

/* Guide texels (see svgf_guide): is the pixel one the filter smooths, and its depth. */
inline int px_guide_filtered(float4 g) { return g.w > 0.0f; }
inline float px_guide_depth(float4 g) { return fabs(g.w); }

/* Index of the k-th (0..7, scan order) 8-neighbour of pixel (x, y), or -1 where it lies outside
 * the image or in a row that is not readable. */
inline int px_neighbour8(int x, int y, int k, const SvgfParams* p) {
  const int m = k < 4 ? k : k + 1; /* skip the centre of the 3x3 window */
  const int tx = x + m % 3 - 1, ty = y + m / 3 - 1;
  if (tx < 0 || tx >= (int)p->width || ty < 0 || ty >= (int)p->height || !px_row_readable(ty, p)) return -1;
  return ty * (int)p->width + tx;
}

/* The centre a PX_SVGF_BORROWED pixel (x, y) borrows: the index of its filtered 8-neighbour
 * nearest to the camera (at a silhouette against the sky or a farther surface, the object its
 * samples hit is the one in front), the first in scan order on equal depth; -1 if none. Reads
 * only guide texels of readable rows, so the choice does not depend on how the image is split. */
inline int px_borrowed_centre(const global float4* guide, int x, int y, const SvgfParams* p) {
  int best = -1;
  float best_depth = INFINITY;
  for (int k = 0; k < 8; ++k) {
    const int j = px_neighbour8(x, y, k, p);
    if (j < 0) continue;
    const float4 g = guide[j];
    if (px_guide_filtered(g) && g.w < best_depth) {
      best = j;
      best_depth = g.w;
    }
  }
  return best;
}

/* Where the current pixel whose G-buffer point lies in direction `d` from the previous camera's
 * origin was in the previous frame: continuous pixel-grid coordinates (*fx, *fy) of its image,
 * pixel (x, y) at (x, y). The point lies at the frame's jitter position inside its pixel
 * (p->jitter), not at the centre; taking the jitter back out gives where the pixel itself (its
 * footprint, which history averages over) was, so a still camera reads its own pixel's history
 * whatever the jitter. 0 when d points behind that camera. */
inline int px_previous_pixel(float3 d, const CameraParams* prev, const SvgfParams* p, float* fx, float* fy) {
  const float zf = dot(d, (float3)(prev->forward[0], prev->forward[1], prev->forward[2]));
  if (!(zf > 0.0f)) return 0;
  const float sx = dot(d, (float3)(prev->right[0], prev->right[1], prev->right[2])) / zf;
  const float sy = dot(d, (float3)(prev->up[0], prev->up[1], prev->up[2])) / zf;
  *fx = (sx / (prev->tan_half_fov_y * prev->aspect) + 1.0f) * 0.5f * (float)p->width - p->jitter[0];
  *fy = (1.0f - sy / prev->tan_half_fov_y) * 0.5f * (float)p->height - p->jitter[1];
  return 1;
}

/* Is previous-frame pixel (tx, ty) one that history may be read from for a pixel of row y:
 * inside the image, within temporal_rows rows, in readable rows. */
inline int px_history_tap_readable(int tx, int ty, int y, const SvgfParams* p) {
  return tx >= 0 && tx < (int)p->width && ty >= 0 && ty < (int)p->height && abs(ty - y) <= (int)p->temporal_rows &&
         px_row_readable(ty, p);
}

/* Tap k (0..3) of the 2x2 bilinear footprint of continuous pixel-grid position (fx, fy) in the
 * previous frame: its index *j and weight *w; 0 where the weight is 0 or the texel may not be
 * read as history for a pixel of row y (px_history_tap_readable). */
inline int px_bilinear_history_tap(float fx, float fy, int k, int y, const SvgfParams* p, uint* j, float* w) {
  const float x0f = floor(fx), y0f = floor(fy);
  const float ax = fx - x0f, ay = fy - y0f;
  const int tx = (int)x0f + (k & 1), ty = (int)y0f + (k >> 1);
  *w = ((k & 1) ? ax : 1.0f - ax) * ((k >> 1) ? ay : 1.0f - ay);
  if (*w <= 0.0f || !px_history_tap_readable(tx, ty, y, p)) return 0;
  *j = (uint)ty * p->width + (uint)tx;
  return 1;
}

/* Is pixel (tx, ty) inside the image and in a readable row (a spatial pass's tap)? */
inline int px_pixel_readable(int tx, int ty, const SvgfParams* p) {
  return tx >= 0 && tx < (int)p->width && ty >= 0 && ty < (int)p->height && px_row_readable(ty, p);
}

/* cos^sigma_n: the exponent is almost always an integer (128, 4...): a few multiplications,
 * where pow is a log and an exp (PoCL's pown and pow are library calls costing about as much as
 * a whole a-trous tap). */
inline int px_integer_exponent(float sigma_n) {
  return sigma_n >= 0.0f && sigma_n <= 1024.0f && floor(sigma_n) == sigma_n;
}

/* (c^k1, c^k2) for integers k1, k2 <= 1024 by repeated squaring, one chain of squares for both:
 * log2(max(k1, k2)) multiplications (7 for the usual 128 and 4). Squares below 1e-10 are
 * flushed to zero: such a weight cannot change a sum whose centre weight is 0.14, and subnormal
 * products cost x86 CPUs a microcode assist each. */
inline float2 px_pow_int2(float c, uint k1, uint k2) {
  float2 r = (float2)(1.0f, 1.0f);
  while ((k1 | k2) != 0u) {
    if (k1 & 1u) r.x *= c;
    if (k2 & 1u) r.y *= c;
    c = c < 1e-10f ? 0.0f : c * c;
    k1 >>= 1;
    k2 >>= 1;
  }
  return r;
}

/* The general case, kept out of line so that the filters' inlined tap code stays small. */
__attribute__((noinline)) float2 px_pow2(float c, float e1, float e2) { return (float2)(pow(c, e1), pow(c, e2)); }

/* (cos^e1, cos^e2) for a cosine c (negative: 0). */
inline float2 px_normal_weights(float c, float e1, float e2) {
  c = fmax(0.0f, c);
  if (px_integer_exponent(e1) && px_integer_exponent(e2)) return px_pow_int2(c, (uint)e1, (uint)e2);
  return px_pow2(c, e1, e2);
}

inline float px_normal_weight(float c, float sigma_n) { return px_normal_weights(c, sigma_n, sigma_n).x; }

/* Exponent of the depth edge-stopping weight between centre (depth z, gradient grad per pixel)
 * and a tap at pixel offset (dx, dy): w_z = exp(-this). */
inline float px_depth_term(float tap_depth, float z, float2 grad, float dx, float dy, const SvgfParams* p) {
  return fabs(z - tap_depth) / (p->sigma_z * fabs(grad.x * dx + grad.y * dy) + 1e-3f * z + 1e-6f);
}

/* Normal and depth edge-stopping weight of a tap with guide texel `t` (0 for unfiltered taps),
 * with an extra exponent (the luminance term) folded into the same exp. */
inline float px_geometry_weight_x(float4 t, float3 n, float z, float2 grad, float dx, float dy, const SvgfParams* p,
                                  float extra) {
  if (!px_guide_filtered(t)) return 0.0f;
  return px_normal_weight(dot(n, t.xyz), p->sigma_n) * px_exp(-(px_depth_term(t.w, z, grad, dx, dy, p) + extra));
}

/* The same weight twice: (strict, loose) = with the normal exponent sigma_n and with the loose
 * one used for isolated pixels (see svgf_atrous), sharing the depth and luminance terms.
 * Always inlined: PoCL's inliner otherwise leaves it a call per tap, with its arguments passed
 * through the stack (docs/measurements.md, SVGF a-trous on PoCL). */
__attribute__((always_inline)) inline float2 px_geometry_weights(float4 t, float3 n, float z, float2 grad, float dx,
                                                                 float dy, const SvgfParams* p, float extra) {
  if (!px_guide_filtered(t)) return (float2)(0.0f, 0.0f);
  const float rest = px_exp(-(px_depth_term(t.w, z, grad, dx, dy, p) + extra));
  return px_normal_weights(dot(n, t.xyz), p->sigma_n, fmin(p->sigma_n, PX_SVGF_LOOSE_SIGMA_N)) * rest;
}

inline float px_geometry_weight(float4 t, float3 n, float z, float2 grad, float dx, float dy, const SvgfParams* p) {
  return px_geometry_weight_x(t, n, z, grad, dx, dy, p, 0.0f);
}

/* Screen-space depth gradient at pixel (x, y) from its readable neighbours (one-sided at the
 * edge of the readable rows or of the image). */
inline float2 px_depth_gradient(const global float4* guide, int x, int y, const SvgfParams* p) {
  const int xl = max(x - 1, 0), xr = min(x + 1, (int)p->width - 1);
  const int yu = px_row_readable(y - 1, p) && y > 0 ? y - 1 : y;
  const int yd = px_row_readable(y + 1, p) && y + 1 < (int)p->height ? y + 1 : y;
  const uint w = p->width;
  float gx = 0.0f, gy = 0.0f;
  if (xr > xl)
    gx = (px_guide_depth(guide[(uint)y * w + (uint)xr]) - px_guide_depth(guide[(uint)y * w + (uint)xl])) /
         (float)(xr - xl);
  if (yd > yu)
    gy = (px_guide_depth(guide[(uint)yd * w + (uint)x]) - px_guide_depth(guide[(uint)yu * w + (uint)x])) /
         (float)(yd - yu);
  return (float2)(gx, gy);
}

/* What every spatial pass needs about its centre pixel for edge-stopping. */
typedef struct FilterCentre {
  float3 n;    /* normal */
  float z;     /* depth */
  float2 grad; /* screen-space depth gradient */
  float l;     /* luminance of the value being filtered */
} FilterCentre;

inline FilterCentre px_filter_centre(const global float4* guide, int x, int y, float3 value, const SvgfParams* p) {
  const float4 g = guide[(uint)y * p->width + (uint)x];
  FilterCentre c;
  c.n = g.xyz;
  c.z = px_guide_depth(g);
  c.grad = px_depth_gradient(guide, x, y, p);
  c.l = px_luminance(value);
  return c;
}

/* The edge-stopping centre of pixel (x, y) filtering `value`: its own guide texel, or for a
 * borrowing pixel (`borrowed` = px_borrowed_centre) the lender's normal, depth and gradient. */
inline FilterCentre px_filter_centre_at(const global float4* guide, int x, int y, int borrowed, float3 value,
                                        const SvgfParams* p) {
  if (borrowed < 0) return px_filter_centre(guide, x, y, value, p);
  return px_filter_centre(guide, borrowed % (int)p->width, borrowed / (int)p->width, value, p);
}

/* The temporal gradients' lambda at pixel (x, y) (gradient_filter.cl: the stratum's filtered
 * sum of |shade now - shade last frame| over the sum of the larger of the two): the share of the
 * history that the lighting's change since last frame made untrue, 0 where nothing changed (or
 * no gradients: `gradient` null), 1 at most. */
inline float px_gradient_lambda(const global float4* gradient, uint x, uint y, uint width) {
  if (!gradient) return 0.0f;
  const uint strata_w = (width + PX_GRADIENT_STRATUM - 1u) / PX_GRADIENT_STRATUM;
  const float4 g = gradient[(y / PX_GRADIENT_STRATUM) * strata_w + x / PX_GRADIENT_STRATUM];
  return g.z > 0.0f ? fmin(1.0f, 1.0f * g.w / g.z) : 0.0f;
}

/* How much brighter the light at pixel (x, y) is than last frame's (the stratum's filtered
 * shades now / last frame's, the same paths): the history is scaled by it before blending, so
 * it follows a light that changes smoothly instead of lagging. 1 without gradients, and where
 * the two sums say too little (either below PX_GRADIENT_MIN_SHADE of the larger). */
inline float px_gradient_ratio(const global float4* gradient, uint x, uint y, uint width) {
  if (!gradient) return 1.0f;
  const uint strata_w = (width + PX_GRADIENT_STRATUM - 1u) / PX_GRADIENT_STRATUM;
  const float4 g = gradient[(y / PX_GRADIENT_STRATUM) * strata_w + x / PX_GRADIENT_STRATUM];
  if (!(g.x > PX_GRADIENT_MIN_SHADE * g.z && g.y > PX_GRADIENT_MIN_SHADE * g.z)) return 1.0f;
  return clamp(g.x / g.y, PX_GRADIENT_MIN_RATIO, 1.0f / PX_GRADIENT_MIN_RATIO);
}

#endif /* PARALLAX_SVGF_COMMON_H */
