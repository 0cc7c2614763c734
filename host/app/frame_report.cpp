#include "app/frame_report.h"

#include "app/cli_enums.h"
#include "util/statistics.h"

#include <nlohmann/json.hpp>

#include <algorithm>

namespace px {

void RenderTotals::add(const FrameStats& stats) {
  if (frames == 0) first_frame_ms = stats.wall_ms;
  ++frames;
  makespan_ms += stats.wall_ms;
  reprojected += stats.reprojected;
  right_pixels += stats.right_pixels;
  bytes_transferred += stats.bytes_transferred;
}

double RenderTotals::hz() const {
  const double ms = frames > 1 ? makespan_ms - first_frame_ms : makespan_ms;
  return ms > 0 ? 1000.0 * hz_frames() / ms : 0.0;
}

RenderReport::RenderReport(const RenderCommand& cmd, const StereoPipeline::Options& options, int ranks)
    : cmd_(cmd), options_(options), ranks_(ranks), file_(cmd.report) {
  file_.write("{\n  \"frames\": [");
}

void AnimationTotals::add(const SceneAnimator::Update& u) {
  ++frames;
  bytes_last = u.bytes;
  updates.push_back(u);
}

double AnimationTotals::median(double SceneAnimator::Update::*field) const {
  std::vector<double> v;
  for (const auto& u : updates) v.push_back(u.*field);
  return px::median(std::move(v));
}

void RenderReport::add_frame(unsigned frame, const FrameStats& st, const std::vector<RowRange>& strips,
                             const FrameQuality& quality, std::optional<double> predicted_ms,
                             const SceneAnimator::Update* update) {
  nlohmann::json strip_rows = nlohmann::json::array();  // [row0, rows] per device
  for (const RowRange& r : strips) strip_rows.push_back({r.begin, r.size()});
  nlohmann::json stages = nlohmann::json::array();
  for (const auto& s : st.stages)
    stages.push_back({{"stage", static_cast<int>(s.stage)},
                      {"name", stage_name(s.stage)},
                      {"device", s.device},
                      {"device_ms", s.ms}});
  // One line per frame.
  file_.write((first_frame_ ? "\n    " : ",\n    ") +
              nlohmann::json{{"frame", frame},
                             {"wall_ms", st.wall_ms},
                             {"stages", stages},
                             {"right_pixels", st.right_pixels},
                             {"reprojected", st.reprojected},
                             {"bytes_transferred", st.bytes_transferred},
                             {"strips", strip_rows},
                             {"mpi", ranks_ > 1 ? nlohmann::json{{"bytes_sent", st.mpi_bytes}, {"ms", st.mpi_ms}}
                                                : nlohmann::json(nullptr)},
                             {"spp", quality.spp},
                             {"bounces", quality.bounces},
                             {"svgf_iterations", options_.denoise ? quality.svgf_iterations : 0u},
                             {"predicted_ms", predicted_ms ? nlohmann::json(*predicted_ms) : nlohmann::json(nullptr)},
                             {"scene_update", update ? nlohmann::json{{"pose_ms", update->pose_ms},
                                                                      {"bvh_ms", update->bvh_ms},
                                                                      {"upload_ms", update->upload_ms},
                                                                      {"bvh_rebuilt", update->rebuilt},
                                                                      {"bytes", update->bytes}}
                                                     : nlohmann::json(nullptr)}}
                  .dump());
  first_frame_ = false;
}

void RenderReport::finish(const RenderTotals& totals, int devices, DeviceMode device_mode, BvhLayout bvh_layout,
                          const DeviceScene& scene, const StartTimes& start, std::uint64_t nonfinite_paths,
                          const BvhBuildStats& bvh, bool quick_kernels) {
  // How the tree was built: spatial splits as asked, stopped at their budget, or put on trial
  // (large scenes: BvhBuildOptions::split_trial_triangles) and taken or not. A tree from a cache
  // keeps its stats but not its trial.
  const char* splits = bvh.split_trial             ? (bvh.split_trial_taken ? "trial: taken" : "trial: binned kept")
                       : bvh.split_budget_exceeded ? "over budget: binned"
                       : bvh.leaf_triangles > bvh.scene_triangles ? "yes"
                                                                  : "none taken or off";
  // Without denoising: the denoiser's defaults (the keys stay).
  const DenoiseStage::Options denoise = options_.denoise.value_or(DenoiseStage::Options{});
  const nlohmann::json r = {
      {"schema", "parallax-render-report/1"},
      {"scene", cmd_.scene.name},
      {"pipeline", cli_word(options_.pipeline)},
      {"devices", devices},
      {"ranks", ranks_},
      {"device_mode", to_string(device_mode)},
      {"width", cmd_.size.width},
      {"height", cmd_.size.height},
      {"spp", options_.trace.spp},
      {"bounces", options_.trace.bounces},
      {"denoise", options_.denoise.has_value()},
      {"jitter", cli_word(options_.jitter)},
      {"taa_alpha", denoise.svgf.taa_alpha},
      {"path_tracer", cli_word(options_.path_kernel)},
      {"direct_light", cli_word(options_.trace.direct_light)},
      {"restir", StereoPipeline::wants_direct_light_stage(options_)
                     ? nlohmann::json{{"candidates", options_.restir.candidates},
                                      {"neighbours", options_.restir.neighbours},
                                      {"radius", options_.restir.radius},
                                      {"temporal", options_.restir.temporal},
                                      {"stereo_reuse", options_.restir.stereo_reuse}}
                     : nlohmann::json(nullptr)},
      {"bvh_layout", to_string(bvh_layout)},
      {"kernels", cli_word(cmd_.scene.kernels)},
      {"kernel_build", quick_kernels ? "quick" : "optimized"},
      {"kernel_features", kernel_feature_list(scene.kernel_features())},
      {"bvh",
       {{"nodes", bvh.nodes},
        {"leaf_triangles", bvh.leaf_triangles},
        {"depth", bvh.depth},
        {"sah_cost", bvh.sah_cost},
        {"block_leaves", bvh.block_leaves},
        {"build_ms", bvh.build_ms},
        {"spatial_splits", splits},
        {"split_trial_gain", bvh.split_trial ? nlohmann::json(bvh.split_trial_gain) : nlohmann::json(nullptr)},
        {"split_trial_sampled", bvh.split_trial_sampled},
        {"split_trial_ms", bvh.split_trial_ms}}},
      {"scene_device_bytes", scene.bytes_in_context()},
      {"shading_records", to_string(scene.shading_records())},
      {"instances", scene.instance_count()},
      {"instance_bytes", scene.instance_bytes()},
      {"start",
       {{"scene_load_ms", start.load_ms},
        {"bvh_ms", start.bvh_ms},
        {"bvh_from_cache", start.bvh_from_cache},
        {"bvh_validate_ms", start.validate_ms},
        {"bvh_validated_when_cached", start.bvh_validated_when_cached},
        {"bvh_cache_store_ms", start.cache_store_ms},
        {"devices_ms", start.devices_ms},
        {"device_layout_ms", scene.layout_ms()},
        {"device_layout_host_part_ms", scene.host_part_ms()},
        {"device_layout_from_cache", scene.layout_from_cache()},
        {"device_layout_cache_store_ms", scene.layout_store_ms()},
        {"cache_write_background_ms", start.background_cache_write_ms},
        {"scene_hash_ms", start.scene_hash_ms},
        {"upload_ms", scene.upload_ms()},
        {"scene_host_backed", scene.host_backed()},
        {"host_rss_after_start_mib", start.host_rss_after_start_mib}}},
      {"seams", cli_word(denoise.seams)},
      {"balance", cli_word(cmd_.balance)},
      {"target_ms", cmd_.target_ms.empty() ? nlohmann::json(nullptr) : nlohmann::json(cmd_.target_ms)},
      {"frames_requested", cmd_.frames},
      {"frames_done", totals.frames},
      {"interrupted", totals.frames < cmd_.frames},
      {"makespan_ms", totals.makespan_ms},
      {"first_frame_ms", totals.first_frame_ms},
      {"hz", totals.hz()},
      {"hz_frames", totals.hz_frames()},
      {"reprojected_share", totals.right_pixels ? double(totals.reprojected) / totals.right_pixels : 0.0},
      {"bytes_transferred", totals.bytes_transferred},
      {"nonfinite_paths", nonfinite_paths}};
  // The summary's members follow the frames: "{\n  ...\n}" minus its opening brace.
  file_.write("\n  ],\n" + r.dump(2).substr(2) + "\n");
  file_.commit();
}

RenderTimeline::RenderTimeline(const std::string& path) : file_(path) {}

void RenderTimeline::event(const nlohmann::json& e) {
  chunk_ += first_event_ ? "\n" : ",\n";
  chunk_ += e.dump();
  first_event_ = false;
}

void RenderTimeline::flush() {
  file_.write(chunk_);
  chunk_.clear();
}

void RenderTimeline::name_devices(const DeviceSet& devices) {
  file_.write("{\"displayTimeUnit\": \"ms\", \"traceEvents\": [");
  // Two tracks per device: its main queue (tid 2d) and its side queue (2d + 1, queue_lanes.h).
  for (int d = 0; d < devices.size(); ++d) {
    event({{"name", "thread_name"},
           {"ph", "M"},
           {"pid", 0},
           {"tid", 2 * d},
           {"args", {{"name", "device " + std::to_string(d) + ": " + devices.devices()[d].description}}}});
    event({{"name", "thread_name"},
           {"ph", "M"},
           {"pid", 0},
           {"tid", 2 * d + 1},
           {"args", {{"name", "device " + std::to_string(d) + ": side queue"}}}});
  }
  flush();
}

void RenderTimeline::add_frame(unsigned frame, const FrameStats& st) {
  if (origin_ns_ == 0 && !st.spans.empty())
    origin_ns_ = std::min_element(st.spans.begin(), st.spans.end(), [](const StageSpan& a, const StageSpan& b) {
                   return a.start_ns < b.start_ns;
                 })->start_ns;
  for (const auto& sp : st.spans) {
    const double ts = (static_cast<double>(sp.start_ns) - static_cast<double>(origin_ns_)) * 1e-3;
    const std::string name = sp.pass ? std::string(stage_name(sp.stage)) + ": " + sp.pass : stage_name(sp.stage);
    event({{"name", name},
           {"cat", "frame " + std::to_string(frame)},
           {"ph", "X"},
           {"pid", 0},
           {"tid", 2 * sp.device + sp.lane},
           {"ts", ts},
           {"dur", static_cast<double>(sp.end_ns - sp.start_ns) * 1e-3}});
  }
  flush();
}

void RenderTimeline::finish() {
  file_.write("\n]}\n");
  file_.commit();
}

}  // namespace px
