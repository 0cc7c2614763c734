#include "render/wavefront_path_tracer.h"

#include "cl/launch.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace px {

const char* to_string(PathTraceKernel kernel) {
  return kernel == PathTraceKernel::Wavefront ? "wavefront" : "megakernel";
}

PathTraceKernel parse_path_trace_kernel(const std::string& name) {
  if (name == "megakernel") return PathTraceKernel::Megakernel;
  if (name == "wavefront") return PathTraceKernel::Wavefront;
  throw std::invalid_argument("unknown path tracer '" + name + "' (megakernel or wavefront)");
}

void WavefrontPathTracer::Scratch::reserve(const cl::Context& context, std::size_t n, std::size_t k) {
  if (n > paths) {
    states = cl::Buffer(context, CL_MEM_READ_WRITE, n * PX_PATH_STATE_FLOAT4S * sizeof(cl_float4));
    shadows = cl::Buffer(context, CL_MEM_READ_WRITE, n * PX_SHADOW_RAY_FLOAT4S * sizeof(cl_float4));
    hits = cl::Buffer(context, CL_MEM_READ_WRITE, n * sizeof(Hit));
    path_pixel = cl::Buffer(context, CL_MEM_READ_WRITE, n * sizeof(cl_uint));
    for (auto& q : queue) q = cl::Buffer(context, CL_MEM_READ_WRITE, n * sizeof(cl_uint));
    shadow_queue = cl::Buffer(context, CL_MEM_READ_WRITE, n * sizeof(cl_uint));
    paths = n;
  }
  if (k > slots) {
    sums = cl::Buffer(context, CL_MEM_READ_WRITE, k * 2 * sizeof(cl_float4));
    slots = k;
  }
  if (!counts()) counts = cl::Buffer(context, CL_MEM_READ_WRITE, PX_WAVEFRONT_COUNTERS * sizeof(cl_uint));
}

std::size_t WavefrontPathTracer::paths_per_launch(std::size_t slots, unsigned spp, std::size_t max_paths) {
  const std::size_t batch =
      std::max<std::size_t>(1, std::min<std::size_t>(spp, max_paths / std::max<std::size_t>(slots, 1)));
  return slots * batch;
}

namespace {

static_assert(WavefrontPathTracer::kBytesPerPath ==
              (PX_PATH_STATE_FLOAT4S + PX_SHADOW_RAY_FLOAT4S) * sizeof(cl_float4) + sizeof(Hit) + 4 * sizeof(cl_uint));

using Commands = std::vector<WavefrontPathTracer::Command>;

// One batch's vertices, after its generate kernel: extend / shade / connect per vertex. `paths`
// bounds every launch (the queues' counts live on the device, so the host never waits for them).
void trace_vertices(const cl::CommandQueue& queue, const cl::Program& program, const DeviceSceneBuffers& scene,
                    WavefrontPathTracer::Scratch& s, const cl::Buffer* gbuffer, const cl::Buffer* gbuffer_hits,
                    const FrameParams& params, const CameraParams& camera, std::size_t paths, Commands& log) {
  cl::Kernel extend(program, "wf_extend"), shade(program, "wf_shade"), connect(program, "wf_connect");
  extend.setArg(0, s.states);
  extend.setArg(1, s.hits);
  extend.setArg(3, s.counts);
  extend.setArg(5, s.path_pixel);
  set_optional_buffer(extend, 6, gbuffer_hits);
  extend.setArg(7, params);
  scene.bind(extend, 8);
  shade.setArg(0, s.states);
  shade.setArg(1, s.shadows);
  shade.setArg(2, s.hits);
  shade.setArg(3, s.path_pixel);
  shade.setArg(6, s.shadow_queue);
  shade.setArg(7, s.counts);
  set_optional_buffer(shade, 9, gbuffer);
  shade.setArg(10, params);
  shade.setArg(11, camera);
  scene.bind(shade, 12);
  connect.setArg(0, s.states);
  connect.setArg(1, s.shadows);
  connect.setArg(2, s.shadow_queue);
  connect.setArg(3, s.counts);
  scene.bind(connect, 5);
  for (cl_uint b = 0; b <= params.max_bounces; ++b) {
    const cl::Buffer& live = s.queue[b % 2];
    extend.setArg(2, live);
    extend.setArg(4, b);
    log.push_back({"extend", launch_1d(queue, extend, paths)});
    shade.setArg(4, live);
    shade.setArg(5, s.queue[(b + 1) % 2]);
    shade.setArg(8, b);
    log.push_back({"shade", launch_1d(queue, shade, paths)});
    connect.setArg(4, b);
    // The last vertex makes no shadow ray (px_path_vertex ends the path before sampling a light).
    if (b < params.max_bounces) log.push_back({"connect", launch_1d(queue, connect, paths)});
  }
}

// Every batch of samples: reset the counters, generate (`generate` binds its kernel's own
// arguments for a batch's FrameParams), the vertices, and resolve into `out` or the sums.
template <typename Generate>
Commands trace_batches(const cl::Context& context, const cl::CommandQueue& queue, const cl::Program& program,
                       const DeviceSceneBuffers& scene, WavefrontPathTracer::Scratch& s, const PathTracer::Targets& out,
                       const cl::Buffer* gbuffer_hits, const FrameParams& params, const CameraParams& camera,
                       std::size_t slots, std::size_t max_paths, const Generate& generate) {
  if (params.spp == 0) throw std::invalid_argument("wavefront path tracer: spp must be at least 1");
  if (params.max_bounces > PX_MAX_BOUNCES_LIMIT) throw std::invalid_argument("wavefront path tracer: too many bounces");
  const std::size_t paths = WavefrontPathTracer::paths_per_launch(slots, params.spp, max_paths);
  const unsigned batch_spp = static_cast<unsigned>(paths / std::max<std::size_t>(slots, 1));
  s.reserve(context, paths, slots);
  Commands log;
  cl::Kernel resolve(program, "wf_resolve");
  resolve.setArg(0, out.radiance);
  resolve.setArg(1, out.albedo);
  resolve.setArg(2, out.nonfinite);
  resolve.setArg(3, s.states);
  resolve.setArg(4, s.path_pixel);
  resolve.setArg(5, s.counts);
  resolve.setArg(6, s.sums);
  resolve.setArg(10, static_cast<cl_uint>(params.gbuffer_ray_samples == PX_GBUFFER_RAY_FIRST_KIND));
  for (unsigned first = 0; first < params.spp; first += batch_spp) {
    FrameParams batch = params;
    batch.spp = std::min(batch_spp, params.spp - first);
    batch.sample_offset = params.sample_offset + first;
    cl::Event zeroed;
    queue.enqueueFillBuffer(s.counts, cl_uint{0}, 0, PX_WAVEFRONT_COUNTERS * sizeof(cl_uint), nullptr, &zeroed);
    log.push_back({"reset", zeroed});
    log.push_back({"generate", generate(batch, slots * batch.spp)});
    trace_vertices(queue, program, scene, s, out.gbuffer, gbuffer_hits, batch, camera, slots * batch.spp, log);
    resolve.setArg(7, static_cast<cl_uint>(batch.spp));
    resolve.setArg(8, static_cast<cl_uint>(first == 0));
    resolve.setArg(9, static_cast<cl_uint>(first + batch.spp == params.spp));
    log.push_back({"resolve", launch_1d(queue, resolve, slots)});
  }
  return log;
}

// The generate kernels' first four arguments, once Scratch holds its buffers for the launch.
void bind_generate(cl::Kernel& generate, const WavefrontPathTracer::Scratch& s) {
  generate.setArg(0, s.states);
  generate.setArg(1, s.path_pixel);
  generate.setArg(2, s.queue[0]);
  generate.setArg(3, s.counts);
}

}  // namespace

std::vector<WavefrontPathTracer::Command> WavefrontPathTracer::trace_rows(
    const cl::Context& context, const cl::CommandQueue& queue, const cl::Program& program,
    const DeviceSceneBuffers& scene, Scratch& scratch, const PathTracer::Targets& out, const FrameParams& params,
    const CameraParams& camera, unsigned width, std::size_t max_paths) {
  PathTracer::check_gbuffer_target(out, params);
  cl::Kernel generate(program, "wf_generate_rows");
  generate.setArg(5, camera);
  const std::size_t slots = static_cast<std::size_t>(params.rows) * width;
  return trace_batches(context, queue, program, scene, scratch, out, nullptr, params, camera, slots, max_paths,
                       [&](const FrameParams& batch, std::size_t paths) {
                         bind_generate(generate, scratch);
                         generate.setArg(4, batch);
                         return launch_1d(queue, generate, paths);
                       });
}

std::vector<WavefrontPathTracer::Command> WavefrontPathTracer::trace_list(
    const cl::Context& context, const cl::CommandQueue& queue, const cl::Program& program,
    const DeviceSceneBuffers& scene, Scratch& scratch, const PathTracer::Targets& out, const cl::Buffer& holes,
    const cl::Buffer& hole_count, std::size_t max_pixels, const FrameParams& params, const CameraParams& camera,
    const cl::Buffer* gbuffer_hits, std::size_t max_paths) {
  cl::Kernel generate(program, "wf_generate_list");
  generate.setArg(4, holes);
  generate.setArg(5, hole_count);
  generate.setArg(7, camera);
  return trace_batches(context, queue, program, scene, scratch, out, gbuffer_hits, params, camera, max_pixels,
                       max_paths, [&](const FrameParams& batch, std::size_t paths) {
                         bind_generate(generate, scratch);
                         generate.setArg(6, batch);
                         return launch_1d(queue, generate, paths);
                       });
}

}  // namespace px
