// bench_balance: static vs dynamic strips for the proposed pipeline, side by side in one
// process on the same devices and camera animation. The two pipelines render frame f one
// after the other (interleaved, so a noisy machine slows both alike). Per mode: makespan of
// the timed frames, median frame wall time, median busy time of the slowest device and the
// median imbalance (slowest / mean device busy time - 1), and where the boundaries settled.
// Both modes must produce the same images (checked every frame, bit for bit), so the error
// against the reference is the same for both and printed once.
//
//   build/bench_balance --scene atrium --width 160 --height 90 --frames 30 --devices 2 --ref-spp 256
//       --frames-csv balance.csv
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_common.h"
#include "cl/device_set.h"
#include "control/strip_balancer.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/path_tracer.h"
#include "render/reference_render.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numeric>

namespace {

using px::bench::median;

struct ModeResult {
  const char* name = "";
  double makespan_ms = 0;
  std::vector<double> frame_ms, slowest_ms, imbalance;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_balance: static vs dynamic strips (proposed pipeline) on one camera animation"};
  std::string scene = "atrium";
  unsigned width = 160, height = 90, frames = 30, warmup = 2, spp = 1, bounces = 6, ref_spp = 0, step = 8;
  int devices = 2;
  float fps = 30.0f;
  bool denoise = true;
  std::string frames_csv;
  app.add_option("--scene", scene)->capture_default_str();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--frames", frames, "timed frames of the camera animation")->capture_default_str();
  app.add_option("--warmup", warmup, "untimed frames first (kernel compilation; the balancer starts after them)")
      ->capture_default_str();
  app.add_option("--spp", spp)->capture_default_str();
  app.add_option("--bounces", bounces)->capture_default_str();
  app.add_option("--devices", devices)->check(CLI::Range(2, 64))->capture_default_str();
  app.add_option("--fps", fps, "camera-path time step")->capture_default_str();
  app.add_option("--balance-step", step, "most rows a boundary moves per frame")->capture_default_str();
  app.add_option("--ref-spp", ref_spp, "samples of the frame-0 reference (0 = skip the error figure)")
      ->capture_default_str();
  app.add_flag("!--no-denoise", denoise, "leave SVGF out");
  app.add_option("--frames-csv", frames_csv, "per mode and frame: wall ms, each device's busy ms and rows");
  CLI11_PARSE(app, argc, argv);
  if (frames == 0 || width == 0 || height < static_cast<unsigned>(devices) || spp == 0) {
    std::fprintf(stderr, "bench_balance: --frames, --width, --spp must be positive and --height >= --devices\n");
    return 1;
  }
  std::ofstream csv;
  if (!frames_csv.empty()) {
    csv.open(frames_csv);
    if (!csv) {
      std::fprintf(stderr, "bench_balance: cannot write %s\n", frames_csv.c_str());
      return 1;
    }
    csv << "mode,frame,wall_ms";
    for (int d = 0; d < devices; ++d) csv << ",busy_ms_d" << d;
    for (int d = 0; d < devices; ++d) csv << ",rows_d" << d;
    csv << '\n';
  }
  return px::run_guarded([&]() -> int {
    px::SceneOnDevices on_devices(scene, {devices, px::DeviceMode::Auto, "", std::nullopt});
    const px::LoadedScene& loaded = on_devices.loaded;
    px::DeviceSet& set = on_devices.devices;
    const px::DeviceScene& ds = on_devices.device_scene;
    std::fprintf(stderr, "[bench] %s: %d devices (%s)\n", scene.c_str(), set.size(), px::to_string(set.mode()));
    px::StereoPipeline::Options opt;
    opt.trace.spp = spp;
    opt.trace.bounces = bounces;
    if (!denoise) opt.denoise.reset();
    px::StereoPipeline fixed(set, ds, loaded.scene, width, height, opt);
    px::StereoPipeline moving(set, ds, loaded.scene, width, height, opt);
    px::StripBalancer::Options bo;
    bo.max_step_rows = step;
    px::StripBalancer balancer(height, set.size(), bo);
    ModeResult results[2];
    results[0].name = "static";
    results[1].name = "dynamic";
    px::StereoPipeline* pipelines[2] = {&fixed, &moving};
    unsigned mismatched = 0;
    double psnr = 0, rel_mse = 0;
    for (unsigned f = 0; f < warmup + frames; ++f) {
      std::array<px::ImageRGB, 2> images[2];
      for (int m = 0; m < 2; ++m) {
        px::StereoPipeline& p = *pipelines[m];
        const std::vector<px::RowRange> strips = p.strips();
        const px::FrameStats st = p.render(f, static_cast<float>(f) / fps);
        images[m] = p.radiance();
        const std::vector<double> busy = px::StereoPipeline::device_busy_ms(st, set.size());
        if (m == 1 && f + 1 >= warmup) {
          p.set_strips(px::strips_from_sizes(balancer.update(px::strip_sizes(strips), busy)));
        }
        if (f < warmup) continue;
        ModeResult& r = results[m];
        r.makespan_ms += st.wall_ms;
        r.frame_ms.push_back(st.wall_ms);
        const double slowest = *std::max_element(busy.begin(), busy.end());
        const double mean = std::accumulate(busy.begin(), busy.end(), 0.0) / busy.size();
        r.slowest_ms.push_back(slowest);
        r.imbalance.push_back(mean > 0 ? slowest / mean - 1.0 : 0.0);
        if (csv) {
          csv << r.name << ',' << f << ',' << st.wall_ms;
          for (double b : busy) csv << ',' << b;
          for (const auto& s : strips) csv << ',' << s.size();
          csv << '\n';
        }
      }
      for (int e = 0; e < 2; ++e)
        if (images[0][e].rgb.size() != images[1][e].rgb.size() ||
            std::memcmp(images[0][e].rgb.data(), images[1][e].rgb.data(), images[0][e].rgb.size() * sizeof(float)))
          ++mismatched;
      if (f == 0 && ref_spp > 0) {
        px::PathTracer tracer(set, ds, loaded.scene);
        px::ReferenceOptions ref_opt;
        ref_opt.spp = ref_spp;
        ref_opt.bounces = bounces;
        auto reference = px::render_reference(tracer, 0.0f, 0, width, height, ref_opt, px::eta_printer("reference"));
        const auto d = px::compare_images(images[0][1], reference[1]);
        psnr = d.psnr_db;
        rel_mse = d.rel_mse;
      }
    }
    std::printf("\n== %s, %ux%u per eye, %u spp, %u bounces, SVGF %s, %d devices (%s), %u frames after %u warm-up ==\n",
                scene.c_str(), width, height, spp, bounces, denoise ? "on" : "off", set.size(),
                px::to_string(set.mode()), frames, warmup);
    std::printf("%-8s %12s %10s %14s %14s  %s\n", "mode", "makespan ms", "median ms", "slowest busy", "imbalance",
                "strips (rows) at the end");
    for (int m = 0; m < 2; ++m) {
      const ModeResult& r = results[m];
      std::printf("%-8s %12.0f %10.1f %14.1f %13.1f%% ", r.name, r.makespan_ms, median(r.frame_ms),
                  median(r.slowest_ms), 100.0 * median(r.imbalance));
      for (const auto& s : pipelines[m]->strips()) std::printf(" %u", s.size());
      std::printf("\n");
    }
    std::printf("makespan static / dynamic: x%.2f; median slowest-device busy static / dynamic: x%.2f\n",
                results[0].makespan_ms / results[1].makespan_ms,
                median(results[0].slowest_ms) / median(results[1].slowest_ms));
    if (ref_spp > 0)
      std::printf("right eye, frame 0, vs %u spp reference: %.2f dB PSNR, relMSE %.4f (both modes)\n", ref_spp, psnr,
                  rel_mse);
    std::printf("images static vs dynamic: %s\n",
                mismatched ? (std::to_string(mismatched) + " eye-frames differ").c_str() : "bit-identical every frame");
    return mismatched ? 2 : 0;
  });
}
