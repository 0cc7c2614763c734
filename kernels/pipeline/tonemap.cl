/* Stage 8: linear radiance -> 8-bit sRGB RGBA (exposure scale, clamp, sRGB transfer curve). */
inline float px_srgb(float c) {
  c = clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * pow(c, 1.0f / 2.4f) - 0.055f;
}

/* Pixels [first, first + count) of full-frame images. */
kernel void tonemap(global uchar4* out, const global float4* radiance, uint first, uint count, float exposure) {
  const uint gid = get_global_id(0);
  if (gid >= count) return;
  const uint i = first + gid;
  const float3 c = radiance[i].xyz * exposure;
  out[i] = (uchar4)((uchar)(px_srgb(c.x) * 255.0f + 0.5f), (uchar)(px_srgb(c.y) * 255.0f + 0.5f),
                    (uchar)(px_srgb(c.z) * 255.0f + 0.5f), (uchar)255);
}
