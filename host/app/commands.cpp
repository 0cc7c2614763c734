#include "app/commands.h"

#include "app/output_dir.h"
#include "app/scene_setup.h"
#include "image/image_io.h"
#include "image/image_metrics.h"
#include "render/device_scene.h"
#include "render/preview_renderer.h"
#include "render/reference_render.h"
#include "pipeline/stereo_pipeline.h"

#include <nlohmann/json.hpp>
#include <fstream>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>

namespace px {
namespace {

namespace fs = std::filesystem;
using clock_type = std::chrono::steady_clock;

double ms_since(clock_type::time_point t0) {
  return std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
}

void print_device_set(const DeviceSet& set) {
  std::fprintf(stderr, "[devices] %d on '%s' (%s):\n", set.size(), set.platform_name().c_str(), to_string(set.mode()));
  for (const auto& d : set.devices()) std::fprintf(stderr, "  %d: %s\n", d.index, d.description.c_str());
}

std::string frame_name(unsigned frame, const char* what) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "frame_%04u_%s", frame, what);
  return buf;
}

// Writes left/right EXR + PNG and the side-by-side stereo PNG under `dir` with `prefix`.
void write_stereo(const std::string& dir, const std::string& prefix, const std::array<ImageRGB, 2>& eyes,
                  float exposure) {
  std::array<std::vector<std::uint8_t>, 2> png;
  for (int e = 0; e < 2; ++e) {
    const std::string name = prefix + (e == 0 ? "left" : "right");
    write_exr((fs::path(dir) / (name + ".exr")).string(), eyes[e]);
    png[e] = to_srgb8(eyes[e], exposure);
    write_png((fs::path(dir) / (name + ".png")).string(), eyes[e].width, eyes[e].height, png[e]);
  }
  write_png((fs::path(dir) / (prefix + "stereo.png")).string(), 2 * eyes[0].width, eyes[0].height,
            side_by_side(png[0], png[1], eyes[0].width, eyes[0].height));
}

}  // namespace

DeviceSet DeviceChoice::create() const { return DeviceSet::create({count, parse_device_mode(mode), platform}); }

int run_devices(const DeviceChoice& choice) {
  std::printf("%s", describe_platforms().c_str());
  auto set = choice.create();
  std::printf("--devices %d gives (%s mode):\n", set.size(), to_string(set.mode()));
  for (const auto& d : set.devices()) std::printf("  %d: %s\n", d.index, d.description.c_str());
  return 0;
}

int run_preview(const PreviewCommand& cmd) {
  prepare_output_dir(cmd.out, cmd.overwrite);
  auto loaded = load_and_build(cmd.scene);
  auto devices = cmd.devices.create();
  print_device_set(devices);
  DeviceScene device_scene(devices, loaded.scene, loaded.bvh);
  PreviewRenderer renderer(devices, device_scene);
  std::fprintf(stderr, "[preview] %ux%u per eye, t = %.2f s ...\n", cmd.width, cmd.height, cmd.time_s);
  auto t0 = clock_type::now();
  auto eyes = renderer.render(loaded.scene, cmd.time_s, cmd.width, cmd.height);
  std::fprintf(stderr, "[preview] done in %.0f ms (first run includes kernel compilation)\n", ms_since(t0));
  write_stereo(cmd.out, "", eyes, 1.0f);
  std::printf("wrote %s/{left,right}.{exr,png} and %s/stereo.png\n", cmd.out.c_str(), cmd.out.c_str());
  return 0;
}

int run_render(const RenderCommand& cmd) {
  if (cmd.trace.spp == 0) throw std::invalid_argument("--spp must be at least 1");
  if (cmd.frames == 0) throw std::invalid_argument("--frames must be at least 1");
  if (!(cmd.fps > 0.0f)) throw std::invalid_argument("--fps must be positive");
  StereoPipeline::Options opt;
  opt.pipeline = parse_pipeline(cmd.pipeline);
  opt.trace = cmd.trace;
  opt.trace.light_sampling = parse_light_sampling(cmd.light_sampling);
  opt.exposure = cmd.exposure;
  opt.denoise = !cmd.no_denoise;
  opt.svgf = cmd.svgf;
  opt.seams = parse_seam_mode(cmd.seams);
  if (cmd.explain) {
    // The schedule depends only on pipeline, device count, height and denoising: no scene needed.
    std::printf("%s", make_schedule(opt.pipeline, cmd.devices.count, cmd.height, opt.denoise).explain().c_str());
    return 0;
  }
  prepare_output_dir(cmd.out, cmd.overwrite);
  auto loaded = load_and_build(cmd.scene);
  auto devices = cmd.devices.create();
  print_device_set(devices);
  DeviceScene device_scene(devices, loaded.scene, loaded.bvh);
  StereoPipeline pipeline(devices, device_scene, loaded.scene, cmd.width, cmd.height, opt);
  std::fprintf(stderr, "[render] %u frame(s), %ux%u per eye, %u spp, %u bounces, pipeline %s, denoise %s\n", cmd.frames,
               cmd.width, cmd.height, opt.trace.spp, opt.trace.bounces, cmd.pipeline.c_str(),
               opt.denoise ? ("SVGF, seams " + cmd.seams).c_str() : "off");
  nlohmann::json report_frames = nlohmann::json::array();
  // Chrome trace events: one track (tid) per device, one slice per OpenCL command. Device
  // clocks are made relative to the run's first command; devices that do not share a clock
  // (separate GPUs) are only comparable within their own track.
  nlohmann::json trace_events = nlohmann::json::array();
  std::uint64_t trace_origin = 0;
  for (int d = 0; d < devices.size(); ++d)
    trace_events.push_back({{"name", "thread_name"}, {"ph", "M"}, {"pid", 0}, {"tid", d},
                            {"args", {{"name", "device " + std::to_string(d) + ": " + devices.devices()[d].description}}}});
  double makespan_ms = 0.0;
  std::size_t reprojected = 0, right_pixels = 0, bytes = 0;
  for (unsigned f = 0; f < cmd.frames; ++f) {
    const FrameStats st = pipeline.render(f, static_cast<float>(f) / cmd.fps);
    makespan_ms += st.wall_ms;
    reprojected += st.reprojected;
    right_pixels += st.right_pixels;
    bytes += st.bytes_transferred;
    std::fprintf(stderr, "[render] frame %u/%u: %.0f ms, %.1f%% of the right eye reprojected\n", f + 1, cmd.frames,
                 st.wall_ms, st.right_pixels ? 100.0 * st.reprojected / st.right_pixels : 0.0);
    auto eyes = pipeline.radiance();
    auto png = pipeline.rgba8();
    const std::string prefix = frame_name(f, "");
    for (int e = 0; e < 2; ++e) {
      const std::string name = prefix + (e == 0 ? "left" : "right");
      write_exr((fs::path(cmd.out) / (name + ".exr")).string(), eyes[e]);
      write_png((fs::path(cmd.out) / (name + ".png")).string(), eyes[e].width, eyes[e].height, png[e]);
    }
    write_png((fs::path(cmd.out) / (prefix + "stereo.png")).string(), 2 * eyes[0].width, eyes[0].height,
              side_by_side(png[0], png[1], eyes[0].width, eyes[0].height));
    if (trace_origin == 0 && !st.spans.empty())
      trace_origin = std::min_element(st.spans.begin(), st.spans.end(), [](const StageSpan& a, const StageSpan& b) {
                       return a.start_ns < b.start_ns;
                     })->start_ns;
    for (const auto& sp : st.spans) {
      const double ts = (static_cast<double>(sp.start_ns) - static_cast<double>(trace_origin)) * 1e-3;
      trace_events.push_back({{"name", stage_name(sp.stage)}, {"cat", "frame " + std::to_string(f)}, {"ph", "X"},
                              {"pid", 0}, {"tid", sp.device}, {"ts", ts},
                              {"dur", static_cast<double>(sp.end_ns - sp.start_ns) * 1e-3}});
    }
    nlohmann::json stages = nlohmann::json::array();
    for (const auto& s : st.stages)
      stages.push_back({{"stage", static_cast<int>(s.stage)}, {"name", stage_name(s.stage)}, {"device", s.device},
                        {"device_ms", s.ms}});
    report_frames.push_back({{"frame", f}, {"wall_ms", st.wall_ms}, {"stages", stages},
                             {"right_pixels", st.right_pixels}, {"reprojected", st.reprojected},
                             {"bytes_transferred", st.bytes_transferred}});
  }
  if (pipeline.nonfinite_paths() > 0)
    std::fprintf(stderr, "[render] warning: %llu paths had non-finite radiance and were dropped\n",
                 static_cast<unsigned long long>(pipeline.nonfinite_paths()));
  if (!cmd.report.empty()) {
    nlohmann::json r = {{"schema", "parallax-render-report/1"},
                        {"scene", cmd.scene},
                        {"pipeline", cmd.pipeline},
                        {"devices", devices.size()},
                        {"device_mode", to_string(devices.mode())},
                        {"width", cmd.width},
                        {"height", cmd.height},
                        {"spp", opt.trace.spp},
                        {"bounces", opt.trace.bounces},
                        {"denoise", opt.denoise},
                        {"seams", cmd.seams},
                        {"frames", report_frames},
                        {"makespan_ms", makespan_ms},
                        {"hz", makespan_ms > 0 ? 1000.0 * cmd.frames / makespan_ms : 0.0},
                        {"reprojected_share", right_pixels ? double(reprojected) / right_pixels : 0.0},
                        {"bytes_transferred", bytes},
                        {"nonfinite_paths", pipeline.nonfinite_paths()}};
    std::ofstream out(cmd.report);
    if (!out) throw std::runtime_error("cannot write report " + cmd.report);
    out << r.dump(2) << "\n";
    std::fprintf(stderr, "[render] report written to %s\n", cmd.report.c_str());
  }
  if (!cmd.timeline.empty()) {
    std::ofstream out(cmd.timeline);
    if (!out) throw std::runtime_error("cannot write timeline " + cmd.timeline);
    out << nlohmann::json{{"traceEvents", trace_events}, {"displayTimeUnit", "ms"}}.dump() << "\n";
    std::fprintf(stderr, "[render] timeline written to %s (open in chrome://tracing or ui.perfetto.dev)\n",
                 cmd.timeline.c_str());
  }
  std::printf("wrote %u frame(s) to %s (frame_NNNN_{left,right}.{exr,png}, frame_NNNN_stereo.png); %.1f Hz over the run\n",
              cmd.frames, cmd.out.c_str(), makespan_ms > 0 ? 1000.0 * cmd.frames / makespan_ms : 0.0);
  return 0;
}

int run_reference(const ReferenceCommand& cmd) {
  prepare_output_dir(cmd.out, cmd.overwrite);
  auto loaded = load_and_build(cmd.scene);
  auto devices = cmd.devices.create();
  print_device_set(devices);
  DeviceScene device_scene(devices, loaded.scene, loaded.bvh);
  PathTracer tracer(devices, device_scene, loaded.scene);
  ReferenceOptions opt;
  opt.spp = cmd.spp;
  opt.pass_spp = cmd.pass_spp;
  opt.bounces = cmd.bounces;
  auto eyes = render_reference(tracer, static_cast<float>(cmd.frame) / cmd.fps, cmd.frame, cmd.width, cmd.height, opt,
                               eta_printer("reference"));
  write_stereo(cmd.out, "reference_", eyes, cmd.exposure);
  if (tracer.nonfinite_paths() > 0)
    std::fprintf(stderr, "[reference] warning: %llu paths had non-finite radiance and were dropped\n",
                 static_cast<unsigned long long>(tracer.nonfinite_paths()));
  std::printf("wrote %s/reference_{left,right}.exr (%u spp) and PNG previews\n", cmd.out.c_str(), cmd.spp);
  return 0;
}

int run_compare(const CompareCommand& cmd) {
  const auto a = read_image_rgb(cmd.image);
  const auto r = read_image_rgb(cmd.reference);
  const auto d = compare_images(a, r);
  std::printf("psnr_db %.3f\nrel_mse %.6g\nmse %.6g\n", d.psnr_db, d.rel_mse, d.mse);
  return 0;
}

}  // namespace px
