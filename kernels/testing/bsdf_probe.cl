/* Exposes the kernels' BSDF routines to the test suite, which checks them statistically on
 * the host (pdf integrates to the valid-sample fraction, sample and pdf agree, the sampled
 * distribution matches the pdf bin by bin, Fresnel and Snell for glass). Shading frame:
 * n = +z, on wo's side.
 *
 * dielectric: x = index of refraction (0 = the opaque BSDF given by diffuse / specular_alpha /
 * mirror), y = 1 when wo lies outside the glass, 0 when inside. */
#include "sampling/sample_stream.h"
#include "sampling/warp.h"
#include "shading/bsdf.h"

inline Bsdf px_probe_bsdf(float4 diffuse, float4 specular_alpha, uint mirror, float4 dielectric) {
  if (dielectric.x > 0.0f)
    return px_make_dielectric_bsdf((float3)(1.0f, 1.0f, 1.0f), diffuse.xyz, dielectric.x, dielectric.y > 0.5f);
  return px_make_bsdf(diffuse.xyz, specular_alpha.xyz, specular_alpha.w, (int)mirror);
}

/* One BSDF sample per work-item: out[i] = (wi.xyz, pdf from sample), out2[i] = (weight.xyz,
 * pdf recomputed by px_bsdf_pdf(wi)); weight = 0 and pdfs 0 when the sample is invalid; a
 * delta sample gets pdf -1. For a dielectric, diffuse.xyz is the transmission filter. */
kernel void probe_sample(global float4* out, global float4* out2, uint count, float4 diffuse, float4 specular_alpha,
                         uint mirror, float4 wo4, float4 dielectric, uint seed) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const Bsdf b = px_probe_bsdf(diffuse, specular_alpha, mirror, dielectric);
  const float3 n = (float3)(0.0f, 0.0f, 1.0f);
  const float3 wo = normalize(wo4.xyz);
  const float4 u = px_sample4(px_sample_key(i & 0xffffu, i >> 16, 0u, 0u, 0u, seed), 0u);
  const BsdfSample s = px_bsdf_sample(&b, n, wo, u.xyz);
  if (!s.valid) {
    out[i] = (float4)(s.wi, 0.0f);
    out2[i] = (float4)(0.0f, 0.0f, 0.0f, 0.0f);
    return;
  }
  out[i] = (float4)(s.wi, s.delta ? -1.0f : s.pdf);
  out2[i] = (float4)(s.weight, s.delta ? -1.0f : px_bsdf_pdf(&b, n, wo, s.wi));
}

/* Evaluates f and pdf at given directions: out[i] = (f.xyz, pdf). */
kernel void probe_eval(const global float4* wi, global float4* out, uint count, float4 diffuse, float4 specular_alpha,
                       uint mirror, float4 wo4, float4 dielectric) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const Bsdf b = px_probe_bsdf(diffuse, specular_alpha, mirror, dielectric);
  const float3 n = (float3)(0.0f, 0.0f, 1.0f);
  const float3 wo = normalize(wo4.xyz);
  const float3 w = wi[i].xyz;
  out[i] = (float4)(px_bsdf_eval(&b, n, wo, w), px_bsdf_pdf(&b, n, wo, w));
}
