// The wavefront path tracer's launches (kernels/pathtrace/wavefront.cl): the megakernel's
// images, a kernel per path step. Which of the two a device runs is PathTraceKernel; both give
// the same images to the last bit, so the choice is speed alone (GPUs: measure with
// bench_pipelines --path-tracer).
#pragma once

#include "cl/cl_error.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"

#include <cstddef>
#include <string>
#include <vector>

namespace px {

enum class PathTraceKernel { Megakernel, Wavefront };
const char* to_string(PathTraceKernel kernel);
PathTraceKernel parse_path_trace_kernel(const std::string& name);  // throws std::invalid_argument

class WavefrontPathTracer {
 public:
  // One device's path buffers (types.h: PX_PATH_STATE_FLOAT4S), grown on demand and reused
  // frame after frame: kBytesPerPath (96 + 48 + 20 + 4 * 4) per path of a launch, e.g. 166 MB
  // for 1280x720 pixels at 1 spp, plus 32 bytes per pixel for sums across launches.
  struct Scratch {
    cl::Buffer states, shadows, hits, path_pixel, queue[2], shadow_queue, counts, sums;
    std::size_t paths = 0, slots = 0;
    void reserve(const cl::Context& context, std::size_t paths, std::size_t slots);
  };
  static constexpr std::size_t kBytesPerPath = 180;
  // The most paths one launch holds (720 MiB of buffers): a pixel's samples beyond it come in
  // further launches (batches of samples), their sums carried over in order, so the images do
  // not depend on it. Every pixel's first batch has at least one sample.
  static constexpr std::size_t kMaxPathsPerLaunch = std::size_t{1} << 22;
  // The paths a launch of `slots` pixels at `spp` samples holds (what Scratch must reserve).
  static std::size_t paths_per_launch(std::size_t slots, unsigned spp, std::size_t max_paths = kMaxPathsPerLaunch);

  // A launch's commands, in order, with the pass each belongs to (for the event log).
  struct Command {
    const char* pass;
    cl::Event event;
  };

  // `params.rows` rows of `width` pixels from `params.row0`: every pixel, params.spp paths each.
  static std::vector<Command> trace_rows(const cl::Context& context, const cl::CommandQueue& queue,
                                         const cl::Program& program, const DeviceSceneBuffers& scene, Scratch& scratch,
                                         const PathTracer::Targets& out, const FrameParams& params,
                                         const CameraParams& camera, unsigned width,
                                         std::size_t max_paths = kMaxPathsPerLaunch);
  // The pixels listed in `holes` (*hole_count of them, on the device; at most `max_pixels`).
  // `gbuffer_hits`, if not null: the G-buffer pass's full-frame hits of the eye, where the
  // first samples (the G-buffer's rays) start instead of tracing their camera rays again.
  static std::vector<Command> trace_list(const cl::Context& context, const cl::CommandQueue& queue,
                                         const cl::Program& program, const DeviceSceneBuffers& scene, Scratch& scratch,
                                         const PathTracer::Targets& out, const cl::Buffer& holes,
                                         const cl::Buffer& hole_count, std::size_t max_pixels,
                                         const FrameParams& params, const CameraParams& camera,
                                         const cl::Buffer* gbuffer_hits = nullptr,
                                         std::size_t max_paths = kMaxPathsPerLaunch);
};

}  // namespace px
