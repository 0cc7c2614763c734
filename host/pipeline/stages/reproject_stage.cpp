#include "pipeline/stages/reproject_stage.h"

#include "cl/launch.h"

namespace px {

void ReprojectStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    // The hole count starts at zero (FrameImages::zero_counters, earlier on this queue); one
    // reprojection per device and frame appends to it.
    cl::Kernel k(env_.devices.program("pipeline/reproject.cl"), "reproject");
    k.setArg(0, f.radiance[1]);
    k.setArg(1, f.albedo[1]);
    k.setArg(2, f.holes);
    k.setArg(3, f.hole_count);
    k.setArg(4, f.radiance[0]);
    k.setArg(5, f.albedo[0]);
    k.setArg(6, f.gbuffer[0]);
    k.setArg(7, f.gbuffer[1]);
    k.setArg(8, static_cast<cl_uint>(op->rows.begin));
    k.setArg(9, static_cast<cl_uint>(op->rows.size()));
    k.setArg(10, in.cams[0]);
    env_.log.record(Stage::Reproject, op->device, launch_1d(env_.queue(op->device), k, env_.pixels(op->rows)));
  }
}

}  // namespace px
