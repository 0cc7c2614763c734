/* Stage 8: linear radiance -> 8-bit sRGB RGBA (exposure scale, clamp, sRGB transfer curve).
 *
 * The byte of a channel value c is the number of the 255 thresholds (host/image/
 * srgb_thresholds.h: the linear values where the correctly rounded sRGB byte steps up) that are
 * <= c, found by an eight-step binary search: the exact sRGB byte without a pow per channel. */

inline uchar px_srgb8(float c, const global float* thresholds) {
  uint v = 0u;
#pragma unroll
  for (uint step = 128u; step != 0u; step >>= 1) v = thresholds[v + step] <= c ? v + step : v;
  return (uchar)v;
}

/* Pixels [first, first + count) of full-frame images. nonfinite_pixels counts pixels whose
 * radiance is NaN or infinite (written black): where only the RGBA8 image leaves the device,
 * this count is what stops a silently wrong image. */
kernel void tonemap(global uchar4* out, const global float4* radiance, uint first, uint count, float exposure,
                    volatile global uint* nonfinite_pixels, const global float* thresholds) {
  const uint gid = get_global_id(0);
  if (gid >= count) return;
  const uint i = first + gid;
  float3 c = radiance[i].xyz * exposure;
  if (any(isnan(c)) || any(isinf(c))) {
    atomic_inc(nonfinite_pixels);
    c = (float3)(0.0f, 0.0f, 0.0f);
  }
  out[i] = (uchar4)(px_srgb8(c.x, thresholds), px_srgb8(c.y, thresholds), px_srgb8(c.z, thresholds), (uchar)255);
}
