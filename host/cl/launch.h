// How every kernel in the project is launched: one-dimensional, with the explicit local size
// PX_LOCAL_SIZE (kernels/shared/types.h) that the kernels using local memory are written for.
// PoCL compiles one work-group function per local size, so a single size also means a single
// compilation per kernel.
#pragma once

#include "cl/cl_error.h"
#include "shared/types.h"

#include <cstddef>
#include <vector>

namespace px {

inline constexpr std::size_t kLocalSize = PX_LOCAL_SIZE;

// Rounds `n` up to a multiple of `local` (global sizes must be multiples of the explicit local
// size in OpenCL 1.2).
inline std::size_t round_up(std::size_t n, std::size_t local = kLocalSize) { return (n + local - 1) / local * local; }

// Enqueues `kernel` over `items` work-items (rounded up to kLocalSize; the kernels return early
// past their item count) after `waits`, and returns its event.
cl::Event launch_1d(const cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t items,
                    const std::vector<cl::Event>* waits = nullptr);

// Whether `queue`'s device is a CPU. On CPUs the path tracing and hole filling stages launch one
// kernel, path_trace_pixels, where GPUs launch path_trace and path_trace_list
// (kernels/pathtrace/path_trace.cl says why).
bool runs_on_cpu(const cl::CommandQueue& queue);

// Sets kernel argument `index` to `*buffer`, or to a null buffer (the kernel sees a null
// pointer: an optional input or output it skips) where `buffer` is null.
inline void set_optional_buffer(cl::Kernel& kernel, cl_uint index, const cl::Buffer* buffer) {
  kernel.setArg(index, buffer ? *buffer : cl::Buffer());
}

}  // namespace px
