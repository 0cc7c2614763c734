#include "pipeline/frame_images.h"

#include <algorithm>

namespace px {

namespace {

cl::Buffer device_buffer(const cl::Context& ctx, std::size_t bytes) {
  return cl::Buffer(ctx, CL_MEM_READ_WRITE, std::max<std::size_t>(bytes, 16));
}

}  // namespace

FrameImages FrameImages::allocate(const cl::Context& ctx, unsigned width, unsigned height) {
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  FrameImages f;
  for (int e = 0; e < 2; ++e) {
    f.radiance[e] = device_buffer(ctx, pixels * sizeof(cl_float4));
    f.albedo[e] = device_buffer(ctx, pixels * sizeof(cl_float4));
    f.gbuffer[e] = device_buffer(ctx, pixels * sizeof(GBufferTexel));
    f.rgba[e] = device_buffer(ctx, pixels * sizeof(cl_uchar4));
  }
  f.right_hits = device_buffer(ctx, pixels * sizeof(Hit));
  f.holes = device_buffer(ctx, pixels * sizeof(cl_uint));
  f.hole_count = device_buffer(ctx, sizeof(cl_uint));
  f.nonfinite_paths = device_buffer(ctx, sizeof(cl_uint));
  f.nonfinite_pixels = device_buffer(ctx, sizeof(cl_uint));
  return f;
}

void FrameImages::zero_counters(const cl::CommandQueue& queue) const {
  const cl_uint zero = 0;
  queue.enqueueFillBuffer(nonfinite_paths, zero, 0, sizeof(cl_uint));
  queue.enqueueFillBuffer(nonfinite_pixels, zero, 0, sizeof(cl_uint));
  queue.enqueueFillBuffer(hole_count, zero, 0, sizeof(cl_uint));
}

}  // namespace px
