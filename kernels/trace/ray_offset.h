/* Self-intersection-free secondary ray origins (Wächter & Binder, "A Fast and Robust Method
 * for Avoiding Self-Intersection", Ray Tracing Gems ch. 6). The hit point is pushed off the
 * surface along the geometric normal by a fixed number of ULPs, so the offset scales with the
 * coordinate's magnitude: no global epsilon, and it works at 1e5-1e6 units. Near the origin,
 * where ULPs are tiny, a small fixed offset takes over. */
#ifndef PARALLAX_RAY_OFFSET_H
#define PARALLAX_RAY_OFFSET_H

#define PX_OFFSET_ORIGIN (1.0f / 32.0f)
#define PX_OFFSET_FLOAT_SCALE (1.0f / 65536.0f)
#define PX_OFFSET_INT_SCALE 256.0f

inline float px_offset_component(float p, float n) {
  int of_i = (int)(PX_OFFSET_INT_SCALE * n);
  /* Moving away from zero in ULPs means adding to the integer bits of a positive float and
   * subtracting from those of a negative one. */
  float p_i = as_float(as_int(p) + (p < 0.0f ? -of_i : of_i));
  return fabs(p) < PX_OFFSET_ORIGIN ? p + PX_OFFSET_FLOAT_SCALE * n : p_i;
}

/* p: hit point; n: geometric normal on the side the new ray leaves from (flip it for
 * transmission or for rays leaving the back face). */
inline float3 px_offset_ray_origin(float3 p, float3 n) {
  return (float3)(px_offset_component(p.x, n.x), px_offset_component(p.y, n.y), px_offset_component(p.z, n.z));
}

#endif
