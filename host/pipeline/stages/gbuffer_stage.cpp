#include "pipeline/stages/gbuffer_stage.h"

#include "cl/launch.h"

namespace px {

void GBufferStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    // Two pixels a work-item (gbuffer_pairs) on CPUs, one (gbuffer) on GPUs; the G-buffer is the
    // same to the bit.
    const bool pairs = !env_.is_gpu(op->device);
    cl::Kernel k(env_.devices.program("pipeline/gbuffer.cl", env_.device_scene.kernel_options()),
                 pairs ? "gbuffer_pairs" : "gbuffer");
    const FrameImages& f = env_.images[op->device];
    k.setArg(0, f.gbuffer[op->eye]);
    set_optional_buffer(k, 1, op->shares_hits ? &f.right_hits : nullptr);
    k.setArg(2, static_cast<cl_uint>(op->rows.begin));
    k.setArg(3, static_cast<cl_uint>(op->rows.size()));
    k.setArg(4, in.cams[op->eye]);
    env_.scene_on(op->device).bind(k, 5);
    const std::size_t pixels = env_.pixels(op->rows);
    env_.log.record(Stage::GBuffer, op->device,
                    launch_1d(env_.queue(op->device), k, pairs ? (pixels + 1) / 2 : pixels));
  }
}

}  // namespace px
