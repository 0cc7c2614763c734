/* The shading records: what shading reads of a scene triangle (its vertices' normals and
 * texture coordinates, its material), indexed by Hit::prim, in one of three layouts the host
 * picks for the scene (DeviceScene::shading_records). Part of types.h (included there, after
 * its scalar types), shared by host and kernels as it is. */
#ifndef PARALLAX_SHADING_RECORDS_H
#define PARALLAX_SHADING_RECORDS_H

/* Per-scene-triangle shading attributes, 64 bytes, indexed by Hit::prim (scene order, not
 * leaf order: traversal never reads them, only shading does).
 *
 *   0..11 n0[3]  12..19 uv0[2]  20..31 n1[3]  32..39 uv1[2]  40..51 n2[3]  52..59 uv2[2]
 *  60..63 material */
typedef struct TriangleShading {
  float n0[3];
  float uv0[2];
  float n1[3];
  float uv1[2];
  float n2[3];
  float uv2[2];
  uint material;
} TriangleShading;

/* The shading record of a scene whose every triangle is flat (its three vertex normals the
 * same bits) and has no texture coordinates (all six +0): 16 bytes instead of 64. Such a scene
 * (a mesh without NORMAL and TEXCOORD_0, e.g. a scanned or generated heightfield) has nothing
 * per vertex to shade with, and a full record would repeat the normal three times beside six
 * zeros: at 10M triangles 458 MiB of 610 on every device. Kernels built with PX_FLAT_SHADING read
 * these (DeviceScene::flat_shading); they compute the same expressions as with full records,
 * with n for n0, n1 and n2 and zero uvs, so the images are the same bits.
 *
 *   0..11 n[3]  12..15 material */
typedef struct FlatTriangleShading {
  float n[3];
  uint material;
} FlatTriangleShading;

/* The shading record of a smooth mesh (per-vertex normals and texture coordinates, as scanned
 * and modelled meshes come), 16 bytes instead of 64: its three vertices' entries in a table of
 * ShadingVertex (each distinct normal and uv once, where a full record repeats a vertex's for
 * every triangle that shares it), and the material. The table follows the records in the same
 * buffer, so kernels need no other argument: v[k] is how many floats past the record itself
 * vertex k's entry begins (a relative offset, the same wherever the buffer lies). Kernels built
 * with PX_INDEXED_SHADING read these (DeviceScene::indexed_shading); they read the same floats
 * a full record holds and compute the same expressions, so the images are the same bits.
 *
 *   0..11 v[3]  12..15 material */
typedef struct IndexedTriangleShading {
  uint v[3];
  uint material;
} IndexedTriangleShading;

/* One entry of an indexed record's vertex table, 20 bytes (floats only: 4-byte aligned).
 *
 *   0..11 n[3]  12..19 uv[2] */
typedef struct ShadingVertex {
  float n[3];
  float uv[2];
} ShadingVertex;

#ifdef __OPENCL_C_VERSION__
/* The shading buffer's element type as kernels see it (read through px_shading_normal and
 * px_shading_uv, kernels/scene/scene_view.h). */
#if defined(PX_FLAT_SHADING) && PX_FLAT_SHADING
typedef FlatTriangleShading PxTriangleShading;
#elif defined(PX_INDEXED_SHADING) && PX_INDEXED_SHADING
typedef IndexedTriangleShading PxTriangleShading;
#else
typedef TriangleShading PxTriangleShading;
#endif
#endif

#endif
