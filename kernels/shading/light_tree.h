/* The light tree's walk (host/render/light_tree.h builds it; types.h, LightTreeNode, lays it out
 * in the `lights` buffer after the LightTriangle table): next-event estimation picks an emissive
 * triangle by descending from the root, choosing each child in proportion to its importance at
 * the shading point (Conty Estevez and Kulla 2018; the importance is pbrt-v4's
 * LightBounds::Importance). Each leaf is one light, so a light's probability is the product of
 * the choices on its path, which px_light_tree_pmf recomputes from the light's trail with the
 * same arithmetic as px_light_tree_sample: the two agree to the bit, as MIS needs. */
#ifndef PARALLAX_LIGHT_TREE_H
#define PARALLAX_LIGHT_TREE_H

#include "scene/scene_view.h"

/* The nodes of a table of `count` lights, and the lights' trails after them. */
inline const global LightTreeNode* px_light_tree_nodes(const SceneView* s, uint count) {
  return (const global LightTreeNode*)(s->lights + count);
}

inline const global uint* px_light_tree_trails(const SceneView* s, uint count) {
  return (const global uint*)(px_light_tree_nodes(s, count) + (2u * count - 1u));
}

/* cos(max(0, a - b)) and sin(max(0, a - b)) from the sines and cosines of angles a, b in [0, pi]. */
inline float px_cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  if (cos_a > cos_b) return 1.0f;
  return cos_a * cos_b + sin_a * sin_b;
}

inline float px_sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
  if (cos_a > cos_b) return 0.0f;
  return sin_a * cos_b - cos_a * sin_b;
}

/* An upper estimate of what the lights under `node` send to a point p with normal n: power over
 * squared distance, times the cosine at the emitters (the angle from p to the cone of normals,
 * less the cone's own spread theta_o and the angle theta_b the box subtends from p; nothing
 * beyond theta_e), times the |cosine| at p (less theta_b). 0: no light under the node can reach p. */
inline float px_light_node_importance(const global LightTreeNode* node, float3 p, float3 n) {
  const float3 lo = px_load3(node->bounds_min), hi = px_load3(node->bounds_max);
  const float3 centre = 0.5f * (lo + hi);
  const float3 diag = hi - lo;
  const float3 to_p = p - centre;
  const float dist2 = dot(to_p, to_p);
  /* Clamped below so that points close to or inside a large box do not get unbounded importance. */
  const float d2 = fmax(dist2, 0.5f * length(diag));
  if (!(d2 > 0.0f)) return 0.0f;
  const float dist = sqrt(dist2);
  const float3 wi = dist > 0.0f ? to_p / dist : (float3)(0.0f, 0.0f, 1.0f);
  const float cos_w = dot(px_load3(node->axis), wi);
  const float sin_w = sqrt(fmax(0.0f, 1.0f - cos_w * cos_w));
  /* The directions from p into the box's bounding sphere: every direction from inside it. */
  const float r2 = 0.25f * dot(diag, diag);
  float cos_b = -1.0f, sin_b = 0.0f;
  if (dist2 >= r2) {
    const float sin2_b = dist2 > 0.0f ? r2 / dist2 : 0.0f;
    cos_b = sqrt(fmax(0.0f, 1.0f - sin2_b));
    sin_b = sqrt(sin2_b);
  }
  const float cos_o = node->cos_theta_o;
  const float sin_o = sqrt(fmax(0.0f, 1.0f - cos_o * cos_o));
  const float cos_x = px_cos_sub_clamped(sin_w, cos_w, sin_o, cos_o);
  const float sin_x = px_sin_sub_clamped(sin_w, cos_w, sin_o, cos_o);
  const float cos_p = px_cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
  if (cos_p <= node->cos_theta_e) return 0.0f;
  const float cos_i = fabs(dot(wi, n));
  const float sin_i = sqrt(fmax(0.0f, 1.0f - cos_i * cos_i));
  const float cos_pi = px_cos_sub_clamped(sin_i, cos_i, sin_b, cos_b);
  return fmax(node->phi * cos_p / d2 * cos_pi, 0.0f);
}

/* The probability of child 1 of interior node `node` at (p, n) as both walks compute it, from
 * the two children's importances: i1 / (i0 + i1); that of child 0 is i0 / (i0 + i1). Returns
 * the total (0: neither child can light p). */
inline float px_light_tree_children(const global LightTreeNode* nodes, const global LightTreeNode* node, float3 p,
                                    float3 n, float* i0, float* i1) {
  *i0 = px_light_node_importance(nodes + node->child[0], p, n);
  *i1 = px_light_node_importance(nodes + node->child[1], p, n);
  return *i0 + *i1;
}

/* A light of the table of `count` lights for shading point p with normal n, chosen with u in
 * [0, 1): its index, and in *pmf its probability; -1 (pmf 0) if no light can light p. */
inline int px_light_tree_sample(const SceneView* s, uint count, float3 p, float3 n, float u, float* pmf) {
  *pmf = 0.0f;
  if (count == 0u) return -1;
  if (count == 1u) {
    *pmf = 1.0f;
    return 0;
  }
  const global LightTreeNode* nodes = px_light_tree_nodes(s, count);
  uint at = 0u;
  float prob = 1.0f;
  for (uint depth = 0u; depth <= 32u; ++depth) {
    const global LightTreeNode* node = nodes + at;
    if (node->child[0] & PX_LIGHT_TREE_LEAF) {
      *pmf = prob;
      return prob > 0.0f ? (int)(node->child[0] & ~PX_LIGHT_TREE_LEAF) : -1;
    }
    float i0, i1;
    const float total = px_light_tree_children(nodes, node, p, n, &i0, &i1);
    if (!(total > 0.0f)) return -1;
    const float p0 = i0 / total;
    if (u < p0) {
      prob *= p0;
      u = fmin(u / p0, 0.99999994f);
      at = node->child[0];
    } else {
      prob *= i1 / total;
      u = fmin((u - p0) / (1.0f - p0), 0.99999994f);
      at = node->child[1];
    }
  }
  return -1; /* deeper than any tree the host builds */
}

/* The probability that px_light_tree_sample at (p, n) picks `light`: the choices along its trail. */
inline float px_light_tree_pmf(const SceneView* s, uint count, float3 p, float3 n, int light) {
  if (light < 0 || (uint)light >= count) return 0.0f;
  if (count == 1u) return 1.0f;
  const global LightTreeNode* nodes = px_light_tree_nodes(s, count);
  const uint trail = px_light_tree_trails(s, count)[light];
  uint at = 0u;
  float prob = 1.0f;
  for (uint depth = 0u; depth < 32u; ++depth) {
    const global LightTreeNode* node = nodes + at;
    if (node->child[0] & PX_LIGHT_TREE_LEAF) return prob;
    float i0, i1;
    const float total = px_light_tree_children(nodes, node, p, n, &i0, &i1);
    if (!(total > 0.0f)) return 0.0f;
    const uint right = (trail >> depth) & 1u;
    prob *= (right ? i1 : i0) / total;
    at = node->child[right];
  }
  return (nodes[at].child[0] & PX_LIGHT_TREE_LEAF) ? prob : 0.0f;
}

#endif
