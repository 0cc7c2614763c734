#include "pipeline/stereo_pipeline.h"

#include "cl/profiling.h"
#include "pipeline/stages/direct_light_stage.h"
#include "pipeline/stages/gbuffer_stage.h"
#include "pipeline/stages/hole_fill_stage.h"
#include "pipeline/stages/reproject_stage.h"
#include "pipeline/stages/tonemap_stage.h"
#include "pipeline/stages/transfer_stage.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

namespace px {

StereoPipeline::StereoPipeline(DeviceSet& devices, const DeviceScene& device_scene, const Scene& scene, unsigned width,
                               unsigned height, Options options)
    : devices_(devices),
      cluster_(options.cluster && options.cluster->distributed() ? options.cluster : nullptr),
      layout_{cluster_ ? cluster_->rank() : 0, cluster_ ? cluster_->size() : 1, devices.size()},
      scene_(scene),
      width_(width),
      height_(height),
      options_(options),
      schedule_(make_schedule(options.pipeline, layout_.count(), height, options.denoise.has_value(), {},
                              wants_gbuffer(options), wants_direct_light_stage(options))),
      images_(layout_.count()),
      lanes_(devices, !cluster_ && wants_side_queue(options.overlap, devices)),
      transfer_(devices, layout_, cluster_, width, height, log_, lanes_),
      env_{devices, layout_, device_scene, scene, width, height, images_, log_, transfer_, lanes_} {
  if (width == 0 || height == 0 || width > 65535 || height > 65535)
    throw std::invalid_argument("image size must be between 1 and 65535 per side");
  // Set frame by frame on the path-tracing stage (render), never from the options given.
  options.trace.every_sample_on_gbuffer_ray = options.trace.same_kind_samples = false;
  if (options.aovs.any() && cluster_)
    throw std::invalid_argument("auxiliary images (--aov) are read in one process only, not across MPI ranks");
  for (int d = 0; d < layout_.count(); ++d)
    if (local(d)) images_[d] = FrameImages::allocate(devices.context(), width, height);
  // The units, each registered for the stages it runs (adding a stage: its unit here, its row
  // in the pipelines' tables).
  path_trace_ =
      &add_unit<PathTraceStage>({Stage::PathTraceLeft, Stage::PathTraceRight}, options.trace, options.path_kernel);
  add_unit<GBufferStage>({Stage::GBuffer});
  add_unit<ReprojectStage>({Stage::Reproject});
  add_unit<HoleFillStage>({Stage::HoleFill}, *path_trace_, options.hole_fill);
  if (wants_direct_light_stage(options))
    add_unit<DirectLightStage>({Stage::DirectLight}, options.restir, *path_trace_,
                               options.pipeline != PipelineKind::Mono);
  if (options.denoise) denoise_ = &add_unit<DenoiseStage>({Stage::Denoise}, *options.denoise, path_trace_);
  add_unit<TonemapStage>({Stage::Tonemap}, options.tonemap);
  add_unit<TransferStage>({Stage::Transfer},
                          TransferStage::Options{options.gather_radiance, options.denoise.has_value()});
  for (const StageWork& w : schedule_.stages) unit(w.stage);  // every scheduled stage has a unit
  set_quality(quality());                                     // the one check of spp and bounces
}

StageUnit& StereoPipeline::unit(Stage stage) {
  const auto it = unit_of_.find(stage);
  if (it == unit_of_.end())
    throw std::logic_error(std::string("no unit runs the scheduled stage '") + stage_name(stage) + "'");
  return *it->second;
}

unsigned StereoPipeline::gbuffer_margin(const FrameSchedule& schedule, const Options& options) {
  unsigned margin = 0;
  for (const StageWork& w : schedule.stages) {
    if (w.stage == Stage::Reproject) margin = std::max(margin, ReprojectStage::gbuffer_rows_read());
    if (w.stage == Stage::Denoise && options.denoise)
      margin = std::max(margin, DenoiseStage::gbuffer_rows_read(*options.denoise));
  }
  return margin;
}

void StereoPipeline::set_quality(const FrameQuality& q) {
  if (q.spp == 0) throw std::invalid_argument("spp must be at least 1");
  if (q.bounces > PathTracer::kMaxBounces)
    throw std::invalid_argument("bounces must be at most " + std::to_string(PathTracer::kMaxBounces));
  if (denoise_) denoise_->set_iterations(q.svgf_iterations);  // checks the range
  path_trace_->options().spp = options_.trace.spp = q.spp;
  path_trace_->options().bounces = options_.trace.bounces = q.bounces;
  if (denoise_) options_.denoise->svgf.iterations = q.svgf_iterations;
}

FrameQuality StereoPipeline::quality() const {
  // Without denoising: the iterations a denoiser would start with (what the control loop keeps).
  return {options_.trace.spp, options_.trace.bounces,
          options_.denoise.value_or(DenoiseStage::Options{}).svgf.iterations};
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

FrameStats StereoPipeline::render(unsigned frame, float time_s) {
  return render(frame, evaluate_camera(scene_, time_s));
}

namespace {

// Selects a lane for what a unit enqueues (and records) until the scope ends, even by an
// exception: the main lane is what everything outside the executor expects.
class LaneScope {
 public:
  LaneScope(QueueLanes& lanes, EventLog& log, int lane) : lanes_(lanes), log_(log) {
    lanes_.select(lane);
    log_.set_lane(lanes_.selected());
  }
  ~LaneScope() {
    lanes_.select(QueueLanes::kMain);
    log_.set_lane(QueueLanes::kMain);
  }
  LaneScope(const LaneScope&) = delete;
  LaneScope& operator=(const LaneScope&) = delete;

 private:
  QueueLanes& lanes_;
  EventLog& log_;
};

}  // namespace

bool StereoPipeline::still_view(const Camera& centre) const {
  if (!last_centre_ || last_centre_->up != centre.up || last_centre_->vfov_deg != centre.vfov_deg) return false;
  // Unmoved within a millionth of the viewing distance (a camera path sampled microseconds apart
  // is still): far below a pixel's angle at any image size.
  const float reach = 1e-6f * glm::length(centre.target - centre.position);
  if (glm::length(last_centre_->position - centre.position) > reach ||
      glm::length(last_centre_->target - centre.target) > reach)
    return false;
  for (int d = 0; d < layout_.count(); ++d)
    if (local(d) && env_.scene_on(d).motion()) return false;
  return true;
}

FrameStats StereoPipeline::render(unsigned frame, const Camera& centre) {
  using clock_type = std::chrono::steady_clock;
  const auto t0 = clock_type::now();
  // Where the samples of a denoised frame go (PathTracer::Options::every_sample_on_gbuffer_ray). In a
  // still view, every sample along the G-buffer's ray: the anti-aliasing covers the pixel over frames
  // (the jitter moves), and samples spread within a frame mixed surfaces under one texel that the
  // denoiser then darkened (a lamp's rim). Where the view or the scene moves, spread: the
  // anti-aliasing keeps less history there, and the frame's own samples are what smooth an edge.
  const bool denoised = options_.denoise.has_value() && options_.trace.first_sample_on_gbuffer_ray;
  const bool every = denoised && still_view(centre);
  // Spread, a pixel counts only the samples of its first one's kind (emitter or not).
  path_trace_->set_sample_placement(every, denoised && !every);
  last_centre_ = centre;
  log_.clear();
  transfer_.reset_bytes();
  if (cluster_) cluster_->reset_traffic();
  // Stage 1, scene update: this frame's camera constants, passed to every launch.
  const std::array<float, 2> jitter = pixel_jitter(options_.jitter, frame);
  const FrameInputs in{frame,
                       {make_eye_camera(centre, Eye::Left, scene_.ipd_units(), width_, height_, jitter),
                        make_eye_camera(centre, Eye::Right, scene_.ipd_units(), width_, height_, jitter)}};
  const int n = layout_.count();
  for (int d = 0; d < n; ++d)
    if (local(d)) images_[d].zero_counters(main_queue(d));

  // The executor: each run of consecutive operations of one stage and lane goes to that stage's
  // unit, on that lane. What an operation waits for on the other lane becomes a barrier on its
  // device's lane (and its receiver's, for a transfer) before the batch: the markers enqueued on
  // the waited-for operations' devices after their batches. Waits on the same lane are kept by
  // the queues' order and the transfers' events.
  const std::vector<Operation> ops = operations();
  const int local_n = devices_.size();  // lanes exist only in one process: global = local indices
  std::vector<std::size_t> batch_of(ops.size());
  std::vector<std::vector<cl::Event>> done;  // per batch and device: a marker after the batch
  for (std::size_t i = 0; i < ops.size();) {
    const int lane = ops[i].lane;
    std::vector<const Operation*> batch;
    std::vector<std::vector<cl::Event>> waits(static_cast<std::size_t>(local_n));  // per device
    std::size_t j = i;
    for (; j < ops.size() && ops[j].stage == ops[i].stage && ops[j].lane == lane; ++j) {
      batch.push_back(&ops[j]);
      batch_of[j] = done.size();
      if (!lanes_.has_side()) continue;
      for (std::size_t a : ops[j].after) {
        if (ops[a].lane == lane) continue;
        for (int at : {ops[a].device, ops[a].to})
          if (at >= 0)
            for (int on : {ops[j].device, ops[j].to})
              if (on >= 0) waits[on].push_back(done[batch_of[a]][at]);
      }
    }
    for (int d = 0; d < local_n; ++d)
      if (!waits[d].empty()) lanes_.lane(d, lane).enqueueBarrierWithWaitList(&waits[d]);
    {
      const LaneScope on_lane(lanes_, log_, lane);
      unit(ops[i].stage).run(batch, in);
    }
    std::vector<cl::Event> markers(static_cast<std::size_t>(local_n));
    if (lanes_.has_side())
      for (int d = 0; d < local_n; ++d) {
        lanes_.lane(d, lane).enqueueMarkerWithWaitList(nullptr, &markers[d]);
        // OpenCL requires a flush before another queue's commands may wait on these events.
        lanes_.lane(d, lane).flush();
      }
    done.push_back(std::move(markers));
    i = j;
  }
  lanes_.finish_all();
  transfer_.end_frame();
  if (options_.aovs.any()) capture_aovs();
  // Stage 7: what a unit keeps for the next frame becomes the previous frame's (SVGF history
  // and G-buffer).
  for (const auto& u : units_) u->end_frame(in);

  FrameStats stats;
  stats.frame = frame;
  stats.wall_ms = std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
  std::map<std::pair<Stage, int>, double> sums;
  for (const EventLog::Entry& entry : log_.entries()) {
    sums[{entry.stage, entry.device}] += event_ms(entry.event);
    stats.spans.push_back({entry.stage, entry.device, entry.event.getProfilingInfo<CL_PROFILING_COMMAND_START>(),
                           entry.event.getProfilingInfo<CL_PROFILING_COMMAND_END>(), entry.pass, entry.lane});
  }
  for (auto& [key, ms] : sums) stats.stages.push_back({key.first, key.second, ms});
  stats.right_pixels = static_cast<std::size_t>(width_) * height_;
  const StageWork* fill = schedule_.find(Stage::HoleFill);
  std::uint64_t holes = 0, bad_total = 0, bad_pixels = 0;
  for (int d = 0; d < n; ++d) {
    if (!local(d)) continue;
    cl_uint count = 0, bad = 0, bad_px = 0;
    auto& q = main_queue(d);
    q.enqueueReadBuffer(images_[d].nonfinite_paths, CL_FALSE, 0, sizeof(cl_uint), &bad);
    q.enqueueReadBuffer(images_[d].nonfinite_pixels, CL_FALSE, 0, sizeof(cl_uint), &bad_px);
    if (fill) q.enqueueReadBuffer(images_[d].hole_count, CL_FALSE, 0, sizeof(cl_uint), &count);
    q.finish();
    holes += count;  // one reprojection launch per device and frame at most, in either pipeline
    bad_total += bad;
    bad_pixels += bad_px;
  }
  std::uint64_t bytes = transfer_.bytes_this_frame();
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

void StereoPipeline::set_strips(const std::vector<RowRange>& strips) {
  if (strips == schedule_.strips) return;
  // make_schedule checks the strips and refuses the baseline pipeline; the history moves to the
  // new strips in the next frame's denoising (DenoiseStage).
  schedule_ = make_schedule(options_.pipeline, layout_.count(), height_, options_.denoise.has_value(), strips,
                            wants_gbuffer(options_), wants_direct_light_stage(options_));
}

std::vector<std::uint8_t> StereoPipeline::hole_mask() {
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(width_) * height_, 0);
  const StageWork* fill = schedule_.find(Stage::HoleFill);
  if (!fill) return mask;
  for (int d = 0; d < layout_.count(); ++d) {
    if (fill->right_rows[d].empty() || !local(d)) continue;
    auto& q = main_queue(d);
    cl_uint count = 0;
    q.enqueueReadBuffer(images_[d].hole_count, CL_TRUE, 0, sizeof(cl_uint), &count);
    std::vector<cl_uint> list(count);
    if (count) q.enqueueReadBuffer(images_[d].holes, CL_TRUE, 0, count * sizeof(cl_uint), list.data());
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
      const std::size_t first = static_cast<std::size_t>(r.begin) * width_,
                        count = static_cast<std::size_t>(r.size()) * width_;
      // With the denoiser, end_frame() swapped the frame's G-buffer into its history.
      const cl::Buffer& gbuffer = denoise_ ? denoise_->last_gbuffer(d, eye) : images_[d].gbuffer[eye];
      main_queue(d).enqueueReadBuffer(gbuffer, CL_TRUE, first * sizeof(GBufferTexel), count * sizeof(GBufferTexel),
                                      out.data() + first);
    }
  return out;
}

std::vector<int> StereoPipeline::row_owners(int eye, std::initializer_list<Stage> writes) const {
  std::vector<int> owner(height_, -1);
  for (const StageWork& w : schedule_.stages) {
    if (std::find(writes.begin(), writes.end(), w.stage) == writes.end()) continue;
    const auto& rows = eye == 0 ? w.left_rows : w.right_rows;
    for (std::size_t d = 0; d < rows.size(); ++d)
      for (const RowRange& r : rows[d])
        for (unsigned y = r.begin; y < r.end; ++y) owner[y] = static_cast<int>(d);
  }
  return owner;
}

void StereoPipeline::capture_aovs() {
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  // Reads the texels of every row of `image` (per device: its buffer for that eye) from the
  // device `owner` names, one read per run of rows with the same owner.
  auto gather = [&](const std::vector<int>& owner, std::array<cl::Buffer, 2> FrameImages::*image, int eye,
                    std::size_t texel, void* out) {
    for (unsigned y = 0; y < height_;) {
      const int d = owner[y];
      if (d < 0 || !local(d))
        throw std::logic_error("auxiliary images: no device of this process wrote row " + std::to_string(y));
      unsigned end = y + 1;
      while (end < height_ && owner[end] == d) ++end;
      const std::size_t first = static_cast<std::size_t>(y) * width_,
                        count = static_cast<std::size_t>(end - y) * width_;
      main_queue(d).enqueueReadBuffer((images_[d].*image)[eye], CL_FALSE, first * texel, count * texel,
                                      static_cast<char*>(out) + first * texel);
      y = end;
    }
    for (int d = 0; d < layout_.count(); ++d)
      if (local(d)) main_queue(d).finish();
  };
  auto blank = [&](ImageRGB& img) {
    img.width = static_cast<int>(width_);
    img.height = static_cast<int>(height_);
    img.rgb.assign(pixels * 3, 0.0f);
  };
  for (int e = 0; e < 2; ++e) {
    if (options_.aovs.albedo) {
      // The path traces write each pixel's albedo; the right eye's reprojection and hole filling
      // overwrite it where they run.
      std::vector<cl_float4> px(pixels);
      gather(row_owners(e, {Stage::PathTraceLeft, Stage::PathTraceRight, Stage::Reproject, Stage::HoleFill}),
             &FrameImages::albedo, e, sizeof(cl_float4), px.data());
      blank(albedo_aov_[e]);
      for (std::size_t i = 0; i < pixels; ++i)
        for (int c = 0; c < 3; ++c) albedo_aov_[e].rgb[i * 3 + c] = px[i].s[c];
    }
    if (options_.aovs.normal) {
      // Each device's G-buffer rows of the eye (without the margins, which equal their owner's
      // texels): written by its G-buffer pass or its path trace's first sample (the G-buffer's ray).
      if (!schedule_.find(Stage::GBuffer)) throw std::logic_error("auxiliary normals: no G-buffer stage scheduled");
      std::vector<GBufferTexel> g(pixels);
      gather(row_owners(e, {Stage::GBuffer}), &FrameImages::gbuffer, e, sizeof(GBufferTexel), g.data());
      blank(normal_aov_[e]);
      for (std::size_t i = 0; i < pixels; ++i)
        if (g[i].material_class != PX_CLASS_MISS && g[i].prim != PX_NO_HIT)
          for (int c = 0; c < 3; ++c) normal_aov_[e].rgb[i * 3 + c] = g[i].normal[c];
    }
  }
}

std::array<ImageRGB, 2> StereoPipeline::radiance() {
  if (!options_.gather_radiance && layout_.count() > 1)
    throw std::logic_error("radiance(): the pipeline gathers RGBA8 only (Options::gather_radiance is off)");
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  if (!holds_frame()) throw std::logic_error("only rank 0 holds the finished frame");
  auto& q = main_queue(schedule_.tree.root);
  std::array<ImageRGB, 2> out;
  for (int e = 0; e < 2; ++e) {
    std::vector<cl_float4> px(pixels);
    q.enqueueReadBuffer(images_[schedule_.tree.root].radiance[e], CL_TRUE, 0, pixels * sizeof(cl_float4), px.data());
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
  auto& q = main_queue(schedule_.tree.root);
  std::array<std::vector<std::uint8_t>, 2> out;
  for (int e = 0; e < 2; ++e) {
    out[e].resize(pixels * 4);
    q.enqueueReadBuffer(images_[schedule_.tree.root].rgba[e], CL_TRUE, 0, pixels * 4, out[e].data());
  }
  return out;
}

}  // namespace px
