// Traces host-made ray lists on the devices: the ray list is cut into one contiguous chunk per
// device, every chunk runs concurrently on its device's queue, and the hits come back in input
// order. The test suite checks the kernels through this against independent host code, and
// bench-trace times it against Embree on the same rays.
#pragma once

#include "cl/device_set.h"
#include "render/device_scene.h"
#include "shared/types.h"

#include <glm/glm.hpp>
#include <string>
#include <vector>

namespace px {

class RayBatchTracer {
 public:
  // `extra_options`: more kernel build options after the scene's (bench_trace --counters passes
  // -DPX_TRACE_COUNTERS=1).
  RayBatchTracer(DeviceSet& devices, const DeviceScene& scene, std::string extra_options = {});

  // Closest hits: on CPU devices two rays a work-item, their walks in step (trace_closest_pairs),
  // on GPUs one (trace_closest); closest_one_per_item takes one ray a work-item everywhere. The
  // hits are the same to the bit either way.
  std::vector<Hit> closest(const std::vector<Ray>& rays);
  std::vector<Hit> closest_one_per_item(const std::vector<Ray>& rays);
  std::vector<std::uint32_t> occluded(const std::vector<Ray>& rays);

  // The kernels' self-intersection-free origin offset applied to points along normals.
  std::vector<glm::vec3> offset_origins(const std::vector<glm::vec3>& points, const std::vector<glm::vec3>& normals);

  // Device time of the last closest()/occluded() call: the slowest device's kernel time from
  // OpenCL profiling events (the makespan of the concurrent chunks), in milliseconds.
  double last_kernel_ms() const { return last_kernel_ms_; }

 private:
  template <typename Out>
  // `kernel_name` over the rays, one a work-item; on CPU devices `cpu_pair_kernel` instead (if not
  // null: the same kernel two rays a work-item) over half as many work-items.
  std::vector<Out> run(const char* kernel_name, const char* cpu_pair_kernel, const std::vector<Ray>& rays);

  DeviceSet& devices_;
  const DeviceScene& scene_;
  std::string options_;
  double last_kernel_ms_ = 0.0;
};

}  // namespace px
