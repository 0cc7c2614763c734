#include "pipeline/stages/denoise_stage.h"

#include "cl/launch.h"
#include "denoise/svgf_constants.h"

#include <algorithm>
#include <stdexcept>

namespace px {

const char* to_string(SeamMode m) {
  switch (m) {
    case SeamMode::Independent: return "independent";
    case SeamMode::Bilateral: return "bilateral";
    case SeamMode::Halo: return "halo";
  }
  return "?";
}

DenoiseStage::DenoiseStage(StageEnv& env, const Options& options, const PathTraceStage* tracer)
    : StageUnit(env),
      options_(options),
      max_iterations_(options.svgf.iterations),
      dev_(env.layout.count()),
      tracer_(tracer) {
  if (options.svgf.iterations < 1) throw std::invalid_argument("SVGF needs at least one a-trous iteration");
  const std::size_t pixels = static_cast<std::size_t>(env.width) * env.height;
  for (int d = 0; d < env.layout.count(); ++d) {
    if (!env.local(d)) continue;  // another rank's device: nothing of it lives here
    for (int e = 0; e < 2; ++e) {
      dev_[d].gbuffer_prev[e] = cl::Buffer(env.devices.context(), CL_MEM_READ_WRITE, pixels * sizeof(GBufferTexel));
      dev_[d].svgf[e] = std::make_unique<SvgfDenoiser>(env.devices, env.layout.local_index(d), env.width, env.height,
                                                       options.svgf, &env.lanes);
      if (options.temporal_gradients && tracer)
        dev_[d].gradients[e] = std::make_unique<TemporalGradients>(env.devices, env.layout.local_index(d), env.width,
                                                                   env.height, &env.lanes);
    }
  }
}

void DenoiseStage::set_iterations(unsigned n) {
  if (n < 1 || n > max_iterations_)
    throw std::invalid_argument("SVGF iterations must be within [1, " + std::to_string(max_iterations_) + "]");
  options_.svgf.iterations = n;
}

unsigned DenoiseStage::gbuffer_rows_read(const Options& o) {
  switch (o.seams) {
    case SeamMode::Independent: return 0;
    case SeamMode::Bilateral: return o.seam_band + 3;
    case SeamMode::Halo: break;
  }
  const unsigned atrous = 2u << (o.svgf.iterations - 1);
  // 3: the variance estimate; PX_SVGF_NEAR_MOTION_REACH: the motion pass (animated scenes);
  // PX_GRADIENT_ROWS: the temporal gradients' picks and filter taps.
  const unsigned gradients = o.temporal_gradients ? PX_GRADIENT_ROWS : 0u;
  return std::max({atrous, o.svgf.temporal_rows + 1, 3u, static_cast<unsigned>(PX_SVGF_NEAR_MOTION_REACH), gradients}) +
         1;
}

void DenoiseStage::run(const std::vector<const Operation*>& ops, const FrameInputs& in) {
  // The eyes these operations denoise (with the side lane, each eye comes as its own batch).
  for (int e = 0; e < 2; ++e) {
    const std::vector<RowRange> strip = eye_rows(ops, e);
    if (strip.empty()) continue;
    denoise_eye(e, strip, in);
    frame_strips_[e] = strip;
  }
}

void DenoiseStage::denoise_eye(int e, const std::vector<RowRange>& strip, const FrameInputs& in) {
  const int n = env_.layout.count();
  const bool halo = options_.seams == SeamMode::Halo;
  const RowRange image{0, env_.height};
  auto readable = [&](int d) { return halo ? image : strip[d]; };
  auto svgf = [&](int d) -> SvgfDenoiser& { return *dev_[d].svgf[e]; };
  auto halo_staging = [&](int d) -> StagingBuffer& { return dev_[d].halo[e]; };
  auto widened = [&](unsigned radius) { return widen(strip, radius, env_.height); };
  // Copies into each device the rows within `radius` of its strip that its neighbours own.
  auto exchange_halo = [&](const RowTransfer::BufferOf& buffer, unsigned radius) {
    env_.transfer.exchange(buffer, strip, widened(radius), sizeof(cl_float4), halo_staging);
  };
  const CameraParams prev = prev_cams_ ? (*prev_cams_)[e] : in.cams[e];
  const auto& o = options_.svgf;
  // Last frame's history lives with last frame's strips. The temporal pass reads it within
  // temporal_rows of each pixel (halo seams) or within the strip (otherwise): fetch those rows
  // from whichever device holds them — the neighbours' halo rows, and, when the strips moved,
  // the rows this device took over (with their G-buffer, which the history test reads).
  const std::vector<RowRange>& held = history_strips_[e].empty() ? strip : history_strips_[e];
  const bool moved = held != strip;
  const std::vector<RowRange> history_rows = widened(halo ? o.temporal_rows + 1 : 0);
  if (halo || moved) {
    env_.transfer.exchange([&](int d) -> const cl::Buffer& { return svgf(d).history_illum_prev(); }, held, history_rows,
                           sizeof(cl_float4), halo_staging);
    env_.transfer.exchange([&](int d) -> const cl::Buffer& { return svgf(d).history_moments_prev(); }, held,
                           history_rows, sizeof(cl_float4), halo_staging);
    if (o.taa_alpha < 1.0f)
      env_.transfer.exchange([&](int d) -> const cl::Buffer& { return svgf(d).history_resolved_prev(); }, held,
                             history_rows, sizeof(cl_float4), halo_staging);
  }
  const bool gradients = options_.temporal_gradients && tracer_;
  if (moved) {
    // The temporal gradients re-shade last frame's picks within PX_GRADIENT_ROWS of the strip:
    // their G-buffer texels and last frame's shades come along.
    const std::vector<RowRange> prev_rows =
        gradients ? widened(std::max(halo ? o.temporal_rows + 1 : 0u, static_cast<unsigned>(PX_GRADIENT_ROWS)))
                  : history_rows;
    env_.transfer.exchange([&](int d) -> const cl::Buffer& { return dev_[d].gbuffer_prev[e]; }, held, prev_rows,
                           sizeof(GBufferTexel), [&](int d) -> StagingBuffer& { return dev_[d].gbuffer[e]; });
    if (gradients)
      env_.transfer.exchange([&](int d) -> const cl::Buffer& { return dev_[d].gradients[e]->previous_shades(); }, held,
                             prev_rows, sizeof(cl_float4), halo_staging);
  }
  // The guide covers every G-buffer row the spatial passes read: the strip and the margin that
  // gbuffer_rows_read declares (which the G-buffer stage computed).
  const std::vector<RowRange> guided = widened(gbuffer_rows_read(options_));
  for (int d = 0; d < n; ++d)
    if (env_.local(d)) svgf(d).guide(env_.images[d].gbuffer[e], guided[d]);
  for (int d = 0; d < n; ++d)
    if (env_.local(d) && tracer_ && options_.motion_edge_samples > 0 && env_.scene_on(d).motion())
      sample_motion_edges(e, d, strip[d], readable(d), in);
  for (int d = 0; d < n; ++d)
    if (env_.local(d)) {
      TemporalGradients* g = dev_[d].gradients[e].get();
      if (g) {
        // Within the G-buffer rows this frame traced (gbuffer_rows_read's margin), as the motion edges.
        const RowRange margin = widen(strip[d], gbuffer_rows_read(options_), env_.height);
        const RowRange valid{std::max(margin.begin, readable(d).begin), std::min(margin.end, readable(d).end)};
        g->run(env_.devices.program("denoise/temporal_gradient.cl", env_.device_scene.kernel_options()),
               env_.scene_on(d), env_.images[d].gbuffer[e], dev_[d].gbuffer_prev[e], env_.images[d].nonfinite_paths,
               tracer_->frame_params(e, strip[d], in.frame), in.cams[e], strip[d], valid);
        for (auto& ev : g->take_events()) env_.log.record(Stage::TemporalGradient, d, ev.event, ev.pass);
      }
      svgf(d).set_gradient(g ? &g->lambda() : nullptr);
    }
  for (int d = 0; d < n; ++d)
    if (env_.local(d))
      svgf(d).temporal(env_.images[d].radiance[e], env_.images[d].albedo[e], env_.images[d].gbuffer[e],
                       dev_[d].gbuffer_prev[e], in.cams[e], prev, strip[d], readable(d),
                       env_.scene_on(d).motion() ? &env_.scene_on(d).motion : nullptr,
                       env_.scene_on(d).motion() ? &env_.scene_on(d).instances : nullptr);
  if (halo) {
    exchange_halo([&](int d) -> const cl::Buffer& { return svgf(d).illum(); }, 3);
    // Moments (with the filtered flag) are read within the variance pass's 7x7 window; farther
    // taps learn the flag from the guide.
    exchange_halo([&](int d) -> const cl::Buffer& { return svgf(d).moments(); }, 3);
  }
  for (int d = 0; d < n; ++d)
    if (env_.local(d)) svgf(d).variance(strip[d], readable(d));
  for (unsigned i = 0; i < o.iterations; ++i) {
    // The taps reach 2^(i+1) rows; their luminance guide one more (SvgfDenoiser::atrous).
    if (halo) exchange_halo([&](int d) -> const cl::Buffer& { return svgf(d).illum(); }, (2u << i) + 1);
    for (int d = 0; d < n; ++d)
      if (env_.local(d)) svgf(d).atrous(i, strip[d], readable(d));
  }
  for (int d = 0; d < n; ++d)
    if (env_.local(d)) svgf(d).remodulate(env_.images[d].radiance[e], env_.images[d].albedo[e], strip[d], readable(d));
  if (o.taa_alpha < 1.0f) {
    // Anti-aliasing reads the remodulated radiance one row beyond the strip.
    if (halo) exchange_halo([&](int d) -> const cl::Buffer& { return env_.images[d].radiance[e]; }, 1);
    for (int d = 0; d < n; ++d)
      if (env_.local(d))
        svgf(d).antialias(env_.images[d].radiance[e], env_.images[d].gbuffer[e], in.cams[e], prev, strip[d],
                          readable(d));
  }
  if (options_.seams == SeamMode::Bilateral && n > 1) {
    exchange_halo([&](int d) -> const cl::Buffer& { return env_.images[d].radiance[e]; }, options_.seam_band + 2);
    for (int d = 0; d < n; ++d) {
      if (strip[d].size() == 0 || !env_.local(d)) continue;
      const int above = strip[d].begin > 0 ? static_cast<int>(strip[d].begin) : -1;
      const int below = strip[d].end < env_.height ? static_cast<int>(strip[d].end) : -1;
      svgf(d).seam_filter(env_.images[d].radiance[e], strip[d], image, above, below,
                          static_cast<int>(options_.seam_band));
    }
  }
  for (int d = 0; d < n; ++d)
    if (env_.local(d))
      for (auto& e : svgf(d).take_events()) env_.log.record(e.stage, d, e.event, e.pass);
}

void DenoiseStage::sample_motion_edges(int e, int d, RowRange rows, RowRange readable, const FrameInputs& in) {
  if (rows.size() == 0) return;
  PerDevice& dev = dev_[d];
  const cl::Context& ctx = env_.devices.context();
  if (!dev.edge_list[e]()) {
    dev.edge_list[e] =
        cl::Buffer(ctx, CL_MEM_READ_WRITE, static_cast<std::size_t>(env_.width) * env_.height * sizeof(cl_uint));
    dev.edge_count[e] = cl::Buffer(ctx, CL_MEM_READ_WRITE, sizeof(cl_uint));
  }
  cl::CommandQueue& q = env_.queue(d);
  const FrameImages& f = env_.images[d];
  const DeviceSceneBuffers& scene = env_.scene_on(d);
  q.enqueueFillBuffer(dev.edge_count[e], cl_uint(0), 0, sizeof(cl_uint));
  // The list reads the G-buffer within two rows of the strip: rows the G-buffer pass traced
  // (gbuffer_rows_read's margin) where the seams are exchanged, the strip alone otherwise.
  const RowRange margin = widen(rows, gbuffer_rows_read(options_), env_.height);
  const RowRange valid{std::max(margin.begin, readable.begin), std::min(margin.end, readable.end)};
  cl::Kernel list(env_.devices.program("pipeline/motion_edges.cl"), "motion_edge_list");
  list.setArg(0, dev.edge_list[e]);
  list.setArg(1, dev.edge_count[e]);
  list.setArg(2, f.gbuffer[e]);
  list.setArg(3, scene.motion);
  set_optional_buffer(list, 4, scene.instances() ? &scene.instances : nullptr);
  list.setArg(5, static_cast<cl_uint>(rows.begin));
  list.setArg(6, static_cast<cl_uint>(rows.size()));
  list.setArg(7, static_cast<cl_uint>(env_.width));
  list.setArg(8, static_cast<cl_uint>(env_.height));
  list.setArg(9, static_cast<cl_uint>(valid.begin));
  list.setArg(10, static_cast<cl_uint>(valid.end));
  env_.log.record(Stage::Denoise, d, launch_1d(q, list, env_.pixels(rows)), "motion edges");
  // Samples spp .. spp + motion_edge_samples - 1 of each listed pixel's stream.
  FrameParams fp = tracer_->frame_params(e, rows, in.frame);
  fp.sample_offset = fp.spp;
  fp.spp = options_.motion_edge_samples;
  // Spread over the pixel whatever the frame's own samples do: these samples anti-alias a moving
  // edge within the frame, where the anti-aliasing's history cannot follow it.
  fp.gbuffer_ray_samples = PX_GBUFFER_RAY_FIRST;
  cl::Kernel more(env_.devices.program("pathtrace/path_trace.cl", env_.device_scene.kernel_options()),
                  "path_trace_list_more");
  more.setArg(0, f.radiance[e]);
  more.setArg(1, f.albedo[e]);
  more.setArg(2, f.nonfinite_paths);
  more.setArg(3, dev.edge_list[e]);
  more.setArg(4, dev.edge_count[e]);
  more.setArg(5, fp);
  more.setArg(6, in.cams[e]);
  scene.bind(more, 7);
  // Sized for the worst case (every pixel listed): the count stays on the device.
  env_.log.record(Stage::Denoise, d, launch_1d(q, more, env_.pixels(rows)), "motion edge samples");
}

std::size_t DenoiseStage::motion_edge_pixels(int e) {
  std::size_t total = 0;
  for (int d = 0; d < env_.layout.count(); ++d) {
    if (!env_.local(d) || !dev_[d].edge_count[e]()) continue;
    cl_uint n = 0;
    env_.lanes.main(env_.layout.local_index(d)).enqueueReadBuffer(dev_[d].edge_count[e], CL_TRUE, 0, sizeof n, &n);
    total += n;
  }
  return total;
}

void DenoiseStage::end_frame(const FrameInputs& in) {
  // This frame's G-buffers and SVGF history become the previous frame's.
  for (std::size_t d = 0; d < dev_.size(); ++d) {
    PerDevice& dev = dev_[d];
    if (!dev.svgf[0]) continue;  // another rank's device
    for (int e = 0; e < 2; ++e) {
      std::swap(env_.images[d].gbuffer[e], dev.gbuffer_prev[e]);
      dev.svgf[e]->end_frame();
      if (dev.gradients[e]) dev.gradients[e]->end_frame();
    }
    for (int e = 0; e < 2; ++e) {
      dev.halo[e].readers.clear();
      dev.gbuffer[e].readers.clear();
    }
  }
  prev_cams_ = in.cams;
  history_strips_ = frame_strips_;
}

}  // namespace px
