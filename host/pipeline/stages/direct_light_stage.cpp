#include "pipeline/stages/direct_light_stage.h"

#include "cl/launch.h"

#include <stdexcept>
#include <string>

namespace px {

DirectLightStage::DirectLightStage(StageEnv& env, const Options& options, const PathTraceStage& tracer,
                                   bool right_eye_holes)
    : StageUnit(env), options_(options), tracer_(tracer), right_eye_holes_(right_eye_holes), dev_(env.layout.count()) {
  if (options.candidates < 1 || options.candidates > PX_RESTIR_MAX_CANDIDATES)
    throw std::invalid_argument("ReSTIR candidates must be between 1 and " + std::to_string(PX_RESTIR_MAX_CANDIDATES));
  if (options.neighbours > PX_RESTIR_MAX_NEIGHBOURS)
    throw std::invalid_argument("ReSTIR neighbours must be at most " + std::to_string(PX_RESTIR_MAX_NEIGHBOURS));
  if (!(options.max_history >= 1.0f)) throw std::invalid_argument("ReSTIR history cap must be at least 1");
  const std::size_t pixels = static_cast<std::size_t>(env.width) * env.height;
  for (int d = 0; d < env.layout.count(); ++d) {
    if (!env.local(d)) continue;
    cl::CommandQueue& q = env.devices.devices()[env.layout.local_index(d)].queue;
    for (PerEye& pe : dev_[d]) {
      // Zeroed: tag 0 is "no reservoir", so nothing uninitialised is ever reused.
      auto zeroed = [&](std::size_t bytes) {
        cl::Buffer b(env.devices.context(), CL_MEM_READ_WRITE, bytes);
        q.enqueueFillBuffer(b, cl_uint{0}, 0, bytes);
        return b;
      };
      for (int k = 0; k < 2; ++k) {
        pe.reservoirs[k] = zeroed(pixels * 2 * sizeof(cl_float4));
        pe.hits[k] = zeroed(pixels * sizeof(cl_uint4));
      }
    }
    q.finish();
  }
}

RestirParams DirectLightStage::params(RowRange rows, RowRange readable, unsigned frame) const {
  RestirParams p{};
  p.width = env_.width;
  p.height = env_.height;
  p.row0 = rows.begin;
  p.rows = rows.size();
  p.lo_row = readable.begin;
  p.hi_row = readable.end;
  p.candidates = options_.candidates;
  p.neighbours = options_.neighbours;
  p.radius = options_.radius;
  p.temporal = options_.temporal ? 1u : 0u;
  p.max_history = options_.max_history;
  p.tag = frame + 1;
  p.temporal_rows = options_.temporal_rows;
  return p;
}

void DirectLightStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  for (int e = 0; e < 2; ++e) {
    const std::vector<RowRange> strip = eye_rows(ops, e);
    if (!strip.empty()) run_eye(e, strip, in);
  }
}

void DirectLightStage::run_eye(int e, const std::vector<RowRange>& strip, const FrameInputs& in) {
  const int n = env_.layout.count();
  const bool holes = e == 1 && right_eye_holes_;
  const unsigned reach = holes ? 0u : options_.radius;  // rows beyond the strip the spatial taps read
  auto widened = [&](unsigned radius) { return widen(strip, radius, env_.height); };
  // Last frame's reservoirs and hits live with last frame's strips: fetch those within the
  // temporal taps' reach of the rows this device computes candidates for.
  const unsigned prev_tag = history_tag_[e] == in.frame ? history_tag_[e] : 0u;  // frame - 1 + 1
  const std::vector<RowRange> prev_rows = widened(reach + options_.temporal_rows + 1);
  if (prev_tag && options_.temporal && n > 1) {
    auto staging = [&](int d) -> StagingBuffer& { return dev_[d][e].staging; };
    const int last = 1 - parity_;
    env_.transfer.exchange([&](int d) -> const cl::Buffer& { return dev_[d][e].reservoirs[last]; }, history_strips_[e],
                           prev_rows, 2 * sizeof(cl_float4), staging);
    env_.transfer.exchange([&](int d) -> const cl::Buffer& { return dev_[d][e].hits[last]; }, history_strips_[e],
                           prev_rows, sizeof(cl_uint4), staging);
  }
  const CameraParams prev_cam = prev_cam_[e] && prev_tag ? *prev_cam_[e] : in.cams[e];
  for (int d = 0; d < n; ++d) {
    if (!env_.local(d) || strip[d].size() == 0) continue;
    PerEye& pe = dev_[d][e];
    const FrameImages& f = env_.images[d];
    const cl::Program& program = env_.devices.program("restir/restir_di.cl", env_.device_scene.kernel_options());
    const RowRange computed = widen(strip[d], reach, env_.height);
    FrameParams fp = tracer_.frame_params(e, computed, in.frame);
    // Pass 1: candidates and temporal reuse over the strip and the spatial taps' margin.
    RestirParams rp = params(computed, prev_rows[d], in.frame);
    rp.prev_tag = prev_tag;
    cl::Kernel candidates(program, "restir_candidates");
    candidates.setArg(0, pe.reservoirs[parity_]);
    candidates.setArg(1, pe.hits[parity_]);
    set_optional_buffer(candidates, 2, prev_tag ? &pe.reservoirs[1 - parity_] : nullptr);
    candidates.setArg(3, pe.hits[1 - parity_]);
    set_optional_buffer(candidates, 4, holes ? &f.holes : nullptr);
    set_optional_buffer(candidates, 5, holes ? &f.hole_count : nullptr);
    candidates.setArg(6, rp);
    candidates.setArg(7, fp);
    candidates.setArg(8, in.cams[e]);
    candidates.setArg(9, prev_cam);
    env_.scene_on(d).bind(candidates, 10);
    env_.log.record(Stage::DirectLight, d, launch_1d(env_.queue(d), candidates, env_.pixels(computed)), "candidates");
    // Pass 2: spatial reuse and shading over the strip (the holes).
    fp = tracer_.frame_params(e, strip[d], in.frame);
    rp = params(strip[d], computed, in.frame);
    if (holes) rp.neighbours = 0;
    cl::Kernel shade(program, "restir_spatial_shade");
    shade.setArg(0, f.radiance[e]);
    shade.setArg(1, f.nonfinite_paths);
    shade.setArg(2, pe.reservoirs[parity_]);
    shade.setArg(3, pe.hits[parity_]);
    set_optional_buffer(shade, 4, holes ? &f.holes : nullptr);
    set_optional_buffer(shade, 5, holes ? &f.hole_count : nullptr);
    // The left eye's reservoirs of this frame (its stage ran before hole filling, on this device).
    const bool stereo = holes && options_.stereo_reuse && frame_tag_[0] == in.frame + 1;
    set_optional_buffer(shade, 6, stereo ? &dev_[d][0].reservoirs[parity_] : nullptr);
    set_optional_buffer(shade, 7, stereo ? &dev_[d][0].hits[parity_] : nullptr);
    shade.setArg(8, rp);
    shade.setArg(9, fp);
    shade.setArg(10, in.cams[e]);
    shade.setArg(11, in.cams[0]);
    env_.scene_on(d).bind(shade, 12);
    env_.log.record(Stage::DirectLight, d, launch_1d(env_.queue(d), shade, env_.pixels(strip[d])), "spatial + shade");
  }
  frame_strips_[e] = strip;
  frame_tag_[e] = in.frame + 1;
  frame_cam_[e] = in.cams[e];
}

void DirectLightStage::end_frame(const FrameInputs&) {
  for (int e = 0; e < 2; ++e) {
    if (frame_tag_[e] == 0) continue;  // this eye did not run this frame
    history_strips_[e] = frame_strips_[e];
    history_tag_[e] = frame_tag_[e];
    prev_cam_[e] = frame_cam_[e];
    frame_tag_[e] = 0;
  }
  parity_ = 1 - parity_;
  for (auto& eyes : dev_)
    for (PerEye& pe : eyes) pe.staging.readers.clear();
}

}  // namespace px
