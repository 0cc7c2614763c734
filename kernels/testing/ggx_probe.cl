/* The opaque BSDF (Lambert + GGX, shading/bsdf.h) for the absolute checks in
 * tests/test_path_tracer.cpp (Ggx.*), which compare it with an independent double-precision
 * host implementation and its quadrature. Shading frame: n = +z. Each work-item has its own
 * outgoing direction, so one launch covers many (wo, wi) pairs. */
#include "shared/types.h"
#include "sampling/sample_stream.h"
#include "sampling/warp.h"
#include "shading/bsdf.h"

/* out[i] = (f(wo[i], wi[i]).xyz, pdf). */
kernel void ggx_eval(const global float4* wo, const global float4* wi, global float4* out, uint count, float4 diffuse,
                     float4 specular_alpha) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const Bsdf b = px_make_bsdf(diffuse.xyz, specular_alpha.xyz, specular_alpha.w, 0);
  const float3 n = (float3)(0.0f, 0.0f, 1.0f);
  out[i] = (float4)(px_bsdf_eval(&b, n, wo[i].xyz, wi[i].xyz), px_bsdf_pdf(&b, n, wo[i].xyz, wi[i].xyz));
}

/* Sample i from direction wo: out[i] = (weight.xyz, 1) for a valid sample, else 0. */
kernel void ggx_sample(global float4* out, uint count, float4 diffuse, float4 specular_alpha, float4 wo4, uint seed) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const Bsdf b = px_make_bsdf(diffuse.xyz, specular_alpha.xyz, specular_alpha.w, 0);
  const float3 n = (float3)(0.0f, 0.0f, 1.0f);
  const float4 u = px_sample4(px_sample_key(i & 0xffffu, i >> 16, 0u, 0u, 0u, seed), 0u);
  const BsdfSample s = px_bsdf_sample(&b, n, normalize(wo4.xyz), u.xyz);
  out[i] = s.valid ? (float4)(s.weight, 1.0f) : (float4)(0.0f, 0.0f, 0.0f, 0.0f);
}
