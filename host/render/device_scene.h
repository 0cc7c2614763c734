// Scene data replicated on every device (sort-first rendering partitions the image, never the
// scene): BVH nodes, leaf-order triangles, per-triangle shading, materials, textures and the
// emissive-triangle table. One set of buffers per ComputeDevice, each written through that
// device's own queue. Kernels take these as their last parameters (PX_SCENE_PARAMS in
// kernels/scene/scene_view.h); bind() sets them in that order.
#pragma once

#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "scene/scene.h"

#include <string>
#include <vector>

namespace px {

struct DeviceSceneBuffers {
  cl::Buffer nodes;      // BvhNode[], Bvh4Node[], Bvh8Node[] or CompressedBvh8Node[] (DeviceSet::bvh_layout())
  cl::Buffer triangles;  // BvhTriangle[] (leaf order, flags filled from materials)
  cl::Buffer shading;    // TriangleShading[] (scene order)
  cl::Buffer materials;  // GpuMaterial[]
  cl::Buffer textures;   // TextureInfo[]
  cl::Buffer texels;     // float4[] (all textures back to back)
  cl::Buffer lights;     // LightTriangle[]

  // Sets the seven scene arguments starting at argument index `first`; returns the next index.
  cl_uint bind(cl::Kernel& kernel, cl_uint first) const;
};

// Host-side conversions to the kernel layouts (also used by tests).
std::vector<TriangleShading> make_triangle_shading(const Scene& scene);
std::vector<GpuMaterial> make_gpu_materials(const Scene& scene);
std::vector<LightTriangle> make_light_table(const Scene& scene);
// PX_TRI_* flags of every scene triangle, from its material (alpha-tested, emissive).
std::vector<std::uint32_t> triangle_flags(const Scene& scene);

// How next-event estimation picks a light type, and the sun/sky constants, as FrameParams
// fields (the per-launch fields are left for the caller).
void fill_light_params(const Scene& scene, std::size_t light_count, FrameParams& params);

class DeviceScene {
 public:
  // Uploads `bvh` and the scene's shading data to every device in `devices` (blocking).
  DeviceScene(DeviceSet& devices, const Scene& scene, const FlatBvh& bvh);

  const DeviceSceneBuffers& on(int device_index) const { return per_device_.at(device_index); }
  std::size_t bytes_per_device() const { return bytes_per_device_; }
  std::size_t light_count() const { return light_count_; }
  // The node layout uploaded (the set's bvh_layout() at construction), and the kernel build
  // option that matches it (DeviceSet::program uses the set's current layout when none is given).
  BvhLayout layout() const { return layout_; }
  std::string kernel_options() const { return "-DPX_BVH_WIDTH=" + std::to_string(bvh_layout_width(layout_)); }

 private:
  std::vector<DeviceSceneBuffers> per_device_;
  std::size_t bytes_per_device_ = 0;
  std::size_t light_count_ = 0;
  BvhLayout layout_ = BvhLayout::Binary;
};

}  // namespace px
