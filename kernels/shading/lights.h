/* Lights: emissive triangles (front face only, unless their material is two-sided), point and spot lights (entries of
 * the same table, picked like the triangles: a delta, no density), and an environment made of a sun disk and an
 * analytic sky. Next-event estimation first picks a kind of light (FrameParams p_*), then: triangles - one
 * triangle by power (binary search of the CDF) or, with FrameParams::direct_light tree or restir, by the light tree's
 * importance at the shading point (light_tree.h), a uniform point on it; sun       - a uniform direction inside the
 * sun's cone; sky       - a cosine-weighted direction around the shading normal. The sun and sky form one environment:
 * a direction inside the sun's cone sees the sun, any other the sky. Its light pdf is the mixture p_sun pdf_sun + p_sky
 * pdf_sky, so a direction has the same density whichever strategy produced it, which is what MIS needs. */
#ifndef PARALLAX_LIGHTS_H
#define PARALLAX_LIGHTS_H

#include "sampling/warp.h"
#include "scene/scene_view.h"
#include "shading/bsdf.h"
#include "shading/light_tree.h"

inline float3 px_sky_radiance(const FrameParams* fp, float3 d) {
  if (!PX_HAS(PX_FEATURE_SKY)) return (float3)(0.0f, 0.0f, 0.0f); /* the host zeroes a disabled sky */
  if (d.y < 0.0f) return px_load3_private(fp->sky_ground);
  return mix(px_load3_private(fp->sky_horizon), px_load3_private(fp->sky_zenith), sqrt(d.y));
}

/* Radiance arriving along a ray that left the scene in direction d. */
inline float3 px_environment(const FrameParams* fp, float3 d) {
  if (PX_HAS(PX_FEATURE_SUN) && fp->p_sun > 0.0f && dot(d, px_load3_private(fp->sun_dir)) >= fp->sun_cos_max)
    return px_load3_private(fp->sun_radiance);
  return px_sky_radiance(fp, d);
}

/* Density (solid angle, light-type selection included) with which NEE samples d toward the
 * environment from a point with shading normal n. */
inline float px_environment_pdf(const FrameParams* fp, float3 n, float3 d) {
  float pdf = 0.0f;
  if (PX_HAS(PX_FEATURE_SUN) && fp->p_sun > 0.0f && dot(d, px_load3_private(fp->sun_dir)) >= fp->sun_cos_max)
    pdf += fp->p_sun / (2.0f * PX_PI * (1.0f - fp->sun_cos_max));
  if (PX_HAS(PX_FEATURE_SKY) && fp->p_sky > 0.0f) pdf += fp->p_sky * fmax(0.0f, dot(n, d)) * PX_INV_PI;
  return pdf;
}

/* Index into the light table of scene triangle `prim` (the table is sorted by prim), or -1. */
inline int px_find_light(const SceneView* s, uint count, uint prim) {
  int lo = 0, hi = (int)count - 1;
  while (lo <= hi) {
    const int mid = (lo + hi) / 2;
    const uint p = s->lights[mid].prim;
    if (p == prim) return mid;
    if (p < prim)
      lo = mid + 1;
    else
      hi = mid - 1;
  }
  return -1;
}

/* Whether next-event estimation picks triangles through the light tree (restir draws its
 * candidates the same way). */
inline int px_direct_light_tree(const FrameParams* fp) { return fp->direct_light != PX_DIRECT_POWER; }

/* The probability that next-event estimation at point p with shading normal n picks emissive
 * triangle `light` (index into the table) among the triangles. */
inline float px_light_select_pmf(const SceneView* s, const FrameParams* fp, int light, float3 p, float3 n) {
  if (px_direct_light_tree(fp)) return px_light_tree_pmf(s, fp->light_count, p, n, light);
  return s->lights[light].pdf_select;
}

/* Density (solid angle, selection included) of NEE reaching emissive triangle `l`, picked with
 * probability `select` among the triangles, at distance `dist`, arriving with cosine
 * `cos_light` to its plane. */
inline float px_triangle_light_pdf(const FrameParams* fp, const global LightTriangle* l, float select, float dist,
                                   float cos_light) {
  if (cos_light <= 0.0f || l->area <= 0.0f) return 0.0f;
  return fp->p_triangles * select * dist * dist / (l->area * cos_light);
}

/* The point with barycentrics b on emissive triangle *l as seen from p: the direction *wi and
 * distance *dist to it, and in *cos_light the |cosine| at the light. 0 where it sends p nothing:
 * p on its plane, or behind a one-sided emitter (exactly as a BSDF-sampled ray that hits its back
 * gets no emission). Shared by next-event estimation and ReSTIR's evaluation of a kept sample. */
inline int px_triangle_light_point(const SceneView* s, const global LightTriangle* l, float2 b, float3 p, float3* wi,
                                   float* dist, float* cos_light) {
  const float3 v0 = px_load3(l->v0), v1 = px_load3(l->v1), v2 = px_load3(l->v2);
  const float3 q = (1.0f - b.x - b.y) * v0 + b.x * v1 + b.y * v2;
  const float3 to = q - p;
  const float d2 = dot(to, to);
  if (!(d2 > 0.0f)) return 0;
  *dist = sqrt(d2);
  *wi = to / *dist;
  const float3 ng = normalize(cross(v1 - v0, v2 - v0));
  const uint flags = s->materials[s->shading[l->prim].material].flags;
  if (!(PX_HAS(PX_FEATURE_TWO_SIDED) && (flags & PX_MAT_TWO_SIDED_EMITTER)) && dot(ng, *wi) >= 0.0f) return 0;
  *cos_light = fabs(dot(ng, *wi));
  return 1;
}

typedef struct LightSample {
  float3 wi;
  float dist; /* INFINITY for the environment */
  float3 radiance;
  float pdf; /* solid angle, light-type selection included; 0 = no sample */
  int delta; /* a point or spot light: radiance is I falloff / d^2, pdf the probability of picking
              * it (no density; no BSDF sample reaches it, so its MIS weight is 1) */
} LightSample;

/* Whether light table entry l is a point or spot light (types.h, LightTriangle). */
inline int px_is_punctual_light(const global LightTriangle* l) {
  return PX_HAS(PX_FEATURE_PUNCTUAL) && l->prim >= PX_LIGHT_PUNCTUAL;
}

/* A point or spot light seen from p: the unit direction to it in *wi, the distance in *dist, and
 * its intensity towards p (glTF's spot falloff: the square of a ramp in the cosine to the axis,
 * whose scale and offset are v2[0], v2[1]; 1 for a point light). 0 when p is on the light. */
inline float3 px_punctual_light_towards(const global LightTriangle* l, float3 p, float3* wi, float* dist) {
  const float3 to = px_load3(l->v0) - p;
  const float d2 = dot(to, to);
  *dist = sqrt(d2);
  *wi = d2 > 0.0f ? to / *dist : (float3)(0.0f, 0.0f, 1.0f);
  if (!(d2 > 0.0f)) return (float3)(0.0f, 0.0f, 0.0f);
  const float a = clamp(dot(px_load3(l->v1), -*wi) * l->v2[0] + l->v2[1], 0.0f, 1.0f);
  return px_load3(l->emission) * (a * a);
}

/* One emissive triangle for next-event estimation at point p with shading normal n, by the
 * direct-light strategy (power: the first entry whose inclusive CDF exceeds u; tree: the light
 * tree's walk), its selection probability in *select; -1 for none. ReSTIR's candidates are picked
 * by the same function. */
inline int px_pick_triangle_light(const SceneView* s, const FrameParams* fp, float3 p, float3 n, float u,
                                  float* select) {
  *select = 0.0f;
  if (fp->light_count == 0u) return -1;
  if (px_direct_light_tree(fp)) return px_light_tree_sample(s, fp->light_count, p, n, u, select);
  int lo = 0, hi = (int)fp->light_count - 1;
  while (lo < hi) {
    const int mid = (lo + hi) / 2;
    if (s->lights[mid].cdf > u)
      hi = mid;
    else
      lo = mid + 1;
  }
  *select = s->lights[lo].pdf_select;
  return lo;
}

/* A light sample for point p with shading normal n (the tree's choice depends on both: the MIS
 * weight of a BSDF-sampled hit asks px_light_select_pmf at the same p and n). */
inline LightSample px_sample_light(const SceneView* s, const FrameParams* fp, float3 p, float3 n, float4 u) {
  LightSample ls;
  ls.pdf = 0.0f;
  ls.dist = INFINITY;
  ls.radiance = (float3)(0.0f, 0.0f, 0.0f);
  ls.wi = n;
  ls.delta = 0;
  float pick = u.z;
  if (PX_HAS(PX_FEATURE_EMISSIVE) && pick < fp->p_triangles) {
    float select;
    const int lo = px_pick_triangle_light(s, fp, p, n, u.w, &select);
    if (lo < 0) return ls;
    const global LightTriangle* l = s->lights + lo;
    if (px_is_punctual_light(l)) {
      const float3 intensity = px_punctual_light_towards(l, p, &ls.wi, &ls.dist);
      if (!(ls.dist > 0.0f) || !(px_luminance(intensity) > 0.0f)) return ls;
      ls.radiance = intensity / (ls.dist * ls.dist);
      ls.pdf = fp->p_triangles * select;
      ls.delta = 1;
      return ls;
    }
    float cos_light;
    if (!px_triangle_light_point(s, l, px_uniform_triangle(u.x, u.y), p, &ls.wi, &ls.dist, &cos_light)) return ls;
    ls.pdf = px_triangle_light_pdf(fp, l, select, ls.dist, cos_light);
    ls.radiance = px_load3(l->emission);
    return ls;
  }
  pick -= fp->p_triangles;
  if (PX_HAS(PX_FEATURE_SUN) && pick < fp->p_sun) {
    const float3 sd = px_load3_private(fp->sun_dir);
    ls.wi = px_to_world(px_uniform_cone(u.x, u.y, fp->sun_cos_max), sd);
  } else if (PX_HAS(PX_FEATURE_SKY) && fp->p_sky > 0.0f) {
    ls.wi = px_to_world(px_cosine_hemisphere(u.x, u.y), n);
  } else {
    return ls;
  }
  ls.pdf = px_environment_pdf(fp, n, ls.wi);
  ls.radiance = px_environment(fp, ls.wi);
  return ls;
}

#endif
