#include "pipeline/stages/temporal_gradients.h"

#include "cl/launch.h"
#include "denoise/svgf_constants.h"
#include "render/path_tracer.h"

#include <algorithm>

namespace px {

TemporalGradients::TemporalGradients(DeviceSet& devices, int device, unsigned width, unsigned height, QueueLanes* lanes)
    : devices_(devices),
      device_(device),
      lanes_(lanes),
      width_(width),
      height_(height),
      strata_w_(strata_count(width)),
      strata_h_(strata_count(height)) {
  const auto& ctx = devices.context();
  auto& q = devices.devices()[device].queue;
  const cl_float4 zero{{0, 0, 0, 0}};
  const std::size_t pixels = static_cast<std::size_t>(width) * height * sizeof(cl_float4);
  const std::size_t strata = static_cast<std::size_t>(strata_w_) * strata_h_ * sizeof(cl_float4);
  for (int k = 0; k < 2; ++k) {
    // Zero: "no valid shade" (y = 0), so a pick never written reads as unknown.
    shades_[k] = cl::Buffer(ctx, CL_MEM_READ_WRITE, pixels);
    q.enqueueFillBuffer(shades_[k], zero, 0, pixels);
    filtered_[k] = cl::Buffer(ctx, CL_MEM_READ_WRITE, strata);
    q.enqueueFillBuffer(filtered_[k], zero, 0, strata);
  }
  raw_ = cl::Buffer(ctx, CL_MEM_READ_WRITE, strata);
  q.enqueueFillBuffer(raw_, zero, 0, strata);
}

RowRange TemporalGradients::strata_of(RowRange strip) const {
  if (strip.size() == 0) return {0, 0};
  const unsigned lo = strip.begin / PX_GRADIENT_STRATUM;
  const unsigned hi = strata_count(strip.end);
  return {lo > PX_GRADIENT_REACH ? lo - PX_GRADIENT_REACH : 0u, std::min(strata_h_, hi + PX_GRADIENT_REACH)};
}

GradientParams TemporalGradients::params(RowRange write, RowRange read, RowRange gbuffer_rows, unsigned step,
                                         const FrameParams& fp) const {
  GradientParams p{};
  p.width = width_;
  p.height = height_;
  p.strata_w = strata_w_;
  p.strata_h = strata_h_;
  p.s_row0 = write.begin;
  p.s_rows = write.size();
  p.s_lo = read.begin;
  p.s_hi = read.end;
  p.lo_row = gbuffer_rows.begin;
  p.hi_row = gbuffer_rows.end;
  p.step = step;
  p.frame = fp.frame;
  p.eye = fp.eye;
  p.seed = fp.seed;
  p.have_history = have_history_ ? 1u : 0u;
  return p;
}

void TemporalGradients::run(const cl::Program& shading, const DeviceSceneBuffers& scene, const cl::Buffer& gbuf,
                            const cl::Buffer& prev_gbuf, const cl::Buffer& nonfinite, const FrameParams& fp,
                            const CameraParams& cam, RowRange strip, RowRange gbuffer_rows) {
  if (strip.size() == 0 || gbuffer_rows.size() == 0) return;
  // Only strata whose rows the G-buffers hold: all of strata_of(strip) where the margin is
  // exchanged (the denoise stage sizes it), the strip's own otherwise.
  const RowRange wanted = strata_of(strip);
  const RowRange held{gbuffer_rows.begin / PX_GRADIENT_STRATUM, strata_count(gbuffer_rows.end)};
  const RowRange shaded{std::max(wanted.begin, held.begin), std::min(wanted.end, held.end)};
  if (shaded.size() == 0) return;
  // The re-shaded paths stop after PX_GRADIENT_MAX_BOUNCES bounces: the change of the light a
  // surface sees is measured by its first bounces, at a fraction of the image's paths' cost.
  FrameParams shade_fp = fp;
  shade_fp.max_bounces = std::min<cl_uint>(fp.max_bounces, PX_GRADIENT_MAX_BOUNCES);
  const GradientParams shade_params = params(shaded, shaded, gbuffer_rows, 0, fp);
  const cl::Buffer* motion = scene.motion() ? &scene.motion : nullptr;
  if (runs_on_cpu(queue())) {
    // CPUs: in the path tracer's kernel, which a first run compiles once for all its stages.
    const PathTracer::GradientInputs in{raw_,      shades_[parity_], shades_[1 - parity_], gbuf, prev_gbuf,
                                        nonfinite, motion,           shade_params};
    events_.push_back({PathTracer::launch_gradient(queue(), shading, scene, in, shade_fp, cam), "gradient shade"});
  } else {
    cl::Kernel k(shading, "gradient_shade");
    cl_uint a = 0;
    k.setArg(a++, raw_);
    k.setArg(a++, shades_[parity_]);
    k.setArg(a++, shades_[1 - parity_]);
    k.setArg(a++, gbuf);
    k.setArg(a++, prev_gbuf);
    k.setArg(a++, nonfinite);
    set_optional_buffer(k, a++, motion);
    k.setArg(a++, shade_fp);
    k.setArg(a++, cam);
    k.setArg(a++, shade_params);
    scene.bind(k, a);
    events_.push_back({launch_1d(queue(), k, static_cast<std::size_t>(shaded.size()) * strata_w_), "gradient shade"});
  }

  // The a-trous steps: step i reads 2^i strata each way, so its output is needed that much less
  // far beyond the strip than its input was; the last covers the strip's strata alone.
  const RowRange own{strip.begin / PX_GRADIENT_STRATUM, strata_count(strip.end)};
  cl::Kernel f(devices_.program("denoise/gradient_filter.cl"), "gradient_atrous");
  RowRange read = shaded;
  unsigned remaining = PX_GRADIENT_REACH;
  const cl::Buffer* in = &raw_;
  for (unsigned i = 0; i < PX_GRADIENT_STEPS; ++i) {
    const unsigned step = 1u << i;
    remaining -= step;
    const RowRange want{own.begin > remaining ? own.begin - remaining : 0u, std::min(strata_h_, own.end + remaining)};
    const RowRange write{std::max(want.begin, read.begin), std::min(want.end, read.end)};
    const int out = static_cast<int>(i % 2);
    f.setArg(0, filtered_[out]);
    f.setArg(1, *in);
    f.setArg(2, gbuf);
    f.setArg(3, params(write, read, gbuffer_rows, step, fp));
    events_.push_back({launch_1d(queue(), f, static_cast<std::size_t>(write.size()) * strata_w_), "gradient filter"});
    in = &filtered_[out];
    final_ = out;
    read = write;
  }
}

void TemporalGradients::end_frame() {
  parity_ = 1 - parity_;
  have_history_ = true;
}

std::vector<TemporalGradients::PassEvent> TemporalGradients::take_events() {
  std::vector<PassEvent> out;
  out.swap(events_);
  return out;
}

}  // namespace px
