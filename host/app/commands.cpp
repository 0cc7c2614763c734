#include "app/commands.h"

#include "app/cli_enums.h"
#include "app/frame_report.h"
#include "app/output_dir.h"
#include "app/render_setup.h"
#include "app/scene_setup.h"
#include "app/video_writer.h"
#include "cluster/cluster.h"
#include "control/strip_balancer.h"
#include "image/image_io.h"
#include "image/image_metrics.h"
#include "io/interrupt.h"
#include "render/preview_renderer.h"
#include "render/reference_render.h"
#include "render/scene_animator.h"
#include "render/stereo_camera.h"
#include "pipeline/stereo_pipeline.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

namespace px {
namespace {

namespace fs = std::filesystem;
using clock_type = std::chrono::steady_clock;

double ms_since(clock_type::time_point t0) {
  return std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
}

std::string frame_name(unsigned frame, const char* what) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "frame_%04u_%s", frame, what);
  return buf;
}

// Pixels of `image` with a NaN or infinite channel. An image is either finite or the run fails:
// a NaN made before the path loop (camera, primary hit) is not caught by the kernels'
// per-path guard and would otherwise be written as a silently wrong image.
std::size_t count_nonfinite(const ImageRGB& image) {
  std::size_t bad = 0;
  for (std::size_t i = 0; i + 2 < image.rgb.size(); i += 3)
    bad += !(std::isfinite(image.rgb[i]) && std::isfinite(image.rgb[i + 1]) && std::isfinite(image.rgb[i + 2]));
  return bad;
}

void require_finite(const std::array<ImageRGB, 2>& eyes, const std::string& what) {
  for (int e = 0; e < 2; ++e)
    if (const std::size_t bad = count_nonfinite(eyes[e]))
      throw std::runtime_error(what + ": " + std::to_string(bad) + " of " +
                               std::to_string(static_cast<std::size_t>(eyes[e].width) * eyes[e].height) +
                               " pixels of the " + (e == 0 ? "left" : "right") +
                               " eye are NaN or infinite (not written). The scene's coordinates or camera are "
                               "probably beyond what 32-bit floats resolve: scale or recentre it");
}

// The camera at `time_s`, checked before rendering with it. Every key of a camera path is
// valid on load, but interpolating between two keys can still make position meet target (keys
// that swap them) or the view parallel to up: a NaN camera, whose rays miss everything, gave a
// silently black frame with exit 0.
void check_camera(const Scene& scene, float time_s, const std::string& what) {
  const Camera c = evaluate_camera(scene, time_s);
  const glm::vec3 forward = c.target - c.position;
  const glm::vec3 side = glm::cross(forward, c.up);
  const float f2 = glm::dot(forward, forward), s2 = glm::dot(side, side);
  if (std::isfinite(f2) && f2 > 0.0f && std::isfinite(s2) && s2 > 0.0f) return;
  char when[64];
  std::snprintf(when, sizeof when, " (t = %.4g s)", double(time_s));
  throw std::runtime_error(what + when + ": the camera path gives no view direction there (position meets target, "
                                         "or the view is parallel to up); adjust the camera_path keys");
}

// Writes left/right EXR + PNG and the side-by-side stereo PNG under `dir` with `prefix`.
void write_stereo(const OutputDir& dir, const std::string& prefix, const std::array<ImageRGB, 2>& eyes,
                  float exposure) {
  std::array<std::vector<std::uint8_t>, 2> png;
  for (int e = 0; e < 2; ++e) {
    const std::string name = prefix + (e == 0 ? "left" : "right");
    write_exr(dir.file(name + ".exr"), eyes[e]);
    png[e] = to_srgb8(eyes[e], exposure);
    write_png(dir.file(name + ".png"), eyes[e].width, eyes[e].height, png[e]);
  }
  write_png(dir.file(prefix + "stereo.png"), 2 * eyes[0].width, eyes[0].height,
            side_by_side(png[0], png[1], eyes[0].width, eyes[0].height));
}

// Frame `f` of `render`: per eye an EXR (unless --no-exr: `eyes` is then unused) and a PNG,
// the auxiliary EXRs --aov asks for, the side-by-side stereo PNG, and the video's next frame.
void write_render_frame(const RenderCommand& cmd, const OutputDir& dir, unsigned f,
                        const std::array<ImageRGB, 2>& eyes, const std::array<std::vector<std::uint8_t>, 2>& png,
                        const StereoPipeline& pipeline, VideoWriter* video) {
  const std::string prefix = frame_name(f, "");
  const int w = static_cast<int>(cmd.width), h = static_cast<int>(cmd.height);
  // A build without an image codec renders for its report, timeline and video only (said once
  // at the start).
  const bool files = image_codec_available();
  try {
    for (int e = 0; e < 2 && files; ++e) {
      const std::string name = prefix + (e == 0 ? "left" : "right");
      if (!cmd.no_exr) write_exr(dir.file(name + ".exr"), eyes[e]);
      write_png(dir.file(name + ".png"), w, h, png[e]);
      if (!pipeline.albedo_aov()[e].rgb.empty()) write_exr(dir.file(name + "_albedo.exr"), pipeline.albedo_aov()[e]);
      if (!pipeline.normal_aov()[e].rgb.empty()) write_exr(dir.file(name + "_normal.exr"), pipeline.normal_aov()[e]);
    }
    const auto stereo = side_by_side(png[0], png[1], w, h);
    if (files) write_png(dir.file(prefix + "stereo.png"), 2 * w, h, stereo);
    if (video) video->write_frame(stereo);
  } catch (const ImageError& e) {
    // Say what is usable: the frames before this one are complete.
    throw std::runtime_error(std::string(e.what()) + " (frame " + std::to_string(f) + "; " +
                             (f ? "frames 0-" + std::to_string(f - 1) + " in " + cmd.out + " are complete"
                                : std::string("no frame was completed")) + ")");
  }
}

}  // namespace

DeviceOptions DeviceChoice::options() const { return {count, mode, platform}; }

int run_devices(const DeviceChoice& choice) {
  std::printf("%s", describe_platforms().c_str());
  auto set = DeviceSet::create(choice.options());
  std::printf("--devices %d gives (%s mode):\n", set.size(), to_string(set.mode()));
  for (const auto& d : set.devices()) std::printf("  %d: %s\n", d.index, d.description.c_str());
  return 0;
}

int run_preview(const PreviewCommand& cmd) {
  install_interrupt_handlers();
  const OutputDir out_dir(cmd.out, cmd.overwrite);
  SceneOnDevices on_devices(cmd.scene, cmd.devices.options(), false, cmd.sky, cmd.kernels);
  print_device_set(on_devices.devices);
  print_scene_upload(on_devices.device_scene, on_devices.devices.size());
  print_kernel_features(on_devices.device_scene);
  SceneAnimator animator(on_devices.loaded.scene, cmd.animation);
  if (animator.moves()) {
    std::fprintf(stderr, "[preview] animation: %s\n", animator.describe().c_str());
    animator.update(cmd.time_s, on_devices.devices, on_devices.device_scene);
  }
  PreviewRenderer renderer(on_devices.devices, on_devices.device_scene);
  std::fprintf(stderr, "[preview] %ux%u per eye, t = %.2f s ...\n", cmd.width, cmd.height, cmd.time_s);
  check_camera(on_devices.loaded.scene, cmd.time_s, "preview");
  auto t0 = clock_type::now();
  auto eyes = renderer.render(on_devices.loaded.scene, cmd.time_s, cmd.width, cmd.height);
  std::fprintf(stderr, "[preview] done in %.0f ms (first run includes kernel compilation)\n", ms_since(t0));
  require_finite(eyes, "preview");
  write_stereo(out_dir, "", eyes, 1.0f);
  std::printf("wrote %s/{left,right}.{exr,png} and %s/stereo.png\n", cmd.out.c_str(), cmd.out.c_str());
  if (interrupted()) return interrupt_exit_code();
  return 0;
}

int run_render(const RenderCommand& cmd) {
  if (cmd.frames == 0) throw std::invalid_argument("--frames must be at least 1");
  PipelineConfig config = make_pipeline_config(cmd);
  StereoPipeline::Options& opt = config.options;
  std::optional<FrameTimeController>& controller = config.controller;
  const bool dynamic_strips = cmd.balance == StripBalance::Dynamic;
  if (dynamic_strips && !has_movable_strips(opt.pipeline))
    throw std::invalid_argument("--balance dynamic needs the proposed or mono pipeline (baseline already spreads path "
                                "tracing over many shuffled strips and runs the rest on one device)");
  // Under mpirun every rank runs this with the same flags: each drives its own --devices N, the
  // frame is split over all ranks' devices, and rank 0 owns the frame and writes every file.
  Cluster& cluster = Cluster::world();
  const bool distributed = cluster.distributed();
  const bool root = cluster.rank() == 0;
  if (root)
    for (const auto& w : config.warnings) std::fprintf(stderr, "render: %s\n", w.c_str());
  opt.cluster = &cluster;
  opt.gather_radiance = !cmd.no_exr;
  if (opt.aovs.any() && cmd.no_exr)
    throw std::invalid_argument("--aov writes EXR files and --no-exr asks for PNGs only: drop one of them");
  if (opt.aovs.any() && distributed)
    throw std::invalid_argument("--aov is read in one process only: run it without mpirun");
  opt.overlap = cmd.no_overlap ? Overlap::Off : cmd.force_overlap ? Overlap::On : Overlap::Auto;
  if (cmd.explain) {
    if (!root) return 0;
    // The schedule depends only on pipeline, device count, height and denoising: no scene needed.
    const FrameSchedule schedule =
        make_schedule(opt.pipeline, cmd.devices.count * cluster.size(), cmd.height, opt.denoise, {},
                      StereoPipeline::wants_gbuffer(opt));
    std::printf("%s\n%s", schedule.explain().c_str(),
                explain_operations(make_operations(schedule, StereoPipeline::gbuffer_margin(schedule, opt),
                                                  opt.overlap != Overlap::Off && !distributed,
                                                  StereoPipeline::fuses_gbuffer(opt)))
                    .c_str());
    if (opt.overlap != Overlap::Off && !distributed)
      std::printf(cmd.force_overlap ? "lanes: 'side' operations run on a second queue per device (--overlap)\n"
                                    : "lanes: 'side' operations run on a second queue per device where a device is a "
                                      "GPU; on CPU devices (unless --overlap), and with --no-overlap, every operation "
                                      "runs on the main queue\n");
    if (distributed)
      std::printf("MPI: %d ranks x %d device(s); rank r drives devices %d*r .. %d*r+%d\n", cluster.size(),
                  cmd.devices.count, cmd.devices.count, cmd.devices.count, cmd.devices.count - 1);
    if (dynamic_strips)
      std::printf("balance: dynamic — the strips above are the starting split; between frames each boundary moves "
                  "up to %u rows toward equal measured device time\n",
                  cmd.balance_step);
    return 0;
  }
  install_interrupt_handlers();
  // The report and the timeline are opened before anything renders, so that an unwritable path
  // fails at once.
  std::optional<OutputDir> out_dir;
  std::optional<RenderReport> report;
  std::optional<RenderTimeline> timeline;
  std::optional<SceneOnDevices> on_devices;
  std::optional<StereoPipeline> pipeline_slot;
  std::optional<VideoWriter> video;
  std::optional<SceneAnimator> animator;
  auto setup = [&] {
    if (root) {
      if (!image_codec_available())
        std::fprintf(stderr, "render: this build has no image codec (configured with -DPX_OPENIMAGEIO=OFF): no image "
                             "files are written; --report, --timeline and --video still are\n");
      out_dir.emplace(cmd.out, cmd.overwrite, is_render_frame_file);
      if (!cmd.report.empty()) report.emplace(cmd, opt, cluster.size());
      if (!cmd.timeline.empty()) timeline.emplace(cmd.timeline);
      if (!cmd.video.empty()) video.emplace(cmd.video, 2 * cmd.width, cmd.height, cmd.fps);
    }
    // Every rank loads the scene itself (the scene is replicated, not sent).
    on_devices.emplace(cmd.scene, cmd.devices.options(), !root, cmd.sky, cmd.kernels);
    const DeviceSet& set = on_devices->devices;
    if (root) print_device_set(set);
    if (root) print_scene_upload(on_devices->device_scene, set.size());
    if (root) print_kernel_features(on_devices->device_scene);
    // Queues sharing one device run on the same compute units: dynamic strips still move, but
    // by times that say more about the order the queues run in than about speed.
    if (root && dynamic_strips && set.mode() == DeviceMode::SharedQueues && set.size() > 1)
      std::printf("balance: dynamic over %d queues on one OpenCL device: they share its compute units, so the "
                  "strips follow the queues' measured times but the frame gets no faster\n",
                  set.size());
    animator.emplace(on_devices->loaded.scene, cmd.animation);
    if (root && animator->moves()) std::fprintf(stderr, "[scene] animation: %s\n", animator->describe().c_str());
    pipeline_slot.emplace(on_devices->devices, on_devices->device_scene, on_devices->loaded.scene, cmd.width,
                          cmd.height, opt);
  };
  if (!distributed) {
    setup();
  } else {
    // A rank that cannot start (a scene path missing on its node, no OpenCL device) must stop
    // every rank with its reason, not leave the others waiting for its messages.
    std::string why;
    try {
      setup();
    } catch (const cl::Error& e) {
      why = std::string("OpenCL: ") + describe(e);
    } catch (const std::exception& e) {
      why = e.what();
    }
    const auto failed = cluster.failures(why.empty(), why);
    if (!failed.empty()) {
      cluster.mark_orderly_exit();
      if (!root) return 1;  // rank 0 says why, for every rank
      std::string all = std::to_string(failed.size()) + " of " + std::to_string(cluster.size()) +
                        " MPI ranks could not start, so none renders:";
      for (const auto& f : failed) all += "\n  " + f;
      throw std::runtime_error(all);
    }
    if (root)
      std::fprintf(stderr, "[mpi] %d ranks x %d device(s) = %d devices; rank 0 owns the frame and writes the files\n",
                   cluster.size(), cmd.devices.count, pipeline_slot->layout().count());
  }
  const DeviceSet& devices = on_devices->devices;
  const Scene& scene = on_devices->loaded.scene;
  StereoPipeline& pipeline = *pipeline_slot;
  StageSummary summary;
  FrameQuality last_quality = pipeline.quality();  // the quality of the last frame rendered
  const int all_devices = pipeline.layout().count();
  std::optional<StripBalancer> balancer;
  if (dynamic_strips && all_devices > 1) {
    if (cmd.height < static_cast<unsigned>(all_devices))
      throw std::invalid_argument("--balance dynamic needs at least one row per device");
    StripBalancer::Options b;
    b.max_step_rows = cmd.balance_step;
    balancer.emplace(cmd.height, all_devices, b);
  }
  if (root)
    std::fprintf(stderr, "[render] %u frame(s), %ux%u per eye, %u spp, %u bounces, pipeline %s, denoise %s\n",
                 cmd.frames, cmd.width, cmd.height, opt.trace.spp, opt.trace.bounces,
                 cli_word(cmd.pipeline).c_str(), opt.denoise ? ("SVGF, seams " + cli_word(cmd.seams)).c_str() : "off");
  // Whether to render the next frame, and with what. Under MPI, rank 0 decides (its interrupt,
  // its control loop's quality, its balancer's strips) and every rank follows.
  auto next_frame_agreed = [&]() -> bool {
    if (!distributed) return !interrupted();
    std::vector<std::uint32_t> order(4 + static_cast<std::size_t>(all_devices), 0);
    if (root) {
      const FrameQuality q = pipeline.quality();
      order[0] = interrupted() ? 1u : 0u;
      order[1] = q.spp;
      order[2] = q.bounces;
      order[3] = q.svgf_iterations;
      if (balancer)
        for (int d = 0; d < all_devices; ++d) order[4 + d] = pipeline.strips()[d].size();
    }
    cluster.broadcast(order.data(), order.size() * sizeof(std::uint32_t));
    if (!root && order[0] == 0) {
      pipeline.set_quality({order[1], order[2], order[3]});
      if (balancer) pipeline.set_strips(strips_from_sizes({order.begin() + 4, order.end()}));
    }
    return order[0] == 0;
  };
  if (timeline) timeline->name_devices(devices);
  RenderTotals totals;  // over the frames written (on rank 0)
  AnimationTotals animation_totals;
  unsigned done = 0;
  // Every frame's camera is checked before the first is rendered: a bad one fails the run now.
  for (unsigned f = 0; f < cmd.frames; ++f)
    check_camera(scene, static_cast<float>(f) / cmd.fps, "frame " + std::to_string(f));
  std::optional<double> predicted_ms;  // the control loop's prediction for the coming frame
  for (unsigned f = 0; f < cmd.frames; ++f) {
    if (!next_frame_agreed()) {
      if (f > 0) break;
      if (root) std::printf("interrupted by %s before the first frame: nothing written\n", interrupt_signal_name());
      return interrupt_exit_code();
    }
    const FrameQuality quality = pipeline.quality();
    last_quality = quality;
    const std::vector<RowRange> strips = pipeline.strips();
    // One clock: the animation and the camera path are both at f / fps (every rank poses the
    // same triangles; the last frame's queues are finished, so the geometry may be rewritten).
    const SceneAnimator::Update update =
        animator->update(static_cast<double>(f) / cmd.fps, on_devices->devices, on_devices->device_scene);
    if (animator->moves()) animation_totals.add(update);
    const FrameStats st = pipeline.render(f, static_cast<float>(f) / cmd.fps);
    if (!root) {  // rank 0 holds the frame, decides the next and writes everything
      done = f + 1;
      continue;
    }
    const std::optional<double> predicted_this_frame = predicted_ms;
    // Frame 0 compiles the kernels (seconds on PoCL): it says nothing about the frame time.
    if (controller && f > 0) {
      pipeline.set_quality(controller->update(quality, StereoPipeline::frame_cost(st)));
      predicted_ms = controller->predicted_ms();
    }
    // Frame 0's times include kernel compilation: the balancer starts from frame 1's.
    if (balancer && f > 0) {
      pipeline.set_strips(strips_from_sizes(
          balancer->update(strip_sizes(strips), StereoPipeline::device_busy_ms(st, all_devices))));
    }
    if (st.nonfinite_pixels > 0)
      throw std::runtime_error("frame " + std::to_string(f) + ": " + std::to_string(st.nonfinite_pixels) +
                               " pixels are NaN or infinite (not written). The scene's coordinates or camera are "
                               "probably beyond what 32-bit floats resolve: scale or recentre it");
    std::array<ImageRGB, 2> eyes;
    if (!cmd.no_exr) {
      eyes = pipeline.radiance();
      require_finite(eyes, "frame " + std::to_string(f));
    }
    write_render_frame(cmd, *out_dir, f, eyes, pipeline.rgba8(), pipeline, video ? &*video : nullptr);
    done = f + 1;
    summary.add(st);
    totals.add(st);
    std::fprintf(stderr, "[render] frame %u/%u: %.0f ms%s, %.1f%% of the right eye reprojected", f + 1, cmd.frames,
                 st.wall_ms, f == 0 ? " (includes kernel compilation)" : "",
                 st.right_pixels ? 100.0 * st.reprojected / st.right_pixels : 0.0);
    if (controller)
      std::fprintf(stderr, "; %u spp, %u bounces, %u iterations%s", quality.spp, quality.bounces,
                   quality.svgf_iterations,
                   predicted_this_frame ? (" (predicted " + std::to_string(int(*predicted_this_frame + 0.5)) + " ms)").c_str()
                                        : "");
    if (balancer) {
      std::fprintf(stderr, "; strips");
      for (std::size_t d = 0; d < strips.size(); ++d) std::fprintf(stderr, "%s%u", d ? "/" : " ", strips[d].size());
      std::fprintf(stderr, " rows");
    }
    std::fputc('\n', stderr);
    if (timeline) timeline->add_frame(f, st);
    if (report) report->add_frame(f, st, strips, quality, predicted_this_frame, animator->moves() ? &update : nullptr);
    // Under MPI the next frame's agreement stops every rank together.
    if (!distributed && interrupted()) break;
  }
  if (!root) return 0;
  const double hz = totals.hz();
  if (pipeline.nonfinite_paths() > 0)
    std::fprintf(stderr, "[render] warning: %llu paths had non-finite radiance and were dropped\n",
                 static_cast<unsigned long long>(pipeline.nonfinite_paths()));
  const bool stopped = done < cmd.frames;
  if (report) {
    report->finish(totals, all_devices, devices.mode(), devices.bvh_layout(), on_devices->device_scene,
                   on_devices->loaded.times, pipeline.nonfinite_paths());
    std::fprintf(stderr, "[render] report written to %s\n", cmd.report.c_str());
  }
  if (video) {
    video->commit();
    std::fprintf(stderr, "[render] video written to %s\n", cmd.video.c_str());
  }
  if (timeline) {
    timeline->finish();
    std::fprintf(stderr, "[render] timeline written to %s (open in chrome://tracing or ui.perfetto.dev)\n",
                 cmd.timeline.c_str());
  }
  const char* eye_files = cmd.no_exr ? "png" : "{exr,png}";
  // The one-screen summary on stdout: what ran, how fast, where the time went, where the files are.
  if (done > 0) {
    const FrameQuality& q = last_quality;
    std::printf("\n== render summary ==\n");
    std::printf("%s: pipeline %s, %d device(s) (%s%s), %ux%u per eye, %u spp, %u bounces, denoise %s%s\n",
                scene.name.c_str(), cli_word(cmd.pipeline).c_str(), all_devices, to_string(devices.mode()),
                distributed ? (", " + std::to_string(cluster.size()) + " MPI ranks").c_str() : "", cmd.width,
                cmd.height, q.spp, q.bounces,
                opt.denoise ? ("SVGF " + std::to_string(q.svgf_iterations) + " iterations, seams " + cli_word(cmd.seams)).c_str()
                            : "off",
                controller ? (" (last frame's; control loop " + cmd.target_ms + " ms)").c_str() : "");
    if (done > 1)
      std::printf("%.1f Hz over frames 1-%u (frame 0 took %.0f ms: it includes kernel compilation)\n", hz, done - 1,
                  totals.first_frame_ms);
    else
      std::printf("%.1f Hz (one frame, including kernel compilation)\n", hz);
    std::printf("median device time per stage%s:\n%s", done > 1 ? " (frames after the first)" : "",
                summary.table(1).c_str());
    {
      const StartTimes& t = on_devices->loaded.times;
      const DeviceScene& ds = on_devices->device_scene;
      std::printf("start: scene %.0f ms, BVH %.0f ms (%s), validation %.0f ms%s, upload %.0f ms (%.1f MiB, one copy "
                  "for the %d device(s) of the context)\n",
                  t.load_ms, t.bvh_ms, t.bvh_from_cache ? "read from the cache" : "built", t.validate_ms,
                  t.cache_store_ms > 0.0 ? (", cache write " + std::to_string(static_cast<long>(t.cache_store_ms)) + " ms").c_str() : "",
                  ds.upload_ms(), static_cast<double>(ds.bytes_in_context()) / (1024.0 * 1024.0), devices.size());
    }
    if (animation_totals.frames > 0)
      std::printf("animation: %s; per frame (median) pose %.1f ms, BVH rebuild %.1f ms, upload %.1f ms of %.2f MiB\n",
                  animator->describe().c_str(), animation_totals.median(&SceneAnimator::Update::pose_ms),
                  animation_totals.median(&SceneAnimator::Update::bvh_ms),
                  animation_totals.median(&SceneAnimator::Update::upload_ms),
                  static_cast<double>(animation_totals.bytes_last) / (1024.0 * 1024.0));
    if (balancer) {
      std::printf("strips at the end (rows per device):");
      for (const RowRange& r : pipeline.strips()) std::printf(" %u", r.size());
      std::printf("\n");
    }
    if (image_codec_available()) {
      std::printf("files:\n  %s/frame_NNNN_{left,right}.%s, frame_NNNN_stereo.png (NNNN = 0000-%04u)\n",
                  cmd.out.c_str(), eye_files, done - 1);
      if (opt.aovs.any())
        std::printf("  %s/frame_NNNN_{left,right}_%s.exr (auxiliary images)\n", cmd.out.c_str(),
                    opt.aovs.albedo && opt.aovs.normal ? "{albedo,normal}" : opt.aovs.albedo ? "albedo" : "normal");
    } else {
      std::printf("files:\n  no images (this build has no image codec)\n");
    }
    if (report) std::printf("  report:   %s\n", cmd.report.c_str());
    if (timeline) std::printf("  timeline: %s\n", cmd.timeline.c_str());
    if (video) std::printf("  video:    %s (left | right, %g fps)\n", cmd.video.c_str(), double(cmd.fps));
    std::printf("\n");
  }
  if (stopped) {
    std::printf("interrupted by %s after %u of %u frame(s): wrote frames 0-%u to %s "
                "(frame_NNNN_{left,right}.%s, frame_NNNN_stereo.png), every file complete%s\n",
                interrupt_signal_name(), done, cmd.frames, done - 1, cmd.out.c_str(), eye_files,
                report ? "; the report covers those frames" : "");
    return interrupt_exit_code();
  }
  if (image_codec_available())
    std::printf("wrote %u frame(s) to %s (frame_NNNN_{left,right}.%s, frame_NNNN_stereo.png); ", cmd.frames,
                cmd.out.c_str(), eye_files);
  else
    std::printf("rendered %u frame(s), no image files (this build has no image codec); ", cmd.frames);
  std::printf("%.1f Hz %s\n", hz,
              done > 1 ? "over the frames after the first (which includes kernel compilation)"
                       : "(one frame, including kernel compilation)");
  // A signal after the last frame: every frame is written, but the exit status still says so.
  if (interrupted()) return interrupt_exit_code();
  return 0;
}

int run_reference(const ReferenceCommand& cmd) {
  install_interrupt_handlers();
  const OutputDir out_dir(cmd.out, cmd.overwrite);
  SceneOnDevices on_devices(cmd.scene, cmd.devices.options(), false, cmd.sky, cmd.kernels);
  print_device_set(on_devices.devices);
  print_scene_upload(on_devices.device_scene, on_devices.devices.size());
  print_kernel_features(on_devices.device_scene);
  const Scene& scene = on_devices.loaded.scene;
  // The scene posed at the frame's time, as `render` poses it for that frame.
  SceneAnimator animator(on_devices.loaded.scene, cmd.animation);
  if (animator.moves()) {
    std::fprintf(stderr, "[reference] animation: %s, at t = %.4g s\n", animator.describe().c_str(),
                 static_cast<double>(cmd.frame) / cmd.fps);
    animator.update(static_cast<double>(cmd.frame) / cmd.fps, on_devices.devices, on_devices.device_scene);
  }
  PathTracer tracer(on_devices.devices, on_devices.device_scene, scene);
  ReferenceOptions opt;
  opt.spp = cmd.spp;
  opt.pass_spp = cmd.pass_spp;
  opt.bounces = cmd.bounces;
  check_camera(scene, static_cast<float>(cmd.frame) / cmd.fps, "reference frame " + std::to_string(cmd.frame));
  // Ctrl-C stops after the pass in flight and writes the average of the passes done.
  opt.stop = [] { return interrupted(); };
  unsigned spp_done = 0;
  auto eyes = render_reference(tracer, static_cast<float>(cmd.frame) / cmd.fps, cmd.frame, cmd.width, cmd.height, opt,
                               eta_printer("reference"), &spp_done);
  require_finite(eyes, "reference");
  write_stereo(out_dir, "reference_", eyes, cmd.exposure);
  if (tracer.nonfinite_paths() > 0)
    std::fprintf(stderr, "[reference] warning: %llu paths had non-finite radiance and were dropped\n",
                 static_cast<unsigned long long>(tracer.nonfinite_paths()));
  if (spp_done < cmd.spp) {
    std::fprintf(stderr, "\n");
    std::printf("interrupted by %s after %u of %u spp: wrote %s/reference_{left,right}.exr with the %u spp done, "
                "and PNG previews\n",
                interrupt_signal_name(), spp_done, cmd.spp, cmd.out.c_str(), spp_done);
    return interrupt_exit_code();
  }
  std::printf("wrote %s/reference_{left,right}.exr (%u spp) and PNG previews\n", cmd.out.c_str(), cmd.spp);
  if (interrupted()) return interrupt_exit_code();
  return 0;
}

// Error figures (psnr_db on values clamped to [0, 1]; rel_mse and mse unclamped), or with
// --exact: "identical" and 0 when every channel of every pixel has the same bit pattern, else what
// differs and 1. A size mismatch is an error (exit 1) in both modes.
int run_compare(const CompareCommand& cmd) {
  const auto a = read_image_rgb(cmd.image);
  const auto r = read_image_rgb(cmd.reference);
  if (!cmd.exact) {
    const auto d = compare_images(a, r);
    std::printf("psnr_db %.3f\nrel_mse %.6g\nmse %.6g\n", d.psnr_db, d.rel_mse, d.mse);
    return 0;
  }
  const auto d = compare_exact(a, r);
  if (d.identical()) {
    std::printf("identical\n");
    return 0;
  }
  static const char* const kChannel = "rgb";
  // %.9g round-trips a float; the bit patterns show -0 vs +0 and NaN payloads.
  std::printf("differ: %zu of %zu pixels (%zu channel values)\n", d.differing_pixels, d.pixels, d.differing_values);
  std::printf("first difference: x %d y %d channel %c: %.9g vs %.9g (bits 0x%08x vs 0x%08x)\n", d.x, d.y,
              kChannel[d.channel], d.image_value, d.reference_value, static_cast<unsigned>(d.image_bits),
              static_cast<unsigned>(d.reference_bits));
  std::printf("largest absolute difference %.9g", d.max_abs_difference);
  if (d.nan_values > 0) std::printf(" (%zu more differing values involve a NaN)", d.nan_values);
  std::printf("\n");
  return 1;
}

}  // namespace px
