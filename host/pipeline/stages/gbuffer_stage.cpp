#include "pipeline/stages/gbuffer_stage.h"

#include "cl/launch.h"
#include "render/path_tracer.h"

namespace px {

void GBufferStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (const Operation* op : ops) {
    if (!env_.local(op->device)) continue;
    const FrameImages& f = env_.images[op->device];
    const cl::Buffer* hits = op->shares_hits ? &f.right_hits : nullptr;
    if (env_.is_cpu(op->device)) {
      // CPUs: the path tracer's kernel, which a frame compiles anyway, in its G-buffer mode. A
      // kernel of its own (two pixels a work-item) made this stage 14-17% faster in later frames
      // but cost every first run 0.67 s of PoCL's compile (docs/measurements.md, "The G-buffer
      // pass in the path tracer's kernel on CPUs"). The same texels and hits to the bit.
      env_.log.record(Stage::GBuffer, op->device,
                      PathTracer::launch_gbuffer(
                          env_.queue(op->device),
                          env_.devices.program("pathtrace/path_trace.cl", env_.device_scene.kernel_options()),
                          env_.scene_on(op->device), f.gbuffer[op->eye], hits,
                          PathTracer::gbuffer_params(op->eye, op->rows.begin, op->rows.size(), in.frame),
                          in.cams[op->eye], env_.width));
      continue;
    }
    cl::Kernel k(env_.devices.program("pipeline/gbuffer.cl", env_.device_scene.kernel_options()), "gbuffer");
    k.setArg(0, f.gbuffer[op->eye]);
    set_optional_buffer(k, 1, hits);
    k.setArg(2, static_cast<cl_uint>(op->rows.begin));
    k.setArg(3, static_cast<cl_uint>(op->rows.size()));
    k.setArg(4, in.cams[op->eye]);
    env_.scene_on(op->device).bind(k, 5);
    env_.log.record(Stage::GBuffer, op->device, launch_1d(env_.queue(op->device), k, env_.pixels(op->rows)));
  }
}

}  // namespace px
