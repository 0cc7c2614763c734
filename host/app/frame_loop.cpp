// `render`'s frame loop: see frame_loop.h for why it is a unit of its own. The console output,
// files and report are the command's interface (tests/cli_smoke.sh, tests/report_values.sh and
// the scripts read them): a change here is a change users and scripts see.
#include "app/frame_loop.h"

#include "app/cli_enums.h"
#include "app/frame_checks.h"
#include "cl/cl_error.h"
#include "cluster/cluster.h"
#include "image/image_io.h"
#include "io/interrupt.h"
#include "io/progress_ticker.h"
#include "pipeline/strip_schedule.h"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>

namespace px {
namespace {

std::string frame_name(unsigned frame, const char* what) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "frame_%04u_%s", frame, what);
  return buf;
}

// Frame `f` of `render`: per eye an EXR (unless --no-exr: `eyes` is then unused) and a PNG,
// the auxiliary EXRs --aov asks for, the side-by-side stereo PNG, and the video's next frame.
void write_render_frame(const RenderCommand& cmd, const OutputDir& dir, unsigned f, const std::array<ImageRGB, 2>& eyes,
                        const std::array<std::vector<std::uint8_t>, 2>& png, const StereoPipeline& pipeline,
                        VideoWriter* video) {
  const std::string prefix = frame_name(f, "");
  const int w = static_cast<int>(cmd.size.width), h = static_cast<int>(cmd.size.height);
  try {
    for (int e = 0; e < 2; ++e) {
      const std::string name = prefix + (e == 0 ? "left" : "right");
      if (!cmd.no_exr) write_exr(dir.file(name + ".exr"), eyes[e]);
      write_png(dir.file(name + ".png"), w, h, png[e]);
      if (!pipeline.albedo_aov()[e].rgb.empty()) write_exr(dir.file(name + "_albedo.exr"), pipeline.albedo_aov()[e]);
      if (!pipeline.normal_aov()[e].rgb.empty()) write_exr(dir.file(name + "_normal.exr"), pipeline.normal_aov()[e]);
    }
    const auto stereo = side_by_side(png[0], png[1], w, h);
    write_png(dir.file(prefix + "stereo.png"), 2 * w, h, stereo);
    if (video) video->write_frame(stereo);
  } catch (const ImageError& e) {
    // Say what is usable: the frames before this one are complete.
    throw std::runtime_error(std::string(e.what()) + " (frame " + std::to_string(f) + "; " +
                             (f ? "frames 0-" + std::to_string(f - 1) + " in " + cmd.out + " are complete"
                                : std::string("no frame was completed")) +
                             ")");
  }
}

}  // namespace

RenderLoop::RenderLoop(const RenderCommand& cmd, PipelineConfig config, Cluster& cluster)
    : cmd_(cmd),
      config_(std::move(config)),
      cluster_(cluster),
      clock_(cmd.clock),
      distributed_(cluster.distributed()),
      root_(cluster.rank() == 0),
      dynamic_strips_(cmd.balance == StripBalance::Dynamic) {}

std::optional<int> RenderLoop::start() {
  const StereoPipeline::Options& opt = config_.options;
  auto setup = [&] {
    if (root_) {
      out_dir_.emplace(cmd_.out, cmd_.overwrite, is_render_frame_file);
      if (!cmd_.report.empty()) report_.emplace(cmd_, opt, cluster_.size());
      if (!cmd_.timeline.empty()) timeline_.emplace(cmd_.timeline);
      if (!cmd_.video.empty()) video_.emplace(cmd_.video, 2 * cmd_.size.width, cmd_.size.height, cmd_.clock.fps);
    }
    // Every rank loads the scene itself (the scene is replicated, not sent).
    on_devices_.emplace(cmd_.scene.name, cmd_.devices.options(render_kernel_work(cmd_, cluster_.size())), !root_,
                        cmd_.scene.load_options(), cmd_.scene.kernels, StartBuilds::Frames);
    const DeviceSet& set = on_devices_->devices;
    if (root_) print_device_set(set);
    if (root_) print_scene_upload(on_devices_->device_scene, set.size());
    if (root_) print_kernel_features(on_devices_->device_scene);
    if (root_) print_kernel_build(set);
    // Queues sharing one device run on the same compute units: dynamic strips still move, but
    // by times that say more about the order the queues run in than about speed.
    if (root_ && dynamic_strips_ && set.mode() == DeviceMode::SharedQueues && set.size() > 1)
      std::printf(
          "balance: dynamic over %d queues on one OpenCL device: they share its compute units, so the "
          "strips follow the queues' measured times but the frame gets no faster\n",
          set.size());
    animator_.emplace(on_devices_->loaded.scene, cmd_.scene.animation);
    if (root_ && animator_->moves()) std::fprintf(stderr, "[scene] animation: %s\n", animator_->describe().c_str());
    pipeline_.emplace(on_devices_->devices, on_devices_->device_scene, on_devices_->loaded.scene, cmd_.size.width,
                      cmd_.size.height, opt);
  };
  if (!distributed_) {
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
    const auto failed = cluster_.failures(why.empty(), why);
    if (!failed.empty()) {
      cluster_.mark_orderly_exit();
      if (!root_) return 1;  // rank 0 says why, for every rank
      std::string all = std::to_string(failed.size()) + " of " + std::to_string(cluster_.size()) +
                        " MPI ranks could not start, so none renders:";
      for (const auto& f : failed) all += "\n  " + f;
      throw std::runtime_error(all);
    }
    if (root_)
      std::fprintf(stderr, "[mpi] %d ranks x %d device(s) = %d devices; rank 0 owns the frame and writes the files\n",
                   cluster_.size(), cmd_.devices.count, pipeline_->layout().count());
  }
  last_quality_ = pipeline_->quality();
  all_devices_ = pipeline_->layout().count();
  if (dynamic_strips_ && all_devices_ > 1) {
    if (cmd_.size.height < static_cast<unsigned>(all_devices_))
      throw std::invalid_argument("--balance dynamic needs at least one row per device");
    StripBalancer::Options b;
    b.max_step_rows = cmd_.balance_step;
    balancer_.emplace(cmd_.size.height, all_devices_, b);
  }
  if (root_)
    std::fprintf(stderr, "[render] %u frame(s), %ux%u per eye, %u spp, %u bounces, pipeline %s, denoise %s\n",
                 cmd_.frames, cmd_.size.width, cmd_.size.height, opt.trace.spp, opt.trace.bounces,
                 cli_word(opt.pipeline).c_str(),
                 opt.denoise ? ("SVGF, seams " + cli_word(opt.denoise->seams)).c_str() : "off");
  if (timeline_) timeline_->name_devices(on_devices_->devices);
  // Every frame's camera is checked before the first is rendered: a bad one fails the run now.
  for (unsigned f = 0; f < cmd_.frames; ++f)
    check_camera(on_devices_->loaded.scene, clock_.camera_time_s(f), "frame " + std::to_string(f));
  return std::nullopt;
}

bool RenderLoop::next_frame_agreed() {
  if (!distributed_) return !interrupted();
  StereoPipeline& pipeline = *pipeline_;
  std::vector<std::uint32_t> order(4 + static_cast<std::size_t>(all_devices_), 0);
  if (root_) {
    const FrameQuality q = pipeline.quality();
    order[0] = interrupted() ? 1u : 0u;
    order[1] = q.spp;
    order[2] = q.bounces;
    order[3] = q.svgf_iterations;
    if (balancer_)
      for (int d = 0; d < all_devices_; ++d) order[4 + d] = pipeline.strips()[d].size();
  }
  cluster_.broadcast(order.data(), order.size() * sizeof(std::uint32_t));
  if (!root_ && order[0] == 0) {
    pipeline.set_quality({order[1], order[2], order[3]});
    if (balancer_) pipeline.set_strips(strips_from_sizes({order.begin() + 4, order.end()}));
  }
  return order[0] == 0;
}

std::optional<int> RenderLoop::run() {
  for (unsigned f = 0; f < cmd_.frames; ++f) {
    if (!next_frame_agreed()) {
      if (f > 0) break;
      if (root_) std::printf("interrupted by %s before the first frame: nothing written\n", interrupt_signal_name());
      return interrupt_exit_code();
    }
    step(f);
    // Under MPI the next frame's agreement stops every rank together.
    if (!distributed_ && interrupted()) break;
  }
  return std::nullopt;
}

void RenderLoop::step(unsigned f) {
  StereoPipeline& pipeline = *pipeline_;
  std::optional<FrameTimeController>& controller = config_.controller;
  const FrameQuality quality = pipeline.quality();
  last_quality_ = quality;
  const std::vector<RowRange> strips = pipeline.strips();
  // One clock: the animation and the camera path are both at frame f's time (every rank poses
  // the same triangles; the last frame's queues are finished, so the geometry may be rewritten).
  const SceneAnimator::Update update =
      animator_->update(clock_.time_s(f), on_devices_->devices, on_devices_->device_scene);
  if (animator_->moves()) animation_totals_.add(update);
  // The cache files the next start reads are written beside the first frame, not before it.
  if (f == 0) on_devices_->first_frame_on_its_way();
  // Frame 0 compiles the kernels PoCL has not cached (seconds for a new feature set, with nothing
  // written meanwhile): past two seconds, a line says what the wait is.
  std::optional<ProgressTicker> first_frame;
  if (f == 0 && root_)
    first_frame.emplace(
        "[render] still on frame 1, which compiles the kernels on a first run (PoCL caches them for "
        "the next)",
        ProgressTicker::Options{std::chrono::milliseconds(2000), std::chrono::milliseconds(5000)});
  const FrameStats st = pipeline.render(f, clock_.camera_time_s(f));
  first_frame.reset();
  if (!root_) {  // rank 0 holds the frame, decides the next and writes everything
    done_ = f + 1;
    return;
  }
  const std::optional<double> predicted_this_frame = predicted_ms_;
  // Frame 0 compiles the kernels (seconds on PoCL): it says nothing about the frame time.
  if (controller && f > 0) {
    pipeline.set_quality(controller->update(quality, StereoPipeline::frame_cost(st)));
    predicted_ms_ = controller->predicted_ms();
  }
  // Frame 0's times include kernel compilation: the balancer starts from frame 1's.
  if (balancer_ && f > 0) {
    pipeline.set_strips(
        strips_from_sizes(balancer_->update(strip_sizes(strips), StereoPipeline::device_busy_ms(st, all_devices_))));
  }
  if (st.nonfinite_pixels > 0)
    throw std::runtime_error("frame " + std::to_string(f) + ": " + std::to_string(st.nonfinite_pixels) +
                             " pixels are NaN or infinite (not written). The scene's coordinates or camera are "
                             "probably beyond what 32-bit floats resolve: scale or recentre it");
  std::array<ImageRGB, 2> eyes;
  if (!cmd_.no_exr) {
    eyes = pipeline.radiance();
    require_finite(eyes, "frame " + std::to_string(f));
  }
  write_render_frame(cmd_, *out_dir_, f, eyes, pipeline.rgba8(), pipeline, video_ ? &*video_ : nullptr);
  done_ = f + 1;
  stages_.add(st);
  totals_.add(st);
  std::fprintf(stderr, "[render] frame %u/%u: %.0f ms%s, %.1f%% of the right eye reprojected", f + 1, cmd_.frames,
               st.wall_ms, f == 0 ? " (includes kernel compilation)" : "",
               st.right_pixels ? 100.0 * st.reprojected / st.right_pixels : 0.0);
  if (controller)
    std::fprintf(stderr, "; %u spp, %u bounces, %u iterations%s", quality.spp, quality.bounces, quality.svgf_iterations,
                 predicted_this_frame
                     ? (" (predicted " + std::to_string(int(*predicted_this_frame + 0.5)) + " ms)").c_str()
                     : "");
  if (balancer_) {
    std::fprintf(stderr, "; strips");
    for (std::size_t d = 0; d < strips.size(); ++d) std::fprintf(stderr, "%s%u", d ? "/" : " ", strips[d].size());
    std::fprintf(stderr, " rows");
  }
  std::fputc('\n', stderr);
  if (timeline_) timeline_->add_frame(f, st);
  if (report_) report_->add_frame(f, st, strips, quality, predicted_this_frame, animator_->moves() ? &update : nullptr);
}

int RenderLoop::finish() {
  // The cache files are complete (or absent) before the process goes on to exit.
  on_devices_->wait_for_cache_writes();
  if (!root_) return 0;
  const StereoPipeline& pipeline = *pipeline_;
  const DeviceSet& devices = on_devices_->devices;
  const double hz = totals_.hz();
  if (pipeline.nonfinite_paths() > 0)
    std::fprintf(stderr, "[render] warning: %llu paths had non-finite radiance and were dropped\n",
                 static_cast<unsigned long long>(pipeline.nonfinite_paths()));
  const bool stopped = done_ < cmd_.frames;
  if (report_) {
    report_->finish(totals_, all_devices_, devices.mode(), devices.bvh_layout(), on_devices_->device_scene,
                    on_devices_->loaded.times, pipeline.nonfinite_paths(), on_devices_->loaded.bvh.stats,
                    devices.kernel_build().quick);
    std::fprintf(stderr, "[render] report written to %s\n", cmd_.report.c_str());
  }
  if (video_) {
    video_->commit();
    std::fprintf(stderr, "[render] video written to %s\n", cmd_.video.c_str());
  }
  if (timeline_) {
    timeline_->finish();
    std::fprintf(stderr, "[render] timeline written to %s (open in chrome://tracing or ui.perfetto.dev)\n",
                 cmd_.timeline.c_str());
  }
  const char* eye_files = cmd_.no_exr ? "png" : "{exr,png}";
  if (done_ > 0) print_summary();
  if (stopped) {
    std::printf(
        "interrupted by %s after %u of %u frame(s): wrote frames 0-%u to %s "
        "(frame_NNNN_{left,right}.%s, frame_NNNN_stereo.png), every file complete%s\n",
        interrupt_signal_name(), done_, cmd_.frames, done_ - 1, cmd_.out.c_str(), eye_files,
        report_ ? "; the report covers those frames" : "");
    return interrupt_exit_code();
  }
  std::printf("wrote %u frame(s) to %s (frame_NNNN_{left,right}.%s, frame_NNNN_stereo.png); ", cmd_.frames,
              cmd_.out.c_str(), eye_files);
  std::printf("%.1f Hz %s\n", hz,
              done_ > 1 ? "over the frames after the first (which includes kernel compilation)"
                        : "(one frame, including kernel compilation)");
  // A signal after the last frame: every frame is written, but the exit status still says so.
  if (interrupted()) return interrupt_exit_code();
  return 0;
}

// The one-screen summary on stdout: what ran, how fast, where the time went, where the files are.
void RenderLoop::print_summary() const {
  const StereoPipeline::Options& opt = config_.options;
  const StereoPipeline& pipeline = *pipeline_;
  const DeviceSet& devices = on_devices_->devices;
  const FrameQuality& q = last_quality_;
  const double hz = totals_.hz();
  const char* eye_files = cmd_.no_exr ? "png" : "{exr,png}";
  std::printf("\n== render summary ==\n");
  std::printf(
      "%s: pipeline %s, %d device(s) (%s%s), %ux%u per eye, %u spp, %u bounces, denoise %s%s\n",
      on_devices_->loaded.scene.name.c_str(), cli_word(opt.pipeline).c_str(), all_devices_, to_string(devices.mode()),
      distributed_ ? (", " + std::to_string(cluster_.size()) + " MPI ranks").c_str() : "", cmd_.size.width,
      cmd_.size.height, q.spp, q.bounces,
      opt.denoise
          ? ("SVGF " + std::to_string(q.svgf_iterations) + " iterations, seams " + cli_word(opt.denoise->seams)).c_str()
          : "off",
      config_.controller ? (" (last frame's; control loop " + cmd_.target_ms + " ms)").c_str() : "");
  if (done_ > 1)
    std::printf("%.1f Hz over frames 1-%u (frame 0 took %.0f ms: it includes kernel compilation)\n", hz, done_ - 1,
                totals_.first_frame_ms);
  else
    std::printf("%.1f Hz (one frame, including kernel compilation)\n", hz);
  std::printf("median device time per stage%s:\n%s", done_ > 1 ? " (frames after the first)" : "",
              stages_.table(1).c_str());
  {
    const StartTimes& t = on_devices_->loaded.times;
    const DeviceScene& ds = on_devices_->device_scene;
    std::printf(
        "start: scene %.0f ms, BVH %.0f ms (%s), validation %.0f ms%s%s, OpenCL devices %.0f ms, device layout %.0f "
        "ms%s, upload %.0f ms (%.1f MiB, one copy for the %d device(s) of the context%s); host memory after the start "
        "%.0f MiB\n",
        t.load_ms, t.bvh_ms,
        t.device_layout_from_cache ? "its device layout mapped from the cache"
        : t.bvh_from_cache         ? "read from the cache"
                                   : "built",
        t.validate_ms, t.bvh_validated_when_cached ? " (validated when cached)" : "",
        t.cache_store_ms + ds.layout_store_ms() > 0.0
            ? (", cache write " + std::to_string(static_cast<long>(t.cache_store_ms + ds.layout_store_ms())) + " ms")
                  .c_str()
        : t.background_cache_write_ms > 0.0
            ? (", cache write " + std::to_string(static_cast<long>(t.background_cache_write_ms)) +
               " ms in the background")
                  .c_str()
            : "",
        t.devices_ms, ds.layout_ms(),
        ds.host_part_ms() > 0.0 ? (" (the shading records made before the BVH: " +
                                   std::to_string(static_cast<long>(ds.host_part_ms())) + " ms of it)")
                                      .c_str()
                                : "",
        ds.upload_ms(), static_cast<double>(ds.bytes_in_context()) / (1024.0 * 1024.0), devices.size(),
        ds.host_backed() ? ", the host's own arrays" : "", t.host_rss_after_start_mib);
  }
  if (animation_totals_.frames > 0)
    std::printf(
        "animation: %s; per frame (median) pose %.1f ms, BVH refit or rebuild %.1f ms, upload %.1f ms of %.2f MiB\n",
        animator_->describe().c_str(), animation_totals_.median(&SceneAnimator::Update::pose_ms),
        animation_totals_.median(&SceneAnimator::Update::bvh_ms),
        animation_totals_.median(&SceneAnimator::Update::upload_ms),
        static_cast<double>(animation_totals_.bytes_last) / (1024.0 * 1024.0));
  if (balancer_) {
    std::printf("strips at the end (rows per device):");
    for (const RowRange& r : pipeline.strips()) std::printf(" %u", r.size());
    std::printf("\n");
  }
  std::printf("files:\n  %s/frame_NNNN_{left,right}.%s, frame_NNNN_stereo.png (NNNN = 0000-%04u)\n", cmd_.out.c_str(),
              eye_files, done_ - 1);
  if (opt.aovs.any())
    std::printf("  %s/frame_NNNN_{left,right}_%s.exr (auxiliary images)\n", cmd_.out.c_str(),
                opt.aovs.albedo && opt.aovs.normal ? "{albedo,normal}"
                : opt.aovs.albedo                  ? "albedo"
                                                   : "normal");
  if (report_) std::printf("  report:   %s\n", cmd_.report.c_str());
  if (timeline_) std::printf("  timeline: %s\n", cmd_.timeline.c_str());
  if (video_) std::printf("  video:    %s (left | right, %g fps)\n", cmd_.video.c_str(), double(cmd_.clock.fps));
  std::printf("\n");
}

}  // namespace px
