#include "pipeline/stages/path_trace_stage.h"

namespace px {

FrameParams PathTraceStage::frame_params(int eye, RowRange rows, unsigned frame) const {
  return PathTracer::frame_params(env_.scene, env_.device_scene.light_count(), options_, eye, rows.begin, rows.size(),
                                  frame);
}

void PathTraceStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    const int e = op->eye;
    env_.log.record(op->stage, op->device,
                    PathTracer::launch(env_.queue(op->device), env_.devices.program("pathtrace/path_trace.cl"),
                                       env_.scene_on(op->device), {f.radiance[e], f.albedo[e], f.nonfinite_paths},
                                       frame_params(e, op->rows, in.frame), in.cams[e], env_.width));
  }
}

}  // namespace px
