#include "render/path_tracer.h"

#include "cl/launch.h"
#include "cl/profiling.h"

#include <stdexcept>

namespace px {
namespace {

// path_trace_pixels' arguments from the pixel list on (kernels/pathtrace/path_trace.cl), the one
// kernel CPUs launch for stages 2, 3 and 5 and the temporal gradients' shading: the list and its
// count (null: the strip's pixels), the G-buffer pass's hits a list starts from, the hits the
// G-buffer mode writes, the mode, and the gradient mode's inputs (null and zero in the others).
// Leaves `arg` at FrameParams.
void bind_pixel_selection(cl::Kernel& k, cl_uint& arg, const cl::Buffer* holes, const cl::Buffer* hole_count,
                          const cl::Buffer* hits_in, const cl::Buffer* hits_out, cl_uint mode,
                          const PathTracer::GradientInputs* gradient = nullptr) {
  set_optional_buffer(k, arg++, holes);
  set_optional_buffer(k, arg++, hole_count);
  set_optional_buffer(k, arg++, hits_in);
  set_optional_buffer(k, arg++, hits_out);
  k.setArg(arg++, mode);
  set_optional_buffer(k, arg++, gradient ? &gradient->prev_ref : nullptr);
  set_optional_buffer(k, arg++, gradient ? &gradient->prev_gbuffer : nullptr);
  set_optional_buffer(k, arg++, gradient ? gradient->tri_motion : nullptr);
  k.setArg(arg++, gradient ? gradient->params : GradientParams{});
}

}  // namespace

FrameParams PathTracer::frame_params(const Scene& scene, std::size_t light_count, const Options& options, int eye,
                                     unsigned row0, unsigned rows, std::uint32_t frame, std::uint32_t sample_offset) {
  FrameParams fp{};
  fill_light_params(scene, light_count, fp);
  fp.frame = frame;
  fp.eye = static_cast<cl_uint>(eye);
  fp.spp = options.spp;
  fp.max_bounces = options.bounces;
  fp.seed = options.seed;
  fp.light_sampling = static_cast<cl_uint>(options.light_sampling);
  fp.direct_light = static_cast<cl_uint>(options.direct_light);
  fp.rr_start_bounce = options.rr_start_bounce;
  fp.row0 = row0;
  fp.rows = rows;
  fp.sample_offset = sample_offset;
  fp.gbuffer_ray_samples = !options.first_sample_on_gbuffer_ray  ? PX_GBUFFER_RAY_NONE
                           : options.every_sample_on_gbuffer_ray ? PX_GBUFFER_RAY_EVERY
                           : options.same_kind_samples           ? PX_GBUFFER_RAY_FIRST_KIND
                                                                 : PX_GBUFFER_RAY_FIRST;
  return fp;
}

void PathTracer::check_gbuffer_target(const Targets& out, const FrameParams& params) {
  // Without sample 0 on the G-buffer's ray nothing would write the texels: a stale G-buffer, silently.
  if (out.gbuffer && !(params.gbuffer_ray_samples != PX_GBUFFER_RAY_NONE && params.sample_offset == 0))
    throw std::logic_error("path tracer: a G-buffer target needs the frame's first sample on the G-buffer's ray");
}

cl::Event PathTracer::launch(const cl::CommandQueue& queue, const cl::Program& program, const DeviceSceneBuffers& scene,
                             const Targets& out, const FrameParams& params, const CameraParams& camera,
                             unsigned width) {
  check_gbuffer_target(out, params);
  // CPUs: path_trace_pixels, path_trace with a pixel list, null here (the strip's pixels).
  const bool cpu = runs_on_cpu(queue);
  cl::Kernel k(program, cpu ? "path_trace_pixels" : "path_trace");
  k.setArg(0, out.radiance);
  k.setArg(1, out.albedo);
  k.setArg(2, out.nonfinite);
  set_optional_buffer(k, 3, out.gbuffer);
  cl_uint arg = 4;
  if (cpu) bind_pixel_selection(k, arg, nullptr, nullptr, nullptr, nullptr, PX_PIXELS_PATHS);
  k.setArg(arg++, params);
  k.setArg(arg++, camera);
  scene.bind(k, arg);
  return launch_1d(queue, k, static_cast<std::size_t>(params.rows) * width);
}

cl::Event PathTracer::launch_list(const cl::CommandQueue& queue, const cl::Program& program,
                                  const DeviceSceneBuffers& scene, const Targets& out, const cl::Buffer& holes,
                                  const cl::Buffer& hole_count, const cl::Buffer* gbuffer_hits,
                                  const FrameParams& params, const CameraParams& camera, std::size_t max_items) {
  if (out.gbuffer) throw std::logic_error("path tracer: a hole list writes no G-buffer texels");
  const bool cpu = runs_on_cpu(queue);
  cl::Kernel k(program, cpu ? "path_trace_pixels" : "path_trace_list");
  k.setArg(0, out.radiance);
  k.setArg(1, out.albedo);
  k.setArg(2, out.nonfinite);
  cl_uint arg = 3;
  if (cpu) {
    k.setArg(arg++, cl::Buffer());  // no G-buffer texels
    bind_pixel_selection(k, arg, &holes, &hole_count, gbuffer_hits, nullptr, PX_PIXELS_PATHS);
  } else {
    k.setArg(arg++, holes);
    k.setArg(arg++, hole_count);
    set_optional_buffer(k, arg++, gbuffer_hits);
  }
  k.setArg(arg++, params);
  k.setArg(arg++, camera);
  scene.bind(k, arg);
  return launch_1d(queue, k, max_items);
}

FrameParams PathTracer::gbuffer_params(int eye, unsigned row0, unsigned rows, std::uint32_t frame) {
  FrameParams fp{};
  fp.frame = frame;
  fp.eye = static_cast<cl_uint>(eye);
  fp.spp = 1;
  fp.row0 = row0;
  fp.rows = rows;
  fp.sample_offset = 0;
  fp.gbuffer_ray_samples = PX_GBUFFER_RAY_FIRST;
  return fp;
}

cl::Event PathTracer::launch_gbuffer(const cl::CommandQueue& queue, const cl::Program& program,
                                     const DeviceSceneBuffers& scene, const cl::Buffer& gbuffer,
                                     const cl::Buffer* first_hits, const FrameParams& params,
                                     const CameraParams& camera, unsigned width) {
  if (!runs_on_cpu(queue))
    throw std::logic_error("path tracer: the G-buffer pass runs in path_trace_pixels on CPUs only");
  if (params.spp != 1 || params.sample_offset != 0 || params.gbuffer_ray_samples == PX_GBUFFER_RAY_NONE)
    throw std::logic_error("path tracer: the G-buffer pass needs gbuffer_params (one sample, on the G-buffer's ray)");
  cl::Kernel k(program, "path_trace_pixels");
  // Radiance, albedo and the non-finite counter: untouched in this mode (a path of no vertex has
  // radiance 0, always finite), so none.
  for (cl_uint unused = 0; unused < 3; ++unused) k.setArg(unused, cl::Buffer());
  k.setArg(3, gbuffer);
  cl_uint arg = 4;
  bind_pixel_selection(k, arg, nullptr, nullptr, nullptr, first_hits, PX_PIXELS_GBUFFER);
  k.setArg(arg++, params);
  k.setArg(arg++, camera);
  scene.bind(k, arg);
  return launch_1d(queue, k, static_cast<std::size_t>(params.rows) * width);
}

cl::Event PathTracer::launch_gradient(const cl::CommandQueue& queue, const cl::Program& program,
                                      const DeviceSceneBuffers& scene, const GradientInputs& in,
                                      const FrameParams& frame, const CameraParams& camera) {
  if (!runs_on_cpu(queue))
    throw std::logic_error("path tracer: the temporal gradients' shading runs in path_trace_pixels on CPUs only");
  cl::Kernel k(program, "path_trace_pixels");
  k.setArg(0, in.raw);
  k.setArg(1, in.ref);
  k.setArg(2, in.nonfinite);
  k.setArg(3, in.gbuffer);
  cl_uint arg = 4;
  bind_pixel_selection(k, arg, nullptr, nullptr, nullptr, nullptr, PX_PIXELS_GRADIENT, &in);
  k.setArg(arg++, frame);
  k.setArg(arg++, camera);
  scene.bind(k, arg);
  // The launch's local size is the other modes' (launch_1d's): PoCL makes one work-group function
  // for the kernel, not one per mode.
  return launch_1d(queue, k, static_cast<std::size_t>(in.params.s_rows) * in.params.strata_w);
}

std::array<ImageRGB, 2> PathTracer::render_stereo(float time_s, std::uint32_t frame, unsigned width, unsigned height,
                                                  const Options& options, std::uint32_t sample_offset) {
  if (options.spp == 0) throw std::invalid_argument("spp must be at least 1");
  if (options.bounces > kMaxBounces)
    throw std::invalid_argument("bounces must be at most " + std::to_string(kMaxBounces));
  if (width > 65535 || height > 65535) throw std::invalid_argument("image too large (65535 max per side)");
  const Camera centre = evaluate_camera(scene_, time_s);
  const int n = devices_.size();
  const cl::Program& program = devices_.program("pathtrace/path_trace.cl", device_scene_.kernel_options());

  struct Launch {
    cl::Buffer out, albedo, counter;
    cl::Event done;
    std::vector<cl_float4> pixels;
    cl_uint nonfinite = 0;
    unsigned row0 = 0, rows = 0;
    int eye = 0, device = 0;
  };
  std::vector<Launch> launches;
  launches.reserve(2 * n);
  for (int e = 0; e < 2; ++e) {
    const CameraParams cam = make_eye_camera(centre, static_cast<Eye>(e), scene_.ipd_units(), width, height);
    const std::vector<RowRange> strips = split_rows(height, static_cast<unsigned>(n));
    for (int d = 0; d < n; ++d) {
      Launch l;
      l.row0 = strips[d].begin;
      l.rows = strips[d].size();
      l.eye = e;
      l.device = d;
      if (l.rows == 0) continue;
      auto& dev = devices_.devices()[d];
      const std::size_t pixels = static_cast<std::size_t>(l.rows) * width;
      // The kernel writes a full-frame image at absolute pixel indices; only this strip's rows
      // (the tail of the allocation) are touched and read back.
      l.out = cl::Buffer(devices_.context(), CL_MEM_WRITE_ONLY,
                         static_cast<std::size_t>(l.row0 + l.rows) * width * sizeof(cl_float4));
      // The per-pixel albedo output only feeds the denoiser, which this path does not run.
      l.albedo = cl::Buffer(devices_.context(), CL_MEM_WRITE_ONLY,
                            static_cast<std::size_t>(l.row0 + l.rows) * width * sizeof(cl_float4));
      const cl_uint zero = 0;
      l.counter = cl::Buffer(devices_.context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof(cl_uint),
                             const_cast<cl_uint*>(&zero));
      // No ReSTIR stage follows this launch: its first vertices keep next-event estimation (by the tree).
      PathTracer::Options plain = options;
      if (plain.direct_light == DirectLight::Restir) plain.direct_light = DirectLight::Tree;
      const FrameParams fp =
          frame_params(scene_, device_scene_.light_count(), plain, e, l.row0, l.rows, frame, sample_offset);
      l.done = launch(dev.queue, program, device_scene_.on(d), {l.out, l.albedo, l.counter}, fp, cam, width);
      l.pixels.resize(pixels);
      launches.push_back(std::move(l));
    }
  }
  // Read back after every launch is queued so devices run concurrently.
  for (auto& l : launches) {
    auto& q = devices_.devices()[l.device].queue;
    q.enqueueReadBuffer(l.out, CL_FALSE, static_cast<std::size_t>(l.row0) * width * sizeof(cl_float4),
                        l.pixels.size() * sizeof(cl_float4), l.pixels.data());
    q.enqueueReadBuffer(l.counter, CL_FALSE, 0, sizeof(cl_uint), &l.nonfinite);
  }
  devices_.finish_all();

  std::array<ImageRGB, 2> images;
  for (auto& img : images) {
    img.width = static_cast<int>(width);
    img.height = static_cast<int>(height);
    img.rgb.assign(static_cast<std::size_t>(width) * height * 3, 0.0f);
  }
  last_device_ms_.assign(n, 0.0);
  for (auto& l : launches) {
    auto& img = images[l.eye];
    for (std::size_t i = 0; i < l.pixels.size(); ++i)
      for (int c = 0; c < 3; ++c) img.rgb[(static_cast<std::size_t>(l.row0) * width + i) * 3 + c] = l.pixels[i].s[c];
    nonfinite_total_ += l.nonfinite;
    last_device_ms_[l.device] += event_ms(l.done);
  }
  return images;
}

}  // namespace px
