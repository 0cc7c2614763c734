#include "pipeline/stages/hole_fill_stage.h"

#include "cl/launch.h"

namespace px {

void HoleFillStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    cl::Kernel k(env_.devices.program("pathtrace/path_trace.cl"), "path_trace_list");
    k.setArg(0, f.radiance[1]);
    k.setArg(1, f.albedo[1]);
    k.setArg(2, f.nonfinite_paths);
    k.setArg(3, f.holes);
    k.setArg(4, f.hole_count);
    k.setArg(5, tracer_.frame_params(1, op->rows, in.frame));
    k.setArg(6, in.cams[1]);
    env_.scene_on(op->device).bind(k, 7);
    // Sized for the worst case (every pixel a hole): the hole count lives on the device, so no
    // host round trip is needed between reprojection and hole filling.
    env_.log.record(Stage::HoleFill, op->device, launch_1d(env_.queue(op->device), k, env_.pixels(op->rows)));
  }
}

}  // namespace px
