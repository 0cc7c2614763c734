// bench_seams: what the strip borders cost when denoising is distributed. For each seam mode
// (independent, bilateral, halo) on N devices, and a 1-device run, over the same camera
// animation: the median denoising device time per device (stage 6, halo copies counted under
// transfers and listed separately), and at the last frame the PSNR against a converged
// reference over the whole image and in 8-row bands centred on each seam (the paper's seam
// measure), plus the difference from the 1-device image.
//
//   build/bench_seams --scene atrium --width 160 --height 90 --frames 8 --devices 2 --ref-spp 1024
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_common.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/reference_render.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <map>

namespace {

using px::bench::median;

struct ModeResult {
  std::string name;
  int devices = 1;
  std::vector<double> denoise_ms, exchange_ms;  // per device: median over frames
  double psnr = 0, band_psnr = 0, band_psnr_vs_single = 0;
};

// Mean PSNR of both eyes over the rows in `bands`.
double band_psnr(const std::array<px::ImageRGB, 2>& a, const std::array<px::ImageRGB, 2>& b,
                 const std::vector<std::pair<int, int>>& bands) {
  double sum = 0;
  int n = 0;
  for (int e = 0; e < 2; ++e)
    for (auto [r0, r1] : bands) {
      sum += px::compare_images(a[e], b[e], r0, r1).psnr_db;
      ++n;
    }
  return n ? sum / n : 0.0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_seams: denoising cost and seam error per seam mode"};
  std::string scene = "atrium";
  unsigned width = 160, height = 90, frames = 8, spp = 1, bounces = 6, ref_spp = 1024, iterations = 5;
  int devices = 2;
  float fps = 30.0f;
  std::string csv;
  app.add_option("--scene", scene)->capture_default_str();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--frames", frames, "frames of the animation (error measured at the last)")->capture_default_str();
  app.add_option("--spp", spp)->capture_default_str();
  app.add_option("--bounces", bounces)->capture_default_str();
  app.add_option("--devices", devices)->capture_default_str();
  app.add_option("--svgf-iterations", iterations)->capture_default_str();
  app.add_option("--ref-spp", ref_spp)->capture_default_str();
  app.add_option("--fps", fps)->capture_default_str();
  app.add_option("--csv", csv);
  CLI11_PARSE(app, argc, argv);

  return px::run_guarded([&]() -> int {
    auto loaded = px::load_and_build(scene);
    const float last_time = static_cast<float>(frames - 1) / fps;
    std::array<px::ImageRGB, 2> reference;
    {
      auto set = px::DeviceSet::create({devices, px::DeviceMode::Auto, ""});
      px::DeviceScene ds(set, loaded.scene, loaded.bvh);
      px::PathTracer tracer(set, ds, loaded.scene);
      px::ReferenceOptions ro;
      ro.spp = ref_spp;
      ro.bounces = bounces;
      reference = px::render_reference(tracer, last_time, frames - 1, width, height, ro, px::eta_printer("reference"));
    }
    // Seams of the N-device split, and the 8-row bands centred on them.
    const auto strips = px::split_rows(height, static_cast<unsigned>(devices));
    std::vector<std::pair<int, int>> bands;
    for (std::size_t i = 1; i < strips.size(); ++i) {
      const int s = static_cast<int>(strips[i].begin);
      bands.push_back({std::max(0, s - 4), std::min(static_cast<int>(height), s + 4)});
    }

    std::vector<ModeResult> results;
    std::array<px::ImageRGB, 2> single_image;
    struct Config {
      const char* name;
      int devices;
      px::SeamMode mode;
    };
    const Config configs[] = {{"1 device", 1, px::SeamMode::Halo},
                              {"independent", devices, px::SeamMode::Independent},
                              {"bilateral", devices, px::SeamMode::Bilateral},
                              {"halo", devices, px::SeamMode::Halo}};
    for (const Config& c : configs) {
      auto set = px::DeviceSet::create({c.devices, px::DeviceMode::Auto, ""});
      px::DeviceScene ds(set, loaded.scene, loaded.bvh);
      px::StereoPipeline::Options opt;
      opt.pipeline = px::PipelineKind::Proposed;
      opt.trace.spp = spp;
      opt.trace.bounces = bounces;
      opt.seams = c.mode;
      opt.svgf.iterations = iterations;
      px::StereoPipeline pipeline(set, ds, loaded.scene, width, height, opt);
      ModeResult r;
      r.name = c.name;
      r.devices = c.devices;
      std::vector<std::vector<double>> den(c.devices), xfer(c.devices);
      for (unsigned f = 0; f < frames; ++f) {
        const auto st = pipeline.render(f, static_cast<float>(f) / fps);
        if (f == 0) continue;  // kernel compilation
        std::vector<double> d(c.devices, 0.0), x(c.devices, 0.0);
        for (const auto& s : st.stages) {
          if (s.stage == px::Stage::Denoise || s.stage == px::Stage::RecordPrevious) d[s.device] += s.ms;
          if (s.stage == px::Stage::Transfer) x[s.device] += s.ms;
        }
        for (int k = 0; k < c.devices; ++k) {
          den[k].push_back(d[k]);
          xfer[k].push_back(x[k]);
        }
      }
      for (int k = 0; k < c.devices; ++k) {
        r.denoise_ms.push_back(median(den[k]));
        r.exchange_ms.push_back(median(xfer[k]));
      }
      const auto image = pipeline.radiance();
      if (c.devices == 1) single_image = image;
      r.psnr = 0.5 * (px::compare_images(image[0], reference[0]).psnr_db + px::compare_images(image[1], reference[1]).psnr_db);
      r.band_psnr = band_psnr(image, reference, bands);
      r.band_psnr_vs_single = band_psnr(image, single_image, bands);
      std::fprintf(stderr, "[bench] %s done\n", c.name);
      results.push_back(std::move(r));
    }

    std::printf("\n== %s, %ux%u per eye, %u spp, %u SVGF iterations, %u frames (error at the last), seams at rows:",
                scene.c_str(), width, height, spp, iterations, frames);
    for (auto [a, b] : bands) std::printf(" %d", (a + b) / 2);
    std::printf(" ==\n%-12s %-24s %-24s %10s %12s %14s\n", "mode", "denoise ms/device", "transfer ms/device", "PSNR dB",
                "seam-band dB", "band vs 1-dev");
    std::ofstream out;
    if (!csv.empty()) {
      out.open(csv);
      out << "mode,devices,device,denoise_ms,transfer_ms,psnr_db,seam_band_psnr_db,band_psnr_vs_single_db\n";
    }
    for (const auto& r : results) {
      std::string d, x;
      for (int k = 0; k < r.devices; ++k) {
        d += (k ? " / " : "") + std::to_string(r.denoise_ms[k]).substr(0, 6);
        x += (k ? " / " : "") + std::to_string(r.exchange_ms[k]).substr(0, 5);
        if (out)
          out << r.name << ',' << r.devices << ',' << k << ',' << r.denoise_ms[k] << ',' << r.exchange_ms[k] << ','
              << r.psnr << ',' << r.band_psnr << ',' << r.band_psnr_vs_single << '\n';
      }
      std::printf("%-12s %-24s %-24s %10.2f %12.2f %14.2f\n", r.name.c_str(), d.c_str(), x.c_str(), r.psnr, r.band_psnr,
                  r.band_psnr_vs_single);
    }
    std::printf("\nmedians over frames 1..%u (frame 0 compiles kernels); PSNR vs a %u spp reference, mean of both eyes; "
                "'band vs 1-dev' = PSNR of the seam bands against the 1-device denoised image (inf = identical)\n",
                frames - 1, ref_spp);
    return 0;
  });
}
