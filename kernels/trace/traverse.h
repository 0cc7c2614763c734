/* BVH traversal over the 64-byte binary nodes of shared/types.h: closest hit and any hit.
 *
 * One node fetch tests both child boxes. Leaf children are intersected right away (their
 * triangles are contiguous in leaf order); interior children are visited near-first with the
 * far one pushed. The stack is private and bounded: the host builds trees no deeper than
 * PX_BVH_MAX_DEPTH and each level pushes at most one entry, so PX_BVH_STACK_SIZE never
 * overflows (the validator checks the depth). No barriers: on PoCL a traversal kernel is a
 * plain loop per work-item. */
#ifndef PARALLAX_TRAVERSE_H
#define PARALLAX_TRAVERSE_H

#include "shared/types.h"
#include "trace/watertight.h"
#include "scene/scene_view.h"

inline int px_child_absent(uint index, uint count) { return count == 0u && index == 0u; }

/* Intersects `count` leaf triangles starting at `first`; updates *best. Returns 1 on any hit. */
inline int px_intersect_leaf(const SceneView* scene, uint first, uint count,
                             const RayShear* shear, float tmin, Hit* best) {
  int any = 0;
  for (uint i = first; i < first + count; ++i) {
    const global BvhTriangle* tri = scene->tris + i;
    float t, u, v;
    if (px_intersect_triangle_mem(shear, tri->v0, tri->v1, tri->v2, tmin, best->t, &t, &u, &v) &&
        ((tri->flags & PX_TRI_ALPHA_TESTED) == 0u || px_alpha_visible(scene, tri->prim, u, v))) {
      best->t = t;
      best->u = u;
      best->v = v;
      best->prim = i; /* leaf index; px_trace_closest maps it to the scene index */
      any = 1;
    }
  }
  return any;
}

/* Closest hit along the ray within [tmin, tmax). hit.prim is the index into scene->tris (leaf
 * order, so the caller can read the vertices), PX_NO_HIT on a miss. */
inline Hit px_trace_closest_leaf(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  const global BvhNode* nodes = scene->nodes;
  Hit best;
  best.t = tmax;
  best.u = 0.0f;
  best.v = 0.0f;
  best.prim = PX_NO_HIT;
  const RayShear shear = px_make_shear(org, dir);
  const float3 inv_dir = px_safe_inverse(dir);

  uint stack[PX_BVH_STACK_SIZE];
  int sp = 0;
  uint node_index = 0;
  for (;;) {
    const BvhNode n = nodes[node_index];
    float tl = px_child_absent(n.left, n.left_count) ? INFINITY
                                                     : px_intersect_box(org, inv_dir, n.lmin, n.lmax, tmin, best.t);
    float tr = px_child_absent(n.right, n.right_count) ? INFINITY
                                                       : px_intersect_box(org, inv_dir, n.rmin, n.rmax, tmin, best.t);
    if (tl != INFINITY && n.left_count > 0) {
      px_intersect_leaf(scene, n.left, n.left_count, &shear, tmin, &best);
      tl = INFINITY;
    }
    if (tr != INFINITY && n.right_count > 0) {
      px_intersect_leaf(scene, n.right, n.right_count, &shear, tmin, &best);
      tr = INFINITY;
    }
    /* A leaf hit may have shortened best.t below an interior child's entry: skip it then. */
    if (tl > best.t) tl = INFINITY;
    if (tr > best.t) tr = INFINITY;
    if (tl != INFINITY && tr != INFINITY) {
      const int left_first = tl <= tr;
      node_index = left_first ? n.left : n.right;
      if (sp < PX_BVH_STACK_SIZE) stack[sp++] = left_first ? n.right : n.left;
    } else if (tl != INFINITY) {
      node_index = n.left;
    } else if (tr != INFINITY) {
      node_index = n.right;
    } else {
      if (sp == 0) break;
      node_index = stack[--sp];
    }
  }
  return best;
}

/* Closest hit with hit.prim the scene triangle index (BvhTriangle::prim). */
inline Hit px_trace_closest(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  Hit h = px_trace_closest_leaf(scene, org, dir, tmin, tmax);
  if (h.prim != PX_NO_HIT) h.prim = scene->tris[h.prim].prim;
  return h;
}

/* 1 when anything blocks the ray within [tmin, tmax) (shadow rays). */
inline int px_trace_any(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  const global BvhNode* nodes = scene->nodes;
  const RayShear shear = px_make_shear(org, dir);
  const float3 inv_dir = px_safe_inverse(dir);
  uint stack[PX_BVH_STACK_SIZE];
  int sp = 0;
  uint node_index = 0;
  Hit scratch;
  for (;;) {
    const BvhNode n = nodes[node_index];
    const float tl = px_child_absent(n.left, n.left_count) ? INFINITY
                                                           : px_intersect_box(org, inv_dir, n.lmin, n.lmax, tmin, tmax);
    const float tr = px_child_absent(n.right, n.right_count) ? INFINITY
                                                             : px_intersect_box(org, inv_dir, n.rmin, n.rmax, tmin, tmax);
    int go_left = tl != INFINITY, go_right = tr != INFINITY;
    if (go_left && n.left_count > 0) {
      scratch.t = tmax;
      if (px_intersect_leaf(scene, n.left, n.left_count, &shear, tmin, &scratch)) return 1;
      go_left = 0;
    }
    if (go_right && n.right_count > 0) {
      scratch.t = tmax;
      if (px_intersect_leaf(scene, n.right, n.right_count, &shear, tmin, &scratch)) return 1;
      go_right = 0;
    }
    if (go_left && go_right) {
      node_index = n.left;
      if (sp < PX_BVH_STACK_SIZE) stack[sp++] = n.right;
    } else if (go_left) {
      node_index = n.left;
    } else if (go_right) {
      node_index = n.right;
    } else {
      if (sp == 0) break;
      node_index = stack[--sp];
    }
  }
  return 0;
}

#endif
