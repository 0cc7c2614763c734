/* Temporal gradients, the shading half (A-SVGF, Schied, Peters and Dachsbacher, HPG 2018).
 *
 * SVGF keeps a pixel's history while its surface stays the same; a light that moves, switches or
 * changes colour changes the shading of surfaces that did not move, and the history then shows
 * the old light for as long as it is kept. So each frame, for every stratum of 3x3 pixels, one
 * pixel chosen last frame is shaded again: the surface point its G-buffer texel held last frame,
 * seen from this frame's camera, with the same random numbers as last frame's shade of it, in
 * this frame's scene. Where nothing changed the two shades are the same path and agree to the
 * bit; the difference is what the lighting did. gradient_filter.cl spreads the strata's
 * shades; SVGF's temporal passes scale their history by the ratio of the shades (a light that
 * brightens or dims smoothly) and drop the share that their differences say changed otherwise (a
 * shadow that moves, a light switched).
 *
 * The same kernel also shades this frame's chosen pixel of each stratum, which next frame's
 * gradient compares against: two paths per stratum, 2/9 of a path per pixel at most.
 *
 * A stratum has no gradient (weight 0) where last frame's point is hidden from this frame's
 * camera, belongs to an object that moved (the motion rules of svgf_temporal handle those), or
 * its shade is not finite (counted in `nonfinite`, like the image's paths).
 *
 * A stratum's work is px_gradient_stratum, shared by temporal_gradient.cl's `gradient_shade` (GPUs)
 * and path_trace.cl's `path_trace_pixels` in its gradient mode (CPUs), so both write the same bits. */
#ifndef PARALLAX_GRADIENT_STRATUM_H
#define PARALLAX_GRADIENT_STRATUM_H

#include "shared/types.h"
#include "denoise/svgf_constants.h"
#include "pathtrace/trace_path.h"
#include "pipeline/texel_motion.h"
#include "render/camera.h"
#include "sampling/sample_stream.h"
#include "shading/bsdf.h"

/* The pixel of stratum (sx, sy) shaded in `frame`: a hash of the stratum, frame, eye and seed, so
 * every device picks the same one, inside the image and the rows the G-buffers hold. */
inline uint2 px_gradient_pick(uint sx, uint sy, uint frame, const GradientParams* gp) {
  const uint4 h = px_hash4((uint4)(sx | (sy << 16), frame * 2u + gp->eye, 0x2545F491u, gp->seed));
  const uint x = min(sx * PX_GRADIENT_STRATUM + h.x % PX_GRADIENT_STRATUM, gp->width - 1u);
  const uint y = sy * PX_GRADIENT_STRATUM + h.y % PX_GRADIENT_STRATUM;
  return (uint2)(x, clamp(y, gp->lo_row, gp->hi_row - 1u));
}

/* Luminance of the path through texel g's surface point seen from `origin`, with `key`'s random
 * numbers; *ok = 0 where the point is not what the camera ray meets (hidden, or gone), or the
 * shade is not finite. A miss texel holds its ray's direction: the environment that way. */
inline float px_gradient_shade(const SceneView* scene, const FrameParams* fp, float3 origin,
                               const global GBufferTexel* g, SampleKey key, volatile global uint* nonfinite, int* ok) {
  *ok = 0;
  const int miss = g->material_class == PX_CLASS_MISS;
  float3 dir = (float3)(g->pos[0], g->pos[1], g->pos[2]);
  if (!miss) dir -= origin;
  const float len = length(dir);
  if (!(len > 0.0f)) return 0.0f;
  dir /= len;
  const Hit hit = px_trace_closest_leaf(scene, origin, dir, 0.0f, INFINITY);
  /* The texel names the scene's triangle; the hit, the BVH leaf's (which holds the former). */
  if (miss ? hit.prim != PX_NO_HIT
           : (hit.prim == PX_NO_HIT || scene->tris[hit.prim].prim != g->prim || hit.inst != g->inst))
    return 0.0f;
  float4 albedo;
  const float l = px_luminance(px_trace_path_from_hit(scene, fp, origin, dir, key, hit, 0, &albedo));
  if (!isfinite(l)) {
    atomic_inc(nonfinite);
    return 0.0f;
  }
  *ok = 1;
  return fmax(l, 0.0f);
}

/* Stratum `gid` of strata rows [s_row0, s_row0 + s_rows) (the caller checks gid < s_rows * strata_w).
 * Writes
 *   ref[pick]: (this frame's shade of this frame's pick, 1 if valid else 0, frame, 0), in the
 *              full-frame per-pixel buffer next frame reads as `prev_ref` (it moves between
 *              devices with the strips like SVGF's history, by pixel rows);
 *   raw[s]:    (shade now, shade last frame, the larger of the two, |their difference|) for last
 *              frame's pick, or 0 without a gradient. */
inline void px_gradient_stratum(const SceneView* scene, uint gid, global float4* raw, global float4* ref,
                                const global float4* prev_ref, const global GBufferTexel* gbuf,
                                const global GBufferTexel* prev_gbuf, volatile global uint* nonfinite,
                                const global float4* tri_motion, const FrameParams* fp, const CameraParams* cam,
                                const GradientParams* gp) {
  const uint sx = gid % gp->strata_w, sy = gp->s_row0 + gid / gp->strata_w;
  const float3 origin = px_camera_origin(cam);

  const uint2 now = px_gradient_pick(sx, sy, gp->frame, gp);
  const uint pn = now.y * gp->width + now.x;
  int ok;
  const SampleKey key_now = px_sample_key(now.x, now.y, gp->frame, gp->eye, PX_GRADIENT_SAMPLE, gp->seed);
  const float shade_now = px_gradient_shade(scene, fp, origin, gbuf + pn, key_now, nonfinite, &ok);
  ref[pn] = (float4)(shade_now, ok ? 1.0f : 0.0f, (float)(gp->frame & 0xFFFFu), 0.0f);

  float4 out = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
  if (gp->have_history && gp->frame > 0u) {
    const uint2 was = px_gradient_pick(sx, sy, gp->frame - 1u, gp);
    const uint pw = was.y * gp->width + was.x;
    const float4 before = prev_ref[pw];
    const global GBufferTexel* g = prev_gbuf + pw;
    /* Last frame's shade of this very pixel (a pick clamped by other rows last frame, or a buffer
     * left from an older frame, is not). */
    const int known = before.y > 0.0f && before.z == (float)((gp->frame - 1u) & 0xFFFFu);
    const int moved = tri_motion && px_texel_moved(tri_motion, scene->instances, g);
    if (known && !moved) {
      const SampleKey key_was = px_sample_key(was.x, was.y, gp->frame - 1u, gp->eye, PX_GRADIENT_SAMPLE, gp->seed);
      const float shade = px_gradient_shade(scene, fp, origin, g, key_was, nonfinite, &ok);
      if (ok) out = (float4)(shade, before.x, fmax(shade, before.x), fabs(shade - before.x));
    }
  }
  raw[sy * gp->strata_w + sx] = out;
}

#endif /* PARALLAX_GRADIENT_STRATUM_H */
