/* The one BSDF the scenes need: a Lambertian base plus a specular lobe that is either GGX
 * (glossy, OBJ Ks/Ns) or a perfect mirror; or, for glass, a smooth dielectric (Fresnel
 * reflection and refraction, both delta lobes: shading/dielectric.h).
 *
 *   f(wo, wi) = kd (1 - max(ks)) / pi  +  ks D(h) G(wo, wi) / (4 |n.wo| |n.wi|)
 *
 * Scaling the diffuse part by 1 - max(ks) keeps the total albedo <= 1 (no Fresnel: ks plays
 * the role of a constant reflectance). The specular lobe is picked for sampling with
 * probability proportional to its weight's luminance. All directions point away from the
 * surface; n is the shading normal flipped to the side of wo. */
#ifndef PARALLAX_BSDF_H
#define PARALLAX_BSDF_H

#include "shared/types.h"
#include "sampling/warp.h"
#include "shading/dielectric.h"

typedef struct Bsdf {
  float3 diffuse;      /* already scaled by 1 - max(ks) */
  float3 specular;     /* dielectric: tint of the reflected part */
  float alpha;         /* GGX roughness (alpha = roughness^2 is NOT applied: the material stores alpha) */
  int mirror;          /* specular lobe is a delta */
  float p_specular;    /* probability of sampling the specular lobe */
  int dielectric;      /* smooth dielectric: every sample is a delta reflection or refraction */
  float eta;           /* dielectric: eta_far / eta_near as seen from wo's side */
  float3 transmission; /* dielectric: filter on the refracted part */
} Bsdf;

inline float px_luminance(float3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

inline Bsdf px_make_bsdf(float3 diffuse, float3 specular, float alpha, int mirror) {
  Bsdf b;
  const float ks_max = fmax(specular.x, fmax(specular.y, specular.z));
  b.diffuse = diffuse * (1.0f - fmin(ks_max, 1.0f));
  b.specular = specular;
  b.mirror = mirror || alpha <= 0.0f;
  /* Very small alpha makes D overflow in float; such lobes are mirrors in all but name. */
  b.alpha = fmax(alpha, 1e-3f);
  const float ld = px_luminance(b.diffuse), ls = px_luminance(specular);
  b.p_specular = ld + ls > 0.0f ? ls / (ld + ls) : 0.0f;
  b.dielectric = 0;
  b.eta = 1.0f;
  b.transmission = (float3)(0.0f, 0.0f, 0.0f);
  return b;
}

/* Smooth dielectric of index `ior` (inside relative to outside); `outside`: wo lies on the
 * outside. It has no smooth part (mirror with p_specular = 1), so next-event estimation, eval
 * and pdf all leave it alone; only px_bsdf_sample sees it. */
inline Bsdf px_make_dielectric_bsdf(float3 reflect_tint, float3 transmission, float ior, int outside) {
  Bsdf b;
  b.diffuse = (float3)(0.0f, 0.0f, 0.0f);
  b.specular = reflect_tint;
  b.alpha = 1e-3f;
  b.mirror = 1;
  b.p_specular = 1.0f;
  b.dielectric = 1;
  /* A non-positive or non-finite index would divide by zero in Snell's law: treat it as 1. */
  const float n = ior > 0.0f && isfinite(ior) ? ior : 1.0f;
  b.eta = outside ? n : 1.0f / n;
  b.transmission = transmission;
  return b;
}

/* What the denoiser divides a pixel's radiance by before filtering and multiplies back after:
 * the surface's reflectance, diffuse plus specular weight, within [0, 1]. Any colour that
 * scales all reflected light works, as long as the same one is used both ways and it is
 * averaged over the same samples as the radiance (see px_render_pixel). */
inline float3 px_demodulation_albedo(const Bsdf* b) {
  if (PX_HAS(PX_FEATURE_DIELECTRIC) && b->dielectric)
    return (float3)(1.0f, 1.0f, 1.0f); /* glass passes (nearly) all light on */
  return clamp(b->diffuse + b->specular, 0.0f, 1.0f);
}

/* GGX normal distribution; cos_h = n.h. */
inline float px_ggx_d(float cos_h, float alpha) {
  if (cos_h <= 0.0f) return 0.0f;
  const float a2 = alpha * alpha;
  const float c2 = cos_h * cos_h;
  const float d = c2 * (a2 - 1.0f) + 1.0f;
  return a2 / (PX_PI * d * d);
}

/* Smith masking for one direction, cos_v = |n.v|. */
inline float px_ggx_g1(float cos_v, float alpha) {
  const float a2 = alpha * alpha;
  return 2.0f * cos_v / (cos_v + sqrt(a2 + (1.0f - a2) * cos_v * cos_v));
}

/* f(wo, wi) for the non-delta parts; zero below the surface. */
inline float3 px_bsdf_eval(const Bsdf* b, float3 n, float3 wo, float3 wi) {
  const float cos_o = dot(n, wo), cos_i = dot(n, wi);
  if (cos_o <= 0.0f || cos_i <= 0.0f) return (float3)(0.0f, 0.0f, 0.0f);
  float3 f = b->diffuse * PX_INV_PI;
  if (PX_HAS(PX_FEATURE_GGX) && !b->mirror && b->p_specular > 0.0f) {
    const float3 h = normalize(wo + wi);
    const float d = px_ggx_d(dot(n, h), b->alpha);
    const float g = px_ggx_g1(cos_o, b->alpha) * px_ggx_g1(cos_i, b->alpha);
    f += b->specular * (d * g / (4.0f * cos_o * cos_i));
  }
  return f;
}

/* Solid-angle density with which px_bsdf_sample produces wi (non-delta parts only). */
inline float px_bsdf_pdf(const Bsdf* b, float3 n, float3 wo, float3 wi) {
  const float cos_o = dot(n, wo), cos_i = dot(n, wi);
  if (cos_o <= 0.0f || cos_i <= 0.0f) return 0.0f;
  float pdf = (1.0f - b->p_specular) * cos_i * PX_INV_PI;
  if (PX_HAS(PX_FEATURE_GGX) && !b->mirror && b->p_specular > 0.0f) {
    const float3 h = normalize(wo + wi);
    const float cos_h = dot(n, h);
    /* Half-vector density D(h) cos_h, mapped to wi by the reflection Jacobian 1 / (4 wo.h). */
    pdf += b->p_specular * px_ggx_d(cos_h, b->alpha) * cos_h / (4.0f * fabs(dot(wo, h)));
  }
  return pdf;
}

typedef struct BsdfSample {
  float3 wi;
  float3 weight; /* f cos / pdf (for a delta lobe: ks / p_specular) */
  float pdf;     /* solid-angle pdf of the whole mixture; 0 for a delta sample */
  int delta;
  int valid;
  int transmitted; /* wi crossed the surface (dielectric refraction) */
} BsdfSample;

/* Smooth dielectric: reflect with probability F (Fresnel), else refract; each choice's
 * weight is its tint, since F / F and (1 - F) / (1 - F) cancel. Refracted radiance is scaled
 * by (eta_near / eta_far)^2 = 1 / eta^2: radiance / eta^2 is what is conserved across the
 * interface (Veach 1997, sec. 5.2), and camera paths carry radiance. */
inline BsdfSample px_dielectric_sample(const Bsdf* b, float3 n, float3 wo, float cos_o, float u) {
  BsdfSample s;
  s.pdf = 0.0f;
  s.delta = 1;
  s.valid = 1;
  const float f = px_fresnel_dielectric(cos_o, b->eta);
  if (u < f) {
    s.wi = 2.0f * cos_o * n - wo;
    s.weight = b->specular;
    s.transmitted = 0;
  } else {
    s.wi = px_refract(wo, n, cos_o, b->eta);
    s.weight = b->transmission / (b->eta * b->eta);
    s.transmitted = 1;
  }
  return s;
}

inline BsdfSample px_bsdf_sample(const Bsdf* b, float3 n, float3 wo, float3 u) {
  BsdfSample s;
  s.valid = 0;
  s.delta = 0;
  s.pdf = 0.0f;
  s.weight = (float3)(0.0f, 0.0f, 0.0f);
  s.wi = n;
  s.transmitted = 0;
  const float cos_o = dot(n, wo);
  if (cos_o <= 0.0f) return s;
  if (PX_HAS(PX_FEATURE_DIELECTRIC) && b->dielectric) return px_dielectric_sample(b, n, wo, cos_o, u.z);
  /* Without GGX and mirror lobes in the scene p_specular is <= 0 here; inside, a delta lobe
   * means a mirror material (glass returned above). */
  if ((PX_HAS(PX_FEATURE_GGX) || PX_HAS(PX_FEATURE_MIRROR)) && u.z < b->p_specular) {
    if (PX_HAS(PX_FEATURE_MIRROR) && b->mirror) {
      s.wi = 2.0f * cos_o * n - wo;
      s.delta = 1;
      s.weight = b->specular / b->p_specular;
      s.valid = 1;
      return s;
    }
    /* GGX half vector: tan^2(theta_h) = alpha^2 u / (1 - u). */
    const float a2 = b->alpha * b->alpha;
    const float cos2 = (1.0f - u.x) / (1.0f + (a2 - 1.0f) * u.x);
    const float cos_h = sqrt(fmax(0.0f, cos2));
    const float sin_h = sqrt(fmax(0.0f, 1.0f - cos2));
    const float phi = 2.0f * PX_PI * u.y;
    const float3 h = px_to_world((float3)(sin_h * cos(phi), sin_h * sin(phi), cos_h), n);
    s.wi = 2.0f * dot(wo, h) * h - wo;
  } else {
    s.wi = px_to_world(px_cosine_hemisphere(u.x, u.y), n);
  }
  const float cos_i = dot(n, s.wi);
  if (cos_i <= 0.0f) return s;
  s.pdf = px_bsdf_pdf(b, n, wo, s.wi);
  if (!(s.pdf > 0.0f)) return s;
  s.weight = px_bsdf_eval(b, n, wo, s.wi) * (cos_i / s.pdf);
  s.valid = 1;
  return s;
}

#endif
