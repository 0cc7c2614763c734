/* A pixel's value from its samples, shared by every path tracer (path_trace.cl's kernels and
 * wavefront.cl's wf_resolve), so that they agree to the last bit. */
#ifndef PARALLAX_PIXEL_MEAN_H
#define PARALLAX_PIXEL_MEAN_H

inline int px_finite3(float3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

/* Adds sample l to the pixel's *sum if l is finite and the sum stays finite (a few samples near the
 * float limit can overflow it); returns whether it did. A sample not added is dropped from the
 * pixel's mean and counted as non-finite by the caller. */
inline int px_add_sample(float3* sum, float3 l) {
  if (!px_finite3(l)) return 0;
  const float3 s = *sum + l;
  if (!px_finite3(s)) return 0;
  *sum = s;
  return 1;
}

/* The primary albedo a sample adds to its pixel's sum: an emitter's first hit (w -1) counts as
 * no coverage, as the environment's. */
inline float4 px_albedo_counted(float4 a) { return (float4)(a.xyz, fmax(a.w, 0.0f)); }

/* A sample's kind for PX_GBUFFER_RAY_FIRST_KIND: 1 if its first hit was an emitter, else 0. */
inline int px_sample_kind(float4 a) { return a.w < 0.0f ? 1 : 0; }

/* Whether a sample of kind `kind` counts in a pixel whose first counted sample was of kind
 * `first_kind` (-1: none counted yet). With PX_GBUFFER_RAY_FIRST_KIND, a lamp's sample does not
 * count in a pixel that started on the ceiling, nor the ceiling's in one that started on the lamp:
 * the denoiser's texel describes one of them, and the filter darkened the mix. */
inline int px_same_kind(int same_kind_only, int first_kind, int kind) {
  return !same_kind_only || first_kind < 0 || kind == first_kind;
}

/* Counts sample l, whose first hit's albedo is a, into its pixel's sums: the radiance *sum, the
 * counted albedo *albedo_sum, the count *good and the first counted sample's kind *first_kind.
 * Returns 0 where l is not finite (whatever its kind) or adding it overflowed the sum: the caller
 * counts that sample non-finite. A sample of the other kind (px_same_kind) is left out and not
 * counted as lost.
 * The megakernel, the hole filler and the wavefront all count through here, so that they agree
 * to the last bit. */
inline int px_count_sample(float3* sum, float4* albedo_sum, uint* good, int* first_kind, int same_kind_only, float3 l,
                           float4 a) {
  if (!px_finite3(l)) return 0;
  const int kind = px_sample_kind(a);
  if (!px_same_kind(same_kind_only, *first_kind, kind)) return 1;
  if (!px_add_sample(sum, l)) return 0;
  *albedo_sum += px_albedo_counted(a);
  ++*good;
  if (*first_kind < 0) *first_kind = kind;
  return 1;
}

/* A pixel's mean from the sum of its `good` finite samples: (rgb, good), and in *albedo the mean
 * albedo (w: the coverage). No finite path: (1, 1, 1, 0). */
inline float4 px_pixel_mean(float3 sum, float4 albedo_sum, uint good, float4* albedo) {
  const float inv = good > 0u ? 1.0f / (float)good : 0.0f;
  *albedo = good > 0u ? albedo_sum * inv : (float4)(1.0f, 1.0f, 1.0f, 0.0f);
  return (float4)(good > 0u ? sum / (float)good : sum, (float)good);
}

#endif
