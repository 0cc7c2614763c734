/* Stage 8: linear radiance -> 8-bit sRGB RGBA (exposure scale, clamp, sRGB transfer curve). */
inline float px_srgb(float c) {
  c = clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * pow(c, 1.0f / 2.4f) - 0.055f;
}

/* Pixels [first, first + count) of full-frame images. nonfinite_pixels counts pixels whose
 * radiance is NaN or infinite (written black): where only the RGBA8 image leaves the device,
 * this count is what stops a silently wrong image. */
kernel void tonemap(global uchar4* out, const global float4* radiance, uint first, uint count, float exposure,
                    volatile global uint* nonfinite_pixels) {
  const uint gid = get_global_id(0);
  if (gid >= count) return;
  const uint i = first + gid;
  float3 c = radiance[i].xyz * exposure;
  if (any(isnan(c)) || any(isinf(c))) {
    atomic_inc(nonfinite_pixels);
    c = (float3)(0.0f, 0.0f, 0.0f);
  }
  out[i] = (uchar4)((uchar)(px_srgb(c.x) * 255.0f + 0.5f), (uchar)(px_srgb(c.y) * 255.0f + 0.5f),
                    (uchar)(px_srgb(c.z) * 255.0f + 0.5f), (uchar)255);
}
