#include "pipeline/stereo_pipeline.h"

#include "cl/launch.h"
#include "cl/profiling.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

namespace px {

namespace {

cl::Buffer device_buffer(const cl::Context& ctx, std::size_t bytes) {
  return cl::Buffer(ctx, CL_MEM_READ_WRITE, std::max<std::size_t>(bytes, 16));
}

}  // namespace

const char* to_string(SeamMode m) {
  switch (m) {
    case SeamMode::Independent: return "independent";
    case SeamMode::Bilateral: return "bilateral";
    case SeamMode::Halo: return "halo";
  }
  return "?";
}

SeamMode parse_seam_mode(const std::string& text) {
  if (text == "independent") return SeamMode::Independent;
  if (text == "bilateral") return SeamMode::Bilateral;
  if (text == "halo") return SeamMode::Halo;
  throw std::invalid_argument("unknown seam mode '" + text + "' (expected independent, bilateral or halo)");
}

StereoPipeline::StereoPipeline(DeviceSet& devices, const DeviceScene& device_scene, const Scene& scene,
                               unsigned width, unsigned height, Options options)
    : devices_(devices),
      cluster_(options.cluster && options.cluster->distributed() ? options.cluster : nullptr),
      layout_{cluster_ ? cluster_->rank() : 0, cluster_ ? cluster_->size() : 1, devices.size()},
      device_scene_(device_scene),
      scene_(scene),
      width_(width),
      height_(height),
      options_(options),
      schedule_(make_schedule(options.pipeline, layout_.count(), height, options.denoise)),
      max_svgf_iterations_(options.svgf.iterations) {
  if (width == 0 || height == 0 || width > 65535 || height > 65535)
    throw std::invalid_argument("image size must be between 1 and 65535 per side");
  if (options.trace.spp == 0) throw std::invalid_argument("spp must be at least 1");
  if (options.trace.bounces > PathTracer::kMaxBounces)
    throw std::invalid_argument("bounces must be at most " + std::to_string(PathTracer::kMaxBounces));
  const std::size_t pixels = static_cast<std::size_t>(width) * height;
  const auto& ctx = devices.context();
  for (int d = 0; d < layout_.count(); ++d) {
    DeviceBuffers b;
    if (!local(d)) {  // another rank's device: nothing of it lives here
      buffers_.push_back(std::move(b));
      continue;
    }
    for (int e = 0; e < 2; ++e) {
      b.radiance[e] = device_buffer(ctx, pixels * sizeof(cl_float4));
      b.albedo[e] = device_buffer(ctx, pixels * sizeof(cl_float4));
      b.gbuffer[e] = device_buffer(ctx, pixels * sizeof(GBufferTexel));
      b.rgba[e] = device_buffer(ctx, pixels * sizeof(cl_uchar4));
    }
    b.holes = device_buffer(ctx, pixels * sizeof(cl_uint));
    b.hole_count = device_buffer(ctx, sizeof(cl_uint));
    b.nonfinite = device_buffer(ctx, sizeof(cl_uint));
    b.nonfinite_pixels = device_buffer(ctx, sizeof(cl_uint));
    if (options_.denoise) {
      if (options_.svgf.iterations < 1) throw std::invalid_argument("SVGF needs at least one a-trous iteration");
      for (int e = 0; e < 2; ++e) {
        b.gbuffer_prev[e] = device_buffer(ctx, pixels * sizeof(GBufferTexel));
        b.svgf[e] = std::make_unique<SvgfDenoiser>(devices, layout_.local_index(d), width, height, options_.svgf);
      }
      b.staging_halo.buffer = cl::Buffer(ctx, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, pixels * sizeof(cl_float4));
    }
    if (d != schedule_.tree.root) {
      // Both eyes side by side in one host-allocated buffer per kind.
      b.staging_radiance = cl::Buffer(ctx, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, 2 * pixels * sizeof(cl_float4));
      b.staging_albedo = cl::Buffer(ctx, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, 2 * pixels * sizeof(cl_float4));
      b.staging_rgba = cl::Buffer(ctx, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, 2 * pixels * sizeof(cl_uchar4));
    }
    buffers_.push_back(std::move(b));
  }
}

void StereoPipeline::set_quality(const FrameQuality& q) {
  if (q.spp == 0) throw std::invalid_argument("spp must be at least 1");
  if (q.bounces > PathTracer::kMaxBounces)
    throw std::invalid_argument("bounces must be at most " + std::to_string(PathTracer::kMaxBounces));
  if (options_.denoise && (q.svgf_iterations < 1 || q.svgf_iterations > max_svgf_iterations_))
    throw std::invalid_argument("SVGF iterations must be within [1, " + std::to_string(max_svgf_iterations_) + "]");
  options_.trace.spp = q.spp;
  options_.trace.bounces = q.bounces;
  if (options_.denoise) options_.svgf.iterations = q.svgf_iterations;
}

FrameQuality StereoPipeline::quality() const {
  return {options_.trace.spp, options_.trace.bounces, options_.svgf.iterations};
}

FrameCost StereoPipeline::frame_cost(const FrameStats& stats) {
  std::map<Stage, double> slowest;  // per stage, the slowest device
  for (const StageTiming& t : stats.stages) slowest[t.stage] = std::max(slowest[t.stage], t.ms);
  FrameCost c;
  for (Stage s : {Stage::PathTraceLeft, Stage::PathTraceRight, Stage::HoleFill}) c.trace_ms += slowest[s];
  c.denoise_ms = slowest[Stage::Denoise];
  c.other_ms = std::max(0.0, stats.wall_ms - c.trace_ms - c.denoise_ms);
  return c;
}

std::vector<double> StereoPipeline::device_busy_ms(const FrameStats& stats, int devices) {
  std::vector<double> ms(devices, 0.0);
  for (const StageTiming& t : stats.stages)
    if (t.stage != Stage::Transfer && t.device >= 0 && t.device < devices) ms[t.device] += t.ms;
  return ms;
}

void StereoPipeline::record(Stage stage, int device, const cl::Event& e) { events_.push_back({{stage, device}, e}); }

void StereoPipeline::enqueue(int d, cl::Kernel& k, std::size_t items, Stage stage) {
  record(stage, d, launch_1d(queue(d), k, items));
}

FrameParams StereoPipeline::frame_params(int eye, RowRange rows, unsigned frame) const {
  return PathTracer::frame_params(scene_, device_scene_.light_count(), options_.trace, eye, rows.begin, rows.size(),
                                  frame);
}

void StereoPipeline::path_trace(int d, int eye, RowRange rows, const CameraParams& cam, unsigned frame, Stage stage) {
  if (rows.size() == 0) return;
  const FrameParams fp = frame_params(eye, rows, frame);
  record(stage, d,
         PathTracer::launch(queue(d), devices_.program("pathtrace/path_trace.cl"), device_scene_.on(layout_.local_index(d)),
                            {buffers_[d].radiance[eye], buffers_[d].albedo[eye], buffers_[d].nonfinite}, fp, cam, width_));
}

void StereoPipeline::gbuffer(int d, int eye, RowRange rows, const CameraParams& cam) {
  if (rows.size() == 0) return;
  cl::Kernel k(devices_.program("pipeline/gbuffer.cl"), "gbuffer");
  k.setArg(0, buffers_[d].gbuffer[eye]);
  k.setArg(1, static_cast<cl_uint>(rows.begin));
  k.setArg(2, static_cast<cl_uint>(rows.size()));
  k.setArg(3, cam);
  device_scene_.on(layout_.local_index(d)).bind(k, 4);
  enqueue(d, k, static_cast<std::size_t>(rows.size()) * width_, Stage::GBuffer);
}

void StereoPipeline::reproject(int d, RowRange rows, const CameraParams& left_cam) {
  if (rows.size() == 0) return;
  auto& q = queue(d);
  const cl_uint zero = 0;
  q.enqueueFillBuffer(buffers_[d].hole_count, zero, 0, sizeof(cl_uint));
  cl::Kernel k(devices_.program("pipeline/reproject.cl"), "reproject");
  auto& b = buffers_[d];
  k.setArg(0, b.radiance[1]);
  k.setArg(1, b.albedo[1]);
  k.setArg(2, b.holes);
  k.setArg(3, b.hole_count);
  k.setArg(4, b.radiance[0]);
  k.setArg(5, b.albedo[0]);
  k.setArg(6, b.gbuffer[0]);
  k.setArg(7, b.gbuffer[1]);
  k.setArg(8, static_cast<cl_uint>(rows.begin));
  k.setArg(9, static_cast<cl_uint>(rows.size()));
  k.setArg(10, left_cam);
  enqueue(d, k, static_cast<std::size_t>(rows.size()) * width_, Stage::Reproject);
}

void StereoPipeline::fill_holes(int d, RowRange rows, const CameraParams& right_cam, unsigned frame) {
  if (rows.size() == 0) return;
  const FrameParams fp = frame_params(1, rows, frame);
  auto& b = buffers_[d];
  cl::Kernel k(devices_.program("pathtrace/path_trace.cl"), "path_trace_list");
  k.setArg(0, b.radiance[1]);
  k.setArg(1, b.albedo[1]);
  k.setArg(2, b.nonfinite);
  k.setArg(3, b.holes);
  k.setArg(4, b.hole_count);
  k.setArg(5, fp);
  k.setArg(6, right_cam);
  device_scene_.on(layout_.local_index(d)).bind(k, 7);
  // Sized for the worst case (every pixel a hole): the hole count lives on the device, so no
  // host round trip is needed between reprojection and hole filling.
  enqueue(d, k, static_cast<std::size_t>(rows.size()) * width_, Stage::HoleFill);
}

void StereoPipeline::tonemap(int d, int eye, RowRange rows) {
  if (rows.size() == 0) return;
  const cl_uint first = rows.begin * width_, count = rows.size() * width_;
  cl::Kernel k(devices_.program("pipeline/tonemap.cl"), "tonemap");
  k.setArg(0, buffers_[d].rgba[eye]);
  k.setArg(1, buffers_[d].radiance[eye]);
  k.setArg(2, first);
  k.setArg(3, count);
  k.setArg(4, options_.exposure);
  k.setArg(5, buffers_[d].nonfinite_pixels);
  enqueue(d, k, count, Stage::Tonemap);
}

void StereoPipeline::transfer(int d, int eye, RowRange rows, bool radiance, bool rgba) {
  const int owner = schedule_.tree.root;
  if (d == owner || rows.size() == 0 || (!local(d) && !local(owner))) return;
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  const std::size_t first = static_cast<std::size_t>(rows.begin) * width_, count = static_cast<std::size_t>(rows.size()) * width_;
  auto hop = [&](const cl::Buffer& src, cl::Buffer DeviceBuffers::*staging, const cl::Buffer& dst, std::size_t texel) {
    // Each eye has its own half of the staging buffer, and every row range travels once a
    // frame: no two copies share staging bytes.
    copy_rows(d, src, owner, dst, first * texel, count * texel,
              [&]() -> const cl::Buffer& { return buffers_[d].*staging; },
              (static_cast<std::size_t>(eye) * pixels + first) * texel, nullptr);
  };
  if (radiance) {
    hop(buffers_[d].radiance[eye], &DeviceBuffers::staging_radiance, buffers_[owner].radiance[eye], sizeof(cl_float4));
    // The owner denoises transferred radiance (baseline), which needs its albedo alongside.
    if (options_.denoise && schedule_.pipeline == PipelineKind::Baseline)
      hop(buffers_[d].albedo[eye], &DeviceBuffers::staging_albedo, buffers_[owner].albedo[eye], sizeof(cl_float4));
  }
  if (rgba) hop(buffers_[d].rgba[eye], &DeviceBuffers::staging_rgba, buffers_[owner].rgba[eye], sizeof(cl_uchar4));
}

template <typename StagingOf>
void StereoPipeline::copy_rows(int from, const cl::Buffer& src, int to, const cl::Buffer& dst, std::size_t offset,
                               std::size_t bytes, StagingOf staging, std::size_t staging_offset,
                               std::vector<cl::Event>* readers) {
  if (local(from) && local(to)) {
    const cl::Buffer& st = staging();
    cl::Event out, in;
    std::vector<cl::Event> wait = readers ? *readers : std::vector<cl::Event>{};
    queue(from).enqueueCopyBuffer(src, st, offset, staging_offset, bytes, wait.empty() ? nullptr : &wait, &out);
    std::vector<cl::Event> after{out};
    queue(to).enqueueCopyBuffer(st, dst, staging_offset, offset, bytes, &after, &in);
    if (readers) *readers = {in};
    record(Stage::Transfer, from, out);
    record(Stage::Transfer, to, in);
    bytes_this_frame_ += bytes;
  } else if (local(from)) {
    // To another rank: read the rows (waiting for the commands that write them), then send.
    auto& host = message_rows_.emplace_back(bytes);
    cl::Event out;
    queue(from).enqueueReadBuffer(src, CL_TRUE, offset, bytes, host.data(), nullptr, &out);
    record(Stage::Transfer, from, out);
    cluster_->send(layout_.rank_of(to), host.data(), bytes);
  } else if (local(to)) {
    // From another rank: the message arrives in schedule order; write it behind the commands
    // already queued on `to` (the host copy lives until the frame is finished).
    auto& host = message_rows_.emplace_back(bytes);
    cluster_->recv(layout_.rank_of(from), host.data(), bytes);
    cl::Event in;
    queue(to).enqueueWriteBuffer(dst, CL_FALSE, offset, bytes, host.data(), nullptr, &in);
    record(Stage::Transfer, to, in);
    bytes_this_frame_ += bytes;
  }
}

FrameStats StereoPipeline::render(unsigned frame, float time_s) {
  return render(frame, evaluate_camera(scene_, time_s));
}

FrameStats StereoPipeline::render(unsigned frame, const Camera& centre) {
  using clock_type = std::chrono::steady_clock;
  const auto t0 = clock_type::now();
  events_.clear();
  bytes_this_frame_ = 0;
  if (cluster_) cluster_->reset_traffic();
  // Stage 1, scene update: this frame's camera constants, passed to every launch.
  const std::array<CameraParams, 2> cams = {
      make_eye_camera(centre, Eye::Left, scene_.ipd_units(), width_, height_),
      make_eye_camera(centre, Eye::Right, scene_.ipd_units(), width_, height_)};
  const cl_uint zero = 0;
  const int n = layout_.count();
  for (int d = 0; d < n; ++d) {
    if (!local(d)) continue;
    queue(d).enqueueFillBuffer(buffers_[d].nonfinite, zero, 0, sizeof(cl_uint));
    queue(d).enqueueFillBuffer(buffers_[d].nonfinite_pixels, zero, 0, sizeof(cl_uint));
    queue(d).enqueueFillBuffer(buffers_[d].hole_count, zero, 0, sizeof(cl_uint));
  }

  for (const StageWork& work : schedule_.stages) {
    if (work.stage == Stage::Denoise) {
      denoise(work, cams);
      continue;
    }
    for (int d = 0; d < n; ++d) {
      // Another rank's device: it runs there; only transfers involve this rank (transfer()
      // sends or receives when one end is here).
      if (!local(d) && work.stage != Stage::Transfer) continue;
      for (const RowRange& r : work.left_rows[d]) {
        switch (work.stage) {
          case Stage::PathTraceLeft: path_trace(d, 0, r, cams[0], frame, Stage::PathTraceLeft); break;
          case Stage::GBuffer: {
            const unsigned m = gbuffer_margin();
            gbuffer(d, 0, {r.begin > m ? r.begin - m : 0u, std::min(height_, r.end + m)}, cams[0]);
            break;
          }
          case Stage::Tonemap: tonemap(d, 0, r); break;
          // Baseline transfers the left radiance (before the owner's G-buffer); the others
          // transfer finished images.
          case Stage::Transfer:
            transfer(d, 0, r, schedule_.pipeline == PipelineKind::Baseline || options_.gather_radiance,
                     schedule_.pipeline != PipelineKind::Baseline);
            break;
          default: break;
        }
      }
      for (const RowRange& r : work.right_rows[d]) {
        switch (work.stage) {
          case Stage::PathTraceRight: path_trace(d, 1, r, cams[1], frame, Stage::PathTraceRight); break;
          case Stage::GBuffer: {
            const unsigned m = gbuffer_margin();
            gbuffer(d, 1, {r.begin > m ? r.begin - m : 0u, std::min(height_, r.end + m)}, cams[1]);
            break;
          }
          case Stage::Reproject: reproject(d, r, cams[0]); break;
          case Stage::HoleFill: fill_holes(d, r, cams[1], frame); break;
          case Stage::Tonemap: tonemap(d, 1, r); break;
          case Stage::Transfer: transfer(d, 1, r, options_.gather_radiance, true); break;
          default: break;
        }
      }
    }
  }
  devices_.finish_all();
  if (cluster_) cluster_->wait_sends();
  message_rows_.clear();
  if (options_.denoise) {
    // Stage 7: this frame's G-buffers and SVGF history become the previous frame's.
    for (auto& b : buffers_) {
      if (!b.svgf[0]) continue;  // another rank's device
      for (int e = 0; e < 2; ++e) {
        std::swap(b.gbuffer[e], b.gbuffer_prev[e]);
        b.svgf[e]->end_frame();
      }
      b.staging_halo.readers.clear();
      b.staging_gbuffer.readers.clear();
    }
    prev_cams_ = cams;
    if (const StageWork* dn = schedule_.find(Stage::Denoise))
      for (int e = 0; e < 2; ++e) history_strips_[e] = device_spans(*dn, e);
  }

  FrameStats stats;
  stats.frame = frame;
  stats.wall_ms = std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
  std::map<std::pair<Stage, int>, double> sums;
  for (auto& [key, e] : events_) {
    sums[key] += event_ms(e);
    stats.spans.push_back({key.first, key.second, e.getProfilingInfo<CL_PROFILING_COMMAND_START>(),
                           e.getProfilingInfo<CL_PROFILING_COMMAND_END>()});
  }
  for (auto& [key, ms] : sums) stats.stages.push_back({key.first, key.second, ms});
  stats.right_pixels = static_cast<std::size_t>(width_) * height_;
  const StageWork* fill = schedule_.find(Stage::HoleFill);
  std::uint64_t holes = 0, bad_total = 0, bad_pixels = 0;
  for (int d = 0; d < n; ++d) {
    if (!local(d)) continue;
    cl_uint count = 0, bad = 0, bad_px = 0;
    auto& q = queue(d);
    q.enqueueReadBuffer(buffers_[d].nonfinite, CL_FALSE, 0, sizeof(cl_uint), &bad);
    q.enqueueReadBuffer(buffers_[d].nonfinite_pixels, CL_FALSE, 0, sizeof(cl_uint), &bad_px);
    if (fill) q.enqueueReadBuffer(buffers_[d].hole_count, CL_FALSE, 0, sizeof(cl_uint), &count);
    q.finish();
    holes += count;  // one reprojection launch per device and frame at most, in either pipeline
    bad_total += bad;
    bad_pixels += bad_px;
  }
  std::uint64_t bytes = bytes_this_frame_;
  if (cluster_) {
    // Rank 0 reports the whole frame: every rank's counts, stage times and traffic.
    holes = cluster_->sum(holes);
    bad_total = cluster_->sum(bad_total);
    bad_pixels = cluster_->sum(bad_pixels);
    bytes = cluster_->sum(bytes);
    std::vector<double> mine;
    for (const StageTiming& t : stats.stages) mine.insert(mine.end(), {double(int(t.stage)), double(t.device), t.ms});
    const std::vector<double> all_stages = cluster_->gather(mine);
    std::vector<double> traffic(cluster_->bytes_sent_to().begin(), cluster_->bytes_sent_to().end());
    traffic.push_back(cluster_->mpi_ms());
    const std::vector<double> all_traffic = cluster_->gather(traffic);
    if (cluster_->rank() == 0) {
      stats.stages.clear();
      for (std::size_t i = 0; i + 2 < all_stages.size(); i += 3)
        stats.stages.push_back({static_cast<Stage>(int(all_stages[i])), int(all_stages[i + 1]), all_stages[i + 2]});
      const int ranks = cluster_->size();
      for (int r = 0; r < ranks; ++r) {
        const double* row = all_traffic.data() + static_cast<std::size_t>(r) * (ranks + 1);
        stats.mpi_bytes.emplace_back(row, row + ranks);
        stats.mpi_ms.push_back(row[ranks]);
      }
    }
  }
  nonfinite_total_ += bad_total;
  stats.bytes_transferred = bytes;
  stats.nonfinite_pixels = bad_pixels;
  stats.reprojected = fill ? stats.right_pixels - holes : 0;
  return stats;
}

unsigned StereoPipeline::gbuffer_margin() const {
  // Reprojection checks the 3x3 neighbourhood of every pixel it touches: one row beyond the
  // strip, in both eyes.
  const unsigned reprojection = schedule_.find(Stage::Reproject) ? 1u : 0u;
  if (!options_.denoise || options_.seams == SeamMode::Independent) return reprojection;
  if (options_.seams == SeamMode::Bilateral) return std::max(reprojection, options_.seam_band + 3);
  // Halo: the widest read of any pass: a-trous taps at 2 * 2^(iterations-1), history taps at
  // temporal_rows + 1, the variance estimate at 3; plus one row for the depth gradient.
  const unsigned atrous = 2u << (options_.svgf.iterations - 1);
  return std::max({atrous, options_.svgf.temporal_rows + 1, 3u}) + 1;
}

std::vector<RowRange> StereoPipeline::widen(const std::vector<RowRange>& strip, unsigned radius) const {
  std::vector<RowRange> out(strip.size());
  for (std::size_t d = 0; d < strip.size(); ++d)
    if (strip[d].size() > 0)
      out[d] = {strip[d].begin > radius ? strip[d].begin - radius : 0u, std::min(height_, strip[d].end + radius)};
  return out;
}

template <typename BufferOf>
void StereoPipeline::exchange_halo(BufferOf buffer, const std::vector<RowRange>& strip, unsigned radius) {
  exchange_rows(buffer, strip, widen(strip, radius), sizeof(cl_float4), &DeviceBuffers::staging_halo);
}

template <typename BufferOf>
void StereoPipeline::exchange_rows(BufferOf buffer, const std::vector<RowRange>& owned,
                                   const std::vector<RowRange>& needed, std::size_t texel,
                                   HaloStaging DeviceBuffers::*staging) {
  const int n = layout_.count();
  for (int d = 0; d < n; ++d) {
    if (needed[d].size() == 0) continue;
    for (int src = 0; src < n; ++src) {
      if (src == d || owned[src].size() == 0 || (!local(d) && !local(src))) continue;
      // The owned ranges are disjoint, so this never overwrites rows d holds itself.
      const unsigned a = std::max(needed[d].begin, owned[src].begin), b = std::min(needed[d].end, owned[src].end);
      if (a >= b) continue;
      const std::size_t off = static_cast<std::size_t>(a) * width_ * texel;
      const std::size_t len = static_cast<std::size_t>(b - a) * width_ * texel;
      HaloStaging& st = buffers_[src].*staging;
      // Another rank's device has no buffer here: copy_rows only touches the local end.
      static const cl::Buffer none;
      copy_rows(src, local(src) ? buffer(src) : none, d, local(d) ? buffer(d) : none, off, len,
                [&]() -> const cl::Buffer& {
                  if (!st.buffer())
                    st.buffer = cl::Buffer(devices_.context(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR,
                                           static_cast<std::size_t>(width_) * height_ * texel);
                  return st.buffer;
                },
                off, &st.readers);
    }
  }
}

void StereoPipeline::set_strips(const std::vector<RowRange>& strips) {
  if (strips == schedule_.strips) return;
  // make_schedule checks the strips and refuses the baseline pipeline; the history moves in
  // the next frame's denoising, from history_strips_ to the new strips.
  schedule_ = make_schedule(options_.pipeline, layout_.count(), height_, options_.denoise, strips);
}

void StereoPipeline::denoise(const StageWork& work, const std::array<CameraParams, 2>& cams) {
  const int n = layout_.count();
  const bool halo = options_.seams == SeamMode::Halo;
  const RowRange image{0, height_};
  for (int e = 0; e < 2; ++e) {
    const std::vector<RowRange> strip = device_spans(work, e);
    auto readable = [&](int d) { return halo ? image : strip[d]; };
    auto svgf = [&](int d) -> SvgfDenoiser& { return *buffers_[d].svgf[e]; };
    const CameraParams prev = prev_cams_ ? (*prev_cams_)[e] : cams[e];
    const auto& o = options_.svgf;
    // Last frame's history lives with last frame's strips. The temporal pass reads it within
    // temporal_rows of each pixel (halo seams) or within the strip (otherwise): fetch those
    // rows from whichever device holds them — the neighbours' halo rows, and, when the strips
    // moved, the rows this device took over (with their G-buffer, which the history test reads).
    const std::vector<RowRange>& held = history_strips_[e].empty() ? strip : history_strips_[e];
    const bool moved = held != strip;
    const std::vector<RowRange> history_rows = widen(strip, halo ? o.temporal_rows + 1 : 0);
    if (halo || moved) {
      exchange_rows([&](int d) -> const cl::Buffer& { return svgf(d).history_illum_prev(); }, held, history_rows,
                    sizeof(cl_float4), &DeviceBuffers::staging_halo);
      exchange_rows([&](int d) -> const cl::Buffer& { return svgf(d).history_moments_prev(); }, held, history_rows,
                    sizeof(cl_float4), &DeviceBuffers::staging_halo);
    }
    if (moved)
      exchange_rows([&](int d) -> const cl::Buffer& { return buffers_[d].gbuffer_prev[e]; }, held, history_rows,
                    sizeof(GBufferTexel), &DeviceBuffers::staging_gbuffer);
    for (int d = 0; d < n; ++d)
      if (local(d))
        svgf(d).temporal(buffers_[d].radiance[e], buffers_[d].albedo[e], buffers_[d].gbuffer[e], buffers_[d].gbuffer_prev[e], prev, strip[d],
                       readable(d));
    if (halo) {
      exchange_halo([&](int d) -> const cl::Buffer& { return svgf(d).illum(); }, strip, 3);
      exchange_halo([&](int d) -> const cl::Buffer& { return svgf(d).moments(); }, strip, gbuffer_margin());
    }
    for (int d = 0; d < n; ++d)
      if (local(d)) svgf(d).variance(buffers_[d].gbuffer[e], strip[d], readable(d));
    for (unsigned i = 0; i < o.iterations; ++i) {
      if (halo) exchange_halo([&](int d) -> const cl::Buffer& { return svgf(d).illum(); }, strip, 2u << i);
      for (int d = 0; d < n; ++d)
        if (local(d)) svgf(d).atrous(i, buffers_[d].gbuffer[e], strip[d], readable(d));
    }
    for (int d = 0; d < n; ++d)
      if (local(d)) svgf(d).remodulate(buffers_[d].radiance[e], buffers_[d].albedo[e], strip[d]);
    if (options_.seams == SeamMode::Bilateral && n > 1) {
      exchange_halo([&](int d) -> const cl::Buffer& { return buffers_[d].radiance[e]; }, strip,
                    options_.seam_band + 2);
      for (int d = 0; d < n; ++d) {
        if (strip[d].size() == 0 || !local(d)) continue;
        const int above = strip[d].begin > 0 ? static_cast<int>(strip[d].begin) : -1;
        const int below = strip[d].end < height_ ? static_cast<int>(strip[d].end) : -1;
        svgf(d).seam_filter(buffers_[d].radiance[e], buffers_[d].gbuffer[e], strip[d], image, above, below,
                            static_cast<int>(options_.seam_band));
      }
    }
    for (int d = 0; d < n; ++d)
      if (local(d))
        for (auto& [stage, ev] : svgf(d).take_events()) record(stage, d, ev);
  }
}

std::vector<std::uint8_t> StereoPipeline::hole_mask() {
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(width_) * height_, 0);
  const StageWork* fill = schedule_.find(Stage::HoleFill);
  if (!fill) return mask;
  for (int d = 0; d < layout_.count(); ++d) {
    if (fill->right_rows[d].empty() || !local(d)) continue;
    auto& q = queue(d);
    cl_uint count = 0;
    q.enqueueReadBuffer(buffers_[d].hole_count, CL_TRUE, 0, sizeof(cl_uint), &count);
    std::vector<cl_uint> list(count);
    if (count) q.enqueueReadBuffer(buffers_[d].holes, CL_TRUE, 0, count * sizeof(cl_uint), list.data());
    for (cl_uint p : list) mask.at(p) = 1;
  }
  return mask;
}

std::vector<GBufferTexel> StereoPipeline::gbuffer_of(int eye) {
  std::vector<GBufferTexel> out(static_cast<std::size_t>(width_) * height_);
  const StageWork* g = schedule_.find(Stage::GBuffer);
  if (!g) return out;
  for (int d = 0; d < layout_.count(); ++d)
    for (const RowRange& r : eye == 0 ? g->left_rows[d] : g->right_rows[d]) {
      if (!local(d)) continue;
      const std::size_t first = static_cast<std::size_t>(r.begin) * width_, count = static_cast<std::size_t>(r.size()) * width_;
      queue(d).enqueueReadBuffer(buffers_[d].gbuffer[eye], CL_TRUE, first * sizeof(GBufferTexel),
                                                    count * sizeof(GBufferTexel), out.data() + first);
    }
  return out;
}

std::array<ImageRGB, 2> StereoPipeline::radiance() {
  if (!options_.gather_radiance && layout_.count() > 1)
    throw std::logic_error("radiance(): the pipeline gathers RGBA8 only (Options::gather_radiance is off)");
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  if (!holds_frame()) throw std::logic_error("only rank 0 holds the finished frame");
  auto& q = queue(schedule_.tree.root);
  std::array<ImageRGB, 2> out;
  for (int e = 0; e < 2; ++e) {
    std::vector<cl_float4> px(pixels);
    q.enqueueReadBuffer(buffers_[schedule_.tree.root].radiance[e], CL_TRUE, 0, pixels * sizeof(cl_float4), px.data());
    out[e].width = static_cast<int>(width_);
    out[e].height = static_cast<int>(height_);
    out[e].rgb.resize(pixels * 3);
    for (std::size_t i = 0; i < pixels; ++i)
      for (int c = 0; c < 3; ++c) out[e].rgb[i * 3 + c] = px[i].s[c];
  }
  return out;
}

std::array<std::vector<std::uint8_t>, 2> StereoPipeline::rgba8() {
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  if (!holds_frame()) throw std::logic_error("only rank 0 holds the finished frame");
  auto& q = queue(schedule_.tree.root);
  std::array<std::vector<std::uint8_t>, 2> out;
  for (int e = 0; e < 2; ++e) {
    out[e].resize(pixels * 4);
    q.enqueueReadBuffer(buffers_[schedule_.tree.root].rgba[e], CL_TRUE, 0, pixels * 4, out[e].data());
  }
  return out;
}

}  // namespace px
