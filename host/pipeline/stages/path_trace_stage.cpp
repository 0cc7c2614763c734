#include "pipeline/stages/path_trace_stage.h"

namespace px {

PathTraceStage::PathTraceStage(StageEnv& env, const Options& options, PathTraceKernel kernel)
    : StageUnit(env), options_(options), kernel_(kernel), scratch_(env.layout.count()) {}

FrameParams PathTraceStage::frame_params(int eye, RowRange rows, unsigned frame) const {
  return PathTracer::frame_params(env_.scene, env_.device_scene.light_count(), options_, eye, rows.begin, rows.size(),
                                  frame);
}

void PathTraceStage::record(Stage stage, int d, const std::vector<WavefrontPathTracer::Command>& commands) {
  for (const auto& c : commands) env_.log.record(stage, d, c.event, c.pass);
}

void PathTraceStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    const int e = op->eye;
    const PathTracer::Targets out{f.radiance[e], f.albedo[e], f.nonfinite_paths,
                                  op->writes_gbuffer ? &f.gbuffer[e] : nullptr};
    if (kernel_ == PathTraceKernel::Wavefront) {
      // Sized for the whole frame, so that moving strips never reallocate.
      const std::size_t frame_pixels = static_cast<std::size_t>(env_.width) * env_.height;
      scratch_[op->device].reserve(env_.devices.context(),
                                   WavefrontPathTracer::paths_per_launch(frame_pixels, options_.spp), frame_pixels);
      record(op->stage, op->device,
             WavefrontPathTracer::trace_rows(
                 env_.devices.context(), env_.queue(op->device),
                 env_.devices.program("pathtrace/wavefront.cl", env_.device_scene.kernel_options()),
                 env_.scene_on(op->device), scratch_[op->device], out, frame_params(e, op->rows, in.frame), in.cams[e],
                 env_.width));
      continue;
    }
    env_.log.record(
        op->stage, op->device,
        PathTracer::launch(
            env_.queue(op->device), env_.devices.program("pathtrace/path_trace.cl", env_.device_scene.kernel_options()),
            env_.scene_on(op->device), out, frame_params(e, op->rows, in.frame), in.cams[e], env_.width));
  }
}

}  // namespace px
