/* Smooth dielectric interface (glass, water): the exact Fresnel equations for unpolarised
 * light and Snell's law. Directions point away from the surface; n is the normal on the side
 * of the direction given, and eta is the ratio of refractive indices eta_far / eta_near across
 * the interface as seen from that side (1.5 entering glass from air, 1 / 1.5 leaving it). */
#ifndef PARALLAX_DIELECTRIC_H
#define PARALLAX_DIELECTRIC_H

/* Fraction of light reflected at incidence cosine cos_i (> 0); 1 under total internal
 * reflection. At normal incidence this is ((eta - 1) / (eta + 1))^2. */
inline float px_fresnel_dielectric(float cos_i, float eta) {
  cos_i = fmin(cos_i, 1.0f);
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return 1.0f;
  const float cos_t = sqrt(1.0f - sin2_t);
  /* s- and p-polarised amplitudes, divided through by eta_near. */
  const float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  const float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  return 0.5f * (rs * rs + rp * rp);
}

/* Direction into which w (cos_i = dot(n, w) > 0) refracts; valid only when
 * px_fresnel_dielectric(cos_i, eta) < 1. The result lies on the far side of n. */
inline float3 px_refract(float3 w, float3 n, float cos_i, float eta) {
  const float inv_eta = 1.0f / eta;
  const float sin2_t = (1.0f - cos_i * cos_i) * inv_eta * inv_eta;
  const float cos_t = sqrt(fmax(0.0f, 1.0f - sin2_t));
  return normalize(-w * inv_eta + (cos_i * inv_eta - cos_t) * n);
}

#endif
