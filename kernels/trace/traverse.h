/* BVH traversal: closest hit and any hit, over the node layout PX_BVH_WIDTH selects
 * (shared/types.h): the 64-byte binary nodes (2), the 4- / 8-wide SoA nodes, or the compressed
 * 8-wide nodes (PX_BVH_COMPRESSED8).
 *
 * Binary: one node fetch tests both child boxes. Leaf children are intersected right away
 * (their triangles are contiguous in leaf order); interior children are visited near-first
 * with the far one pushed. The stack is private and bounded: the host builds trees no deeper
 * than PX_BVH_MAX_DEPTH and each level pushes at most one entry, so PX_BVH_STACK_SIZE never
 * overflows (the validator checks the depth). Wide: see the section below. No barriers: on
 * PoCL a traversal kernel is a plain loop per work-item. */
#ifndef PARALLAX_TRAVERSE_H
#define PARALLAX_TRAVERSE_H

#include "shared/types.h"
#include "trace/watertight.h"
#include "scene/scene_view.h"

inline int px_child_absent(uint index, uint count) { return count == 0u && index == 0u; }

/* A hit (u, v) on leaf triangle `tri` that its alpha cut-out removes (never without the
 * ALPHA_TEST feature: the test is compiled out). */
inline int px_cut_out(const SceneView* scene, const global PxLeafTriangle* tri, float u, float v) {
  return PX_HAS(PX_FEATURE_ALPHA_TEST) && (tri->flags & PX_TRI_ALPHA_TESTED) != 0u &&
         !px_alpha_visible(scene, tri->prim, u, v);
}

#if defined(PX_LEAF_REFS) && PX_LEAF_REFS && PX_BVH_WIDTH == 2
#error "PX_LEAF_REFS needs a wide layout: the vertices are in the leaf blocks"
#endif
/* Intersects `count` leaf triangles starting at `first` one by one; updates *best. Returns 1 on
 * any hit. With PX_LEAF_REFS the leaf triangles carry no vertices: each is read from its lane of
 * the leaf's block `block` (types.h: BvhLeafBlock rows, 4 floats apart), the same floats, the
 * same operations and the same order; without it `block` is not read (the binary layout passes
 * none). */
__attribute__((always_inline)) inline int px_intersect_leaf(const SceneView* scene, const global float* block,
                                                            uint first, uint count, const RayShear* shear, float tmin,
                                                            Hit* best) {
  int any = 0;
  for (uint j = 0; j < count; ++j) {
    const uint i = first + j;
    const global PxLeafTriangle* tri = scene->tris + i;
#if defined(PX_LEAF_REFS) && PX_LEAF_REFS
    const global float *v0 = block + j, *v1 = block + 12 + j, *v2 = block + 24 + j;
    const int stride = 4;
#else
    const global float *v0 = tri->v0, *v1 = tri->v1, *v2 = tri->v2;
    const int stride = 1;
#endif
    float t, u, v;
    if (px_intersect_triangle_strided(shear, v0, v1, v2, stride, tmin, best->t, &t, &u, &v) &&
        !px_cut_out(scene, tri, u, v)) {
      best->t = t;
      best->u = u;
      best->v = v;
      best->prim = i; /* leaf index; px_trace_closest maps it to the scene index */
      any = 1;
    }
  }
  return any;
}

/* One step of a near-first walk over binary nodes (the binary layout's closest hit, the
 * instances' top level), once node `n`'s two children have their entry distances tl, tr
 * (INFINITY: not entered, or a leaf already intersected): on into the nearer, the farther
 * pushed (while the stack has room: the host bounds the depth so that it always has); with
 * neither, the stack's top. Returns 0 when the walk is over. */
inline int px_binary_step(const BvhNode* n, float tl, float tr, uint* node_index, uint* stack, int* sp, int capacity) {
  if (tl != INFINITY && tr != INFINITY) {
    const int left_first = tl <= tr;
    *node_index = left_first ? n->left : n->right;
    if (*sp < capacity) stack[(*sp)++] = left_first ? n->right : n->left;
  } else if (tl != INFINITY) {
    *node_index = n->left;
  } else if (tr != INFINITY) {
    *node_index = n->right;
  } else {
    if (*sp == 0) return 0;
    *node_index = stack[--*sp];
  }
  return 1;
}

#if PX_BVH_WIDTH == 2

/* Closest hit in one tree along the ray within (tmin, tmax): hit.prim is the index into
 * scene->tris (leaf order, so the caller can read the vertices), PX_NO_HIT on a miss. */
inline Hit px_tree_closest(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  const global BvhNode* nodes = scene->nodes;
  Hit best;
  best.t = tmax;
  best.u = 0.0f;
  best.v = 0.0f;
  best.prim = PX_NO_HIT;
  best.inst = PX_NO_INSTANCE;
  const RayShear shear = px_make_shear(org, dir);
  const float3 inv_dir = px_safe_inverse(dir);

  uint stack[PX_BVH_STACK_SIZE];
  int sp = 0;
  uint node_index = 0;
  for (;;) {
    const BvhNode n = nodes[node_index];
    float tl =
        px_child_absent(n.left, n.left_count) ? INFINITY : px_intersect_box(org, inv_dir, n.lmin, n.lmax, tmin, best.t);
    float tr = px_child_absent(n.right, n.right_count) ? INFINITY
                                                       : px_intersect_box(org, inv_dir, n.rmin, n.rmax, tmin, best.t);
    if (tl != INFINITY && n.left_count > 0) {
      px_intersect_leaf(scene, 0, n.left, n.left_count, &shear, tmin, &best);
      tl = INFINITY;
    }
    if (tr != INFINITY && n.right_count > 0) {
      px_intersect_leaf(scene, 0, n.right, n.right_count, &shear, tmin, &best);
      tr = INFINITY;
    }
    /* A leaf hit may have shortened best.t below an interior child's entry: skip it then. */
    if (tl > best.t) tl = INFINITY;
    if (tr > best.t) tr = INFINITY;
    if (!px_binary_step(&n, tl, tr, &node_index, stack, &sp, PX_BVH_STACK_SIZE)) break;
  }
  return best;
}

/* 1 when anything in one tree blocks the ray within (tmin, tmax) (shadow rays). */
inline int px_tree_any(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  const global BvhNode* nodes = scene->nodes;
  const RayShear shear = px_make_shear(org, dir);
  const float3 inv_dir = px_safe_inverse(dir);
  uint stack[PX_BVH_STACK_SIZE];
  int sp = 0;
  uint node_index = 0;
  Hit scratch;
  for (;;) {
    const BvhNode n = nodes[node_index];
    const float tl =
        px_child_absent(n.left, n.left_count) ? INFINITY : px_intersect_box(org, inv_dir, n.lmin, n.lmax, tmin, tmax);
    const float tr =
        px_child_absent(n.right, n.right_count) ? INFINITY : px_intersect_box(org, inv_dir, n.rmin, n.rmax, tmin, tmax);
    int go_left = tl != INFINITY, go_right = tr != INFINITY;
    if (go_left && n.left_count > 0) {
      scratch.t = tmax;
      if (px_intersect_leaf(scene, 0, n.left, n.left_count, &shear, tmin, &scratch)) return 1;
      go_left = 0;
    }
    if (go_right && n.right_count > 0) {
      scratch.t = tmax;
      if (px_intersect_leaf(scene, 0, n.right, n.right_count, &shear, tmin, &scratch)) return 1;
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

#else

/* ---------------------------------------------------------------------------------------
 * Wide traversal over Bvh4Node / Bvh8Node (PX_BVH_WIDTH 4 or 8) or CompressedBvh8Node
 * (PX_BVH_COMPRESSED8). One node fetch tests all W child boxes with W-wide vector ops inside the
 * work-item. The ray's octant picks, per axis, which plane row is the near one, so the slab test
 * needs no min/max swap: same arithmetic as px_intersect_box ((plane - org) * inv_dir, far
 * distance widened by PX_BOX_FAR_SCALE), so it is just as conservative. The compressed layout
 * first decodes its 8-bit planes, q * scale + p, which is exact by construction (types.h), so it
 * tests exactly the boxes the host validated. Any hit: leaves are intersected as soon as their
 * box is hit, interior children pushed in any order. Closest hit: see below. The two layouts
 * differ only in px_wide_boxes (box test) and pxw_child_entry (a slot's stack entry). */
#if PX_BVH_WIDTH == PX_BVH_COMPRESSED8
#define PXW 8
#define PXW_COMPRESSED 1
#define PXW_NODE_FLOATS 20 /* 80 bytes */
#else
#define PXW PX_BVH_WIDTH
#define PXW_COMPRESSED 0
#define PXW_NODE_FLOATS (8 * PXW)
#endif
/* The compressed tree is the Bvh8Node tree re-stored (same nodes, same depth), so the 8-wide
 * bound holds for it too: (8 - 1) * PX_BVH_MAX_DEPTH + 1 = 281 entries. */
#define PXW_STACK PX_WBVH_STACK_SIZE(PXW)
/* x86's movemask (the sign bit of each lane into one integer: one instruction, where the
 * portable reduction below takes eight) where the kernel compiler targets AVX, as PoCL does on
 * CPUs that have it; the portable code elsewhere (GPUs, older CPUs). */
#if defined(__x86_64__) && defined(__AVX__) && defined(__has_builtin)
#if __has_builtin(__builtin_ia32_movmskps256) && __has_builtin(__builtin_ia32_movmskps)
#define PX_HAS_MOVEMASK 1
#endif
#endif
#ifndef PX_HAS_MOVEMASK
#define PX_HAS_MOVEMASK 0
#endif
/* Bit i set when lane i of a 4-lane comparison result is true. */
inline uint px_mask4(int4 m) {
#if PX_HAS_MOVEMASK
  return (uint)__builtin_ia32_movmskps(as_float4(m));
#else
  const int4 b = m & (int4)(1, 2, 4, 8);
  const int2 q = b.lo | b.hi;
  return (uint)(q.x | q.y);
#endif
}
#if PXW == 8
typedef float8 pxw_float;
typedef int8 pxw_int;
#define pxw_vload vload8
#define pxw_vstore vstore8
/* Bit i set when lane i is true (a comparison result: all bits set or none). */
inline uint pxw_mask(pxw_int m) {
#if PX_HAS_MOVEMASK
  return (uint)__builtin_ia32_movmskps256(as_float8(m));
#else
  const int8 b = m & (int8)(1, 2, 4, 8, 16, 32, 64, 128);
  const int4 h = b.lo | b.hi;
  const int2 q = h.lo | h.hi;
  return (uint)(q.x | q.y);
#endif
}
#elif PXW == 4
typedef float4 pxw_float;
typedef int4 pxw_int;
#define pxw_vload vload4
#define pxw_vstore vstore4
inline uint pxw_mask(pxw_int m) { return px_mask4(m); }
#else
#error "PX_BVH_WIDTH must be 2, 4, 8 or 9 (PX_BVH_COMPRESSED8)"
#endif

/* max / min as compare-and-select: one vmaxps / vminps each, where fmax / fmin also have to
 * return the non-NaN operand (three instructions on x86). No operand here is NaN for a finite
 * ray: the inverse direction is finite and non-zero (px_safe_inverse), so (plane - org) * inv is
 * finite or +-inf, and tmin / tmax are not NaN; then both give the same value. */
inline pxw_float pxw_max(pxw_float a, pxw_float b) { return select(b, a, a > b); }
inline pxw_float pxw_min(pxw_float a, pxw_float b) { return select(b, a, a < b); }

/* Software prefetch of the 64-byte line holding `p`. On PoCL's CPU devices (clang, x86-64)
 * clang's __builtin_prefetch becomes a prefetcht0, which lets the misses of several children
 * overlap; elsewhere OpenCL's prefetch(), a hint the implementation may ignore. */
#if defined(__x86_64__) && defined(__has_builtin)
#if __has_builtin(__builtin_prefetch)
#define PX_PREFETCH(p) __builtin_prefetch(p)
#endif
#endif
#ifndef PX_PREFETCH
#define PX_PREFETCH(p) prefetch((p), 1)
#endif

/* Prefetches the lines of a stack entry (node or leaf block, see px_trace_closest_leaf), four
 * lines either way: a leaf block's 160 bytes (16-aligned) from its first byte to its last, a
 * node's lines (a smaller node's last line more than once); without a branch on the entry's
 * kind, which a mix of leaf and interior children makes unpredictable. */
inline void px_prefetch_entry(const global float* nodes, uint e) {
  const uint leaf = e >> 29;
  const size_t start = leaf ? (size_t)(e & 0x1fffffffu) * 4 : (size_t)e * PXW_NODE_FLOATS;
  const global float* p = nodes + start;
  PX_PREFETCH(p);
  PX_PREFETCH(p + 16);
  PX_PREFETCH(p + (leaf ? 32 : min(32, PXW_NODE_FLOATS - 1)));
  PX_PREFETCH(p + (leaf ? 39 : PXW_NODE_FLOATS - 1));
}

/* Per-ray constants of the wide box test. */
typedef struct WideRay {
  pxw_float ox, oy, oz, ix, iy, iz;
  /* Plane row offsets: in floats (Bvh4Node / Bvh8Node), in bytes (CompressedBvh8Node). */
  uint near_x, near_y, near_z, far_x, far_y, far_z;
} WideRay;

inline WideRay px_make_wide_ray(float3 org, float3 inv_dir) {
  WideRay w;
  w.ox = (pxw_float)(org.x);
  w.oy = (pxw_float)(org.y);
  w.oz = (pxw_float)(org.z);
  w.ix = (pxw_float)(inv_dir.x);
  w.iy = (pxw_float)(inv_dir.y);
  w.iz = (pxw_float)(inv_dir.z);
  /* A negative inverse direction enters at hi. */
#if PXW_COMPRESSED
  /* Byte rows: qlo_x 32, qlo_y 40, qlo_z 48, qhi_x 56, qhi_y 64, qhi_z 72. */
  w.near_x = inv_dir.x < 0.0f ? 56u : 32u;
  w.far_x = 88u - w.near_x;
  w.near_y = inv_dir.y < 0.0f ? 64u : 40u;
  w.far_y = 104u - w.near_y;
  w.near_z = inv_dir.z < 0.0f ? 72u : 48u;
  w.far_z = 120u - w.near_z;
#else
  /* Float rows: lo_x, hi_x, lo_y, hi_y, lo_z, hi_z. */
  w.near_x = inv_dir.x < 0.0f ? PXW : 0u;
  w.far_x = PXW - w.near_x;
  w.near_y = inv_dir.y < 0.0f ? 3u * PXW : 2u * PXW;
  w.far_y = 5u * PXW - w.near_y;
  w.near_z = inv_dir.z < 0.0f ? 5u * PXW : 4u * PXW;
  w.far_z = 9u * PXW - w.near_z;
#endif
  return w;
}

/* The slab test proper, on the six plane rows: entry distances in *t_enter; the hit mask. */
inline uint px_wide_slabs(pxw_float nx, pxw_float ny, pxw_float nz, pxw_float fx, pxw_float fy, pxw_float fz,
                          const WideRay* w, float tmin, float tmax, pxw_float* t_enter) {
  const pxw_float tnx = (nx - w->ox) * w->ix;
  const pxw_float tny = (ny - w->oy) * w->iy;
  const pxw_float tnz = (nz - w->oz) * w->iz;
  const pxw_float tfx = (fx - w->ox) * w->ix;
  const pxw_float tfy = (fy - w->oy) * w->iy;
  const pxw_float tfz = (fz - w->oz) * w->iz;
  const pxw_float enter = pxw_max(pxw_max(tnx, tny), pxw_max(tnz, (pxw_float)(tmin)));
  const pxw_float leave = pxw_min(pxw_min(tfx, tfy), pxw_min(tfz, (pxw_float)(tmax))) * PX_BOX_FAR_SCALE;
  *t_enter = enter;
  return pxw_mask(enter <= leave);
}

#if PXW_COMPRESSED

/* Scale of axis k from its biased exponent byte: the float whose bit pattern is e << 23. */
inline float px_cw_scale(const global uchar* node, int k) { return as_float((uint)node[12 + k] << 23); }

/* One decoded plane row: q * scale + p, exact (types.h), so fused or not it is the same float. */
inline float8 px_cw_row(const global uchar* node, uint row, float scale, float p) {
  return convert_float8(vload8(0, node + row)) * scale + p;
}

/* Slab test of the 8 children of a compressed node. Unused slots (meta 0) are masked out: their
 * inverted boxes alone would not do, since near and far distances of a tiny inverted box can
 * round to the same value. */
inline uint px_wide_boxes(const global float* node, const WideRay* w, float tmin, float tmax, float8* t_enter) {
  const global uchar* b = (const global uchar*)node;
  const float sx = px_cw_scale(b, 0), sy = px_cw_scale(b, 1), sz = px_cw_scale(b, 2);
  const float px = node[0], py = node[1], pz = node[2];
  const uint hits =
      px_wide_slabs(px_cw_row(b, w->near_x, sx, px), px_cw_row(b, w->near_y, sy, py), px_cw_row(b, w->near_z, sz, pz),
                    px_cw_row(b, w->far_x, sx, px), px_cw_row(b, w->far_y, sy, py), px_cw_row(b, w->far_z, sz, pz), w,
                    tmin, tmax, t_enter);
  const uchar8 meta = vload8(0, b + 24);
  return hits & pxw_mask(convert_int8(meta != (uchar8)(0)));
}

/* Slot i's stack entry: an interior child's node index (child_base + rank), or a leaf's block
 * offset in 16-byte units | count << 29 (leaf_base + 10 * rank; DeviceScene keeps it < 2^29). */
inline uint pxw_child_entry(const global float* node, uint i) {
  const global uint* words = (const global uint*)node;
  const uint m = ((const global uchar*)node)[24 + i];
  const uint rank = m & PX_CWBVH_RANK_MASK;
  const uint count = (m >> PX_CWBVH_META_COUNT_SHIFT) & 7u;
  return count > 0u ? (words[5] + PX_LEAF_BLOCK_UNITS * rank) | (count << 29) : words[4] + rank;
}

/* The node's second cache line (80 bytes span at most two): start its miss with the first's. */
inline void pxw_prefetch_node_rest(const global float* node) { PX_PREFETCH(node + PXW_NODE_FLOATS - 1); }

#else

/* Slab test of all W children of `node`: entry distances in *t_enter; returns the hit mask. */
inline uint px_wide_boxes(const global float* node, const WideRay* w, float tmin, float tmax, pxw_float* t_enter) {
  return px_wide_slabs(pxw_vload(0, node + w->near_x), pxw_vload(0, node + w->near_y), pxw_vload(0, node + w->near_z),
                       pxw_vload(0, node + w->far_x), pxw_vload(0, node + w->far_y), pxw_vload(0, node + w->far_z), w,
                       tmin, tmax, t_enter);
}

/* Slot i's stack entry: node index, or leaf block offset in 16-byte units | count << 29, as the
 * device form's child row holds it (types.h). */
inline uint pxw_child_entry(const global float* node, uint i) { return ((const global uint*)(node + 6 * PXW))[i]; }

/* The child / count rows are read only after the box test: start their miss now. */
inline void pxw_prefetch_node_rest(const global float* node) { PX_PREFETCH(node + 6 * PXW); }

#endif

inline uint px_lowest_bit(uint m) { return 31u - clz(m & (0u - m)); }

/* Intersects the leaf whose BvhLeafBlock starts at `block` (types.h): the watertight test of
 * px_intersect_triangle_strided on all four lanes at once, the same operations in the same order,
 * so each lane computes exactly what the one-triangle test would. Where any lane's edge
 * function is exactly zero (a ray through an edge or vertex, decided in double precision
 * there), the leaf is intersected triangle by triangle instead. Among hit lanes the nearest wins
 * (the lowest lane on equal t); in an alpha-tested leaf, the nearest that its cut-out keeps.
 * `count` is the leaf's triangle count, which the caller has from the node (the block's own
 * count field holds the same).
 * Returns 1 on any hit. Forced inline, with the one-by-one fallback and its triangle test: a call
 * from the traversal loop makes the loop save its ymm ray constants around it (every vector
 * register is caller-saved), and with a call left on the rare fallback path alone LLVM placed
 * those saves on every leaf visit ("Where the trace kernel loses to Embree"). */
__attribute__((always_inline)) inline int px_intersect_block(const SceneView* scene, const global float* block,
                                                             uint count, const RayShear* s, float tmin, Hit* best) {
  const global uint* header = (const global uint*)(block + 36);
  const uint first = header[0];
#if defined(PX_ALPHA_LEAVES_ONE_BY_ONE) && PX_ALPHA_LEAVES_ONE_BY_ONE
  /* The earlier way, an alpha-tested leaf triangle by triangle: kept as the second code path the
   * lane-wise cut-outs below are checked against (test_trace_kernels); no renderer builds it. */
  if (PX_HAS(PX_FEATURE_ALPHA_TEST) && (header[2] & PX_TRI_ALPHA_TESTED))
    return px_intersect_leaf(scene, block, first, count, s, tmin, best);
#endif
  const float ox = s->ox, oy = s->oy, oz = s->oz;
  const int kx = 4 * s->kx, ky = 4 * s->ky, kz = 4 * s->kz;
  const float4 az = vload4(0, block + kz) - oz;
  const float4 bz = vload4(0, block + 12 + kz) - oz;
  const float4 cz = vload4(0, block + 24 + kz) - oz;
  const float4 ax = (vload4(0, block + kx) - ox) - s->sx * az;
  const float4 ay = (vload4(0, block + ky) - oy) - s->sy * az;
  const float4 bx = (vload4(0, block + 12 + kx) - ox) - s->sx * bz;
  const float4 by = (vload4(0, block + 12 + ky) - oy) - s->sy * bz;
  const float4 cx = (vload4(0, block + 24 + kx) - ox) - s->sx * cz;
  const float4 cy = (vload4(0, block + 24 + ky) - oy) - s->sy * cz;
  float4 eu = cx * by - cy * bx;
  float4 ev = ax * cy - ay * cx;
  float4 ew = bx * ay - by * ax;
  if (px_mask4((eu == 0.0f) | (ev == 0.0f) | (ew == 0.0f)) != 0u)
    return px_intersect_leaf(scene, block, first, count, s, tmin, best);
  int4 ok = !(((eu < 0.0f) | (ev < 0.0f) | (ew < 0.0f)) & ((eu > 0.0f) | (ev > 0.0f) | (ew > 0.0f)));
  float4 det = eu + ev + ew;
  ok &= det != 0.0f;
  float4 tt = eu * (s->sz * az) + ev * (s->sz * bz) + ew * (s->sz * cz);
  const int4 flip = det < 0.0f;
  det = select(det, -det, flip);
  tt = select(tt, -tt, flip);
  ev = select(ev, -ev, flip);
  ew = select(ew, -ew, flip);
  ok &= (tt > tmin * det) & (tt < best->t * det);
  ok &= (int4)(0, 1, 2, 3) < (int4)((int)count);
  uint live = px_mask4(ok);
  if (live == 0u) return 0;
  const float4 inv = 1.0f / det;
  /* The nearest hit lane, the lowest on equal t: the lowest set bit of the lanes at the minimum
   * (no branch per lane, which mispredicts wherever the hit lane varies). */
  float4 t4 = select((float4)(INFINITY), tt * inv, ok);
  const float4 u4 = ev * inv, v4 = ew * inv;
  /* An alpha-tested leaf (foliage cards, mostly cut away): the lanes' geometric hits are tried
   * nearest first, each through its cut-out, until one stays. That is the one-by-one test's
   * answer (the nearest hit that stays, the lowest lane on equal t) with one texture lookup per
   * hit nearer than the best so far, as there, and no scalar triangle tests. An opaque leaf takes
   * the first try's lane, with no test more than before (kernels without the ALPHA_TEST feature
   * compile the loop away). At most four tries, one per lane, and none without a lane at the
   * minimum: bounded, and no lookup out of the leaf, whatever the floats. */
  const int opaque = !(PX_HAS(PX_FEATURE_ALPHA_TEST) && (header[2] & PX_TRI_ALPHA_TESTED));
  for (int tries = 0; tries < 4; ++tries) {
    const float tm = fmin(fmin(t4.x, t4.y), fmin(t4.z, t4.w));
    const uint at_min = px_mask4(t4 == tm) & live;
    const uint lane = px_lowest_bit(at_min);
    const uint4 pick = (uint4)(lane);
    const float u = shuffle(u4, pick).x, v = shuffle(v4, pick).x;
    if (opaque || (at_min != 0u && !px_cut_out(scene, scene->tris + first + lane, u, v))) {
      best->t = tm;
      best->u = u;
      best->v = v;
      best->prim = first + lane;
      return 1;
    }
    if (at_min == 0u) return 0;
    live &= ~(1u << lane);
    if (live == 0u) return 0;
    t4 = select(t4, (float4)(INFINITY), (int4)(lane) == (int4)(0, 1, 2, 3));
  }
  return 0;
}

/* Traversal counters for bench_trace --counters (a build with -DPX_TRACE_COUNTERS=1; never in
 * a renderer's build): px_tree_closest then returns in hit.inst the nodes visited (bits 0..7),
 * leaf blocks intersected (8..15), child boxes hit (16..23) and stack pushes (24..31) of the
 * ray, each saturating at 255. Scenes with instances use inst for the instance: not counted. */
#if defined(PX_TRACE_COUNTERS) && PX_TRACE_COUNTERS
#define PX_COUNT(counter, n) ((counter) = min((counter) + (uint)(n), 255u))
#else
#define PX_COUNT(counter, n)
#endif

/* A closest-hit walk of one ray through one tree, as state that px_walk_step advances by one
 * visit: px_tree_closest runs one walk to its end, px_tree_closest_pair two in step.
 *
 * Stack entries are nodes or leaves (a leaf as its block's offset in 16-byte units | count << 29;
 * DeviceScene keeps offsets below 2^29), each with its entry distance. Of a node's hit children
 * the nearest is visited next without touching the stack (a single hit child, the common case
 * deep in the tree, costs no stack traffic at all); the others are pushed sorted so the nearest
 * is on top, so leaves are intersected near-first as well and a far entry is dropped once a
 * nearer hit has cut best.t below its entry distance. Among equal entry distances the higher
 * child slot goes first, as a stable sort of all hit children would pop them. The stack bound
 * is that of PX_WBVH_STACK_SIZE: a node pops one entry and pushes at most W - 1. */
typedef struct PxClosestWalk {
  Hit best;
  RayShear shear;
  WideRay wray;
  float tmin;
  uint entry; /* the node or leaf visited next */
  int sp;
#if defined(PX_TRACE_COUNTERS) && PX_TRACE_COUNTERS
  uint n_nodes, n_leaves, n_hits, n_pushes;
#endif
  uint stack_node[PXW_STACK];
  float stack_t[PXW_STACK];
} PxClosestWalk;

__attribute__((always_inline)) inline void px_walk_begin(PxClosestWalk* w, float3 org, float3 dir, float tmin,
                                                         float tmax) {
  w->best.t = tmax;
  w->best.u = 0.0f;
  w->best.v = 0.0f;
  w->best.prim = PX_NO_HIT;
  w->best.inst = PX_NO_INSTANCE;
  w->shear = px_make_shear(org, dir);
  w->wray = px_make_wide_ray(org, px_safe_inverse(dir));
  w->tmin = tmin;
  w->entry = 0u;
  w->sp = 0;
#if defined(PX_TRACE_COUNTERS) && PX_TRACE_COUNTERS
  w->n_nodes = w->n_leaves = w->n_hits = w->n_pushes = 0u;
#endif
}

/* Visits w->entry (a leaf block's triangles or a node's child boxes) and finds the entry to visit
 * next; returns 0 when there is none, the walk's end (w->best is then the closest hit). */
__attribute__((always_inline)) inline int px_walk_step(const SceneView* scene, PxClosestWalk* w) {
  const global float* nodes = (const global float*)scene->nodes;
  const uint entry = w->entry;
  if (entry >> 29) {
    PX_COUNT(w->n_leaves, 1);
    px_intersect_block(scene, nodes + (size_t)(entry & 0x1fffffffu) * 4, entry >> 29, &w->shear, w->tmin, &w->best);
  } else {
    const global float* node = nodes + (size_t)entry * PXW_NODE_FLOATS;
    pxw_prefetch_node_rest(node);
    pxw_float enter_v;
    uint mask = px_wide_boxes(node, &w->wray, w->tmin, w->best.t, &enter_v);
    PX_COUNT(w->n_nodes, 1);
    PX_COUNT(w->n_hits, popcount(mask));
    if (mask != 0u) {
      uint i = px_lowest_bit(mask);
      mask &= mask - 1u;
      uint near_e = pxw_child_entry(node, i);
      if (mask == 0u) {
        w->entry = near_e;
        return 1;
      }
      float enter[PXW];
      pxw_vstore(enter_v, 0, enter);
      float near_t = enter[i];
      const int base = w->sp;
      int sp = w->sp;
      while (mask != 0u) {
        i = px_lowest_bit(mask);
        mask &= mask - 1u;
        const float ct = enter[i];
        const uint ce = pxw_child_entry(node, i);
        /* The new child becomes the nearest where it is not farther; the other is pushed.
         * Selects, not a branch: which of two hit children is nearer is a coin toss. */
        const int closer = ct <= near_t;
        const float t = closer ? near_t : ct;
        const uint e = closer ? near_e : ce;
        near_t = closer ? ct : near_t;
        near_e = closer ? ce : near_e;
        px_prefetch_entry(nodes, e);
        if (sp >= PXW_STACK) break; /* unreachable for validated trees */
        PX_COUNT(w->n_pushes, 1);
        int j = sp++;
        while (j > base && w->stack_t[j - 1] < t) {
          w->stack_t[j] = w->stack_t[j - 1];
          w->stack_node[j] = w->stack_node[j - 1];
          --j;
        }
        w->stack_t[j] = t;
        w->stack_node[j] = e;
      }
      w->sp = sp;
      w->entry = near_e;
      return 1;
    }
  }
  int sp = w->sp;
  while (sp > 0) {
    --sp;
    if (w->stack_t[sp] <= w->best.t) {
      w->entry = w->stack_node[sp];
      w->sp = sp;
      return 1;
    }
  }
  w->sp = 0;
  return 0;
}

/* The walk's closest hit; with counters (bench_trace --counters) its visits in hit.inst. */
inline Hit px_walk_hit(const PxClosestWalk* w) {
  Hit h = w->best;
#if defined(PX_TRACE_COUNTERS) && PX_TRACE_COUNTERS
  h.inst = w->n_nodes | w->n_leaves << 8 | w->n_hits << 16 | w->n_pushes << 24;
#endif
  return h;
}

/* Closest hit in one tree. */
inline Hit px_tree_closest(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  PxClosestWalk w;
  px_walk_begin(&w, org, dir, tmin, tmax);
  while (px_walk_step(scene, &w)) {}
  return px_walk_hit(&w);
}

/* Closest hits of two rays in one tree, their walks interleaved visit by visit. Each ray's walk
 * is px_tree_closest's, in the same order, so each hit is the one px_tree_closest gives, to the
 * bit. Why two: an incoherent ray's visits form one chain of dependent loads (which child is next
 * depends on the node just read), mostly from memory beyond the cache; two independent chains
 * let the core wait for both rays' lines at once. */
inline void px_tree_closest_pair(const SceneView* scene, float3 org0, float3 dir0, float3 org1, float3 dir1,
                                 float tmin0, float tmax0, float tmin1, float tmax1, Hit* hit0, Hit* hit1) {
  PxClosestWalk a, b;
  px_walk_begin(&a, org0, dir0, tmin0, tmax0);
  px_walk_begin(&b, org1, dir1, tmin1, tmax1);
  int more_a = 1, more_b = 1;
  while (more_a & more_b) {
    more_a = px_walk_step(scene, &a);
    more_b = px_walk_step(scene, &b);
  }
  while (more_a) more_a = px_walk_step(scene, &a);
  while (more_b) more_b = px_walk_step(scene, &b);
  *hit0 = px_walk_hit(&a);
  *hit1 = px_walk_hit(&b);
}

/* 1 when anything in one tree blocks the ray within (tmin, tmax) (shadow rays). */
inline int px_tree_any(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  const global float* nodes = (const global float*)scene->nodes;
  const RayShear shear = px_make_shear(org, dir);
  const WideRay wray = px_make_wide_ray(org, px_safe_inverse(dir));
  uint stack_node[PXW_STACK];
  int sp = 0;
  uint node_index = 0;
  Hit scratch;
  for (;;) {
    const global float* node = nodes + (size_t)node_index * PXW_NODE_FLOATS;
    pxw_float enter_v;
    uint mask = px_wide_boxes(node, &wray, tmin, tmax, &enter_v);
    while (mask != 0u) {
      const uint i = px_lowest_bit(mask);
      mask &= mask - 1u;
      const uint e = pxw_child_entry(node, i);
      if (e >> 29) {
        scratch.t = tmax;
        if (px_intersect_block(scene, nodes + (size_t)(e & 0x1fffffffu) * 4, e >> 29, &shear, tmin, &scratch)) return 1;
      } else if (sp < PXW_STACK) {
        stack_node[sp++] = e;
      }
    }
    if (sp == 0) break;
    node_index = stack_node[--sp];
  }
  return 0;
}

#endif /* PX_BVH_WIDTH */

/* ---------------------------------------------------------------------------------------
 * Instances (PX_FEATURE_INSTANCES; types.h documents the instance buffer). After the world's
 * own tree, the top level (binary nodes over the instances' world boxes) is walked like the
 * binary tree above, near child first; at an instance the ray enters its mesh's tree in the
 * mesh's own space: origin and direction by world_to_object, the direction left unnormalised
 * so that t, tmin and the closest t so far mean the same distances in both spaces. Inside, the
 * watertight test runs unchanged on the mesh's stored vertices. The mesh tree is found by
 * shifting the node and triangle pointers (SceneInstance::node_offset, triangle_offset). */

/* The scene as the tree of instance `in`'s mesh sees it. */
inline SceneView px_instance_view(const SceneView* scene, const global SceneInstance* in) {
  SceneView v = *scene;
  v.nodes = (const global BvhNode*)((const global uint*)scene->nodes + in->node_offset);
  v.tris = scene->tris + in->triangle_offset;
  return v;
}

/* The instance of top-level leaf entry `j` (the header's leaf_order). */
inline uint px_leaf_instance(const SceneView* scene, uint j) {
  return ((const global uint*)((const global uchar*)scene->instances + 16 * (size_t)scene->instances->order))[j];
}

/* Closest hit among the instances of leaf entries [first, first + count); updates *best. */
inline void px_instances_leaf_closest(const SceneView* scene, uint first, uint count, float3 org, float3 dir,
                                      float tmin, Hit* best) {
  for (uint j = first; j < first + count; ++j) {
    const uint k = px_leaf_instance(scene, j);
    const global SceneInstance* in = px_instance(scene, k);
    const SceneView v = px_instance_view(scene, in);
    const Hit h = px_tree_closest(&v, px_xform_point(in->world_to_object, org), px_xform_dir(in->world_to_object, dir),
                                  tmin, best->t);
    if (h.prim != PX_NO_HIT) {
      *best = h;
      best->prim = h.prim + in->triangle_offset;
      best->inst = k;
    }
  }
}

inline int px_instances_leaf_any(const SceneView* scene, uint first, uint count, float3 org, float3 dir, float tmin,
                                 float tmax) {
  for (uint j = first; j < first + count; ++j) {
    const global SceneInstance* in = px_instance(scene, px_leaf_instance(scene, j));
    const SceneView v = px_instance_view(scene, in);
    if (px_tree_any(&v, px_xform_point(in->world_to_object, org), px_xform_dir(in->world_to_object, dir), tmin, tmax))
      return 1;
  }
  return 0;
}

/* The top level, closest hit (any = 0) or any hit (any = 1: returns 1 at the first). */
inline int px_top_level(const SceneView* scene, float3 org, float3 dir, float tmin, Hit* best, int any) {
  const global SceneInstances* header = scene->instances;
  if (header->count == 0u) return 0;
  const global BvhNode* nodes = (const global BvhNode*)(header + 1); /* byte 32 */
  const float3 inv_dir = px_safe_inverse(dir);
  uint stack[PX_TLAS_STACK_SIZE];
  int sp = 0;
  uint node_index = 0;
  for (;;) {
    const BvhNode n = nodes[node_index];
    float tl = px_child_absent(n.left, n.left_count) ? INFINITY
                                                     : px_intersect_box(org, inv_dir, n.lmin, n.lmax, tmin, best->t);
    float tr = px_child_absent(n.right, n.right_count) ? INFINITY
                                                       : px_intersect_box(org, inv_dir, n.rmin, n.rmax, tmin, best->t);
    if (tl != INFINITY && n.left_count > 0) {
      if (any) {
        if (px_instances_leaf_any(scene, n.left, n.left_count, org, dir, tmin, best->t)) return 1;
      } else {
        px_instances_leaf_closest(scene, n.left, n.left_count, org, dir, tmin, best);
      }
      tl = INFINITY;
    }
    if (tr != INFINITY && n.right_count > 0) {
      if (any) {
        if (px_instances_leaf_any(scene, n.right, n.right_count, org, dir, tmin, best->t)) return 1;
      } else {
        px_instances_leaf_closest(scene, n.right, n.right_count, org, dir, tmin, best);
      }
      tr = INFINITY;
    }
    if (tl > best->t) tl = INFINITY;
    if (tr > best->t) tr = INFINITY;
    if (!px_binary_step(&n, tl, tr, &node_index, stack, &sp, PX_TLAS_STACK_SIZE)) break;
  }
  return 0;
}

/* Closest hit along the ray within (tmin, tmax): the world's tree, then (with instances) the
 * top level. hit.prim is the index into scene->tris (leaf order, so the caller can read the
 * vertices), PX_NO_HIT on a miss; hit.inst the instance (PX_NO_INSTANCE for the world's own). */
inline Hit px_trace_closest_leaf(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  if (!PX_HAS(PX_FEATURE_INSTANCES)) return px_tree_closest(scene, org, dir, tmin, tmax);
  Hit best;
  if (scene->instances->world_triangles != 0u) {
    best = px_tree_closest(scene, org, dir, tmin, tmax);
  } else {
    best.t = tmax;
    best.u = 0.0f;
    best.v = 0.0f;
    best.prim = PX_NO_HIT;
    best.inst = PX_NO_INSTANCE;
  }
  px_top_level(scene, org, dir, tmin, &best, 0);
  return best;
}

/* 1 when anything blocks the ray within (tmin, tmax) (shadow rays). */
inline int px_trace_any(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  if (!PX_HAS(PX_FEATURE_INSTANCES)) return px_tree_any(scene, org, dir, tmin, tmax);
  if (scene->instances->world_triangles != 0u && px_tree_any(scene, org, dir, tmin, tmax)) return 1;
  Hit scratch;
  scratch.t = tmax;
  return px_top_level(scene, org, dir, tmin, &scratch, 1);
}

/* Closest hit with hit.prim the scene triangle index (BvhTriangle::prim). */
inline Hit px_trace_closest(const SceneView* scene, float3 org, float3 dir, float tmin, float tmax) {
  Hit h = px_trace_closest_leaf(scene, org, dir, tmin, tmax);
  if (h.prim != PX_NO_HIT) h.prim = scene->tris[h.prim].prim;
  return h;
}

/* px_trace_closest_leaf of two rays, the same hits to the bit: on wide trees without instances
 * the two walks go in step (px_tree_closest_pair), elsewhere one after the other. */
inline void px_trace_closest_leaf_pair(const SceneView* scene, float3 org0, float3 dir0, float tmin0, float tmax0,
                                       float3 org1, float3 dir1, float tmin1, float tmax1, Hit* hit0, Hit* hit1) {
#if PX_BVH_WIDTH != 2
  if (!PX_HAS(PX_FEATURE_INSTANCES)) {
    px_tree_closest_pair(scene, org0, dir0, org1, dir1, tmin0, tmax0, tmin1, tmax1, hit0, hit1);
    return;
  }
#endif
  *hit0 = px_trace_closest_leaf(scene, org0, dir0, tmin0, tmax0);
  *hit1 = px_trace_closest_leaf(scene, org1, dir1, tmin1, tmax1);
}

/* px_trace_closest of two rays (px_trace_closest_leaf_pair, then the scene triangle indices). */
inline void px_trace_closest_pair(const SceneView* scene, float3 org0, float3 dir0, float tmin0, float tmax0,
                                  float3 org1, float3 dir1, float tmin1, float tmax1, Hit* hit0, Hit* hit1) {
  px_trace_closest_leaf_pair(scene, org0, dir0, tmin0, tmax0, org1, dir1, tmin1, tmax1, hit0, hit1);
  if (hit0->prim != PX_NO_HIT) hit0->prim = scene->tris[hit0->prim].prim;
  if (hit1->prim != PX_NO_HIT) hit1->prim = scene->tris[hit1->prim].prim;
}

#endif
