#include "app/render_setup.h"

#include "app/cli_enums.h"
#include "util/statistics.h"

#include <algorithm>
#include <cstdio>

namespace px {
namespace {

// A float as the help shows a default ("0.2").
std::string shortest(float v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", static_cast<double>(v));
  return text;
}

}  // namespace

PipelineConfig make_pipeline_config(const RenderCommand& cmd) {
  if (!(cmd.clock.fps > 0.0f)) throw std::invalid_argument("--fps must be positive");
  PipelineConfig cfg;
  auto& opt = cfg.options;
  opt = cmd.pipeline;
  if (!cmd.aov.empty()) opt.aovs = parse_aov_list(cmd.aov);
  // SVGF's temporal variance is the spread of the luminance moments accumulated over frames.
  // With --alpha-moments 1 nothing is accumulated: from the frame where a pixel's history is
  // long enough for the temporal estimate (4 frames) its variance is exactly 0, every a-trous
  // tap's luminance weight is 0, and the "denoised" image is the noisy one. Never what is meant.
  if (opt.denoise && opt.denoise->svgf.alpha_moments >= 1.0f)
    throw std::invalid_argument(
        "--alpha-moments 1 keeps no moment history: from the 4th frame on SVGF's variance estimate is 0 and "
        "its filter returns the noisy image unchanged; use a value below 1 (default " +
        shortest(SvgfDenoiser::Options{}.alpha_moments) + "), or --no-denoise for the noisy image");
  // --alpha 1 is a real choice (SVGF on each frame alone, e.g. to see the spatial filter), but it
  // switches the colour history off: say so.
  if (opt.denoise && opt.denoise->svgf.alpha >= 1.0f)
    cfg.warnings.push_back(
        "warning: --alpha 1 switches SVGF's colour history off: every frame is filtered from its own samples "
        "alone (no temporal accumulation: noisier, and the image flickers); the default is " +
        shortest(SvgfDenoiser::Options{}.alpha));
  // The control loop, when asked for: limits from the command line (the starting bounces and
  // iterations are the most it may use; spp may rise to --max-spp).
  if (!cmd.target_ms.empty()) {
    FrameTimeController::Options c;
    std::tie(c.lo_ms, c.hi_ms) = FrameTimeController::parse_window(cmd.target_ms);
    if (opt.trace.bounces == 0) throw std::invalid_argument("--target-ms needs --bounces of at least 1");
    c.spp = {1, std::max(cmd.max_spp, opt.trace.spp)};
    c.bounces = {1, opt.trace.bounces};
    // Without denoising the iterations cost nothing and stay where they are (the pipeline's
    // quality() reports the denoiser's default).
    const unsigned iterations = opt.denoise.value_or(DenoiseStage::Options{}).svgf.iterations;
    c.svgf_iterations = {opt.denoise ? 1u : iterations, iterations};
    cfg.controller.emplace(c);
  }
  return cfg;
}

void print_device_set(const DeviceSet& set) {
  std::fprintf(stderr, "[devices] %d on '%s' (%s):\n", set.size(), set.platform_name().c_str(), to_string(set.mode()));
  for (const auto& d : set.devices()) std::fprintf(stderr, "  %d: %s\n", d.index, d.description.c_str());
  std::fprintf(stderr, "  BVH nodes: %s (%s)\n", to_string(set.bvh_layout()),
               set.bvh_layout_requested() ? "requested" : "the default for these devices");
}

void print_scene_upload(const DeviceScene& scene, int devices) {
  std::fprintf(stderr, "[scene] on the devices: %.1f MiB, one copy in the context of its %d device(s) (%.0f ms)\n",
               static_cast<double>(scene.bytes_in_context()) / (1024.0 * 1024.0), devices, scene.upload_ms());
  if (scene.flat_shading())
    std::fprintf(stderr, "[scene] flat triangles without texture coordinates: 16-byte shading records, not 64\n");
  if (scene.indexed_shading())
    std::fprintf(stderr, "[scene] smooth triangles: 16-byte shading records and each vertex's normal and uv once\n");
  if (scene.instance_count() > 0)
    std::fprintf(stderr, "[scene] %zu instances: their top level and records take %.1f KiB of that\n",
                 scene.instance_count(), static_cast<double>(scene.instance_bytes()) / 1024.0);
}

void print_kernel_features(const DeviceScene& scene) {
  if (scene.kernel_choice() == KernelChoice::General)
    std::fprintf(stderr, "[kernels] general: every feature compiled in (the scene uses: %s)\n",
                 describe_kernel_features(scene.scene_features()).c_str());
  else
    std::fprintf(stderr, "[kernels] compiled for the scene's features: %s (--kernels general: all)\n",
                 describe_kernel_features(scene.kernel_features()).c_str());
}

void print_kernel_build(const DeviceSet& set) {
  const KernelBuildDecision& b = set.kernel_build();
  if (!b.quick) return;
  std::fprintf(stderr, "[kernels] quick build, the compiler's optimisation off (the same images): %s\n", b.why.c_str());
}

RenderSession::RenderSession(const RenderCommand& cmd, const StereoPipeline::Options& options)
    : SceneOnDevices(cmd.scene.name, cmd.devices.options(), false, cmd.scene.load_options(), cmd.scene.kernels,
                     StartBuilds::Frames),
      pipeline(devices, device_scene, loaded.scene, cmd.size.width, cmd.size.height, options) {
  print_device_set(devices);
  print_scene_upload(device_scene, devices.size());
  print_kernel_features(device_scene);
  print_kernel_build(devices);
}

std::map<Stage, double> slowest_device_ms(const FrameStats& stats) {
  std::map<Stage, double> out;
  for (const auto& s : stats.stages) out[s.stage] = std::max(out[s.stage], s.ms);
  return out;
}

std::optional<std::pair<Stage, double>> slowest_stage(const FrameStats& stats) {
  std::optional<std::pair<Stage, double>> best;
  for (const auto& [stage, ms] : slowest_device_ms(stats))
    if (!best || ms > best->second) best = {stage, ms};
  return best;
}

void StageSummary::add(const FrameStats& stats) {
  const std::size_t index = wall_ms_.size();
  std::map<Stage, double> total;
  for (const auto& s : stats.stages) total[s.stage] += s.ms;
  for (const auto& [stage, ms] : slowest_device_ms(stats)) {
    // A stage missing from earlier frames counts 0 ms there.
    slowest_[stage].resize(index, 0.0);
    total_[stage].resize(index, 0.0);
    slowest_[stage].push_back(ms);
    total_[stage].push_back(total[stage]);
  }
  wall_ms_.push_back(stats.wall_ms);
  for (auto* m : {&slowest_, &total_})
    for (auto& [stage, v] : *m) v.resize(wall_ms_.size(), 0.0);
}

std::string StageSummary::table(std::size_t skip) const {
  if (wall_ms_.empty()) return "";
  if (skip >= wall_ms_.size()) skip = 0;
  auto tail = [skip](const std::vector<double>& v) { return std::vector<double>(v.begin() + skip, v.end()); };
  std::string out;
  char line[160];
  std::snprintf(line, sizeof line, "  %-18s %14s %14s\n", "stage", "slowest device", "all devices");
  out += line;
  for (const auto& [stage, v] : slowest_) {
    std::snprintf(line, sizeof line, "  %-18s %11.2f ms %11.2f ms\n", stage_name(stage), median(tail(v)),
                  median(tail(total_.at(stage))));
    out += line;
  }
  std::snprintf(line, sizeof line, "  %-18s %11.2f ms   (host, first enqueue to last command)\n", "frame wall",
                median(tail(wall_ms_)));
  out += line;
  return out;
}

}  // namespace px
