// bench_speed_error: what each spp level costs and what it buys. For every scene: a converged
// reference (progressive, --ref-spp samples), then stereo frames at each --spp level, timed
// (median of --repeats) and compared with the reference (relative MSE and PSNR, both eyes).
//
//   build/bench_speed_error --scene cornell --scene atrium --width 128 --height 72
//       --ref-spp 4096 --spp 1 --spp 2 --spp 4 --spp 8 --devices 2 --csv speed_error.csv
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_bvh_layout.h"
#include "bench_common.h"
#include "image/image_metrics.h"
#include "render/path_tracer.h"
#include "render/reference_render.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>

namespace {
using clock_type = std::chrono::steady_clock;
using px::bench::median;
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_speed_error: ms per stereo frame vs error against a converged reference"};
  std::vector<std::string> scenes{"cornell", "atrium"};
  std::vector<unsigned> spps{1, 2, 4, 8};
  unsigned width = 128, height = 72, ref_spp = 4096, bounces = 6;
  int devices = 2, repeats = 5;
  std::string csv;
  app.add_option("--scene", scenes)->capture_default_str();
  app.add_option("--spp", spps, "spp levels to measure")->capture_default_str();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--ref-spp", ref_spp, "samples of the reference")->capture_default_str();
  app.add_option("--bounces", bounces)->capture_default_str();
  app.add_option("--devices", devices)->capture_default_str();
  app.add_option("--repeats", repeats, "timed frames per level (median)")->capture_default_str();
  app.add_option("--csv", csv, "write the table as CSV");
  px::DirectLight direct_light = px::PathTracer::Options{}.direct_light;
  px::bench::add_direct_light_flag(app, direct_light);
  CLI11_PARSE(app, argc, argv);

  struct Row {
    std::string scene;
    unsigned spp;
    double wall_ms, device_ms, rel_mse, psnr;
  };
  std::vector<Row> rows;
  const int rc = px::run_guarded([&]() -> int {
    for (const auto& name : scenes) {
      px::SceneOnDevices on_devices(name, {devices, px::DeviceMode::Auto, "", std::nullopt});
      px::PathTracer tracer(on_devices.devices, on_devices.device_scene, on_devices.loaded.scene);
      px::PathTracer::Options opt;
      opt.bounces = bounces;
      opt.direct_light = direct_light;
      px::ReferenceOptions ref_opt;
      ref_opt.spp = ref_spp;
      ref_opt.bounces = bounces;
      const auto ref =
          px::render_reference(tracer, 0.0f, 0, width, height, ref_opt, px::eta_printer(name + " reference"));
      opt.seed = 0;
      for (unsigned spp : spps) {
        opt.spp = spp;
        tracer.render_stereo(0.0f, 0, width, height, opt);  // warm-up (kernel compile for this launch shape)
        std::vector<double> wall, dev;
        double rel = 0, psnr = 0;
        for (int r = 0; r < repeats; ++r) {
          auto t = clock_type::now();
          auto eyes = tracer.render_stereo(0.0f, 0, width, height, opt, 1000000u * (r + 1));
          wall.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t).count());
          dev.push_back(*std::max_element(tracer.last_device_ms().begin(), tracer.last_device_ms().end()));
          for (int e = 0; e < 2; ++e) {
            auto d = px::compare_images(eyes[e], ref[e]);
            rel += d.rel_mse / (2.0 * repeats);
            psnr += d.psnr_db / (2.0 * repeats);
          }
        }
        rows.push_back({name, spp, median(wall), median(dev), rel, psnr});
      }
    }
    return 0;
  });
  if (rc != 0) return rc;
  std::printf("\n%-10s %5s %14s %14s %12s %10s\n", "scene", "spp", "ms/frame wall", "ms/frame dev", "relMSE",
              "PSNR dB");
  for (const auto& r : rows)
    std::printf("%-10s %5u %14.1f %14.1f %12.5f %10.2f\n", r.scene.c_str(), r.spp, r.wall_ms, r.device_ms, r.rel_mse,
                r.psnr);
  std::printf(
      "\n%ux%u per eye, stereo frame = both eyes, %d devices, %u bounces; medians of %d frames; error vs a "
      "%u spp reference, mean of both eyes and of the frames\n",
      width, height, devices, bounces, repeats, ref_spp);
  if (!csv.empty()) {
    std::ofstream out(csv);
    out << "scene,spp,wall_ms,device_ms,rel_mse,psnr_db\n";
    for (const auto& r : rows)
      out << r.scene << ',' << r.spp << ',' << r.wall_ms << ',' << r.device_ms << ',' << r.rel_mse << ',' << r.psnr
          << '\n';
  }
  return 0;
}
