/* Structs shared by the host (C++) and the kernels (OpenCL C).
 *
 * This header is compiled by both sides, so a layout cannot drift: the host static_asserts
 * every size and offset documented here (host/cl/layout_checks.cpp). Rules that keep the two
 * compilers in agreement:
 *   - only 4-byte scalars (float, uint, int) and arrays of them, plus uchar arrays whose
 *     lengths keep every 4-byte field 4-aligned (CompressedBvh8Node); no float3 (16 bytes in
 *     OpenCL C, 12 in C++), no pointers, no bool;
 *   - every struct is a multiple of 16 bytes where it is read in bulk, so a node or triangle
 *     never straddles more cache lines than it must.
 */
#ifndef PARALLAX_SHARED_TYPES_H
#define PARALLAX_SHARED_TYPES_H

#ifndef __OPENCL_C_VERSION__
#include <cstdint>
namespace px {
typedef std::uint32_t uint;
typedef std::uint8_t uchar; /* only in byte arrays of 4-byte-multiple length (CompressedBvh8Node) */
#endif

/* Work-items per work-group of every kernel launch (host/cl/launch.h; kernels that use
 * local memory, e.g. reprojection's hole compaction, must agree). */
#define PX_LOCAL_SIZE 64

/* Deepest BVH the kernels can traverse. The host asks Embree for at most this depth
 * (RTCBuildArguments::maxDepth) and the validator re-checks it (leaves at depth <= 40, the root
 * at 1, so interior nodes at <= 39). The binary walk pushes at most one entry per interior level
 * above the node it is at, so PX_BVH_STACK_SIZE = PX_BVH_MAX_DEPTH entries cover it: every entry
 * is private memory a GPU work-item holds once per traversal it inlines (docs/measurements.md,
 * "GPU registers from ptxas"). */
#define PX_BVH_MAX_DEPTH 40
#define PX_BVH_STACK_SIZE PX_BVH_MAX_DEPTH

/* Largest leaf the builder produces. */
#define PX_BVH_MAX_LEAF_SIZE 4

/* Binary BVH node, 64 bytes (one cache line), holding both children's boxes so one node
 * fetch tests two boxes (Aila & Laine 2009).
 *
 *  offset  field
 *   0..11  lmin[3]   left child box min
 *  12..15  left      left child: node index, or first triangle index if left_count > 0
 *  16..27  lmax[3]   left child box max
 *  28..31  left_count  0 = interior child, else number of triangles in the leaf
 *  32..43  rmin[3]
 *  44..47  right
 *  48..59  rmax[3]
 *  60..63  right_count
 *
 * An absent child (a root whose whole scene fits in one leaf) has an inverted box
 * (min = +FLT_MAX, max = -FLT_MAX) and count 0 / index 0: no ray ever enters it. */
typedef struct BvhNode {
  float lmin[3];
  uint left;
  float lmax[3];
  uint left_count;
  float rmin[3];
  uint right;
  float rmax[3];
  uint right_count;
} BvhNode;

/* Wide BVH nodes (PX_BVH_WIDTH selects the layout, see below: by default Bvh8Node on CPU device
 * sets, the binary BvhNode above on sets of GPUs, host/bvh/bvh_layout.h bvh_layout_for; the
 * compressed form of the 8-wide tree, CompressedBvh8Node, follows BvhLeafBlock). The same
 * tree as the binary one, collapsed: each wide node stands for a binary node and takes as
 * children up to W of its binary descendants (leaves are the binary leaves, so the triangle
 * array is shared). Children are stored structure-of-arrays, one W-float row per box plane, so
 * the slab test of all W children is six vector loads and a few vector ops in one work-item;
 * a ray reads the near plane rows of its octant first (the row order below lets it pick "lo"
 * or "hi" of an axis by adding W floats).
 *
 * Bvh8Node, 256 bytes (4 cache lines):           Bvh4Node, 128 bytes (2 cache lines):
 *     0..31  lo_x[8]   child boxes' min x             0..15  lo_x[4]
 *    32..63  hi_x[8]   child boxes' max x            16..31  hi_x[4]
 *    64..95  lo_y[8]                                 32..47  lo_y[4]
 *    96..127 hi_y[8]                                 48..63  hi_y[4]
 *   128..159 lo_z[8]                                 64..79  lo_z[4]
 *   160..191 hi_z[8]                                 80..95  hi_z[4]
 *   192..223 child[8]  node index, or first         96..111  child[4]
 *                      triangle index if count > 0
 *   224..255 count[8]  0 = interior child, else     112..127 count[4]
 *                      triangles in the leaf
 *
 * Unused slots (a node with fewer than W children) are absent children as in BvhNode: inverted
 * box (lo = +FLT_MAX, hi = -FLT_MAX on every axis), child 0, count 0; they are never entered.
 * Every wide node is a binary node of the source tree, so the wide tree is no deeper than the
 * binary one (<= PX_BVH_MAX_DEPTH, re-checked by the validator). Nodes are in depth-first
 * order. */
typedef struct Bvh4Node {
  float lo_x[4];
  float hi_x[4];
  float lo_y[4];
  float hi_y[4];
  float lo_z[4];
  float hi_z[4];
  uint child[4];
  uint count[4];
} Bvh4Node;

typedef struct Bvh8Node {
  float lo_x[8];
  float hi_x[8];
  float lo_y[8];
  float hi_y[8];
  float lo_z[8];
  float hi_z[8];
  uint child[8];
  uint count[8];
} Bvh8Node;

/* Leaf block of the wide layouts, 160 bytes: the (at most 4) triangles of one leaf as
 * structure-of-arrays, so the watertight test runs on all of them with float4 ops. Device form
 * only: DeviceScene appends one block per leaf after the wide nodes in the node buffer (Bvh4Node,
 * Bvh8Node: in leaf order, that of their first triangles) and points the leaf slot's `child` at
 * its block, in 16-byte units from the buffer's start, with the leaf's triangle count in bits
 * 29..31 (block | count << 29: the slot's stack entry, read in one load; DeviceScene keeps
 * offsets below 2^29; the count row keeps the count too). The host's Bvh4Node / Bvh8Node keep
 * the first triangle index, as the binary nodes do.
 *
 *     0..143  v[9][4]  rows v0.x v0.y v0.z v1.x v1.y v1.z v2.x v2.y v2.z; lane j = triangle
 *                      first + j; lanes >= count repeat lane 0
 *   144..147  first    leaf-order index (triangle buffer) of lane 0's triangle
 *   148..151  count    triangles in the leaf, 1..4
 *   152..155  flags    OR of the triangles' PX_TRI_* bits (alpha-tested leaves take the
 *                      one-by-one path)
 *   156..159  pad */
typedef struct BvhLeafBlock {
  float v[9][4];
  uint first;
  uint count;
  uint flags;
  uint pad;
} BvhLeafBlock;

/* Leaf triangle without its vertices, 16 bytes: the triangle buffer's element in kernels built
 * with PX_LEAF_REFS (a static scene without instances in a wide layout, DeviceScene), where the
 * leaf blocks already hold every vertex, so the 36 bytes of BvhTriangle's vertices would be a
 * second copy (at 10M triangles, 343 MiB). Same order as BvhTriangle (leaf order).
 *
 *    0..3   prim      scene triangle (TriangleShading index)
 *    4..7   flags     PX_TRI_* bits
 *    8..11  material  GpuMaterial index
 *   12..15  block     its leaf's BvhLeafBlock, in 16-byte units from the node buffer's start;
 *                     the triangle is lane (leaf-order index - block's first) */
typedef struct BvhLeafRef {
  uint prim;
  uint flags;
  uint material;
  uint block;
} BvhLeafRef;

/* Compressed 8-wide BVH node ("cwbvh"), 80 bytes, after Ylitie, Karras & Laine 2017
 * ("Efficient incoherent ray traversal on GPUs through compressed wide BVHs"): the same tree as
 * Bvh8Node (same nodes, same child slots in the same order), with each child box stored as 8-bit
 * offsets on a per-node grid, so a node is 80 bytes instead of 256 (memory traffic is what
 * limits incoherent traversal on GPUs; on a CPU the decode costs more than it saves).
 *
 *  offset  field
 *   0..11  p[3]        grid origin (float): the node's box min snapped down to the grid
 *  12..14  e[3]        per-axis scale as an IEEE-754 biased exponent: scale = 2^(e - 127), whose
 *                      float bit pattern is e << 23 (1 <= e <= 246, so scale and 255 * scale
 *                      are normal floats)
 *  15      imask       bit i set: slot i is an interior child
 *  16..19  child_base  node index of the first interior child; interior children are stored
 *                      contiguously, slot i's at child_base + rank(i)
 *  20..23  leaf_base   host: index into FlatBvh::cleaf_first of the node's first leaf (its
 *                      leaves are contiguous there, slot i's at leaf_base + rank(i));
 *                      device: the first leaf's BvhLeafBlock in 16-byte units from the buffer's
 *                      start, the node's leaf blocks contiguous (slot i's at leaf_base +
 *                      10 * rank(i))
 *  24..31  meta[8]     per slot: 0 = unused; else bit 7 set, bits 3..5 the leaf's triangle
 *                      count (1..4; 0 for an interior child), bits 0..2 rank(i): the slot's
 *                      position among the node's interior children or among its leaves
 *  32..39  qlo_x[8]    quantized child boxes: child i spans, per axis k,
 *  40..47  qlo_y[8]      [p[k] + qlo_k[i] * scale_k, p[k] + qhi_k[i] * scale_k]
 *  48..55  qlo_z[8]    Unused slots hold qlo = 255, qhi = 0 (and meta 0, which traversal
 *  56..63  qhi_x[8]      checks; the inverted box is only a second guard).
 *  64..71  qhi_y[8]
 *  72..79  qhi_z[8]
 *
 * Conservative and exact (host/bvh/compressed_bvh.cpp): qlo is rounded down and qhi up, so the
 * decoded box contains the child's exact box (and the triangles below it); the scale is the
 * smallest power of two for which 255 * scale covers the node's extent from p, raised until p and
 * every p + q * scale (q = 0..255) is an integer multiple of scale below 2^24 * scale, i.e. an
 * exactly representable float. Decoding q * scale + p in float is then exact (with or without a
 * fused multiply-add), so the kernels see exactly the planes the host checked, and the slab test
 * of the decoded box is as conservative as Bvh8Node's (validator: bvh_validator.cpp). Depth and
 * node count are those of the Bvh8Node tree, so PX_WBVH_STACK_SIZE(8) bounds the stack. Nodes are
 * in the order the builder allocates sibling blocks (a node's interior children, then the first
 * child's subtree, depth first). */
typedef struct CompressedBvh8Node {
  float p[3];
  uchar e[3];
  uchar imask;
  uint child_base;
  uint leaf_base;
  uchar meta[8];
  uchar qlo_x[8];
  uchar qlo_y[8];
  uchar qlo_z[8];
  uchar qhi_x[8];
  uchar qhi_y[8];
  uchar qhi_z[8];
} CompressedBvh8Node;

#define PX_CWBVH_META_USED 0x80u
#define PX_CWBVH_META_COUNT_SHIFT 3u
#define PX_CWBVH_RANK_MASK 7u
/* A leaf block (BvhLeafBlock, 160 bytes) in the 16-byte units of leaf_base. */
#define PX_LEAF_BLOCK_UNITS 10u

/* Which node layout the scene's node buffer holds and the traversal reads: 2 (BvhNode), 4
 * (Bvh4Node), 8 (Bvh8Node) or 9 (PX_BVH_COMPRESSED8: CompressedBvh8Node, 8 children per node).
 * This is the one switch: the host passes -DPX_BVH_WIDTH=N to every kernel build and uploads the
 * matching nodes (host/bvh/bvh_layout.h: bvh_layout_width()). */
#define PX_BVH_COMPRESSED8 9
#if defined(__OPENCL_C_VERSION__) && !defined(PX_BVH_WIDTH)
#define PX_BVH_WIDTH 2
#endif

/* The scene features a kernel build carries (-DPX_FEATURES=mask, from the loaded scene:
 * host/render/kernel_features.h). Each run-time branch of a feature is written
 * `if (PX_HAS(PX_FEATURE_X) && <the run-time test>)`: where the scene lacks X the test is false
 * for every pixel anyway, so a build without X drops that code (and, on a GPU, its registers)
 * without changing a bit of any image. A build without the define carries everything.
 *   TEXTURES       diffuse or specular texture lookups (map_Kd, map_Ks, glTF base colour)
 *   ALPHA_TEST     alpha cut-outs tested during traversal (map_d, glTF MASK)
 *   DIELECTRIC     smooth glass: Fresnel reflection and refraction
 *   MIRROR         delta specular lobes (PX_MAT_MIRROR, or a specular colour with alpha 0)
 *   GGX            glossy specular lobes (a specular colour with alpha > 0)
 *   NORMAL_MAP     tangent-space normal maps
 *   EMISSIVE       emissive triangles: emission on hit, next-event estimation of triangles
 *   TWO_SIDED      emitters that emit from both faces
 *   SUN, SKY       the environment's sun disk and analytic sky
 *   VERTEX_COLOURS per-vertex colours (glTF COLOR_0)
 *   INSTANCES      the two-level traversal: after the world tree, the top level over the
 *                  instances (SceneInstances below) and each hit instance's own mesh tree */
#define PX_FEATURE_TEXTURES 0x001u
#define PX_FEATURE_ALPHA_TEST 0x002u
#define PX_FEATURE_DIELECTRIC 0x004u
#define PX_FEATURE_MIRROR 0x008u
#define PX_FEATURE_GGX 0x010u
#define PX_FEATURE_NORMAL_MAP 0x020u
#define PX_FEATURE_EMISSIVE 0x040u
#define PX_FEATURE_TWO_SIDED 0x080u
#define PX_FEATURE_SUN 0x100u
#define PX_FEATURE_SKY 0x200u
#define PX_FEATURE_VERTEX_COLOURS 0x400u /* glTF COLOR_0: per-vertex colours multiply the diffuse colour */
#define PX_FEATURE_INSTANCES 0x800u      /* meshes drawn by several nodes: a top level over instances */
#define PX_FEATURE_PUNCTUAL 0x1000u      /* point and spot lights in the light table (LightTriangle) */
#define PX_FEATURES_ALL 0x1fffu
#if defined(__OPENCL_C_VERSION__)
#ifndef PX_FEATURES
#define PX_FEATURES PX_FEATURES_ALL
#endif
#define PX_HAS(feature) ((PX_FEATURES & (feature)) != 0u)
#endif

/* Wide traversal stack: a node pushes at most W - 1 entries net (it continues into one hit
 * child), nodes are at most PX_BVH_MAX_DEPTH - 1 deep, plus the W - 1 of the last push. */
#define PX_WBVH_STACK_SIZE(w) (((w)-1) * PX_BVH_MAX_DEPTH + 1)

/* Triangle as traversal reads it, 48 bytes, stored in leaf order (with spatial splits a
 * scene triangle may appear in several leaves, so this array can be longer than the scene).
 *
 *   0..11  v0[3]
 *  12..15  prim       index of the triangle in the scene (shading data, material)
 *  16..27  v1[3]
 *  28..31  flags      PX_TRI_* bits (alpha-tested, emissive...)
 *  32..43  v2[3]
 *  44..47  material   material index (duplicated here so any-hit can alpha test without
 *                     another fetch)
 */
typedef struct BvhTriangle {
  float v0[3];
  uint prim;
  float v1[3];
  uint flags;
  float v2[3];
  uint material;
} BvhTriangle;

#ifdef __OPENCL_C_VERSION__
/* The triangle buffer's element type as kernels see it. */
#if defined(PX_LEAF_REFS) && PX_LEAF_REFS
typedef BvhLeafRef PxLeafTriangle;
#else
typedef BvhTriangle PxLeafTriangle;
#endif
#endif

#define PX_TRI_ALPHA_TESTED 1u
#define PX_TRI_EMISSIVE 2u

/* Instances (PX_FEATURE_INSTANCES). A mesh that several glTF nodes draw is stored once, in its
 * own space: its tree's nodes follow the world tree in the node buffer (at a word offset that is
 * a multiple of 16, so its 64-byte lines stay aligned) and its leaf triangles follow the
 * world's in the triangle buffer. Every index inside a mesh tree counts from the tree's own
 * start, so traversal enters it by shifting the two buffer pointers: nothing is rebased.
 * The instance buffer (its ninth scene buffer) holds, from byte 0:
 *   SceneInstances   the header, 32 bytes
 *   BvhNode[]        at byte 32, the top level: binary nodes over the instances' world boxes; a
 *                    leaf's `left` / `right` is the first of its `count` entries of leaf_order
 *   uint leaf_order[count]  at byte 16 * order: the instance of each leaf entry
 *   SceneInstance[count]    at byte 16 * records, in the scene's instance order (so an
 *                    instance keeps its index, Hit::inst, from frame to frame while the top
 *                    level is rebuilt around it)
 * A scene without instances uploads the header alone, with count 0. */
typedef struct SceneInstances {
  uint count;           /* instances */
  uint nodes;           /* top-level nodes (0 when count is 0) */
  uint records;         /* where the SceneInstance array starts, in 16-byte units */
  uint world_triangles; /* 0: the world tree is a placeholder with nothing in it, never entered */
  uint order;           /* where leaf_order starts, in 16-byte units */
  uint pad[3];
} SceneInstances;

/* One instance, 160 bytes: three 3x4 row-major affine matrices (the columns' fourth entry is
 * the translation) and where its mesh lies in the node and triangle buffers.
 *    0..47  world_to_object[12]  a world-space ray enters the mesh through it (direction
 *                                unnormalised, so hit distances t stay the world's)
 *   48..95  object_to_world[12]  hit vertices back to world space; normals go by the
 *                                transpose of world_to_object's 3x3
 *   96..143 previous_object_to_world[12]  the last frame's (the motion pass: where a point of
 *                                the mesh was); object_to_world again for an instance that stood
 *                                still or a scene that does not move
 *  144..147 node_offset          the mesh tree's first word in the node buffer
 *  148..151 triangle_offset      its first leaf triangle in the triangle buffer
 *  152..159 pad[2] */
typedef struct SceneInstance {
  float world_to_object[12];
  float object_to_world[12];
  float previous_object_to_world[12];
  uint node_offset;
  uint triangle_offset;
  uint pad[2];
} SceneInstance;

/* Top-level traversal stack: the host builds the top level by median splits (root at depth 1,
 * a node with more than PX_TLAS_MAX_LEAF instances split in halves), so its interior nodes are at
 * most 31 deep for any instance count a uint holds, and 32 entries cover the walk
 * (top_level_bvh.cpp refuses a deeper one). */
#define PX_TLAS_STACK_SIZE 32
#define PX_TLAS_MAX_LEAF 2

/* A ray, 32 bytes. Hits count in the open interval (tmin, tmax), closest hit and occlusion
 * alike (tmin is exclusive as in Embree: a ray starting on a surface does not hit it at t = 0). */
typedef struct Ray {
  float org[3];
  float tmin;
  float dir[3];
  float tmax;
} Ray;

/* Closest-hit result, 20 bytes. prim = PX_NO_HIT on a miss; (u, v) are the barycentrics of
 * v1 and v2, so the hit point is (1 - u - v) v0 + u v1 + v v2. `inst` is the instance whose
 * mesh was hit (its vertices are then in the mesh's own space: SceneInstance), PX_NO_INSTANCE
 * for the world's own triangles (always, in a scene without instances). */
typedef struct Hit {
  float t;
  float u;
  float v;
  uint prim;
  uint inst;
} Hit;

#define PX_NO_INSTANCE 0xffffffffu
#define PX_NO_HIT 0xffffffffu

/* The shading records (TriangleShading and its flat and indexed forms). */
#include "shared/shading_records.h"

/* Material as the kernels read it, 80 bytes.
 *
 *   0..11 diffuse[3] (linear albedo)       12..15 diffuse_texture (-1 = none)
 *  16..27 specular[3]                      28..31 roughness (GGX alpha; 0 = mirror)
 *  32..43 emission[3] (radiance)           44..47 alpha_texture (-1 = none)
 *  48..51 flags (PX_MAT_*)                 52..55 specular_texture (-1 = none; scales specular)
 *  56..59 normal_texture (-1 = none; tangent-space normal map, linear)
 *  60..63 ior (PX_MAT_DIELECTRIC: index of refraction inside, relative to the outside)
 *  64..75 transmission[3] (PX_MAT_DIELECTRIC: colour filter applied to refracted light)
 *  76..79 normal_scale (normal map strength: the map's tangent-plane components are scaled
 *         by it, MTL -bm) */
typedef struct GpuMaterial {
  float diffuse[3];
  int diffuse_texture;
  float specular[3];
  float roughness;
  float emission[3];
  int alpha_texture;
  uint flags;
  int specular_texture;
  int normal_texture;
  float ior;
  float transmission[3];
  float normal_scale;
} GpuMaterial;

#define PX_MAT_MIRROR 1u
#define PX_MAT_GLOSSY 2u
#define PX_MAT_EMISSIVE 4u
/* Smooth dielectric (glass, water): Fresnel-weighted specular reflection and refraction; the
 * diffuse and glossy parameters are unused. The side a ray arrives from is told by the
 * interpolated shading normal (outward on meshes with vertex normals, the winding's normal
 * otherwise). */
#define PX_MAT_DIELECTRIC 8u
/* Emits from both faces. Without it an emitter emits only from its front face, the side its
 * winding order's normal (v1 - v0) x (v2 - v0) points to, as pbrt and Mitsuba do. */
#define PX_MAT_TWO_SIDED_EMITTER 16u

/* One eye's pinhole camera for one frame, 80 bytes. Rays leave `origin` through the image
 * plane at distance 1 along `forward`; the point (x + jx, y + jy) of pixel (x, y), y = 0 at the
 * top and (jx, jy) in [0, 1)^2 (0.5 is the centre), maps to
 * ndc = ((x + jx) / width * 2 - 1) * tan_half_fov_y * aspect along `right`, and
 * (1 - (y + jy) / height * 2) * tan_half_fov_y along `up`.
 *
 * `jitter` is the frame's sub-pixel position (jx, jy): the G-buffer's ray and the path tracer's
 * first sample of every pixel go through it. It moves from frame to frame along a
 * low-discrepancy sequence (host/render/pixel_jitter.h), so that what the denoiser accumulates
 * over frames covers each pixel's whole footprint (anti-aliased edges, and an emitter's edge
 * pixels converge to their covered share); the same in both eyes and on every device.
 *
 *   0..11 origin[3]   12..15 tan_half_fov_y
 *  16..27 right[3]    28..31 aspect (width / height)
 *  32..43 up[3]       44..47 width
 *  48..59 forward[3]  60..63 height
 *  64..71 jitter[2]   72..79 padding */
typedef struct CameraParams {
  float origin[3];
  float tan_half_fov_y;
  float right[3];
  float aspect;
  float up[3];
  uint width;
  float forward[3];
  uint height;
  float jitter[2];
  uint pad[2];
} CameraParams;

/* Where a texture's texels start in the texel buffer (float4 RGBA, linear, rows top to bottom), 16 bytes. */
typedef struct TextureInfo {
  uint offset; /* in texels */
  uint width;
  uint height;
  uint pad;
} TextureInfo;

/* One emissive triangle for next-event estimation, 64 bytes. Lights are chosen in proportion
 * to power (area x luminance of emission): `cdf` is the inclusive running sum over the table,
 * normalised to 1 at the last entry, and `pdf_select` this triangle's probability.
 *
 *   0..11 v0[3]  12..15 prim   16..27 v1[3]  28..31 area
 *  32..43 v2[3]  44..47 cdf    48..59 emission[3]  60..63 pdf_select
 * Point and spot lights (PX_FEATURE_PUNCTUAL) follow the triangles: prim PX_LIGHT_PUNCTUAL + k
 * (Scene::punctual_lights[k]; above every triangle, so the table stays sorted by prim), area 0,
 * v0 the position, v1 the spot's axis, v2 the falloff's (scale, offset, cos_outer), emission the
 * intensity (W/sr); power 4 pi I, a spot's 2 pi (1 - (cos_inner + cos_outer) / 2) I. */
#define PX_LIGHT_PUNCTUAL 0xc0000000u
typedef struct LightTriangle {
  float v0[3];
  uint prim;
  float v1[3];
  float area;
  float v2[3];
  float cdf;
  float emission[3];
  float pdf_select;
} LightTriangle;

/* One node of the light tree (host/render/light_tree.h), 64 bytes: the binary tree the host builds
 * and refits. A node bounds its lights: box, total power phi (area x luminance, x 2 if
 * two-sided), cone of emitting normals (axis, theta_o) and spread theta_e of emission around a
 * normal. Leaf: the triangle's box and normal, theta_o 0 (pi if two-sided), theta_e pi/2; a point
 * light: its point, phi its intensity's luminance, theta_o pi (a spot: its axis, the outer cone).
 *   0..11 bounds_min[3]  12..23 bounds_max[3]  24..27 phi  28..39 axis[3]  40..43 cos_theta_o
 *  44..47 cos_theta_e  48..55 child[2] (node index, or PX_LIGHT_TREE_LEAF | light: a leaf)
 *  56..59 sin_theta_o  60..63 radius (half the box's diagonal): both derived from the fields above. */
#define PX_LIGHT_TREE_LEAF 0x80000000u
typedef struct LightTreeNode {
  float bounds_min[3];
  float bounds_max[3];
  float phi;
  float axis[3];
  float cos_theta_o;
  float cos_theta_e;
  uint child[2];
  float sin_theta_o;
  float radius;
} LightTreeNode;

/* The light tree as the kernels walk it, 256 bytes: the binary tree two levels to a node. Lane k of
 * a wide node is a node of the binary tree two levels below the one it was made from (lanes 0, 1
 * under child[0], lanes 2, 3 under child[1]), or, where that child is a leaf, the leaf itself in
 * the first of its two lanes and PX_LIGHT_TREE_EMPTY in the second. Each field holds the four
 * lanes' LightTreeNode fields side by side, so that a walk reads a field of all four with one
 * aligned 16-byte load (kernels/shading/light_tree.h).
 *    0..47 bounds_min[3][4]   48..95 bounds_max[3][4]   96..143 axis[3][4]   144..159 phi[4]
 *  160..175 cos_theta_o[4]  176..191 sin_theta_o[4]  192..207 cos_theta_e[4]  208..223 radius[4]
 *  224..239 child[4] (wide node index, PX_LIGHT_TREE_LEAF | light, or PX_LIGHT_TREE_EMPTY)
 *  240..243 by_power (1: the used lanes have the same box and cones, as a quad's two triangles do, so
 *  their importances anywhere are in the ratio of their powers, and the walk weighs them by power
 *  alone)  244..255 pad
 * The `lights` buffer holds LightTriangle x n (the table, by prim), uint trail x n padded to 64 bytes
 * (bit i: light k's path from the root of the binary tree takes child[1] at depth i), then the wide
 * nodes, root first, as 4 records each. */
#define PX_LIGHT_TREE_EMPTY 0xffffffffu
typedef struct LightTreeWideNode {
  float bounds_min[3][4];
  float bounds_max[3][4];
  float axis[3][4];
  float phi[4];
  float cos_theta_o[4];
  float sin_theta_o[4];
  float cos_theta_e[4];
  float radius[4];
  uint child[4];
  uint by_power;
  uint pad[3];
} LightTreeWideNode;

/* FrameParams::gbuffer_ray_samples. NONE: every sample jittered over the pixel (references).
 * FIRST: sample 0 of the frame along the G-buffer's ray, the rest jittered. EVERY: every sample
 * along it (a denoised frame at several spp: the denoiser's G-buffer then describes the surface
 * every sample saw; path_vertex.h, px_sample_camera_dir). */
#define PX_GBUFFER_RAY_NONE 0u
#define PX_GBUFFER_RAY_FIRST 1u
#define PX_GBUFFER_RAY_EVERY 2u
/* FIRST_KIND: as FIRST, but a pixel's mean counts only the samples whose first hit is of its first
 * counted sample's kind, emitter or not (pixel_mean.h, px_same_kind): a denoised frame in a moving
 * view, where the spread samples anti-alias edges but a lamp's must not fall under a ceiling's
 * texel. */
#define PX_GBUFFER_RAY_FIRST_KIND 3u

/* path_trace_pixels' modes (pathtrace/path_trace.cl; CPU devices): the path tracer over a strip or
 * a pixel list (stages 2 and 5), the G-buffer pass (stage 3), the temporal gradients' shading. */
#define PX_PIXELS_PATHS 0u
#define PX_PIXELS_GBUFFER 1u
#define PX_PIXELS_GRADIENT 2u

/* Everything a path-tracing launch needs besides buffers, 128 bytes, passed by value.
 *
 *   0..11 sun_dir[3] (towards the sun)         12..15 sun_cos_max (cos of angular radius)
 *  16..27 sun_radiance[3]                      28..31 p_sun (light-type selection)
 *  32..43 sky_zenith[3]                        44..47 p_sky
 *  48..59 sky_horizon[3]                       60..63 p_triangles
 *  64..75 sky_ground[3]                        76..79 light_count (LightTriangle entries)
 *  80..83 frame   84..87 eye   88..91 spp   92..95 max_bounces
 *  96..99 seed   100..103 light_sampling (PX_LIGHTS_*)  104..107 rr_start_bounce
 * 108..111 row0 (first image row of this launch)  112..115 rows  124..127 direct_light (PX_DIRECT_*)
 * 116..119 sample_offset (index of this launch's first sample: progressive passes)
 * 120..123 gbuffer_ray_samples (PX_GBUFFER_RAY_*: which samples go along the G-buffer's ray, through
 *          CameraParams::jitter) */
typedef struct FrameParams {
  float sun_dir[3];
  float sun_cos_max;
  float sun_radiance[3];
  float p_sun;
  float sky_zenith[3];
  float p_sky;
  float sky_horizon[3];
  float p_triangles;
  float sky_ground[3];
  uint light_count;
  uint frame;
  uint eye;
  uint spp;
  uint max_bounces;
  uint seed;
  uint light_sampling;
  uint rr_start_bounce;
  uint row0;
  uint rows;
  uint sample_offset;
  uint gbuffer_ray_samples;
  uint direct_light;
} FrameParams;

/* Largest FrameParams::max_bounces the host accepts: two sample dimensions per bounce must
 * stay clear of the bits px_sample4 shifts the dimension into. */
#define PX_MAX_BOUNCES_LIMIT 256u

/* Which estimators combine at each vertex: next-event estimation only, BSDF sampling only,
 * or both weighted by the power heuristic (the default). */
#define PX_LIGHTS_MIS 0u
#define PX_LIGHTS_NEE 1u
#define PX_LIGHTS_BSDF 2u

/* FrameParams::direct_light: lights picked by power (a CDF), by the light tree, or by the tree
 * with ReSTIR DI at each pixel's first vertex (no next-event estimate there: stage 14 adds it). */
#define PX_DIRECT_POWER 0u
#define PX_DIRECT_TREE 1u
#define PX_DIRECT_RESTIR 2u

/* The wavefront path tracer (kernels/pathtrace/wavefront.cl) keeps every path of a launch (one
 * per (pixel, sample) pair, path i = slot * spp + sample) in global memory between its kernels.
 * Per path, in float4 buffers:
 *
 *   path state, PX_PATH_STATE_FLOAT4S float4 (96 bytes; PathVertex in pathtrace/path_vertex.h):
 *     0  org.xyz, prev_pdf            the next ray's origin; the last BSDF sample's pdf
 *     1  dir.xyz, prev_delta          the next ray's direction; 1.0f after a delta bounce
 *     2  throughput.xyz, prev_p.x
 *     3  radiance.xyz, prev_p.y       gathered so far; prev_p: the last vertex's hit point
 *     4  prev_n.xyz, prev_p.z         the last vertex's shading normal
 *     5  primary_albedo               the denoiser's demodulation albedo (w: coverage)
 *   shadow ray, PX_SHADOW_RAY_FLOAT4S float4 (48 bytes; ShadowRay there):
 *     0  org.xyz, tmax
 *     1  dir.xyz, 0
 *     2  contribution.xyz, 0          added to the radiance if nothing blocks the ray
 *
 * and besides: one Hit, one uint pixel index (full frame) per path, two uint queues of live
 * path indices (swapped every vertex), one of paths with a shadow ray, and the counters
 * (uint[PX_WAVEFRONT_COUNTERS]): [0] the launch's slots (pixels); [PX_WF_LIVE + b] the paths
 * alive at vertex b; [PX_WF_SHADOWS + b] the shadow rays made at vertex b, b = 0..max_bounces. */
#define PX_PATH_STATE_FLOAT4S 6u
#define PX_SHADOW_RAY_FLOAT4S 3u
#define PX_WF_LIVE 1u
#define PX_WF_SHADOWS (PX_WF_LIVE + PX_MAX_BOUNCES_LIMIT + 1u)
#define PX_WAVEFRONT_COUNTERS (PX_WF_SHADOWS + PX_MAX_BOUNCES_LIMIT + 1u)

/* One G-buffer texel (stage 3): what the primary ray through the pixel centre hit, 40 bytes.
 * (No albedo: the denoiser demodulates by the path tracer's per-pixel mean albedo of the
 * samples themselves, which the centre's albedo is not.)
 *
 *   0..11 pos[3] (world hit point; on a miss the ray's unit direction)
 *                                        12..15 depth (distance along the ray; 0 on a miss)
 *  16..27 normal[3] (shading, facing the eye)  28..31 material_class (PX_CLASS_*)
 *  32..35 prim (scene triangle, PX_NO_HIT on a miss)
 *  36..39 inst (the instance whose mesh holds `prim`, PX_NO_INSTANCE for the world's own
 *         triangles and on a miss: the motion pass moves its point by the instance's matrices) */
typedef struct GBufferTexel {
  float pos[3];
  float depth;
  float normal[3];
  uint material_class;
  uint prim;
  uint inst;
} GBufferTexel;

#define PX_CLASS_MISS 0u
#define PX_CLASS_DIFFUSE 1u /* view-independent: may be reprojected between eyes */
#define PX_CLASS_GLOSSY 2u
#define PX_CLASS_MIRROR 3u
#define PX_CLASS_EMISSIVE 4u
#define PX_CLASS_DIELECTRIC 5u /* refracts: view-dependent, never reprojected */

/* Reprojection tolerances (after Tauray's normal cosine 0.99, made scale-free): a left-eye tap
 * is the same surface when the normals' cosine exceeds PX_REPROJECT_MIN_COS, its distance from
 * the right pixel's tangent plane is below PX_REPROJECT_REL_DIST x depth, and it lies within
 * PX_REPROJECT_FOOTPRINTS pixel footprints (stretched by 1/cos of the viewing angle). */
#define PX_REPROJECT_MIN_COS 0.99f
#define PX_REPROJECT_REL_DIST 0.01f
#define PX_REPROJECT_FOOTPRINTS 3.0f

/* The motion pass's output w (kernels/pipeline/motion.cl): a miss, a point whose object stood
 * still since the last frame, a point whose object moved. */
#define PX_MOTION_MISS 0.0f
#define PX_MOTION_STILL 1.0f
#define PX_MOTION_MOVED 2.0f
/* The neighbours of a reprojected pixel (its footprint's surroundings) only need to lie on the
 * same continuous surface: a looser normal test, so that curved surfaces stay reprojectable. */
#define PX_REPROJECT_NEIGHBOUR_MIN_COS 0.9f

/* SVGF launch constants (Schied et al. 2017), 64 bytes, passed by value to every SVGF pass.
 *
 *   0..3 sigma_l  4..7 sigma_z  8..11 sigma_n  12..15 alpha (colour)  16..19 alpha_moments
 *  20..23 max_history  24..27 temporal_rows (largest vertical reprojection offset, rows, beyond
 *  which history is rejected — a uniform rule, so every strip split reads the same rows)
 *  28..31 step (a-trous tap spacing, 2^i)  32..35 row0  36..39 rows (rows written)
 *  40..43 lo_row  44..47 hi_row (rows that may be read: the strip alone with independent seams,
 *  the whole image with halo exchange)  48..51 width  52..55 height
 *  56..63 jitter[2] (the frame's sub-pixel sample position, CameraParams::jitter: where in its
 *  pixel the G-buffer texel lies, which temporal reprojection takes back out) */
typedef struct SvgfParams {
  float sigma_l;
  float sigma_z;
  float sigma_n;
  float alpha;
  float alpha_moments;
  uint max_history;
  uint temporal_rows;
  uint step;
  uint row0;
  uint rows;
  uint lo_row;
  uint hi_row;
  uint width;
  uint height;
  float jitter[2];
} SvgfParams;

/* Temporal gradients (denoise/temporal_gradient.cl, gradient_filter.cl) of one eye on one device.
 * Strata rows are in units of PX_GRADIENT_STRATUM pixel rows; a launch writes strata rows
 * [s_row0, s_row0 + s_rows) and reads strata rows [s_lo, s_hi) of its input, and pixel rows
 * [lo_row, hi_row) of the G-buffers (the rows it may read; a pick outside is clamped in). */
typedef struct GradientParams {
  uint width;
  uint height;
  uint strata_w;
  uint strata_h;
  uint s_row0;
  uint s_rows;
  uint s_lo;
  uint s_hi;
  uint lo_row;
  uint hi_row;
  uint step;
  uint frame;
  uint eye;
  uint seed;
  uint have_history;
  uint pad;
} GradientParams;

#ifndef __OPENCL_C_VERSION__
} /* namespace px */
#endif

#endif /* PARALLAX_SHARED_TYPES_H */
