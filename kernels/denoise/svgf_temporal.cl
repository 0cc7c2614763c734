/* SVGF's temporal passes (svgf_common.h): the guide texels, the accumulation of illumination and
 * moments over frames, and the variance the spatial passes start from. */
#include "denoise/svgf_common.h"

/* Surfaces the filter smooths. Specular ones (mirror, glass) too: their noise at low sample counts
 * is worse to look at than the blur of what they reflect or refract. */
inline int px_filtered_class(uint c) {
  return c == PX_CLASS_DIFFUSE || c == PX_CLASS_GLOSSY || c == PX_CLASS_MIRROR || c == PX_CLASS_DIELECTRIC;
}

/* Is history texel `q` the same surface as the current pixel (world point pos, normal n,
 * distance `expected` from the previous camera)? */
inline int px_history_matches(const global GBufferTexel* q, float3 n, float expected) {
  if (!px_filtered_class(q->material_class)) return 0;
  return fabs(q->depth - expected) < 0.05f * expected && dot(px_load3(q->normal), n) > 0.9f;
}

/* The environment is not filtered, but it is accumulated over frames: at 1 spp every pixel on
 * the horizon (or the sun's rim) is one jittered sample of a step, and left alone the edge
 * crawls from frame to frame. The environment is at infinity, so its history is found by
 * direction alone (the G-buffer keeps a miss's direction in pos), 2x2 bilinear taps on texels
 * that were the environment too, and not a borrowing silhouette pixel (whose history is
 * illumination, not radiance). Radiance, not illumination: the colour blends like the
 * surfaces' with alpha = max(alpha, 1 / history length); the length rides in moments.z. */
inline float4 px_environment_temporal(float3 c, const global GBufferTexel* g, int y,
                                      const global GBufferTexel* prev_gbuf, const global float4* prev_illum,
                                      const global float4* prev_moments, const SvgfParams* p,
                                      const CameraParams* prev_cam, float lambda) {
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
  float len = fmin((float)p->max_history, floor(hist_len / wsum + 0.5f) + 1.0f);
  float a = fmax(p->alpha, 1.0f / len);
  if (lambda > 0.0f) { /* the sky changed (a sun that turns): as svgf_temporal's surfaces */
    a = mix(a, 1.0f, lambda);
    len = fmax(1.0f, floor(len * (1.0f - lambda) + 0.5f)); /* a whole count, as everywhere */
  }
  return (float4)(mix(hist / wsum, c, a), len);
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

kernel void svgf_temporal(global float4* out_illum, global float4* out_moments, const global float4* color,
                          const global float4* albedo, const global GBufferTexel* gbuf,
                          const global GBufferTexel* prev_gbuf, const global float4* prev_illum,
                          const global float4* prev_moments, SvgfParams p, CameraParams prev_cam, uint have_history,
                          const global float4* guide, const global float4* motion, const global float4* gradient) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int y = (int)(i / p.width);
  const global GBufferTexel* g = gbuf + i;
  const float3 c = color[i].xyz;
  /* Temporal gradients: the share of the history the lighting's change made untrue. */
  /* Not on an object that moved: its history follows the motion rules below, and the strata's
   * shades around it (still surfaces only) say nothing of its own light. */
  const int own_motion = motion && motion[i].w == PX_MOTION_MOVED;
  const global float4* grad = own_motion ? 0 : gradient;
  const float lambda = px_gradient_lambda(grad, i % p.width, (uint)y, p.width);
  if (!px_filtered_class(g->material_class)) {
    /* A silhouette pixel whose samples all hit a filtered surface borrows a neighbour's
     * geometry (PX_SVGF_BORROWED); it has no geometry of its own to match history with, so its
     * history starts over every frame. */
    if (albedo[i].w >= PX_SVGF_BORROW_COVERAGE && px_borrowed_centre(guide, (int)(i % p.width), y, &p) >= 0) {
      const float3 illum = c / px_demod_albedo(albedo, i);
      const float l = px_luminance(illum);
      out_illum[i] = (float4)(illum, 0.0f);
      out_moments[i] = (float4)(l, l * l, 1.0f, PX_SVGF_BORROWED);
      return;
    }
    /* Emitters pass through; the environment is accumulated (colour, history length). */
    const float4 env =
        g->material_class == PX_CLASS_MISS && have_history
            ? px_environment_temporal(c, g, y, prev_gbuf, prev_illum, prev_moments, &p, &prev_cam, lambda)
            : (float4)(c, 1.0f);
    out_illum[i] = (float4)(env.xyz, 0.0f);
    out_moments[i] = (float4)(0.0f, 0.0f, env.w, 0.0f);
    return;
  }
  const float3 illum = c / px_demod_albedo(albedo, i);
  const float l = px_luminance(illum);

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
    /* Temporal gradients: the light here changed by this factor since last frame (1 where it
     * did not, or without gradients): the history follows it. */
    const float ratio = px_gradient_ratio(grad, i % p.width, (uint)y, p.width);
    if (ratio != 1.0f) {
      hist *= ratio;
      hist_m *= (float2)(ratio, ratio * ratio);
    }
    len = fmin((float)p.max_history, floor(hist_len / wsum + 0.5f) + 1.0f);
    float a = fmax(p.alpha, 1.0f / len);
    /* Beside a moving object a still surface's illumination changes from frame to frame: the
     * object's contact shadow and the light it reflects move with it. Its history lags there
     * (docs/measurements.md, SVGF history beside motion), so there it keeps at most half. A stand-in for a temporal
     * gradient (A-SVGF), which would also catch a shadow cast far from its object and need no reach in pixels. */
    if (motion && motion[i].w == PX_MOTION_STILL) {
      const int x0 = (int)(i % p.width);
      for (int dy = -PX_SVGF_NEAR_MOTION_REACH; dy <= PX_SVGF_NEAR_MOTION_REACH; ++dy)
        for (int dx = -PX_SVGF_NEAR_MOTION_REACH; dx <= PX_SVGF_NEAR_MOTION_REACH; ++dx)
          if (px_pixel_readable(x0 + dx, y + dy, &p) &&
              motion[(uint)(y + dy) * p.width + (uint)(x0 + dx)].w == PX_MOTION_MOVED)
            a = fmax(a, PX_SVGF_NEAR_MOTION_ALPHA);
    }
    float am = fmax(p.alpha_moments, 1.0f / len);
    /* The lighting changed here (temporal gradients): that share of the history goes, and the
     * history counts as that much shorter from now on. Nothing changes where lambda is 0. */
    if (lambda > 0.0f) {
      a = mix(a, 1.0f, lambda);
      am = mix(am, 1.0f, lambda);
      len = fmax(1.0f, floor(len * (1.0f - lambda) + 0.5f)); /* a whole count, as everywhere */
    }
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
