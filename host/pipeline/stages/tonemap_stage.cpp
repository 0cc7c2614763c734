#include "pipeline/stages/tonemap_stage.h"

#include "cl/launch.h"
#include "image/srgb_thresholds.h"

namespace px {

TonemapStage::TonemapStage(StageEnv& env, const Options& options) : StageUnit(env), options_(options) {
  auto table = srgb8_thresholds();
  thresholds_ =
      cl::Buffer(env_.devices.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof(table), table.data());
}

void TonemapStage::run(const std::vector<const Operation*>& ops, const FrameInputs&) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    const cl_uint first = op->rows.begin * env_.width, count = op->rows.size() * env_.width;
    cl::Kernel k(env_.devices.program("pipeline/tonemap.cl"), "tonemap");
    k.setArg(0, f.rgba[op->eye]);
    k.setArg(1, f.radiance[op->eye]);
    k.setArg(2, first);
    k.setArg(3, count);
    k.setArg(4, options_.exposure);
    k.setArg(5, f.nonfinite_pixels);
    k.setArg(6, thresholds_);
    env_.log.record(Stage::Tonemap, op->device, launch_1d(env_.queue(op->device), k, count));
  }
}

}  // namespace px
