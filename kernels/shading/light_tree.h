/* The light tree's walk (host/render/light_tree.h builds it; types.h, LightTreeWideNode, lays it out
 * in the `lights` buffer after the LightTriangle table): next-event estimation picks an emissive
 * triangle by descending from the root (Conty Estevez and Kulla 2018; the importance is pbrt-v4's
 * LightBounds::Importance, one-sided at the shading point). The tree is binary, but the walk takes two levels a step:
 * from an interior node it weighs the up to four nodes two levels below (a child that is a leaf stands for itself) by
 * their importances at the shading point and picks one in proportion. Half as many dependent steps as a level-by-level
 * walk for about as many importances, and each node is weighed against its cousins with its own tight bounds rather
 * than through its parent's looser ones. Each leaf is one light, so a light's probability is the product of the choices
 * on its path, which px_light_tree_pmf recomputes from the light's trail with the same arithmetic as
 * px_light_tree_sample: the two agree to the bit, as MIS needs. */
#ifndef PARALLAX_LIGHT_TREE_H
#define PARALLAX_LIGHT_TREE_H

#include "scene/scene_view.h"

/* The trails of a table of `count` lights (right after it), and the wide nodes after them. */
inline const global uint* px_light_tree_trails(const SceneView* s, uint count) {
  return (const global uint*)(s->lights + count);
}

inline const global LightTreeWideNode* px_light_tree_wide(const SceneView* s, uint count) {
  return (const global LightTreeWideNode*)(s->lights + count + (count + 15u) / 16u);
}

/* cos(max(0, a - b)) and sin(max(0, a - b)), lane by lane, of angles a, b in [0, pi] given by
 * their sines and cosines (T: float or a float vector). */
#define PX_COS_SUB_CLAMPED(T, sin_a, cos_a, sin_b, cos_b) \
  select((cos_a) * (cos_b) + (sin_a) * (sin_b), (T)(1.0f), (cos_a) > (cos_b))
#define PX_SIN_SUB_CLAMPED(T, sin_a, cos_a, sin_b, cos_b) \
  select((sin_a) * (cos_b) - (cos_a) * (sin_b), (T)(0.0f), (cos_a) > (cos_b))

/* An upper estimate of what the lights under a node send to a point p with normal n: power over
 * squared distance, times the cosine at the emitters (the angle from p to the cone of normals,
 * less the cone's own spread theta_o and the angle theta_b the node's bounding sphere subtends
 * from p; nothing beyond theta_e), times the cosine at p (less theta_b); 0 where no light under
 * the node can reach p. The cosine at p is one-sided, unlike pbrt-v4's |cosine|: every BSDF that
 * next-event estimation and ReSTIR evaluate here is zero below n (glass refracts only through its
 * delta lobe, which neither samples), so a node wholly behind p's tangent plane can light nothing
 * there. Where a wall stands between two rooms, the lamps of the room behind it are those.
 * The body is written once for T = float (one node) and T = float4 (four nodes, one a lane);
 * LANES(field) is the field of the node or nodes, as a T. Each lane computes what the one-node
 * version does, to the bit. */
#define PX_LIGHT_IMPORTANCE_BODY(T, LANES)                                                                            \
  const T tx = p.x - 0.5f * (LANES(bounds_min[0]) + LANES(bounds_max[0]));                                            \
  const T ty = p.y - 0.5f * (LANES(bounds_min[1]) + LANES(bounds_max[1]));                                            \
  const T tz = p.z - 0.5f * (LANES(bounds_min[2]) + LANES(bounds_max[2]));                                            \
  const T dist2 = tx * tx + ty * ty + tz * tz;                                                                        \
  const T radius = LANES(radius);                                                                                     \
  /* pbrt-v4's clamp, half the diagonal against the squared distance: points close to or inside a large box do        \
   * not get unbounded importance. */                                                                                 \
  const T d2 = fmax(dist2, radius);                                                                                   \
  const T inv_dist = select((T)(0.0f), rsqrt(dist2), dist2 > 0.0f);                                                   \
  /* The cosines below times the distance, and their sines from dist2 less their square: the square roots then hang   \
   * on dist2 and a dot product only, and run beside rsqrt rather than after it (the chain's latency is the walk's    \
   * time on a CPU). Where p is the centre (dist2 0) every angle is 0 here; it is then inside the sphere or d2 is 0,  \
   * and neither result depends on the angles. */                                                                     \
  const T at_axis = LANES(axis[0]) * tx + LANES(axis[1]) * ty + LANES(axis[2]) * tz;                                  \
  /* At p, one-sided: t points away from the lights. */                                                               \
  const T at_n = -(tx * n.x + ty * n.y + tz * n.z);                                                                   \
  const T cos_w = at_axis * inv_dist;                                                                                 \
  const T sin_w = sqrt(fmax(0.0f, dist2 - at_axis * at_axis)) * inv_dist;                                             \
  /* The directions from p into the bounding sphere: every direction from inside it. */                               \
  const T sin_b = select((T)(0.0f), fmin(radius * inv_dist, 1.0f), dist2 >= radius * radius);                         \
  const T cos_b = select((T)(-1.0f), sqrt(fmax(0.0f, dist2 - radius * radius)) * inv_dist, dist2 >= radius * radius); \
  const T cos_o = LANES(cos_theta_o), sin_o = LANES(sin_theta_o);                                                     \
  const T cos_x = PX_COS_SUB_CLAMPED(T, sin_w, cos_w, sin_o, cos_o);                                                  \
  const T sin_x = PX_SIN_SUB_CLAMPED(T, sin_w, cos_w, sin_o, cos_o);                                                  \
  const T cos_p = PX_COS_SUB_CLAMPED(T, sin_x, cos_x, sin_b, cos_b);                                                  \
  const T cos_i = at_n * inv_dist;                                                                                    \
  const T sin_i = sqrt(fmax(0.0f, dist2 - at_n * at_n)) * inv_dist;                                                   \
  const T cos_pi = fmax(PX_COS_SUB_CLAMPED(T, sin_i, cos_i, sin_b, cos_b), 0.0f);                                     \
  /* Power over distance first: its division then runs beside the square roots, not after them. fmax turns a NaN into \
   * 0; nothing beyond theta_e, nothing from a degenerate (zero) distance. */                                         \
  return select((T)(0.0f), fmax(LANES(phi) / d2 * cos_p * cos_pi, 0.0f), (cos_p > LANES(cos_theta_e)) & (d2 > 0.0f));

/* Lane k (0..3, a constant where it is inlined) of wide node w. */
inline __attribute__((always_inline)) float px_light_lane_importance(const global LightTreeWideNode* w, uint k,
                                                                     float3 p, float3 n) {
#define PX_LANES1(field) (w->field[k])
  PX_LIGHT_IMPORTANCE_BODY(float, PX_LANES1)
#undef PX_LANES1
}

/* The four lanes at once. Why: one lane's arithmetic is a chain of dependent square roots and
 * divisions whose latency, not its count of operations, sets its time on a CPU; in four lanes the
 * four chains run side by side in one vector instruction each, on fields read with one load each. */
inline __attribute__((always_inline)) float4 px_light_wide_importance4(const global LightTreeWideNode* w, float3 p,
                                                                       float3 n) {
#define PX_LANES4(field) vload4(0, w->field)
  PX_LIGHT_IMPORTANCE_BODY(float4, PX_LANES4)
#undef PX_LANES4
}

/* The importances at (p, n) of wide node w's lanes, 0 for the empty ones; their powers where the
 * lanes differ in nothing else (LightTreeWideNode::by_power). */
inline __attribute__((always_inline)) float4 px_light_tree_step(const global LightTreeWideNode* w, uint4 child,
                                                                float3 p, float3 n) {
  if (w->by_power) return select(vload4(0, w->phi), (float4)(0.0f), child == (uint4)(PX_LIGHT_TREE_EMPTY));
#if defined(__x86_64__)
  const float4 i = px_light_wide_importance4(w, p, n);
#else
  /* A GPU hides latency with other warps, not within a thread: one lane at a time there keeps the
   * four chains' registers (about 20 a kernel) free for more warps. */
  const float4 i = (float4)(px_light_lane_importance(w, 0u, p, n), px_light_lane_importance(w, 1u, p, n),
                            px_light_lane_importance(w, 2u, p, n), px_light_lane_importance(w, 3u, p, n));
#endif
  return select(i, (float4)(0.0f), child == (uint4)(PX_LIGHT_TREE_EMPTY));
}

/* The sum of a step's importances, in the one order both walks use. */
inline float px_light_step_total(float4 i) { return ((i.x + i.y) + i.z) + i.w; }

/* Lane j of v. On GPUs by masks rather than an index: a vector indexed by a variable is spilled
 * to the stack there (the other lanes' products are exact zeros, importances being finite), and
 * clang turns a chain of selects into that index. On CPUs by selects: the one-hot products were a
 * chain of dependent FMAs on the walk's critical path. Both give the lane to the bit. */
inline float px_lane4(float4 v, uint j) {
#if defined(__x86_64__)
  return j == 0u ? v.x : j == 1u ? v.y : j == 2u ? v.z : v.w;
#else
  const float4 one_hot = (float4)(j == 0u, j == 1u, j == 2u, j == 3u);
  return ((v.x * one_hot.x + v.y * one_hot.y) + v.z * one_hot.z) + v.w * one_hot.w;
#endif
}

inline uint px_lane4u(uint4 v, uint j) {
#if defined(__x86_64__)
  return j == 0u ? v.x : j == 1u ? v.y : j == 2u ? v.z : v.w;
#else
  const uint4 mask = (uint4)(j == 0u, j == 1u, j == 2u, j == 3u) * 0xffffffffu;
  return (v.x & mask.x) | (v.y & mask.y) | (v.z & mask.z) | (v.w & mask.w);
#endif
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
  const global LightTreeWideNode* wide = px_light_tree_wide(s, count);
  uint at = 0u;
  float prob = 1.0f;
  /* A step descends one or two levels of the binary tree, and no leaf is deeper than 32. */
  for (uint step = 0u; step < 32u; ++step) {
    const global LightTreeWideNode* w = wide + at;
    const uint4 child = vload4(0, w->child);
    const float4 i = px_light_tree_step(w, child, p, n);
    const float total = px_light_step_total(i);
    if (!(total > 0.0f)) return -1;
    /* The first lane whose running sum passes u x total: multiplications only on the way to the
     * next node (a lane of importance 0 is never first, its running sum being its left
     * neighbour's); where rounding carries u x total past the last lane that has importance,
     * that lane. */
    const float x = u * total;
    const float s0 = i.x, s1 = s0 + i.y, s2 = s1 + i.z;
    const uint last = i.w > 0.0f ? 3u : i.z > 0.0f ? 2u : i.y > 0.0f ? 1u : 0u;
    const uint j = min((uint)(x >= s0) + (uint)(x >= s1) + (uint)(x >= s2), last);
    const float chosen = px_lane4(i, j);
    prob *= chosen / total;
    const uint next = px_lane4u(child, j);
    if (next & PX_LIGHT_TREE_LEAF) {
      *pmf = prob;
      return prob > 0.0f ? (int)(next & ~PX_LIGHT_TREE_LEAF) : -1;
    }
    u = clamp((x - px_lane4((float4)(0.0f, s0, s1, s2), j)) / chosen, 0.0f, 0.99999994f);
    at = next;
  }
  return -1; /* deeper than any tree the host builds */
}

/* The probability that px_light_tree_sample at (p, n) picks `light`: the choices along its trail. */
inline float px_light_tree_pmf(const SceneView* s, uint count, float3 p, float3 n, int light) {
  if (light < 0 || (uint)light >= count) return 0.0f;
  if (count == 1u) return 1.0f;
  const global LightTreeWideNode* wide = px_light_tree_wide(s, count);
  const uint trail = px_light_tree_trails(s, count)[light];
  uint at = 0u, depth = 0u;
  float prob = 1.0f;
  for (uint step = 0u; step < 32u && depth < 32u; ++step) {
    const global LightTreeWideNode* w = wide + at;
    const uint4 child = vload4(0, w->child);
    const float4 i = px_light_tree_step(w, child, p, n);
    const float total = px_light_step_total(i);
    if (!(total > 0.0f)) return 0.0f;
    /* The trail's bit for this level picks the side; a side that is not a leaf (its second lane
     * not empty) takes the next bit as well. */
    const uint side = (trail >> depth) & 1u;
    ++depth;
    uint j = 2u * side;
    if (px_lane4u(child, j + 1u) != PX_LIGHT_TREE_EMPTY) {
      j += depth < 32u ? (trail >> depth) & 1u : 0u;
      ++depth;
    }
    prob *= px_lane4(i, j) / total;
    const uint next = px_lane4u(child, j);
    if (next & PX_LIGHT_TREE_LEAF) return (next & ~PX_LIGHT_TREE_LEAF) == (uint)light ? prob : 0.0f;
    at = next;
  }
  return 0.0f;
}

#endif
