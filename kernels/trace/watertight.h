/* Watertight ray/triangle intersection (Woop, Benthin, Wald, JCGT 2013) and a conservative
 * ray/box slab test.
 *
 * Triangle: translate the vertices to the ray origin, shear so the ray runs along +z (the
 * ray's dominant axis becomes z), then evaluate the 2D edge functions U, V, W at the origin.
 * A hit needs all three with the same sign; a zero edge function means the ray passes exactly
 * through an edge or vertex, which both neighbours report consistently, so a closed mesh
 * never leaks. Division happens once, at the end, for accepted hits only. */
#ifndef PARALLAX_WATERTIGHT_H
#define PARALLAX_WATERTIGHT_H

#include "shared/types.h"

/* Watertightness rests on two triangles that share an edge computing that edge's function as
 * exact negatives of each other (x1*y2 - y1*x2 against x2*y1 - y2*x1). OpenCL C allows the
 * compiler to contract a*b - c*d into an fma by default, which rounds the two differently and
 * reopens the cracks: contraction stays off in this file. */
#pragma OPENCL FP_CONTRACT OFF

/* Per-ray constants of the shear transform, computed once per ray. */
typedef struct RayShear {
  float ox, oy, oz; /* the origin in the permuted axis order (kx, ky, kz) */
  int kx, ky, kz;   /* permuted axes; kz = dominant direction axis */
  float sx, sy, sz;
} RayShear;

inline float px_axis(float3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

inline RayShear px_make_shear(float3 org, float3 dir) {
  RayShear s;
  float3 a = fabs(dir);
  s.kz = (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
  s.kx = s.kz == 2 ? 0 : s.kz + 1;
  s.ky = s.kx == 2 ? 0 : s.kx + 1;
  /* Keep the winding: if the dominant component is negative, swap x and y. */
  if (px_axis(dir, s.kz) < 0.0f) {
    int t = s.kx;
    s.kx = s.ky;
    s.ky = t;
  }
  float dz = px_axis(dir, s.kz);
  s.sx = px_axis(dir, s.kx) / dz;
  s.sy = px_axis(dir, s.ky) / dz;
  s.sz = 1.0f / dz;
  /* Picked once per ray: every triangle test needs them, and picking is three selects each. */
  s.ox = px_axis(org, s.kx);
  s.oy = px_axis(org, s.ky);
  s.oz = px_axis(org, s.kz);
  return s;
}

/* Returns 1 and sets *t, *u, *v (barycentrics of v1, v2) on a hit with tmin < t < tmax.
 * The lower end is open, as in Embree: a ray whose origin lies exactly in a triangle's plane
 * (t = +0 or -0 in float) must not hit that triangle at distance zero, which with tmin = 0 and
 * a closed lower end it did whenever the edge functions put the origin inside it.
 * Vertices are read component-wise in the ray's permuted axis order straight from memory
 * (indexed loads), which is cheaper than permuting float3 values with selects; `stride` is the
 * distance in floats between a vertex's x, y and z (1 for float[3]; 4 for a lane of a leaf
 * block's rows). Forced inline for the wide traversal's leaf test (traverse.h, px_intersect_block). */
__attribute__((always_inline)) inline int px_intersect_triangle_strided(const RayShear* s, const global float* v0,
                                                                        const global float* v1, const global float* v2,
                                                                        int stride, float tmin, float tmax, float* t,
                                                                        float* u, float* v) {
  const float ox = s->ox, oy = s->oy, oz = s->oz;
  const int kx = stride * s->kx, ky = stride * s->ky, kz = stride * s->kz;
  const float az = v0[kz] - oz, bz = v1[kz] - oz, cz = v2[kz] - oz;
  const float ax = (v0[kx] - ox) - s->sx * az;
  const float ay = (v0[ky] - oy) - s->sy * az;
  const float bx = (v1[kx] - ox) - s->sx * bz;
  const float by = (v1[ky] - oy) - s->sy * bz;
  const float cx = (v2[kx] - ox) - s->sx * cz;
  const float cy = (v2[ky] - oy) - s->sy * cz;
  float eu = cx * by - cy * bx;
  float ev = ax * cy - ay * cx;
  float ew = bx * ay - by * ax;
#ifdef cl_khr_fp64
  /* An exact zero in single precision may be a rounding artefact of a ray that grazes an
   * edge; double precision decides the sign so both triangles sharing the edge agree. */
  if (eu == 0.0f || ev == 0.0f || ew == 0.0f) {
    eu = (float)((double)cx * (double)by - (double)cy * (double)bx);
    ev = (float)((double)ax * (double)cy - (double)ay * (double)cx);
    ew = (float)((double)bx * (double)ay - (double)by * (double)ax);
  }
#endif
  if ((eu < 0.0f || ev < 0.0f || ew < 0.0f) && (eu > 0.0f || ev > 0.0f || ew > 0.0f)) return 0;
  float det = eu + ev + ew;
  if (det == 0.0f) return 0; /* ray in the triangle's plane, or degenerate triangle */

  float tt = eu * (s->sz * az) + ev * (s->sz * bz) + ew * (s->sz * cz);
  /* Compare t against the interval without dividing: flip signs so det > 0. */
  if (det < 0.0f) {
    det = -det;
    tt = -tt;
    ev = -ev;
    ew = -ew;
  }
  if (tt <= tmin * det || tt >= tmax * det) return 0;
  const float inv = 1.0f / det;
  *t = tt * inv;
  *u = ev * inv;
  *v = ew * inv;
  return 1;
}

/* Reciprocal direction without infinities: a zero component becomes a huge finite value of
 * the right sign, so (box - origin) * inv never evaluates 0 * inf = NaN. */
inline float3 px_safe_inverse(float3 d) {
  const float big = 1e30f;
  float3 r;
  r.x = fabs(d.x) > 1e-30f ? 1.0f / d.x : copysign(big, d.x);
  r.y = fabs(d.y) > 1e-30f ? 1.0f / d.y : copysign(big, d.y);
  r.z = fabs(d.z) > 1e-30f ? 1.0f / d.z : copysign(big, d.z);
  return r;
}

/* 1 + 2 * gamma(3), gamma(n) = n eps / (1 - n eps), eps = 2^-24: widening the far distance by
 * this factor makes the slab test conservative under float rounding (Ize 2013; pbrt-v4). */
#define PX_BOX_FAR_SCALE 1.00000036f

/* Slab test. Returns the entry distance, or INFINITY when the ray misses [tmin, tmax]. */
inline float px_intersect_box(float3 org, float3 inv_dir, const float* bmin_p, const float* bmax_p, float tmin,
                              float tmax) {
  const float3 bmin = (float3)(bmin_p[0], bmin_p[1], bmin_p[2]);
  const float3 bmax = (float3)(bmax_p[0], bmax_p[1], bmax_p[2]);
  const float3 t0 = (bmin - org) * inv_dir;
  const float3 t1 = (bmax - org) * inv_dir;
  const float3 tnear = fmin(t0, t1);
  const float3 tfar = fmax(t0, t1);
  const float enter = fmax(fmax(tnear.x, tnear.y), fmax(tnear.z, tmin));
  const float leave = fmin(fmin(tfar.x, tfar.y), fmin(tfar.z, tmax)) * PX_BOX_FAR_SCALE;
  return enter <= leave ? enter : INFINITY;
}

#endif
