// The scene's buffers on the devices (DeviceScene): their host bytes, the allocation limits they
// are checked against, and how they are written and rewritten (device_buffers.cpp).
#pragma once

#include "cl/device_set.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace px {

// A scene buffer's bytes on the host: an array the constructor made, or a mapped file's section
// (device_layout_cache.h). `owner` keeps them alive.
struct SceneBytes {
  const void* data = nullptr;
  std::size_t bytes = 0;    // 0: none (the buffer gets one placeholder element)
  std::size_t element = 1;  // the size of one element
  std::shared_ptr<const void> owner;
};

namespace scene_buffers {

// What one OpenCL context can hold: the largest single allocation and the global memory of
// its smallest device. PARALLAX_MAX_ALLOC_BYTES lowers the first (to test the refusal below without a
// 4 GiB scene).
struct AllocationLimits {
  std::size_t max_alloc = 0, global_mem = 0;
  std::string device;  // the device that sets max_alloc
};

AllocationLimits allocation_limits(const DeviceSet& devices);
// `bytes` in MiB, and exactly.
std::string mib(std::size_t bytes);

// Refuses (before anything is allocated on the device) a scene buffer that exceeds what one
// allocation may hold: a clear error naming the buffer, never a failed allocation deep in the
// driver or a wrong image.
void require_allocation(const char* name, std::size_t bytes, const AllocationLimits& limits);

template <typename T, typename A>
SceneBytes owned_bytes(std::vector<T, A>&& v) {
  auto owner = std::make_shared<const std::vector<T, A>>(std::move(v));
  return {owner->data(), owner->size() * sizeof(T), sizeof(T), owner};
}

// One buffer of the scene (require_allocation first): written through `queue`, or, with `keep`
// (devices that read the host's memory: CPU devices), over the host bytes themselves
// (CL_MEM_USE_HOST_PTR), whose owner then goes into *keep to live as long as the buffer. The
// scene is then in memory once, not twice, and nothing is copied. Read-only buffers: no kernel
// writes them, so a read-only mapping serves as well as an array.
cl::Buffer upload(const char* name, const cl::Context& ctx, cl::CommandQueue& queue, const SceneBytes& data,
                  const AllocationLimits& limits, std::size_t& total, std::vector<std::shared_ptr<const void>>* keep);

// Bytes compared as one piece when a buffer is rewritten: a piece that changed is written whole.
constexpr std::size_t kRewritePiece = 16 * 1024;

// Rewrites `buffer` with `data`, writing only the pieces that differ from `shadow` (what the
// buffer holds, as last written; updated), or replaces it by one a quarter larger than needed
// when the data does not fit its `capacity` (bytes; updated). An animated scene whose moving
// part is small sends little: a static room's triangles, shading and nodes pose to the same
// bytes every frame. Adds the bytes written to `written`.
template <typename T>
void rewrite(const char* name, cl::Buffer& buffer, std::size_t& capacity, std::vector<std::uint8_t>& shadow,
             const cl::Context& ctx, cl::CommandQueue& queue, const std::vector<T>& data,
             const AllocationLimits& limits, std::size_t& written) {
  const std::size_t bytes = std::max<std::size_t>(1, data.size()) * sizeof(T);
  if (bytes > capacity || !buffer()) {
    require_allocation(name, bytes, limits);
    capacity = std::min(limits.max_alloc, bytes + bytes / 4);
    buffer = cl::Buffer(ctx, CL_MEM_READ_ONLY, capacity);
    shadow.clear();  // the new buffer holds nothing yet
  }
  const auto* p = reinterpret_cast<const std::uint8_t*>(data.data());
  const std::size_t n = data.size() * sizeof(T);
  // Runs of changed pieces, each written with one call.
  std::size_t run = n;  // start of the current run, n = none
  for (std::size_t off = 0; off <= n; off += kRewritePiece) {
    const std::size_t len = std::min(kRewritePiece, n - std::min(n, off));
    const bool changed = len > 0 && (off + len > shadow.size() || std::memcmp(p + off, shadow.data() + off, len) != 0);
    if (changed && run == n) run = off;
    if (!changed && run != n) {
      queue.enqueueWriteBuffer(buffer, CL_TRUE, run, off - run, p + run);
      written += off - run;
      run = n;
    }
    if (len == 0) break;
  }
  if (run != n) {
    queue.enqueueWriteBuffer(buffer, CL_TRUE, run, n - run, p + run);
    written += n - run;
  }
  shadow.assign(p, p + n);
}

}  // namespace scene_buffers
}  // namespace px
