// Scene data every device reads whole (sort-first rendering partitions the image, never the
// scene): BVH nodes, leaf-order triangles, per-triangle shading, materials, textures, the
// emissive-triangle table, vertex colours and the instances (their top level and matrices). A
// scene with instances keeps each instanced mesh's tree and leaf triangles after the world's in
// the same node and triangle buffers (types.h: the instance buffer). One set of read-only buffers in the set's OpenCL
// context, shared by all its devices (on(d) gives every device the same buffers); a buffer larger than a device's
// CL_DEVICE_MAX_MEM_ALLOC_SIZE (or PARALLAX_MAX_ALLOC_BYTES) is refused with an error naming it.
// Kernels take these as their last parameters (PX_SCENE_PARAMS in kernels/scene/scene_view.h);
// bind() sets them in that order.
#pragma once

#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"
#include "bvh/top_level_bvh.h"
#include "cl/device_set.h"
#include "io/background_writes.h"
#include "render/device_layout_cache.h"
#include "render/kernel_features.h"
#include "render/light_tree.h"
#include "render/scene_tables.h"
#include "scene/scene.h"

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace px {

struct SceneBytes;  // render/device_buffers.h

struct DeviceSceneBuffers {
  cl::Buffer nodes;      // BvhNode[], Bvh4Node[], Bvh8Node[] or CompressedBvh8Node[] (DeviceSet::bvh_layout())
  cl::Buffer triangles;  // BvhTriangle[] (leaf order, flags filled from materials), or BvhLeafRef[] (leaf_refs())
  cl::Buffer shading;    // TriangleShading[] (scene order)
  cl::Buffer materials;  // GpuMaterial[]
  cl::Buffer textures;   // TextureInfo[]
  cl::Buffer texels;     // float4[] (all textures back to back)
  cl::Buffer lights;     // LightTriangle[]
  cl::Buffer colours;    // float4[3] per scene triangle (vertex colours), or one placeholder float4
  cl::Buffer instances;  // SceneInstances header, top-level BvhNode[], SceneInstance[] (types.h)
  // Animated scenes only (SceneAnimator), else null: per scene triangle six float4, its three
  // vertices now and in the previous frame (the motion pass, kernels/pipeline/motion.cl). Not
  // one of the nine scene arguments bind() sets.
  cl::Buffer motion;

  // Sets the nine scene arguments starting at argument index `first`; returns the next index.
  cl_uint bind(cl::Kernel& kernel, cl_uint first) const;
};

// Where a DeviceScene that lays a static scene without instances out stores that layout for the
// next start to map (device_layout_cache.h). No cache: nothing is stored.
struct DeviceLayoutStore {
  const DeviceLayoutCache* cache = nullptr;
  std::uint64_t content_key = 0;  // scene_content_key(scene)
  BvhBuildOptions options;        // those the tree was built with
  bool quiet = true;              // else say where it went (stderr)
  // A static scene laid out from its host part (prepare_host) is written there on a thread of
  // its own once the first frame is on its way (BackgroundWrites::Start::AfterFirstFrame), from
  // the arrays the devices got (CPU devices read those very arrays; a GPU set's are kept for
  // the write); null, or any other scene: written before the constructor returns.
  BackgroundWrites* background = nullptr;
  // Called before the constructor first changes or frees the tree it was handed, and before it
  // throws: a BVH cache write may still be reading it (scene_setup.cpp). Null: none.
  std::function<void()> before_tree_changes;
};

class DeviceScene {
 public:
  // Uploads `bvh` and the scene's shading data once into the context of `devices` (blocking).
  // `bvh` is taken by value: a caller that no longer needs its tree moves it in, and its
  // memory is gone when the upload is done (SceneOnDevices does).
  // A scene with instances (Scene::instancing): `bvh` is the world tree (build_world_bvh; empty
  // nodes are built here), `mesh_bvhs` the instanced meshes' trees (build_mesh_bvhs; built here
  // when empty). Their nodes go into the one node buffer, mesh after mesh, and the instances'
  // top level into the instance buffer. Such a scene cannot be updated (update_geometry).
  // With `store`, a static scene's layout also goes to the device layout cache.
  // `take_triangles`, if given, is called once the triangles' flags, the light table and the
  // vertex colours are made, before the shading records and the device words: it hands over the
  // scene's triangles (moved out of the scene, which keeps none), and the shading records are
  // made in their memory (64 of each triangle's 100 bytes, 16 where the records are flat:
  // flat_shading(); the rest goes back to the system).
  // A static scene without instances then takes the two steps below (prepare_host first).
  // For a caller that needs the triangles no more (SceneOnDevices, for a static scene): at 10M
  // triangles their 1 GB then holds the shading records instead of standing beside them, and is
  // gone before the layout's largest part is made. After it, the constructor reads nothing of
  // `scene.triangles`.
  DeviceScene(DeviceSet& devices, const Scene& scene, FlatBvh bvh, std::vector<FlatBvh> mesh_bvhs = {},
              const DeviceLayoutStore& store = {},
              const std::function<std::vector<SceneTriangle>()>& take_triangles = {});
  // A static scene without instances in two steps, so that its largest host array is gone before
  // the devices are made (SceneOnDevices): prepare_host makes what does not depend on the
  // devices (the small tables and the triangle flags, then the shading records in the memory of
  // the triangles `take_triangles` hands over, as above), and this constructor the layout of the
  // set (nodes the tree lacks are made here and validated against its leaf triangles:
  // validate_layout_from_leaves; in Wide4 and Wide8 the leaf triangles go as BvhLeafRef records,
  // leaf_refs()). The same buffers as the constructor above with `take_triangles`, which runs
  // these two steps itself for such a scene.
  struct HostPart;
  static std::shared_ptr<HostPart> prepare_host(const Scene& scene,
                                                const std::function<std::vector<SceneTriangle>()>& take_triangles);
  DeviceScene(DeviceSet& devices, std::shared_ptr<HostPart> host, const Scene& scene, FlatBvh bvh,
              const DeviceLayoutStore& store = {});
  // prepare_host for a start whose tree is not built yet: the records (16-byte flat ones where
  // every triangle is flat, has_flat_shading; else indexed ones, indexed_shading.h) go to a block
  // of their own, and each triangle's corners and material (BuildTriangle, 40 bytes) are packed
  // where the triangles were, into `corners`, which the tree is then built, validated and cached
  // from (TriangleSource). The 100-byte triangles are gone before the build begins, so the
  // build's arrays never stand beside them (the cold start's highest point: 48 bytes a triangle
  // lower). The corners' memory goes with the last copy of `corners`. Null, and nothing taken,
  // only where PARALLAX_INDEXED_SHADING=off keeps a smooth scene's 64-byte records (made after
  // its tree).
  struct BuildCorners {
    std::shared_ptr<const void> owner;
    const BuildTriangle* data = nullptr;
    std::size_t count = 0;
    TriangleSource source() const { return {data, count}; }
  };
  static std::shared_ptr<HostPart> prepare_host_before_tree(
      const Scene& scene, const std::function<std::vector<SceneTriangle>()>& take_triangles, BuildCorners& corners);
  // A static scene without instances whose layout a start mapped from the cache
  // (DeviceLayoutCache::open) in the set's layout: its sections are the node, triangle and
  // shading buffers (CPU devices read the mapping itself), nothing is laid out.
  DeviceScene(DeviceSet& devices, const Scene& scene, std::shared_ptr<const MappedDeviceLayout> mapped);

  const DeviceSceneBuffers& on(int device_index) const { return per_device_.at(device_index); }

  // A frame of an animated scene: `scene`'s triangles (same count and order as at construction)
  // and their new tree replace the geometry on the devices: nodes, leaf triangles, shading, the
  // light table and, with `previous` (the last frame's triangles), the motion buffer. Materials
  // and textures stay. Buffers are rewritten in place, or replaced by larger ones when the new
  // data does not fit (a tree of more nodes). The caller makes sure no device still reads them
  // (StereoPipeline::render returns with every queue finished). Only the 16 KiB pieces whose
  // bytes changed since the last call are written (the first call writes all). Returns the
  // bytes written.
  // `bvh` gets the triangle flags and the set's node layout (collapsed if missing) in place, so
  // that a caller keeping its tree for the next frame's refit (SceneAnimator) need not copy it.
  // With instances (Scene::instancing, an animated file's rigid meshes on moving nodes): `bvh`
  // is the world tree (empty nodes when the world has no triangles of its own), the meshes'
  // trees stay as uploaded, and the instance buffer (top level, matrices and, from
  // `previous_instances`, last frame's matrices) is rewritten.
  std::size_t update_geometry(DeviceSet& devices, const Scene& scene, FlatBvh& bvh,
                              const std::vector<SceneTriangle>* previous,
                              const std::vector<glm::mat4>* previous_instances = nullptr);
  // A frame whose only change is where point and spot lights are (SceneAnimator): the light
  // table and its tree rewritten as update_geometry would. Returns the bytes written.
  std::size_t update_lights(DeviceSet& devices, const Scene& scene);
  // Bytes of scene data in the set's context, shared by all its devices (one copy per context).
  std::size_t bytes_in_context() const { return bytes_in_context_; }
  // Host time to create and write those buffers (blocking writes), ms.
  double upload_ms() const { return upload_ms_; }
  // Host time to make the device layout before that (triangle flags, wide nodes and leaf blocks,
  // shading records, the light table, instances; prepare_host's part included), ms.
  double layout_ms() const { return layout_ms_; }
  // Of layout_ms, the host part's (the shading records and tables a static scene makes before
  // its tree is built: prepare_host_before_tree / prepare_host), ms; 0 without one.
  double host_part_ms() const { return host_part_ms_; }
  // Whether the buffers are the host's own arrays (every device a CPU device: no second copy).
  bool host_backed() const { return host_backed_; }
  // Whether the layout came mapped from the device layout cache, and the time spent storing it
  // there (ms, 0 when it was not; not part of layout_ms).
  bool layout_from_cache() const { return layout_from_cache_; }
  double layout_store_ms() const { return layout_store_ms_; }
  using HostBytes = SceneBytes;
  std::size_t light_count() const { return light_count_; }
  // Instances uploaded (0 without), and the instance buffer's bytes (top level and records).
  std::size_t instance_count() const { return instance_count_; }
  std::size_t instance_bytes() const { return instance_bytes_; }
  // The node layout uploaded (the set's bvh_layout() at construction), and the kernel build
  // option that matches it (DeviceSet::program uses the set's current layout when none is given).
  BvhLayout layout() const { return layout_; }
  // Whether the triangle buffer holds BvhLeafRef records (types.h), the leaf blocks in the node
  // buffer holding the vertices: a static scene without instances, handed over (take_triangles)
  // or mapped, in the Wide4 or Wide8 layout. kernel_options() then says PX_LEAF_REFS.
  bool leaf_refs() const { return leaf_refs_; }
  // Whether the shading buffer holds FlatTriangleShading records (types.h: 16 bytes, one normal
  // and the material) instead of TriangleShading (64): a static scene without instances, handed
  // over or mapped, whose every triangle is flat and has no texture coordinates
  // (has_flat_shading). kernel_options() then says PX_FLAT_SHADING; the images are the same.
  bool flat_shading() const { return shading_records_ == ShadingRecords::Flat; }
  // Whether it holds IndexedTriangleShading records and their vertex table (types.h: 16 bytes a
  // triangle and 20 a distinct vertex): a static scene without instances, handed over or mapped,
  // whose triangles are not all flat (a smooth mesh), unless PARALLAX_INDEXED_SHADING=off or
  // its vertices share too little to pay. kernel_options() then says PX_INDEXED_SHADING; the
  // images are the same.
  bool indexed_shading() const { return shading_records_ == ShadingRecords::Indexed; }
  ShadingRecords shading_records() const { return shading_records_; }
  // The build options of the scene-dependent kernels (path tracers, G-buffer, trace, preview):
  // the node layout and the PX_FEATURES the kernels carry (kernel_features.h).
  std::string kernel_options() const;
  // The kernel_options() of the scene that DeviceScene(devices, host, ...) will make on a set in
  // `layout` with kernels of `choice`, known before its tree is built: a start builds the scene's
  // kernels while it builds the tree (DeviceSet::prebuild).
  static std::string kernel_options_for(const HostPart& host, BvhLayout layout, KernelChoice choice);

  // The features the scene uses, and those its kernels are built with: the scene's (the
  // default) or every feature (KernelChoice::General). Choose before any stage builds a kernel.
  std::uint32_t scene_features() const { return scene_features_; }
  std::uint32_t kernel_features() const { return choice_ == KernelChoice::General ? PX_FEATURES_ALL : scene_features_; }
  KernelChoice kernel_choice() const { return choice_; }
  void set_kernel_choice(KernelChoice choice) { choice_ = choice; }

 private:
  // prepare_host's and prepare_host_before_tree's work, once they checked the scene is static: with
  // `corners`, the flat or indexed records go to a block of their own and the corners over the
  // triangles.
  static std::shared_ptr<HostPart> make_host_part(const Scene& scene,
                                                  const std::function<std::vector<SceneTriangle>()>& take_triangles,
                                                  BuildCorners* corners);
  std::vector<DeviceSceneBuffers> per_device_;
  // Allocated bytes of the buffers update_geometry rewrites.
  struct Capacity {
    std::size_t nodes = 0, triangles = 0, shading = 0, lights = 0, motion = 0, instances = 0;
  } capacity_;
  // An animated scene with instances: the meshes' node words and leaf triangles (prims in scene
  // order), kept to be placed behind each frame's world tree.
  std::vector<std::vector<std::uint32_t>> mesh_words_;
  std::vector<std::vector<BvhTriangle>> mesh_triangles_;
  // The node words and leaf triangles of the world tree (null: none) with the meshes' behind it
  // (64-byte aligned), and where each mesh went.
  std::vector<MeshPlacement> assemble_instanced(const FlatBvh* world, std::vector<std::uint32_t>& words,
                                                std::vector<BvhTriangle>& triangles) const;
  // The constructors' common part: the small tables made from the scene (materials, textures,
  // lights, vertex colours; the kernel features), made before the scene's triangles may go ...
  struct SceneTables;  // device_scene.cpp
  static SceneTables make_tables(const Scene& scene, const std::vector<std::uint32_t>& tri_flags, bool instanced);
  // The static scene's layout from its host part (both constructors of such a scene).
  void lay_out_static(DeviceSet& devices, const Scene& scene, FlatBvh bvh, std::shared_ptr<HostPart> host,
                      const DeviceLayoutStore& store, std::chrono::steady_clock::time_point layout_start);
  // Writes `parts` to the store's cache, saying so unless quiet; layout_store_ms_ is its time.
  // With the store's background writes and `keep` (the owners of the arrays `parts` points
  // into), on their thread instead (layout_store_ms_ 0; their busy_ms() says).
  void store_layout(const DeviceLayoutStore& store, const DeviceLayoutParts& parts, std::size_t scene_triangles,
                    std::vector<std::shared_ptr<const void>> keep = {});
  // ... and the upload of everything.
  void upload_all(DeviceSet& devices, const Scene& scene, HostBytes nodes, HostBytes triangles, HostBytes shading,
                  std::vector<std::uint32_t> instance_words, SceneTables tables,
                  const std::vector<std::uint32_t>& tri_flags, std::chrono::steady_clock::time_point layout_start);
  // triangle_flags(scene), fixed by the materials: kept for update_geometry (animated scenes).
  std::vector<std::uint32_t> tri_flags_;
  // What update_geometry last wrote to each of those buffers (empty until its first call, which
  // writes them whole), so that later calls write only the pieces that changed.
  struct Shadows {
    std::vector<std::uint8_t> nodes, triangles, shading, lights, motion, instances;
  } shadows_;
  std::size_t bytes_in_context_ = 0;
  double upload_ms_ = 0.0;
  double layout_ms_ = 0.0;
  double host_part_ms_ = 0.0;
  std::size_t light_count_ = 0;
  // update_geometry's light tree and the prims of the table it was built for (refit while they stay).
  LightTree light_tree_;
  // The scene's light buffer as it now stands: the tree refitted or rebuilt (light_count_ set).
  std::vector<LightTriangle> posed_light_buffer(const Scene& scene);
  std::vector<std::uint32_t> light_prims_;
  std::size_t instance_count_ = 0, instance_bytes_ = 0;
  // CPU devices: the buffers are the host arrays themselves (CL_MEM_USE_HOST_PTR), kept here.
  bool host_backed_ = false;
  std::vector<std::shared_ptr<const void>> host_arrays_;
  bool layout_from_cache_ = false;
  double layout_store_ms_ = 0.0;
  BvhLayout layout_ = BvhLayout::Binary;
  bool leaf_refs_ = false;
  ShadingRecords shading_records_ = ShadingRecords::Full;
  std::uint32_t scene_features_ = PX_FEATURES_ALL;
  KernelChoice choice_ = KernelChoice::Scene;
};

}  // namespace px
