/* Warping uniform numbers to directions and points, with their densities. */
#ifndef PARALLAX_WARP_H
#define PARALLAX_WARP_H

#define PX_PI 3.14159265358979f
#define PX_INV_PI 0.318309886183791f

/* Orthonormal basis around unit n (Duff et al. 2017, branchless). */
inline void px_basis(float3 n, float3* t, float3* b) {
  const float s = n.z >= 0.0f ? 1.0f : -1.0f;
  const float a = -1.0f / (s + n.z);
  const float c = n.x * n.y * a;
  *t = (float3)(1.0f + s * n.x * n.x * a, s * c, -s * n.x);
  *b = (float3)(c, s + n.y * n.y * a, -n.y);
}

inline float3 px_to_world(float3 v, float3 n) {
  float3 t, b;
  px_basis(n, &t, &b);
  return v.x * t + v.y * b + v.z * n;
}

/* Cosine-weighted hemisphere around +z; pdf = cos(theta) / pi. */
inline float3 px_cosine_hemisphere(float u1, float u2) {
  const float r = sqrt(u1);
  const float phi = 2.0f * PX_PI * u2;
  return (float3)(r * cos(phi), r * sin(phi), sqrt(fmax(0.0f, 1.0f - u1)));
}

/* Uniform sphere; pdf = 1 / (4 pi). */
inline float3 px_uniform_sphere(float u1, float u2) {
  const float z = 1.0f - 2.0f * u1;
  const float r = sqrt(fmax(0.0f, 1.0f - z * z));
  const float phi = 2.0f * PX_PI * u2;
  return (float3)(r * cos(phi), r * sin(phi), z);
}

/* Uniform direction in the cone of half-angle acos(cos_max) around +z;
 * pdf = 1 / (2 pi (1 - cos_max)). */
inline float3 px_uniform_cone(float u1, float u2, float cos_max) {
  const float z = 1.0f - u1 * (1.0f - cos_max);
  const float r = sqrt(fmax(0.0f, 1.0f - z * z));
  const float phi = 2.0f * PX_PI * u2;
  return (float3)(r * cos(phi), r * sin(phi), z);
}

/* Uniform point on a triangle as barycentrics (b1, b2) of v1, v2 (square-root warp). */
inline float2 px_uniform_triangle(float u1, float u2) {
  const float s = sqrt(u1);
  return (float2)(s * (1.0f - u2), s * u2);
}

/* Power heuristic with beta = 2 (Veach 1997). */
inline float px_mis_power(float a, float b) {
  const float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

#endif
