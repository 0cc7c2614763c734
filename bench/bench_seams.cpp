// bench_seams: what the strip borders cost when denoising is distributed. For each seam mode
// (independent, bilateral, halo) on N devices, and a 1-device run, over the same camera
// animation: the median denoising device time per device (stage 6, halo copies counted under
// transfers and listed separately), and at the last frame the PSNR against a converged
// reference over the whole image and in 8-row bands centred on each seam (the paper's seam
// measure), plus the difference from the 1-device image, the relative MSE and CAMBI (banding,
// host/image/cambi.h) over the whole image.
//
// With --per-frame-csv the same error figures are measured at every frame after the first,
// each against its own converged reference (the paper's Fig. 5; references cost frames x
// --ref-spp samples). With --images the last frame of every mode and its reference are
// written as stereo PNGs, for a person to look at the seams.
//
//   build/bench_seams --scene atrium --width 160 --height 90 --frames 8 --devices 2 --ref-spp 1024
//       --csv seams.csv --per-frame-csv seams_frames.csv --images seam_images/
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_common.h"
#include "image/cambi.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/reference_render.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

namespace {

using px::bench::median;

struct ModeResult {
  std::string name;
  int devices = 1;
  std::vector<double> denoise_ms, exchange_ms;  // per device: median over frames
  double psnr = 0, band_psnr = 0, band_psnr_vs_single = 0, rel_mse = 0, cambi = 0;
};

// Error of both eyes of one frame: whole-image PSNR and relMSE (means of the eyes), seam-band
// PSNR, CAMBI of the image as shown (8-bit) and of the reference.
struct FrameError {
  double psnr = 0, rel_mse = 0, band_psnr = 0, band_psnr_vs_single = 0, cambi = 0;
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
  std::string csv, per_frame_csv, images;
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
  app.add_option("--csv", csv, "per mode and device: denoising time and the last frame's error");
  app.add_option("--per-frame-csv", per_frame_csv, "per mode and frame: error against that frame's reference");
  app.add_option("--images", images, "folder for stereo PNGs of the last frame of every mode and the reference");
  CLI11_PARSE(app, argc, argv);
  if (frames < 2 || width == 0 || height < 2 || devices < 1 || ref_spp == 0) {
    std::fprintf(stderr, "bench_seams: needs --frames >= 2, --height >= 2, positive --width, --devices, --ref-spp\n");
    return 1;
  }

  return px::run_guarded([&]() -> int {
    const px::LoadedScene loaded = px::load_and_build(scene);
    // references[f]: converged image of frame f (only the last one without --per-frame-csv).
    std::vector<std::array<px::ImageRGB, 2>> references(frames);
    {
      px::SceneOnDevices on_devices(loaded, {devices, px::DeviceMode::Auto, "", std::nullopt});
      px::PathTracer tracer(on_devices.devices, on_devices.device_scene, on_devices.loaded.scene);
      px::ReferenceOptions ro;
      ro.spp = ref_spp;
      ro.bounces = bounces;
      for (unsigned f = per_frame_csv.empty() ? frames - 1 : 1; f < frames; ++f)
        references[f] = px::render_reference(tracer, static_cast<float>(f) / fps, f, width, height, ro,
                                             px::eta_printer(scene + " reference " + std::to_string(f)));
    }
    const auto& reference = references[frames - 1];
    px::CambiOptions cambi_opt;  // 8 bits: as our PNGs show the image
    auto cambi_of = [&](const std::array<px::ImageRGB, 2>& eyes) {
      return 0.5 * (px::cambi(eyes[0], cambi_opt).score + px::cambi(eyes[1], cambi_opt).score);
    };
    // Seams of the N-device split, and the 8-row bands centred on them.
    const auto strips = px::split_rows(height, static_cast<unsigned>(devices));
    std::vector<std::pair<int, int>> bands;
    for (std::size_t i = 1; i < strips.size(); ++i) {
      const int s = static_cast<int>(strips[i].begin);
      bands.push_back({std::max(0, s - 4), std::min(static_cast<int>(height), s + 4)});
    }

    std::vector<ModeResult> results;
    std::array<px::ImageRGB, 2> single_image;
    std::vector<std::array<px::ImageRGB, 2>> single_frames(frames);  // 1-device image per frame
    std::vector<std::vector<FrameError>> per_frame;                  // [mode][frame]
    auto frame_error = [&](const std::array<px::ImageRGB, 2>& image, unsigned f) {
      FrameError e;
      for (int k = 0; k < 2; ++k) {
        const auto d = px::compare_images(image[k], references[f][k]);
        e.psnr += 0.5 * d.psnr_db;
        e.rel_mse += 0.5 * d.rel_mse;
      }
      e.band_psnr = band_psnr(image, references[f], bands);
      e.band_psnr_vs_single = single_frames[f][0].width ? band_psnr(image, single_frames[f], bands) : 0.0;
      e.cambi = cambi_of(image);
      return e;
    };
    if (!images.empty()) std::filesystem::create_directories(images);
    auto write_stereo = [&](const std::string& file, const std::array<px::ImageRGB, 2>& eyes) {
      const auto l = px::to_srgb8(eyes[0]), r = px::to_srgb8(eyes[1]);
      px::write_png((std::filesystem::path(images) / file).string(), 2 * width, height,
                    px::side_by_side(l, r, width, height));
    };
    if (!images.empty()) write_stereo("reference.png", reference);
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
      // Fresh devices for every mode (the scene is loaded once and copied).
      px::SceneOnDevices on_devices(loaded, {c.devices, px::DeviceMode::Auto, "", std::nullopt});
      px::StereoPipeline::Options opt;
      opt.pipeline = px::PipelineKind::Proposed;
      opt.trace.spp = spp;
      opt.trace.bounces = bounces;
      opt.denoise->seams = c.mode;
      opt.denoise->svgf.iterations = iterations;
      px::StereoPipeline pipeline(on_devices.devices, on_devices.device_scene, on_devices.loaded.scene, width, height,
                                  opt);
      ModeResult r;
      r.name = c.name;
      r.devices = c.devices;
      std::vector<std::vector<double>> den(c.devices), xfer(c.devices);
      std::vector<FrameError> errors(frames);
      for (unsigned f = 0; f < frames; ++f) {
        const auto st = pipeline.render(f, static_cast<float>(f) / fps);
        if (f == 0) continue;                            // kernel compilation
        if (!per_frame_csv.empty() && f + 1 < frames) {  // the last frame is measured below
          const auto image = pipeline.radiance();
          if (c.devices == 1) single_frames[f] = image;
          errors[f] = frame_error(image, f);
        }
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
      if (c.devices == 1) single_image = single_frames[frames - 1] = image;
      errors[frames - 1] = frame_error(image, frames - 1);
      r.psnr = errors[frames - 1].psnr;
      r.rel_mse = errors[frames - 1].rel_mse;
      r.band_psnr = errors[frames - 1].band_psnr;
      r.band_psnr_vs_single = errors[frames - 1].band_psnr_vs_single;
      r.cambi = errors[frames - 1].cambi;
      per_frame.push_back(std::move(errors));
      if (!images.empty()) write_stereo(std::string(c.devices == 1 ? "single" : c.name) + ".png", image);
      std::fprintf(stderr, "[bench] %s done\n", c.name);
      results.push_back(std::move(r));
    }

    std::printf("\n== %s, %ux%u per eye, %u spp, %u SVGF iterations, %u frames (error at the last), seams at rows:",
                scene.c_str(), width, height, spp, iterations, frames);
    for (auto [a, b] : bands) std::printf(" %d", (a + b) / 2);
    std::printf(" ==\n%-12s %-24s %-24s %10s %10s %12s %14s %8s\n", "mode", "denoise ms/device", "transfer ms/device",
                "PSNR dB", "relMSE", "seam-band dB", "band vs 1-dev", "CAMBI");
    std::ofstream out;
    if (!csv.empty()) {
      out.open(csv);
      if (!out) throw std::runtime_error("cannot write " + csv);
      out << "scene,mode,devices,device,denoise_ms,transfer_ms,psnr_db,rel_mse,seam_band_psnr_db,"
             "band_psnr_vs_single_db,cambi,reference_cambi,ref_spp\n";
    }
    const double reference_cambi = cambi_of(reference);
    for (const auto& r : results) {
      std::string d, x;
      for (int k = 0; k < r.devices; ++k) {
        d += (k ? " / " : "") + std::to_string(r.denoise_ms[k]).substr(0, 6);
        x += (k ? " / " : "") + std::to_string(r.exchange_ms[k]).substr(0, 5);
        if (out)
          out << scene << ',' << r.name << ',' << r.devices << ',' << k << ',' << r.denoise_ms[k] << ','
              << r.exchange_ms[k] << ',' << r.psnr << ',' << r.rel_mse << ',' << r.band_psnr << ','
              << r.band_psnr_vs_single << ',' << r.cambi << ',' << reference_cambi << ',' << ref_spp << '\n';
      }
      std::printf("%-12s %-24s %-24s %10.2f %10.4f %12.2f %14.2f %8.4f\n", r.name.c_str(), d.c_str(), x.c_str(), r.psnr,
                  r.rel_mse, r.band_psnr, r.band_psnr_vs_single, r.cambi);
    }
    std::printf("reference CAMBI %.4f\n", reference_cambi);
    if (!per_frame_csv.empty()) {
      std::ofstream pf(per_frame_csv);
      if (!pf) throw std::runtime_error("cannot write " + per_frame_csv);
      pf << "scene,mode,frame,psnr_db,rel_mse,seam_band_psnr_db,band_psnr_vs_single_db,cambi\n";
      for (std::size_t m = 0; m < results.size(); ++m)
        for (unsigned f = 1; f < frames; ++f) {
          const auto& e = per_frame[m][f];
          pf << scene << ',' << results[m].name << ',' << f << ',' << e.psnr << ',' << e.rel_mse << ',' << e.band_psnr
             << ',' << e.band_psnr_vs_single << ',' << e.cambi << '\n';
        }
    }
    std::printf(
        "\nmedians over frames 1..%u (frame 0 compiles kernels); PSNR vs a %u spp reference, mean of both eyes; "
        "'band vs 1-dev' = PSNR of the seam bands against the 1-device denoised image (inf = identical)\n",
        frames - 1, ref_spp);
    return 0;
  });
}
