#include "pipeline/stages/hole_fill_stage.h"

#include "cl/launch.h"

namespace px {

HoleFillStage::HoleFillStage(StageEnv& env, PathTraceStage& tracer, const Options& options)
    : StageUnit(env), tracer_(tracer), options_(options), scratch_(env.layout.count()) {}

bool HoleFillStage::spreads(int d, unsigned spp) const {
  switch (options_.spread) {
    case SampleSpread::On: return true;
    case SampleSpread::Off: return false;
    case SampleSpread::Auto: break;
  }
  return env_.is_gpu(d) && spp >= 2 && spp <= kMaxSpreadSpp;
}

void HoleFillStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    const FrameParams fp = tracer_.frame_params(1, op->rows, in.frame);
    const cl::Buffer* gbuffer_hits = op->shares_hits ? &f.right_hits : nullptr;
    if (tracer_.kernel() == PathTraceKernel::Wavefront) {
      const PathTracer::Targets out{f.radiance[1], f.albedo[1], f.nonfinite_paths};
      tracer_.record(Stage::HoleFill, op->device,
                     WavefrontPathTracer::trace_list(
                         env_.devices.context(), env_.queue(op->device),
                         env_.devices.program("pathtrace/wavefront.cl", env_.device_scene.kernel_options()),
                         env_.scene_on(op->device), tracer_.wavefront_scratch(op->device), out, f.holes, f.hole_count,
                         env_.pixels(op->rows), fp, in.cams[1], gbuffer_hits));
      continue;
    }
    const cl::Program& program = env_.devices.program("pathtrace/path_trace.cl", env_.device_scene.kernel_options());
    // Launches are sized for the worst case (every pixel a hole): the hole count lives on the
    // device, so no host round trip is needed between reprojection and hole filling.
    if (!spreads(op->device, fp.spp)) {
      const PathTracer::Targets out{f.radiance[1], f.albedo[1], f.nonfinite_paths};
      env_.log.record(Stage::HoleFill, op->device,
                      PathTracer::launch_list(env_.queue(op->device), program, env_.scene_on(op->device), out, f.holes,
                                              f.hole_count, gbuffer_hits, fp, in.cams[1], env_.pixels(op->rows)));
      continue;
    }
    // A hole's index in the list is below the strip's pixel count, so its samples fit in
    // pixels(rows) x spp pairs; sized for the whole frame, strips can move without a new buffer.
    Scratch& scratch = scratch_[op->device];
    const std::size_t bytes = static_cast<std::size_t>(env_.width) * env_.height * fp.spp * 2 * sizeof(cl_float4);
    if (scratch.bytes < bytes) {
      scratch.samples = cl::Buffer(env_.devices.context(), CL_MEM_READ_WRITE, bytes);
      scratch.bytes = bytes;
    }
    cl::Kernel trace(program, "path_trace_list_samples");
    trace.setArg(0, scratch.samples);
    trace.setArg(1, f.nonfinite_paths);
    trace.setArg(2, f.holes);
    trace.setArg(3, f.hole_count);
    set_optional_buffer(trace, 4, gbuffer_hits);
    trace.setArg(5, fp);
    trace.setArg(6, in.cams[1]);
    env_.scene_on(op->device).bind(trace, 7);
    env_.log.record(Stage::HoleFill, op->device,
                    launch_1d(env_.queue(op->device), trace, env_.pixels(op->rows) * fp.spp), "samples");
    cl::Kernel resolve(program, "resolve_hole_samples");
    resolve.setArg(0, f.radiance[1]);
    resolve.setArg(1, f.albedo[1]);
    resolve.setArg(2, f.nonfinite_paths);
    resolve.setArg(3, scratch.samples);
    resolve.setArg(4, f.holes);
    resolve.setArg(5, f.hole_count);
    resolve.setArg(6, static_cast<cl_uint>(fp.spp));
    resolve.setArg(7, static_cast<cl_uint>(fp.gbuffer_ray_samples == PX_GBUFFER_RAY_FIRST_KIND));
    env_.log.record(Stage::HoleFill, op->device, launch_1d(env_.queue(op->device), resolve, env_.pixels(op->rows)),
                    "resolve");
  }
}

}  // namespace px
