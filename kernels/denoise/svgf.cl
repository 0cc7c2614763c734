/* Spatiotemporal variance-guided filtering (Schied et al., HPG 2017), one eye, rows
 * [p.row0, p.row0 + p.rows) of full-frame buffers. Passes, in order:
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
#include "shared/types.h"
#include "render/camera.h"
#include "scene/scene_view.h"
#include "math/exp.h"
#include "pipeline/texel_motion.h"

inline float px_lum(float3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

/* Surfaces the filter smooths. Specular ones (mirror, glass) too: their noise at low sample counts
 * is worse to look at than the blur of what they reflect or refract. */
inline int px_filtered_class(uint c) {
  return c == PX_CLASS_DIFFUSE || c == PX_CLASS_GLOSSY || c == PX_CLASS_MIRROR || c == PX_CLASS_DIELECTRIC;
}

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

/* Is history texel `q` the same surface as the current pixel (world point pos, normal n,
 * distance `expected` from the previous camera)? */
inline int px_history_matches(const global GBufferTexel* q, float3 n, float expected) {
  if (!px_filtered_class(q->material_class)) return 0;
  return fabs(q->depth - expected) < 0.05f * expected && dot(px_load3(q->normal), n) > 0.9f;
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

/* The environment is not filtered, but it is accumulated over frames: at 1 spp every pixel on
 * the horizon (or the sun's rim) is one jittered sample of a step, and left alone the edge
 * crawls from frame to frame. The environment is at infinity, so its history is found by
 * direction alone (the G-buffer keeps a miss's direction in pos), 2x2 bilinear taps on texels
 * that were the environment too, and not a borrowing silhouette pixel (whose history is
 * illumination, not radiance). Radiance, not illumination: the colour blends like the
 * surfaces' with alpha = max(alpha, 1 / history length); the length rides in moments.z. */
inline float4 px_environment_temporal(float3 c, const global GBufferTexel* g, int y, const global GBufferTexel* prev_gbuf,
                                      const global float4* prev_illum, const global float4* prev_moments,
                                      const SvgfParams* p, const CameraParams* prev_cam) {
  float fx, fy;
  if (!px_previous_pixel(px_load3(g->pos), prev_cam, p, &fx, &fy)) return (float4)(c, 1.0f);
  float3 hist = (float3)(0.0f, 0.0f, 0.0f);
  float hist_len = 0.0f, wsum = 0.0f;
  for (int k = 0; k < 4; ++k) {
    uint j;
    float w;
    if (!px_bilinear_history_tap(fx, fy, k, y, p, &j, &w)) continue;
    if (prev_gbuf[j].material_class != PX_CLASS_MISS || prev_moments[j].w != 0.0f) continue;
    hist += w * prev_illum[j].xyz;
    hist_len += w * prev_moments[j].z;
    wsum += w;
  }
  if (wsum <= 0.0f) return (float4)(c, 1.0f);
  const float len = fmin((float)p->max_history, floor(hist_len / wsum + 0.5f) + 1.0f);
  return (float4)(mix(hist / wsum, c, fmax(p->alpha, 1.0f / len)), len);
}

kernel void svgf_temporal(global float4* out_illum, global float4* out_moments, const global float4* color,
                          const global float4* albedo, const global GBufferTexel* gbuf, const global GBufferTexel* prev_gbuf,
                          const global float4* prev_illum, const global float4* prev_moments, SvgfParams p,
                          CameraParams prev_cam, uint have_history, const global float4* guide,
                          const global float4* motion) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int y = (int)(i / p.width);
  const global GBufferTexel* g = gbuf + i;
  const float3 c = color[i].xyz;
  if (!px_filtered_class(g->material_class)) {
    /* A silhouette pixel whose samples all hit a filtered surface borrows a neighbour's
     * geometry (PX_SVGF_BORROWED); it has no geometry of its own to match history with, so its
     * history starts over every frame. */
    if (albedo[i].w >= PX_SVGF_BORROW_COVERAGE && px_borrowed_centre(guide, (int)(i % p.width), y, &p) >= 0) {
      const float3 illum = c / px_demod_albedo(albedo, i);
      const float l = px_lum(illum);
      out_illum[i] = (float4)(illum, 0.0f);
      out_moments[i] = (float4)(l, l * l, 1.0f, PX_SVGF_BORROWED);
      return;
    }
    /* Emitters pass through; the environment is accumulated (colour, history length). */
    const float4 env = g->material_class == PX_CLASS_MISS && have_history
                           ? px_environment_temporal(c, g, y, prev_gbuf, prev_illum, prev_moments, &p, &prev_cam)
                           : (float4)(c, 1.0f);
    out_illum[i] = (float4)(env.xyz, 0.0f);
    out_moments[i] = (float4)(0.0f, 0.0f, env.w, 0.0f);
    return;
  }
  const float3 illum = c / px_demod_albedo(albedo, i);
  const float l = px_lum(illum);

  float3 hist = (float3)(0.0f, 0.0f, 0.0f);
  float2 hist_m = (float2)(0.0f, 0.0f);
  float hist_len = 0.0f, wsum = 0.0f;
  if (have_history) {
    /* Where the point was: through its object's motion in an animated scene (motion.cl). */
    const float3 pos = motion ? motion[i].xyz : px_load3(g->pos);
    const float3 n = px_load3(g->normal);
    const float3 d = pos - px_camera_origin(&prev_cam);
    const float expected = length(d);
    float fx, fy;
    if (px_previous_pixel(d, &prev_cam, &p, &fx, &fy)) {
      /* 2x2 bilinear taps, each kept only on the same surface. */
      for (int k = 0; k < 4; ++k) {
        uint j;
        float w;
        if (!px_bilinear_history_tap(fx, fy, k, y, &p, &j, &w)) continue;
        if (!px_history_matches(prev_gbuf + j, n, expected)) continue;
        hist += w * prev_illum[j].xyz;
        hist_m += w * prev_moments[j].xy;
        hist_len += w * prev_moments[j].z;
        wsum += w;
      }
      /* 3x3 fallback around the nearest texel: thin features and edges that no bilinear tap
       * matched may still have valid neighbours. */
      if (wsum <= 0.0f) {
        const int cx = (int)floor(fx + 0.5f), cy = (int)floor(fy + 0.5f);
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int tx = cx + dx, ty = cy + dy;
            if (!px_history_tap_readable(tx, ty, y, &p)) continue;
            const uint j = (uint)ty * p.width + (uint)tx;
            if (!px_history_matches(prev_gbuf + j, n, expected)) continue;
            hist += prev_illum[j].xyz;
            hist_m += prev_moments[j].xy;
            hist_len += prev_moments[j].z;
            wsum += 1.0f;
          }
      }
    }
  }
  float len;
  float3 out;
  float2 m;
  const float2 cur_m = (float2)(l, l * l);
  if (wsum > 0.0f) {
    hist /= wsum;
    hist_m /= wsum;
    len = fmin((float)p.max_history, floor(hist_len / wsum + 0.5f) + 1.0f);
    float a = fmax(p.alpha, 1.0f / len);
    /* Beside a moving object a still surface's illumination changes from frame to frame: the
     * object's contact shadow and the light it reflects move with it. Its history lags there
     * (trail test, 8 spp, when this came: the floor the cube left at 4.6x the still run's error
     * with the usual floor of 0.2, 3.1x with this; the floor beyond the swept region -18%), so
     * there it keeps at most half. A stand-in for a temporal gradient (A-SVGF), which would also catch a
     * shadow cast far from its object and need no reach in pixels. */
    if (motion && motion[i].w == PX_MOTION_STILL) {
      const int x0 = (int)(i % p.width);
      for (int dy = -PX_SVGF_NEAR_MOTION_REACH; dy <= PX_SVGF_NEAR_MOTION_REACH; ++dy)
        for (int dx = -PX_SVGF_NEAR_MOTION_REACH; dx <= PX_SVGF_NEAR_MOTION_REACH; ++dx)
          if (px_pixel_readable(x0 + dx, y + dy, &p) &&
              motion[(uint)(y + dy) * p.width + (uint)(x0 + dx)].w == PX_MOTION_MOVED)
            a = fmax(a, PX_SVGF_NEAR_MOTION_ALPHA);
    }
    const float am = fmax(p.alpha_moments, 1.0f / len);
    out = mix(hist, illum, a);
    m = mix(hist_m, cur_m, am);
  } else {
    len = 1.0f; /* disocclusion or first frame: history starts over */
    out = illum;
    m = cur_m;
  }
  /* The moments give the variance of one frame's sample; what the spatial passes filter is the
   * blend of len frames, whose noise is smaller: the mean of len frames while 1 / len is above
   * the blend floor, then an exponential average with weight alpha, whose variance is
   * alpha / (2 - alpha) of a sample's. The a-trous luminance test scales with this, so a pixel
   * with a long history is filtered as much as its remaining noise asks, not as much as one
   * frame's noise would (atrium, still camera: the sun's shadow edges on the floor survive). */
  const float of_mean = fmax(1.0f / len, p.alpha / (2.0f - p.alpha));
  out_illum[i] = (float4)(out, fmax(0.0f, m.y - m.x * m.x) * of_mean);
  out_moments[i] = (float4)(m, len, 1.0f);
}

/* cos^sigma_n: the exponent is almost always an integer (128, 4...): a few multiplications,
 * where pow is a log and an exp (PoCL's pown and pow are library calls costing about as much as
 * a whole a-trous tap). */
inline int px_integer_exponent(float sigma_n) { return sigma_n >= 0.0f && sigma_n <= 1024.0f && floor(sigma_n) == sigma_n; }

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
 * through the stack (27% of the a-trous pass's CPU time on cornell). */
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
    gx = (px_guide_depth(guide[(uint)y * w + (uint)xr]) - px_guide_depth(guide[(uint)y * w + (uint)xl])) / (float)(xr - xl);
  if (yd > yu)
    gy = (px_guide_depth(guide[(uint)yd * w + (uint)x]) - px_guide_depth(guide[(uint)yu * w + (uint)x])) / (float)(yd - yu);
  return (float2)(gx, gy);
}

/* What every spatial pass needs about its centre pixel for edge-stopping. */
typedef struct FilterCentre {
  float3 n;     /* normal */
  float z;      /* depth */
  float2 grad;  /* screen-space depth gradient */
  float l;      /* luminance of the value being filtered */
} FilterCentre;

inline FilterCentre px_filter_centre(const global float4* guide, int x, int y, float3 value, const SvgfParams* p) {
  const float4 g = guide[(uint)y * p->width + (uint)x];
  FilterCentre c;
  c.n = g.xyz;
  c.z = px_guide_depth(g);
  c.grad = px_depth_gradient(guide, x, y, p);
  c.l = px_lum(value);
  return c;
}

/* The edge-stopping centre of pixel (x, y) filtering `value`: its own guide texel, or for a
 * borrowing pixel (`borrowed` = px_borrowed_centre) the lender's normal, depth and gradient. */
inline FilterCentre px_filter_centre_at(const global float4* guide, int x, int y, int borrowed, float3 value,
                                        const SvgfParams* p) {
  if (borrowed < 0) return px_filter_centre(guide, x, y, value, p);
  return px_filter_centre(guide, borrowed % (int)p->width, borrowed / (int)p->width, value, p);
}

/* Guide texels of rows [p.row0, p.row0 + p.rows): every row the spatial passes of this frame
 * read (the G-buffer's rows, margin included). The sign of w carries the material test that
 * svgf_temporal makes (moments.w), so a tap needs no second load to know it. Depth is >= 0 for
 * every pixel (0 for the sky: -0 here, not filtered), and exactly what the G-buffer holds. */
kernel void svgf_guide(global float4* guide, const global GBufferTexel* gbuf, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const global GBufferTexel* g = gbuf + i;
  guide[i] = (float4)(px_load3(g->normal), px_filtered_class(g->material_class) ? g->depth : -g->depth);
}

/* What the next a-trous step's luminance test compares, for rows [p.row0, p.row0 + p.rows): per
 * pixel, (luminance, variance) prefiltered over its 3x3 neighbourhood with the 3x3 Gaussian's
 * weights. The luminance of a filtered pixel is averaged with its neighbours' on the same
 * surface (filtered, normals and depths close: PX_SVGF_LUMA_*); any other pixel keeps its own.
 * The variance is averaged over the filtered neighbours (the pixel's own if there are none), as
 * the SVGF paper prefilters it.
 *
 * Why not the pixel's own luminance, as the paper compares: that makes the filter lose
 * energy. At 1 spp most samples are dark and a few bright; a tap's weight falls with its
 * luminance's distance from the centre's, so every dark centre turns the rare bright taps away,
 * while a bright centre, unlike any neighbour, keeps mostly itself. A weighted mean normalised
 * per centre then spreads less of each bright sample than it removes from it: measured on
 * flat noise with rare bright samples (10% at 10x the mean), the five steps and their colour
 * history lost 8%, and atrium's denoised frame came out 3.5% darker than its own noisy input.
 * Compared through a prefilter, a tap's weight hardly depends on its own sample (a ninth of
 * the average at most), so the weights stop sorting samples by brightness. Edges of light and
 * shadow still stop the filter, one pixel softer. The variance travels with it because the
 * test's scale is the pair's (see PX_ATROUS_TAP_SUM). */
kernel void svgf_luma(global float2* luma, const global float4* illum, const global float4* guide, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  const float4 gc = guide[i];
  const float4 c = illum[i];
  const int filtered = px_guide_filtered(gc);
  float lsum = 0.0f, lw = 0.0f, vsum = 0.0f, vw = 0.0f;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int tx = x + dx, ty = y + dy;
      if (!px_pixel_readable(tx, ty, &p)) continue;
      const uint j = (uint)ty * p.width + (uint)tx;
      const float4 g = guide[j];
      if (!px_guide_filtered(g)) continue;
      const float k = (dx == 0 ? 0.5f : 0.25f) * (dy == 0 ? 0.5f : 0.25f);
      const float4 t = illum[j];
      vsum += k * t.w;
      vw += k;
      if (filtered && dot(g.xyz, gc.xyz) >= PX_SVGF_LUMA_MIN_COS && fabs(g.w - gc.w) <= PX_SVGF_LUMA_REL_DEPTH * gc.w) {
        lsum += k * px_lum(t.xyz);
        lw += k;
      }
    }
  /* A filtered centre always counts itself: lw >= 0.25. */
  luma[i] = (float2)(filtered ? lsum / lw : px_lum(c.xyz), vw > 0.0f ? vsum / vw : c.w);
}

kernel void svgf_variance(global float4* out_illum, const global float4* illum, const global float4* moments,
                          const global float4* guide, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  const float4 c = illum[i];
  const float4 m = moments[i];
  if (m.w == 0.0f || m.z >= 4.0f) {
    out_illum[i] = c;
    return;
  }
  /* Short history: estimate the moments spatially with a 7x7 bilateral filter driven by depth
   * and normals only (as in the SVGF paper). A luminance term here would be circular: it would
   * leave out exactly the rare bright samples that make a one-sample pixel noisy, call the
   * dark pixels around them noise-free, and the a-trous luminance test would then cut those
   * samples off as edges — energy lost, the image darker than its input. */
  const int borrowed = m.w == PX_SVGF_BORROWED ? px_borrowed_centre(guide, x, y, &p) : -1;
  if (m.w == PX_SVGF_BORROWED && borrowed < 0) {
    out_illum[i] = c;
    return;
  }
  const FilterCentre fc = px_filter_centre_at(guide, x, y, borrowed, c.xyz, &p);
  /* Strict and loose normal weights side by side (.x, .y), as in svgf_atrous. */
  float2 wsum = (float2)(0.0f, 0.0f);
  float3 csum_strict = (float3)(0.0f, 0.0f, 0.0f), csum_loose = csum_strict;
  float4 msum = (float4)(0.0f, 0.0f, 0.0f, 0.0f); /* (strict m1, m2, loose m1, m2) */
  for (int dy = -3; dy <= 3; ++dy) {
    const int ty = y + dy;
    if (ty < 0 || ty >= (int)p.height || !px_row_readable(ty, &p)) continue;
    for (int dx = -3; dx <= 3; ++dx) {
      const int tx = x + dx;
      if (tx < 0 || tx >= (int)p.width) continue;
      const uint j = (uint)ty * p.width + (uint)tx;
      if (moments[j].w == 0.0f) continue;
      const float2 w = (dx == 0 && dy == 0)
                           ? (float2)(1.0f, 1.0f)
                           : px_geometry_weights(guide[j], fc.n, fc.z, fc.grad, (float)dx, (float)dy, &p, 0.0f);
      wsum += w;
      csum_strict += w.x * illum[j].xyz;
      csum_loose += w.y * illum[j].xyz;
      msum += (float4)(w.x * moments[j].xy, w.y * moments[j].xy);
    }
  }
  const int isolated = wsum.x - 1.0f < PX_SVGF_ISOLATED;
  const float3 csum = isolated ? csum_loose / wsum.y : csum_strict / wsum.x;
  const float2 m12 = isolated ? msum.zw / wsum.y : msum.xy / wsum.x;
  /* Few frames of history: the estimate is uncertain, so boost it (as in the SVGF paper). */
  const float var = fmax(0.0f, m12.y - m12.x * m12.x) * 4.0f / m.z;
  out_illum[i] = (float4)(csum, var);
}

/* The centre of an a-trous tap sum at pixel i = (x, y): its edge-stopping geometry (its own, or a
 * borrowing pixel's lender's), prefiltered luminance and variance (svgf_luma). Returns 0 for a pixel the pass leaves as it
 * is (not filtered, and not borrowing), having written it to out_illum. */
inline int px_atrous_centre(global float4* out_illum, const global float4* illum, const global float4* guide,
                            const global float4* moments, const global float2* luma, int x, int y,
                            const SvgfParams* p, FilterCentre* fc, float* var) {
  const uint i = (uint)y * p->width + (uint)x;
  const float4 c = illum[i];
  int borrowed = -1;
  if (!px_guide_filtered(guide[i])) {
    if (moments[i].w == PX_SVGF_BORROWED) borrowed = px_borrowed_centre(guide, x, y, p);
    if (borrowed < 0) {
      out_illum[i] = c;
      return 0;
    }
  }
  *fc = px_filter_centre_at(guide, x, y, borrowed, c.xyz, p);
  /* The prefiltered luminance and variance (svgf_luma). */
  const float2 lv = luma[i];
  fc->l = lv.x;
  *var = fmax(0.0f, lv.y);
  return 1;
}

/* The luminance edge-stopping exponent between a centre (prefiltered luminance l, variance v)
 * and a tap's svgf_luma texel t: symmetric in the two. */
inline float px_luminance_term(float l, float v, float2 t, const SvgfParams* p) {
  return fabs(l - t.x) / (p->sigma_l * sqrt(0.5f * (v + fmax(0.0f, t.y))) + 1e-6f);
}

/* B3-spline a-trous weights of taps -2..2. */
__constant float px_atrous_h[5] = {1.0f / 16.0f, 1.0f / 4.0f, 3.0f / 8.0f, 1.0f / 4.0f, 1.0f / 16.0f};

/* The a-trous tap sum of pixel (x, y) (index i) around centre `fc`, written to out_illum[i]: the
 * body of svgf_atrous and svgf_atrous_tiled, which differ only in where a tap's texels come
 * from: GUIDE_AT(tx, ty), ILLUM_AT(tx, ty) and LUMA_AT(tx, ty) are the guide and illumination
 * texels and the prefiltered luminance (svgf_luma) of pixel (tx, ty), read only for taps inside
 * the image and the readable rows.
 *
 * The luminance test's scale is the pair's: sigma_l times the square root of the mean of the
 * centre's and the tap's prefiltered variances, so that a tap weighs on its centre as the
 * centre weighs on it. Scaled by the centre's variance alone, as in the SVGF paper, a bright
 * and noisy centre beside a dark and quiet one took in the dark tap more readily than the dark
 * one took in the bright: at every boundary of sunlight and shade, light flowed out and not
 * back in (atrium, still camera: 1% of the frame's energy).
 *
 * Every tap's weight twice: .x with the normal exponent sigma_n, .y with a loose one. A pixel
 * whose normal no neighbour shares closely — alpha-cut foliage cards, curved surfaces seen at
 * grazing angles, silhouettes — gets no weight from anyone under the strict test and keeps its
 * lone sample, at 1 spp often black. Such an isolated pixel takes the loose weights, which still
 * stop at creases, depth steps and luminance edges; every other pixel is filtered exactly as
 * before. */
#define PX_ATROUS_TAP_SUM(GUIDE_AT, ILLUM_AT, LUMA_AT)                                                 \
  do {                                                                                               \
    const int step_ = (int)p.step;                                                                   \
    float2 wsum = (float2)(0.0f, 0.0f), vsum = (float2)(0.0f, 0.0f);                                 \
    float3 csum_strict = (float3)(0.0f, 0.0f, 0.0f), csum_loose = csum_strict;                       \
    for (int ky = -2; ky <= 2; ++ky) {                                                               \
      const int ty = y + ky * step_;                                                                 \
      if (ty < 0 || ty >= (int)p.height || !px_row_readable(ty, &p)) continue;                       \
      for (int kx = -2; kx <= 2; ++kx) {                                                             \
        const int tx = x + kx * step_;                                                               \
        if (tx < 0 || tx >= (int)p.width) continue;                                                  \
        const float4 g = GUIDE_AT(tx, ty);                                                           \
        /* Unfiltered pixels are never taps; the centre always is (a borrowing one included). */     \
        if (!px_guide_filtered(g) && (kx != 0 || ky != 0)) continue;                                 \
        const float4 t = ILLUM_AT(tx, ty);                                                           \
        float2 w = (float2)(px_atrous_h[kx + 2] * px_atrous_h[ky + 2]);                              \
        if (kx != 0 || ky != 0)                                                                      \
          w *= px_geometry_weights(g, fc.n, fc.z, fc.grad, (float)(kx * step_), (float)(ky * step_), \
                                   &p, px_luminance_term(fc.l, centre_var, LUMA_AT(tx, ty), &p));     \
        wsum += w;                                                                                   \
        vsum += w * w * t.w;                                                                         \
        csum_strict += w.x * t.xyz;                                                                  \
        csum_loose += w.y * t.xyz;                                                                   \
      }                                                                                              \
    }                                                                                                \
    const float centre = px_atrous_h[2] * px_atrous_h[2];                                            \
    if (wsum.x - centre < PX_SVGF_ISOLATED * centre)                                                 \
      out_illum[i] = (float4)(csum_loose / wsum.y, vsum.y / (wsum.y * wsum.y));                      \
    else                                                                                             \
      out_illum[i] = (float4)(csum_strict / wsum.x, vsum.x / (wsum.x * wsum.x));                     \
  } while (0)

#define PX_GLOBAL_GUIDE(tx, ty) guide[(uint)(ty) * p.width + (uint)(tx)]
#define PX_GLOBAL_ILLUM(tx, ty) illum[(uint)(ty) * p.width + (uint)(tx)]
#define PX_GLOBAL_LUMA(tx, ty) luma[(uint)(ty) * p.width + (uint)(tx)]

kernel void svgf_atrous(global float4* out_illum, const global float4* illum, const global float4* guide,
                        const global float4* moments, const global float2* luma, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  FilterCentre fc;
  float centre_var;
  if (!px_atrous_centre(out_illum, illum, guide, moments, luma, x, y, &p, &fc, &centre_var)) return;
  PX_ATROUS_TAP_SUM(PX_GLOBAL_GUIDE, PX_GLOBAL_ILLUM, PX_GLOBAL_LUMA);
}

/* The same a-trous step for GPUs, its taps read from local memory: a work-group filters a tile of
 * PX_ATROUS_TILE x PX_ATROUS_TILE pixels and first loads the guide, illumination and luminance
 * guide texels of the tile and its apron (2 x step pixels on each side) once, where
 * svgf_atrous's 25 taps per pixel each go to global memory (to the caches, at best). For steps up
 * to PX_ATROUS_TILE_MAX_STEP (1, 2 and 4: 144, 256 and 576 texels for 64 pixels, 22.5 KiB of
 * local memory at step 4); larger steps touch too few texels twice to gain, and run
 * svgf_atrous. The centre's work (borrowing) reads global memory as in svgf_atrous, and the tap sum is the same code
 * (PX_ATROUS_TAP_SUM). Items: PX_LOCAL_SIZE per tile, tiles row by row over the strip. */
#define PX_ATROUS_TILE_SPAN (PX_ATROUS_TILE + 4 * PX_ATROUS_TILE_MAX_STEP)
#if PX_ATROUS_TILE * PX_ATROUS_TILE != PX_LOCAL_SIZE
#error "svgf_atrous_tiled: a work-group is one tile"
#endif
__attribute__((reqd_work_group_size(PX_LOCAL_SIZE, 1, 1)))
kernel void svgf_atrous_tiled(global float4* out_illum, const global float4* illum, const global float4* guide,
                              const global float4* moments, const global float2* luma, SvgfParams p) {
  local float4 tile_guide[PX_ATROUS_TILE_SPAN * PX_ATROUS_TILE_SPAN];
  local float4 tile_illum[PX_ATROUS_TILE_SPAN * PX_ATROUS_TILE_SPAN];
  local float2 tile_luma[PX_ATROUS_TILE_SPAN * PX_ATROUS_TILE_SPAN];
  const uint tiles_x = (p.width + PX_ATROUS_TILE - 1u) / PX_ATROUS_TILE;
  const uint group = get_group_id(0), lid = get_local_id(0);
  const int apron = 2 * (int)min(p.step, (uint)PX_ATROUS_TILE_MAX_STEP), span = PX_ATROUS_TILE + 2 * apron;
  const int x0 = (int)((group % tiles_x) * PX_ATROUS_TILE), y0 = (int)(p.row0 + (group / tiles_x) * PX_ATROUS_TILE);
  const int ox = x0 - apron, oy = y0 - apron;
  /* Texels outside the image or the readable rows are not loaded: the tap sum skips them. */
  for (int k = (int)lid; k < span * span; k += PX_LOCAL_SIZE) {
    const int tx = ox + k % span, ty = oy + k / span;
    if (tx >= 0 && tx < (int)p.width && ty >= 0 && ty < (int)p.height && px_row_readable(ty, &p)) {
      tile_guide[k] = PX_GLOBAL_GUIDE(tx, ty);
      tile_illum[k] = PX_GLOBAL_ILLUM(tx, ty);
      tile_luma[k] = PX_GLOBAL_LUMA(tx, ty);
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int x = x0 + (int)(lid % PX_ATROUS_TILE), y = y0 + (int)(lid / PX_ATROUS_TILE);
  if (x >= (int)p.width || y >= (int)(p.row0 + p.rows) || p.step > PX_ATROUS_TILE_MAX_STEP) return;
  const uint i = (uint)y * p.width + (uint)x;
  FilterCentre fc;
  float centre_var;
  if (!px_atrous_centre(out_illum, illum, guide, moments, luma, x, y, &p, &fc, &centre_var)) return;
#define PX_TILE_GUIDE(tx, ty) tile_guide[((ty) - oy) * span + (tx) - ox]
#define PX_TILE_ILLUM(tx, ty) tile_illum[((ty) - oy) * span + (tx) - ox]
#define PX_TILE_LUMA(tx, ty) tile_luma[((ty) - oy) * span + (tx) - ox]
  PX_ATROUS_TAP_SUM(PX_TILE_GUIDE, PX_TILE_ILLUM, PX_TILE_LUMA);
#undef PX_TILE_GUIDE
#undef PX_TILE_ILLUM
#undef PX_TILE_LUMA
}

/* (c^e1, c^e2) for eight cosines at once (negative: 0), as px_normal_weights lane by lane. */
inline void px_normal_weights8(float8 c, float e1, float e2, float8* w1, float8* w2) {
  c = fmax(0.0f, c);
  if (px_integer_exponent(e1) && px_integer_exponent(e2)) {
    uint k1 = (uint)e1, k2 = (uint)e2;
    float8 a = (float8)(1.0f), b = (float8)(1.0f);
    while ((k1 | k2) != 0u) {
      if (k1 & 1u) a *= c;
      if (k2 & 1u) b *= c;
      c = select(c * c, (float8)(0.0f), c < 1e-10f);
      k1 >>= 1;
      k2 >>= 1;
    }
    *w1 = a;
    *w2 = b;
  } else {
    *w1 = pow(c, (float8)(e1));
    *w2 = pow(c, (float8)(e2));
  }
}

/* Eight consecutive float4 texels from `first` as four float8 planes (x, y, z, w). Loaded as
 * float8s, not float16s: PoCL's vload16 returns a float16, which an AVX2 CPU without AVX-512
 * passes in a way clang warns about at every build ("AVX vector return ... changes the ABI"). */
inline void px_load8_planes(const global float4* first, float8* x, float8* y, float8* z, float8* w) {
  const global float* f = (const global float*)first;
  const float8 a = vload8(0, f), b = vload8(1, f), c = vload8(2, f), d = vload8(3, f);
  *x = (float8)(a.s04, b.s04, c.s04, d.s04);
  *y = (float8)(a.s15, b.s15, c.s15, d.s15);
  *z = (float8)(a.s26, b.s26, c.s26, d.s26);
  *w = (float8)(a.s37, b.s37, c.s37, d.s37);
}

/* The same a-trous step for eight horizontally adjacent pixels per work-item, written for CPU
 * devices. PoCL runs each work-item of svgf_atrous as scalar code (its vectorizer gives up on
 * the tap loop), so a tap cost ~100 scalar instructions there. Here the lanes are explicit:
 * each tap's weights for the eight pixels are float8 arithmetic, one AVX register per quantity,
 * and the tap's eight texels are two 64-byte loads (and the luminance guide's one). The per-pixel
 * centre work (borrowing) stays scalar. Same filter, same operations per lane as svgf_atrous (test_svgf
 * checks both against the host implementation); a GPU, where each work-item is already a SIMD
 * lane, runs svgf_atrous. Items: rows x ceil(width / 8). */
#define PX_ATROUS_LANES 8
kernel void svgf_atrous8(global float4* out_illum, const global float4* illum, const global float4* guide,
                         const global float4* moments, const global float2* luma, SvgfParams p) {
  const uint per_row = (p.width + PX_ATROUS_LANES - 1u) / PX_ATROUS_LANES;
  const uint gid = get_global_id(0);
  if (gid >= p.rows * per_row) return;
  const int y = (int)(p.row0 + gid / per_row);
  const int x0 = (int)(gid % per_row) * PX_ATROUS_LANES;
  /* The centres, lane by lane. A lane past the image's right edge or left unfiltered is off. */
  float cnx[PX_ATROUS_LANES], cny[PX_ATROUS_LANES], cnz[PX_ATROUS_LANES], cz[PX_ATROUS_LANES];
  float cgx[PX_ATROUS_LANES], cgy[PX_ATROUS_LANES], cl[PX_ATROUS_LANES], cvar[PX_ATROUS_LANES];
  int on[PX_ATROUS_LANES];
  int any = 0;
  for (int l = 0; l < PX_ATROUS_LANES; ++l) {
    FilterCentre fc;
    float var = 0.0f;
    on[l] = x0 + l < (int)p.width && px_atrous_centre(out_illum, illum, guide, moments, luma, x0 + l, y, &p, &fc, &var);
    if (!on[l]) fc = (FilterCentre){(float3)(0.0f, 0.0f, 1.0f), 1.0f, (float2)(0.0f, 0.0f), 0.0f};
    cnx[l] = fc.n.x; cny[l] = fc.n.y; cnz[l] = fc.n.z; cz[l] = fc.z;
    cgx[l] = fc.grad.x; cgy[l] = fc.grad.y; cl[l] = fc.l; cvar[l] = var;
    any |= on[l];
  }
  if (!any) return;
  const float8 nx = vload8(0, cnx), ny = vload8(0, cny), nz = vload8(0, cnz), z = vload8(0, cz);
  const float8 gx = vload8(0, cgx), gy = vload8(0, cgy), lum = vload8(0, cl), centre_var = vload8(0, cvar);
  const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
  const int step = (int)p.step;
  const float loose = fmin(p.sigma_n, PX_SVGF_LOOSE_SIGMA_N);
  /* As svgf_atrous: .x strict, .y loose normal weights (the isolated-pixel fallback). */
  float8 wsum_x = (float8)(0.0f), wsum_y = wsum_x, vsum_x = wsum_x, vsum_y = wsum_x;
  float8 cs_r = wsum_x, cs_g = wsum_x, cs_b = wsum_x, cl_r = wsum_x, cl_g = wsum_x, cl_b = wsum_x;
  for (int ky = -2; ky <= 2; ++ky) {
    const int ty = y + ky * step;
    if (ty < 0 || ty >= (int)p.height || !px_row_readable(ty, &p)) continue;
    const uint row = (uint)ty * p.width;
    for (int kx = -2; kx <= 2; ++kx) {
      const int tx0 = x0 + kx * step;
      const int8 tx = (int8)(tx0) + lane;
      const int8 inside = tx >= 0 && tx < (int)p.width;
      float8 tnx, tny, tnz, tw, tr, tg, tb, tv, tl, tlv;
      if (tx0 >= 0 && tx0 + PX_ATROUS_LANES <= (int)p.width) {
        px_load8_planes(guide + row + (uint)tx0, &tnx, &tny, &tnz, &tw);
        px_load8_planes(illum + row + (uint)tx0, &tr, &tg, &tb, &tv);
        const float8 l0 = vload8(0, (const global float*)(luma + row + (uint)tx0));
        const float8 l1 = vload8(1, (const global float*)(luma + row + (uint)tx0));
        tl = (float8)(l0.even, l1.even);
        tlv = (float8)(l0.odd, l1.odd);
      } else {
        /* At the image's left and right edges: lane by lane, clamped (outside lanes weigh 0). */
        float a[10][PX_ATROUS_LANES];
        for (int l = 0; l < PX_ATROUS_LANES; ++l) {
          const uint j = row + (uint)clamp(tx0 + l, 0, (int)p.width - 1);
          const float4 g = guide[j], t = illum[j];
          a[0][l] = g.x; a[1][l] = g.y; a[2][l] = g.z; a[3][l] = g.w;
          a[4][l] = t.x; a[5][l] = t.y; a[6][l] = t.z; a[7][l] = t.w;
          const float2 lv = luma[j];
          a[8][l] = lv.x; a[9][l] = lv.y;
        }
        tnx = vload8(0, a[0]); tny = vload8(0, a[1]); tnz = vload8(0, a[2]); tw = vload8(0, a[3]);
        tr = vload8(0, a[4]); tg = vload8(0, a[5]); tb = vload8(0, a[6]); tv = vload8(0, a[7]);
        tl = vload8(0, a[8]); tlv = vload8(0, a[9]);
      }
      const float h = px_atrous_h[kx + 2] * px_atrous_h[ky + 2];
      float8 w_x = (float8)(h), w_y = w_x;
      int8 use = inside;
      if (kx != 0 || ky != 0) {
        /* Unfiltered pixels are never taps (the centre always is). Same terms as
         * px_geometry_weights, in the same order. */
        use = use && tw > 0.0f;
        const float8 extra = fabs(lum - tl) / (p.sigma_l * sqrt(0.5f * (centre_var + fmax(tlv, 0.0f))) + 1e-6f);
        const float dx = (float)(kx * step), dy = (float)(ky * step);
        const float8 depth_term = fabs(z - tw) / (p.sigma_z * fabs(gx * dx + gy * dy) + 1e-3f * z + 1e-6f);
        const float8 rest = px_exp8(-(depth_term + extra));
        float8 n1, n2;
        px_normal_weights8(nx * tnx + ny * tny + nz * tnz, p.sigma_n, loose, &n1, &n2);
        w_x *= n1 * rest;
        w_y *= n2 * rest;
      }
      w_x = select((float8)(0.0f), w_x, use);
      w_y = select((float8)(0.0f), w_y, use);
      wsum_x += w_x;
      wsum_y += w_y;
      vsum_x += w_x * w_x * tv;
      vsum_y += w_y * w_y * tv;
      cs_r += w_x * tr; cs_g += w_x * tg; cs_b += w_x * tb;
      cl_r += w_y * tr; cl_g += w_y * tg; cl_b += w_y * tb;
    }
  }
  const float centre = px_atrous_h[2] * px_atrous_h[2];
  float ws[PX_ATROUS_LANES], wl[PX_ATROUS_LANES], vs[PX_ATROUS_LANES], vl[PX_ATROUS_LANES];
  float sr[PX_ATROUS_LANES], sg[PX_ATROUS_LANES], sb[PX_ATROUS_LANES];
  float lr[PX_ATROUS_LANES], lg[PX_ATROUS_LANES], lb[PX_ATROUS_LANES];
  vstore8(wsum_x, 0, ws); vstore8(wsum_y, 0, wl); vstore8(vsum_x, 0, vs); vstore8(vsum_y, 0, vl);
  vstore8(cs_r, 0, sr); vstore8(cs_g, 0, sg); vstore8(cs_b, 0, sb);
  vstore8(cl_r, 0, lr); vstore8(cl_g, 0, lg); vstore8(cl_b, 0, lb);
  for (int l = 0; l < PX_ATROUS_LANES; ++l) {
    if (!on[l]) continue;
    const uint i = (uint)y * p.width + (uint)(x0 + l);
    if (ws[l] - centre < PX_SVGF_ISOLATED * centre)
      out_illum[i] = (float4)((float3)(lr[l], lg[l], lb[l]) / wl[l], vl[l] / (wl[l] * wl[l]));
    else
      out_illum[i] = (float4)((float3)(sr[l], sg[l], sb[l]) / ws[l], vs[l] / (ws[l] * ws[l]));
  }
}

/* Back from illumination to radiance: multiply the albedo that demodulation divided out, so
 * that an unfiltered pixel comes back exactly as it went in.
 * Unfiltered pixels (background, emitters) already hold their colour; borrowing ones
 * (PX_SVGF_BORROWED) take their own samples' albedo back, as filtered ones do. */
/* A borrowing pixel's centre sees the environment while all its n samples hit the surface: the
 * surface covers only part of it. If a straight edge crosses the pixel at a uniformly random
 * place, the coverage is uniform on [0, 1/2] given the centre outside, and all n samples land
 * inside with probability coverage^n: the expected coverage is (1/2)(n + 1)/(n + 2), 1/3 at
 * 1 spp. The filtered surface colour takes that share, the environment next to the pixel (its
 * environment 8-neighbours' accumulated colour) the rest. Given the whole pixel, the surface
 * grew a pixel of full surface colour wherever a sample crossed the silhouette. Reads rows
 * y - 1 .. y + 1 of illum, moments and guide, all exchanged after svgf_temporal (the
 * environment's colour does not change in the spatial passes). */
inline float3 px_borrowed_blend(float3 surface, float samples, const global float4* illum,
                                const global float4* moments, const global float4* guide, int x, int y,
                                const SvgfParams* p) {
  float3 env = (float3)(0.0f, 0.0f, 0.0f);
  float count = 0.0f;
  for (int k = 0; k < 8; ++k) {
    const int j = px_neighbour8(x, y, k, p);
    /* the environment: not filtered, not borrowing, depth 0 (emitters have a depth) */
    if (j < 0 || moments[j].w != 0.0f || guide[j].w != 0.0f) continue;
    env += illum[j].xyz;
    count += 1.0f;
  }
  if (count == 0.0f) return surface;
  const float n = fmax(samples, 1.0f);
  return mix(env / count, surface, 0.5f * (n + 1.0f) / (n + 2.0f));
}

/* `out_color` holds the pixel's radiance (w: its finite sample count) and is overwritten. */
kernel void svgf_remodulate(global float4* out_color, const global float4* illum, const global float4* moments,
                            const global float4* albedo, const global float4* guide, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const float4 c = illum[i];
  const float m = moments[i].w;
  if (m == 0.0f) {
    out_color[i] = (float4)(c.xyz, 1.0f);
    return;
  }
  float3 radiance = c.xyz * px_demod_albedo(albedo, i);
  if (m == PX_SVGF_BORROWED)
    radiance = px_borrowed_blend(radiance, out_color[i].w, illum, moments, guide, (int)(i % p.width),
                                 (int)(i / p.width), &p);
  out_color[i] = (float4)(radiance, 1.0f);
}

/* Temporal anti-aliasing of the remodulated radiance `color`, rows [p.row0, p.row0 + p.rows).
 *
 * Each frame samples every pixel once at the frame's jitter position; SVGF's history is kept
 * per surface, so a pixel on an edge (an emitter's rim, a silhouette) restarts it whenever its
 * sample lands on the other side, and shows one side or the other: jagged edges and, at 1 spp,
 * a light whose visible area changes by whole rows and columns with the jitter (cornell's
 * mean came out 6% too bright in one frame). Here the final radiance itself is averaged over
 * frames, whatever surface each sample saw: last frame's result, reprojected through the
 * G-buffer point (or the direction of a miss) into the previous camera with the jitter taken
 * out (px_previous_pixel) and read with 2x2 bilinear taps, is blended as
 * mix(history, color, max(alpha, 1 / history length, PX_TAA_MOTION_ALPHA x the pixels moved
 * (at most PX_TAA_MOTION_ALPHA_MAX))): a still pixel averages its jitter positions over many
 * frames (cornell's light: +0.6% at alpha 0.1, +1.6% at 0.3), a moving one keeps less of a
 * history that each bilinear read blurs and that lags behind the view (atrium, camera moving
 * about half a pixel a frame: -1.2% and 26.1 dB without the motion term, -0.8% and 27.2 dB
 * with it). The history is first clipped to
 * mean +- PX_TAA_CLIP_SIGMA standard deviations of the current 3x3 neighbourhood per YCoCg axis,
 * so that what moved or was disoccluded cannot leave a trail: on an edge the neighbourhood
 * holds both sides and the average passes. Reads `color` in rows y - 1 .. y + 1 (readable
 * ones) and `prev` within temporal_rows rows. Writes the result to `resolved` (w = 1) and the
 * new history (rgb, length) to `history`. */
/* Luma and two chroma differences (YCoCg): the history is clipped in these axes, not in R, G
 * and B. A box per RGB channel around a grey neighbourhood still holds a saturated colour's
 * brightest and darkest channels, so a red object that moved on left a reddish trail on a grey
 * edge behind it (the range of R and that of B each pass); in YCoCg the neighbourhood's narrow
 * chroma range removes the hue. */
inline float3 px_ycocg(float3 c) {
  return (float3)(0.25f * c.x + 0.5f * c.y + 0.25f * c.z, 0.5f * c.x - 0.5f * c.z, -0.25f * c.x + 0.5f * c.y - 0.25f * c.z);
}
inline float3 px_from_ycocg(float3 c) { return (float3)(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z); }
#define PX_TAA_CLIP_SIGMA 1.25f
#define PX_TAA_MOTION_ALPHA 1.0f
#define PX_TAA_MOTION_ALPHA_MAX 0.5f
kernel void svgf_antialias(global float4* resolved, global float4* history, const global float4* color,
                           const global float4* prev, const global GBufferTexel* gbuf, SvgfParams p,
                           CameraParams prev_cam, uint have_history, float alpha, const global float4* motion,
                           const global GBufferTexel* prev_gbuf, const global float4* tri_motion,
                           const global SceneInstances* instances) {
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
     * beside the object followed it, the image as a whole got worse.
     * Measured when this came (trail test, 8 spp, where the error is lag rather than noise):
     * the swept region's error 3.9x the still run's, 9.6x when only the object's texels were followed,
     * the trailing column keeping the cube's colour; Khronos's BoxAnimated and RiggedSimple
     * (two frames each, both eyes, against 256-spp references): the summed error -59%. */
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
        if (motion[b].w > 0.0f && px_previous_pixel(motion[b].xyz - px_camera_origin(&prev_cam), &prev_cam, &p, &gx, &gy)) {
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
        hist = px_from_ycocg(clamp(px_ycocg(hist), m1 - PX_TAA_CLIP_SIGMA * sigma, m1 + PX_TAA_CLIP_SIGMA * sigma));
        len = fmin((float)p.max_history, floor(hist_len / wsum + 0.5f) + 1.0f);
        /* Motion: resampled history blurs a little more with every bilinear read and lags behind
         * what the view now shows, so a pixel that moved trusts it less. */
        const float moved = length((float2)(fx - (float)x, fy - (float)y));
        out = mix(hist, c, fmax(fmax(alpha, 1.0f / len), fmin(PX_TAA_MOTION_ALPHA_MAX, PX_TAA_MOTION_ALPHA * moved)));
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
             px_exp(-fabs(fc.l - px_lum(t)) / (0.25f * fc.l + 1e-3f));
      wsum += w;
      csum += w * t;
    }
  }
  out_color[i] = (float4)(csum / wsum, 1.0f);
}
