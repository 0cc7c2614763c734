/* Counter-based sample streams. A sample value is a pure function of
 * (frame, eye, pixel x, pixel y, sample index, dimension): no state is carried between
 * work-items or devices, so a pixel's value never depends on which device, strip or work-group
 * computed it (N devices give bit-identical images to one).
 *
 * The hash is a 4D permutation in the style of Jarzynski & Olano's pcg4d (JCGT 2020): an LCG
 * step on each lane, then lanes mixed into each other, a xorshift, and the mixing again. It is
 * invertible on 4 x 32 bits, so distinct counters never collide. */
#ifndef PARALLAX_SAMPLE_STREAM_H
#define PARALLAX_SAMPLE_STREAM_H

inline uint4 px_hash4(uint4 v) {
  v = v * 1664525u + 1013904223u;
  v.x += v.y * v.w;
  v.y += v.z * v.x;
  v.z += v.x * v.y;
  v.w += v.y * v.z;
  v ^= v >> 16u;
  v.x += v.y * v.w;
  v.y += v.z * v.x;
  v.z += v.x * v.y;
  v.w += v.y * v.z;
  return v;
}

/* Everything that identifies one path's random numbers except the dimension. */
typedef struct SampleKey {
  uint pixel;     /* x | (y << 16) */
  uint frame_eye; /* frame * 2 + eye */
  uint sample;
  uint seed;
} SampleKey;

inline SampleKey px_sample_key(uint x, uint y, uint frame, uint eye, uint sample, uint seed) {
  SampleKey k;
  k.pixel = x | (y << 16);
  k.frame_eye = frame * 2u + eye;
  k.sample = sample;
  k.seed = seed;
  return k;
}

/* Four uniform numbers in [0, 1) for dimension `dim` (24-bit mantissas, never 1.0f). */
inline float4 px_sample4(SampleKey k, uint dim) {
  const uint4 h = px_hash4((uint4)(k.pixel, k.frame_eye ^ (dim << 20), k.sample, k.seed + dim * 0x9E3779B9u));
  return convert_float4(h >> 8u) * (1.0f / 16777216.0f);
}

#endif
