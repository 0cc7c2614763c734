#include "app/commands.h"

#include "app/cli_enums.h"
#include "app/frame_checks.h"
#include "app/frame_loop.h"
#include "app/output_dir.h"
#include "app/render_setup.h"
#include "app/scene_setup.h"
#include "cluster/cluster.h"
#include "image/image_io.h"
#include "image/image_metrics.h"
#include "io/interrupt.h"
#include "render/preview_renderer.h"
#include "render/reference_render.h"
#include "render/scene_animator.h"
#include "pipeline/stereo_pipeline.h"

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

}  // namespace

DeviceOptions DeviceChoice::options(std::optional<KernelWork> work) const {
  return {count, mode, platform, bvh_layout, kernel_build, work};
}

namespace {

// `frames` stereo frames of `size` at `spp` samples a pixel of paths up to `bounces` long, for
// --kernel-build auto; `denoised`: the denoiser runs on every frame.
KernelWork stereo_kernel_work(double frames, const ImageSize& size, unsigned spp, unsigned bounces, bool denoised) {
  const double pixels = 2.0 * frames * size.width * size.height;
  KernelWork w;
  w.pixel_samples = pixels * spp;
  w.denoised_pixels = denoised ? pixels : 0.0;
  w.bounces = bounces;
  return w;
}

}  // namespace

std::optional<KernelWork> render_kernel_work(const RenderCommand& cmd, int ranks) {
  if (!cmd.report.empty() || !cmd.timeline.empty() || !cmd.target_ms.empty()) return std::nullopt;
  return stereo_kernel_work(static_cast<double>(cmd.frames) / std::max(ranks, 1), cmd.size, cmd.pipeline.trace.spp,
                            cmd.pipeline.trace.bounces, cmd.pipeline.denoise.has_value());
}

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
  SceneOnDevices on_devices(cmd.scene.name, cmd.devices.options(stereo_kernel_work(1, cmd.size, 1, 0, false)), false,
                            cmd.scene.load_options(), cmd.scene.kernels);
  print_device_set(on_devices.devices);
  print_scene_upload(on_devices.device_scene, on_devices.devices.size());
  print_kernel_features(on_devices.device_scene);
  print_kernel_build(on_devices.devices);
  SceneAnimator animator(on_devices.loaded.scene, cmd.scene.animation);
  if (animator.moves()) {
    std::fprintf(stderr, "[preview] animation: %s\n", animator.describe().c_str());
    animator.update(cmd.time_s, on_devices.devices, on_devices.device_scene);
  }
  PreviewRenderer renderer(on_devices.devices, on_devices.device_scene);
  std::fprintf(stderr, "[preview] %ux%u per eye, t = %.2f s ...\n", cmd.size.width, cmd.size.height, cmd.time_s);
  check_camera(on_devices.loaded.scene, cmd.time_s, "preview");
  auto t0 = clock_type::now();
  auto eyes = renderer.render(on_devices.loaded.scene, cmd.time_s, cmd.size.width, cmd.size.height);
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
  const bool dynamic_strips = cmd.balance == StripBalance::Dynamic;
  if (dynamic_strips && !has_movable_strips(opt.pipeline))
    throw std::invalid_argument(
        "--balance dynamic needs the proposed or mono pipeline (baseline already spreads path "
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
    const FrameSchedule schedule = make_schedule(opt.pipeline, cmd.devices.count * cluster.size(), cmd.size.height,
                                                 opt.denoise.has_value(), {}, StereoPipeline::wants_gbuffer(opt));
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
      std::printf(
          "balance: dynamic — the strips above are the starting split; between frames each boundary moves "
          "up to %u rows toward equal measured device time\n",
          cmd.balance_step);
    return 0;
  }
  install_interrupt_handlers();
  // The frames themselves, and the summary after them, are the frame loop's (app/frame_loop.h).
  RenderLoop loop(cmd, std::move(config), cluster);
  if (const auto status = loop.start()) return *status;
  if (const auto status = loop.run()) return *status;
  return loop.finish();
}

int run_reference(const ReferenceCommand& cmd) {
  install_interrupt_handlers();
  const OutputDir out_dir(cmd.out, cmd.overwrite);
  SceneOnDevices on_devices(cmd.scene.name,
                            cmd.devices.options(stereo_kernel_work(1, cmd.size, cmd.spp, cmd.bounces, false)), false,
                            cmd.scene.load_options(), cmd.scene.kernels);
  print_device_set(on_devices.devices);
  print_scene_upload(on_devices.device_scene, on_devices.devices.size());
  print_kernel_features(on_devices.device_scene);
  print_kernel_build(on_devices.devices);
  const Scene& scene = on_devices.loaded.scene;
  // The scene and camera at the frame's time, on `render`'s clock: the reference of frame f is
  // the image `render` converges to at frame f.
  const FrameClock& clock = cmd.clock;
  SceneAnimator animator(on_devices.loaded.scene, cmd.scene.animation);
  if (animator.moves()) {
    std::fprintf(stderr, "[reference] animation: %s, at t = %.4g s\n", animator.describe().c_str(),
                 clock.time_s(cmd.frame));
    animator.update(clock.time_s(cmd.frame), on_devices.devices, on_devices.device_scene);
  }
  PathTracer tracer(on_devices.devices, on_devices.device_scene, scene);
  ReferenceOptions opt;
  opt.spp = cmd.spp;
  opt.pass_spp = cmd.pass_spp;
  opt.bounces = cmd.bounces;
  opt.direct_light = cmd.direct_light;
  check_camera(scene, clock.camera_time_s(cmd.frame), "reference frame " + std::to_string(cmd.frame));
  // Ctrl-C stops after the pass in flight and writes the average of the passes done.
  opt.stop = [] { return interrupted(); };
  unsigned spp_done = 0;
  auto eyes = render_reference(tracer, clock.camera_time_s(cmd.frame), cmd.frame, cmd.size.width, cmd.size.height, opt,
                               eta_printer("reference"), &spp_done);
  require_finite(eyes, "reference");
  write_stereo(out_dir, "reference_", eyes, cmd.exposure);
  if (tracer.nonfinite_paths() > 0)
    std::fprintf(stderr, "[reference] warning: %llu paths had non-finite radiance and were dropped\n",
                 static_cast<unsigned long long>(tracer.nonfinite_paths()));
  if (spp_done < cmd.spp) {
    std::fprintf(stderr, "\n");
    std::printf(
        "interrupted by %s after %u of %u spp: wrote %s/reference_{left,right}.exr with the %u spp done, "
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
