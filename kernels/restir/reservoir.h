/* ReSTIR DI's reservoirs and the light samples they hold (Bitterli et al. 2020; the reuse is
 * weighted as in Lin et al. 2022's generalized RIS, which keeps it unbiased).
 *
 * A light sample is stored by what it is, not by where it landed: (light, y) with `light` an
 * index into the LightTriangle table and y = (b1, b2) barycentrics on it, or PX_RESTIR_ENVIRONMENT
 * with y a direction. Evaluating a sample therefore re-reads the light's current vertices and
 * emission: a reservoir kept from last frame lights a pixel from where its lamp is now, never
 * from where it was. Triangle samples are measured by area, environment samples by solid angle
 * and point or spot lights (y unused) by counting, for every pixel alike, so moving a sample
 * between pixels needs no Jacobian.
 *
 * Kept per pixel as two float4 (32 bytes):
 *   [0] light (uint bits), y.x, y.y, y.z
 *   [1] W (unbiased contribution weight), M (confidence: candidates behind it),
 *       tag (uint bits: the frame that wrote it, plus one; 0 = none), 0 */
#ifndef PARALLAX_RESTIR_RESERVOIR_H
#define PARALLAX_RESTIR_RESERVOIR_H

#include "restir/restir_params.h"
#include "restir/shading_point.h"
#include "shading/lights.h"

#define PX_RESTIR_NO_LIGHT 0xffffffffu
#define PX_RESTIR_ENVIRONMENT 0xfffffffeu

typedef struct Reservoir {
  uint light;
  float3 y;
  float W;
  float M;
  uint tag;
} Reservoir;

inline Reservoir px_empty_reservoir(uint tag) {
  Reservoir r;
  r.light = PX_RESTIR_NO_LIGHT;
  r.y = (float3)(0.0f, 0.0f, 0.0f);
  r.W = 0.0f;
  r.M = 0.0f;
  r.tag = tag;
  return r;
}

inline Reservoir px_load_reservoir(const global float4* buf, uint pixel) {
  const float4 a = buf[2 * (size_t)pixel], b = buf[2 * (size_t)pixel + 1];
  Reservoir r;
  r.light = as_uint(a.x);
  r.y = a.yzw;
  r.W = b.x;
  r.M = b.y;
  r.tag = as_uint(b.z);
  return r;
}

inline void px_store_reservoir(global float4* buf, uint pixel, Reservoir r) {
  buf[2 * (size_t)pixel] = (float4)(as_float(r.light), r.y);
  buf[2 * (size_t)pixel + 1] = (float4)(r.W, r.M, as_float(r.tag), 0.0f);
}

/* What light sample (light, y) sends to shading point *sp, shadows aside. */
typedef struct LightContribution {
  float3 wi;
  float dist;        /* INFINITY for the environment */
  float3 unshadowed; /* f(wo, wi) Le cos_surface G: per unit area of the light, or per steradian */
  float target;      /* p-hat: the luminance of `unshadowed` (0: the sample cannot light sp) */
} LightContribution;

inline LightContribution px_restir_evaluate(const SceneView* s, const FrameParams* fp, const ShadingPoint* sp,
                                            uint light, float3 y) {
  LightContribution c;
  c.wi = sp->ns;
  c.dist = INFINITY;
  c.unshadowed = (float3)(0.0f, 0.0f, 0.0f);
  c.target = 0.0f;
  if (!sp->valid) return c;
  float3 le;
  float g = 1.0f;
  if (light == PX_RESTIR_ENVIRONMENT) {
    c.wi = y;
    le = px_environment(fp, y);
  } else if (PX_HAS(PX_FEATURE_EMISSIVE) && light < fp->light_count && px_is_punctual_light(s->lights + light)) {
    /* A point or spot light: Le is its intensity towards sp, G = 1 / d^2 (no cosine at it). */
    le = px_punctual_light_towards(s->lights + light, sp->p, &c.wi, &c.dist);
    if (!(c.dist > 0.0f)) return c;
    g = 1.0f / (c.dist * c.dist);
  } else if (PX_HAS(PX_FEATURE_EMISSIVE) && light < fp->light_count) {
    const global LightTriangle* l = s->lights + light;
    float cos_light;
    if (!px_triangle_light_point(s, l, y.xy, sp->p, &c.wi, &c.dist, &cos_light)) return c;
    g = cos_light / (c.dist * c.dist);
    le = px_load3(l->emission);
  } else {
    return c;
  }
  const float cos_s = dot(sp->ns, c.wi);
  if (!(dot(sp->ng, c.wi) > 0.0f) || !(cos_s > 0.0f)) return c;
  const float3 f = px_bsdf_eval(&sp->bsdf, sp->ns, sp->wo, c.wi);
  c.unshadowed = f * le * (cos_s * g);
  const float t = px_luminance(c.unshadowed);
  c.target = isfinite(t) && t > 0.0f ? t : 0.0f;
  return c;
}

/* One candidate for shading point *sp from the scene's light sampler (the kinds as
 * px_sample_light picks them; among triangles by the chosen direct-light strategy): writes
 * (*light, *y) and returns its source density in the sample's measure (area for triangles,
 * solid angle for the environment, counting for a point or spot light), 0 for no candidate. */
inline float px_restir_candidate(const SceneView* s, const FrameParams* fp, const ShadingPoint* sp, float4 u,
                                 uint* light, float3* y) {
  *light = PX_RESTIR_NO_LIGHT;
  *y = (float3)(0.0f, 0.0f, 0.0f);
  float pick = u.z;
  if (PX_HAS(PX_FEATURE_EMISSIVE) && pick < fp->p_triangles) {
    float pmf = 0.0f;
    const int li = px_pick_triangle_light(s, fp, sp->p, sp->ns, u.w, &pmf);
    if (li < 0 || !(pmf > 0.0f)) return 0.0f;
    const global LightTriangle* l = s->lights + li;
    if (px_is_punctual_light(l)) {
      *light = (uint)li;
      return fp->p_triangles * pmf; /* counting measure: the probability of the light itself */
    }
    if (!(l->area > 0.0f)) return 0.0f;
    const float2 b = px_uniform_triangle(u.x, u.y);
    *light = (uint)li;
    *y = (float3)(b.x, b.y, 0.0f);
    return fp->p_triangles * pmf / l->area;
  }
  pick -= fp->p_triangles;
  float3 wi;
  if (PX_HAS(PX_FEATURE_SUN) && pick < fp->p_sun)
    wi = px_to_world(px_uniform_cone(u.x, u.y, fp->sun_cos_max), px_load3_private(fp->sun_dir));
  else if (PX_HAS(PX_FEATURE_SKY) && fp->p_sky > 0.0f)
    wi = px_to_world(px_cosine_hemisphere(u.x, u.y), sp->ns);
  else
    return 0.0f;
  *light = PX_RESTIR_ENVIRONMENT;
  *y = wi;
  return px_environment_pdf(fp, sp->ns, wi);
}

/* Streaming resampling: adds resampling weight w to the running sum and takes sample
 * (light, y) with probability w / (running sum), using the uniform number u. Returns whether it
 * was taken. */
inline int px_reservoir_offer(Reservoir* r, float* wsum, uint light, float3 y, float w, float u) {
  if (!(w > 0.0f) || !isfinite(w)) return 0;
  *wsum += w;
  if (!(u * *wsum < w)) return 0;
  r->light = light;
  r->y = y;
  return 1;
}

#endif
