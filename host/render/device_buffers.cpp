// The scene's buffers: allocation limits and uploads (device_buffers.h).
#include "render/device_buffers.h"

#include "io/environment.h"

#include <cstdio>
#include <stdexcept>

namespace px::scene_buffers {

AllocationLimits allocation_limits(const DeviceSet& devices) {
  AllocationLimits l;
  l.max_alloc = l.global_mem = static_cast<std::size_t>(-1);
  for (const auto& d : devices.devices()) {
    const auto max_alloc = static_cast<std::size_t>(d.device.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>());
    if (max_alloc < l.max_alloc) {
      l.max_alloc = max_alloc;
      l.device = d.device.getInfo<CL_DEVICE_NAME>();
    }
    l.global_mem = std::min(l.global_mem, static_cast<std::size_t>(d.device.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>()));
  }
  if (const std::size_t v = environment().max_alloc_bytes; v > 0 && v < l.max_alloc) {
    l.max_alloc = v;
    l.device += " (lowered by PARALLAX_MAX_ALLOC_BYTES)";
  }
  return l;
}

std::string mib(std::size_t bytes) {
  char s[64];
  std::snprintf(s, sizeof s, "%.1f MiB (%zu bytes)", static_cast<double>(bytes) / (1024.0 * 1024.0), bytes);
  return s;
}

void require_allocation(const char* name, std::size_t bytes, const AllocationLimits& limits) {
  if (bytes > limits.max_alloc)
    throw std::runtime_error(std::string("the scene's ") + name + " buffer needs " + mib(bytes) +
                             ", more than one allocation may hold on " + limits.device + ": " + mib(limits.max_alloc) +
                             " (CL_DEVICE_MAX_MEM_ALLOC_SIZE); the scene is too large for this device");
}

cl::Buffer upload(const char* name, const cl::Context& ctx, cl::CommandQueue& queue, const SceneBytes& data,
                  const AllocationLimits& limits, std::size_t& total, std::vector<std::shared_ptr<const void>>* keep) {
  // A zero-sized buffer is invalid in OpenCL; keep one element so kernels always get a buffer.
  const std::size_t bytes = std::max(data.element, data.bytes);
  require_allocation(name, bytes, limits);
  total += bytes;
  if (keep && data.bytes > 0) {
    cl::Buffer buffer(ctx, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, bytes, const_cast<void*>(data.data));
    keep->push_back(data.owner);
    return buffer;
  }
  cl::Buffer buffer(ctx, CL_MEM_READ_ONLY, bytes);
  if (data.bytes > 0) queue.enqueueWriteBuffer(buffer, CL_TRUE, 0, data.bytes, data.data);
  return buffer;
}

}  // namespace px::scene_buffers
