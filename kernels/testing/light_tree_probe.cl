/* Exposes the light tree's walk (shading/light_tree.h) to tests/test_light_tree.cpp, which checks
 * it against a host evaluation: pmfs that sum to 1, sampling frequencies that match them, and
 * the pmf a sample reports equal, to the bit, to px_light_tree_pmf's. `lights` is the scene's
 * lights buffer (the table, then the tree: types.h, LightTreeNode). */
#include "shared/types.h"
#include "scene/scene_view.h"
#include "shading/light_tree.h"

inline SceneView px_probe_view(const global LightTriangle* lights) {
  return px_scene_view(0, 0, 0, 0, 0, 0, lights, 0, 0);
}

/* Work-item i < points: out[i * count + k] = pmf of light k at point p[i] with normal n[i]. */
kernel void light_tree_pmfs(const global LightTriangle* lights, uint count, const global float4* p,
                            const global float4* n, uint points, global float* out) {
  const uint i = get_global_id(0);
  if (i >= points) return;
  const SceneView s = px_probe_view(lights);
  for (uint k = 0u; k < count; ++k)
    out[(size_t)i * count + k] = px_light_tree_pmf(&s, count, p[i].xyz, n[i].xyz, (int)k);
}

/* Work-item i < samples: a sample at u = (i + 0.5) / samples from point p with normal n:
 * light[i] (-1: none), pmf[i] as the sample reports it, pmf_again[i] = px_light_tree_pmf's. */
kernel void light_tree_samples(const global LightTriangle* lights, uint count, float4 p, float4 n, uint samples,
                               global int* light, global float* pmf, global float* pmf_again) {
  const uint i = get_global_id(0);
  if (i >= samples) return;
  const SceneView s = px_probe_view(lights);
  const float u = ((float)i + 0.5f) / (float)samples;
  float q;
  const int l = px_light_tree_sample(&s, count, p.xyz, n.xyz, u, &q);
  light[i] = l;
  pmf[i] = q;
  pmf_again[i] = px_light_tree_pmf(&s, count, p.xyz, n.xyz, l);
}
