#include "trace/ray_batch_tracer.h"

#include "cl/launch.h"
#include "cl/profiling.h"

#include <algorithm>

namespace px {

RayBatchTracer::RayBatchTracer(DeviceSet& devices, const DeviceScene& scene, std::string extra_options)
    : devices_(devices),
      scene_(scene),
      options_(extra_options.empty() ? scene.kernel_options() : scene.kernel_options() + " " + extra_options) {}

template <typename Out>
std::vector<Out> RayBatchTracer::run(const char* kernel_name, const char* cpu_pair_kernel,
                                     const std::vector<Ray>& rays) {
  std::vector<Out> out(rays.size());
  last_kernel_ms_ = 0.0;
  if (rays.empty()) return out;
  const cl::Program& program = devices_.program("trace/trace_rays.cl", options_);
  const std::size_t n = devices_.size();
  struct Chunk {
    std::size_t first, count;
    cl::Buffer rays, out;
    cl::Event done;
  };
  std::vector<Chunk> chunks(n);
  // Enqueue every device's chunk before waiting on any, so they run concurrently.
  for (std::size_t d = 0; d < n; ++d) {
    Chunk& c = chunks[d];
    c.first = rays.size() * d / n;
    c.count = rays.size() * (d + 1) / n - c.first;
    if (c.count == 0) continue;
    auto& dev = devices_.devices()[d];
    c.rays = cl::Buffer(devices_.context(), CL_MEM_READ_ONLY, c.count * sizeof(Ray));
    c.out = cl::Buffer(devices_.context(), CL_MEM_WRITE_ONLY, c.count * sizeof(Out));
    dev.queue.enqueueWriteBuffer(c.rays, CL_FALSE, 0, c.count * sizeof(Ray), rays.data() + c.first);
    // CPUs take two rays a work-item (their loads in flight together); a GPU hides memory
    // latency with other warps, and two walks a thread would halve its threads.
    const bool pairs = cpu_pair_kernel && !dev.is_gpu();
    cl::Kernel k(program, pairs ? cpu_pair_kernel : kernel_name);
    const auto& buffers = scene_.on(static_cast<int>(d));
    k.setArg(0, c.rays);
    k.setArg(1, c.out);
    k.setArg(2, static_cast<cl_uint>(c.count));
    buffers.bind(k, 3);
    c.done = launch_1d(dev.queue, k, pairs ? (c.count + 1) / 2 : c.count);
    dev.queue.enqueueReadBuffer(c.out, CL_FALSE, 0, c.count * sizeof(Out), out.data() + c.first);
  }
  for (std::size_t d = 0; d < n; ++d) {
    if (chunks[d].count == 0) continue;
    devices_.devices()[d].queue.finish();
    last_kernel_ms_ = std::max(last_kernel_ms_, event_ms(chunks[d].done));
  }
  return out;
}

std::vector<Hit> RayBatchTracer::closest(const std::vector<Ray>& rays) {
  return run<Hit>("trace_closest", "trace_closest_pairs", rays);
}

std::vector<Hit> RayBatchTracer::closest_one_per_item(const std::vector<Ray>& rays) {
  return run<Hit>("trace_closest", nullptr, rays);
}

std::vector<std::uint32_t> RayBatchTracer::occluded(const std::vector<Ray>& rays) {
  return run<std::uint32_t>("trace_any", nullptr, rays);
}

std::vector<glm::vec3> RayBatchTracer::offset_origins(const std::vector<glm::vec3>& points,
                                                      const std::vector<glm::vec3>& normals) {
  const std::size_t count = points.size();
  std::vector<glm::vec3> result(count);
  if (count == 0) return result;
  std::vector<cl_float4> p(count), nrm(count), out(count);
  for (std::size_t i = 0; i < count; ++i) {
    p[i] = {{points[i].x, points[i].y, points[i].z, 0.0f}};
    nrm[i] = {{normals[i].x, normals[i].y, normals[i].z, 0.0f}};
  }
  auto& dev = devices_.devices()[0];
  const auto& ctx = devices_.context();
  cl::Buffer bp(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, count * sizeof(cl_float4), p.data());
  cl::Buffer bn(ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, count * sizeof(cl_float4), nrm.data());
  cl::Buffer bo(ctx, CL_MEM_WRITE_ONLY, count * sizeof(cl_float4));
  cl::Kernel k(devices_.program("trace/trace_rays.cl", options_), "offset_origins");
  k.setArg(0, bp);
  k.setArg(1, bn);
  k.setArg(2, bo);
  k.setArg(3, static_cast<cl_uint>(count));
  launch_1d(dev.queue, k, count);
  dev.queue.enqueueReadBuffer(bo, CL_TRUE, 0, count * sizeof(cl_float4), out.data());
  for (std::size_t i = 0; i < count; ++i) result[i] = {out[i].s[0], out[i].s[1], out[i].s[2]};
  return result;
}

}  // namespace px
