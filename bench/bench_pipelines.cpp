// bench_pipelines: proposed vs baseline vs mono, side by side in one process, on the same
// devices, scene and camera animation. Reports per pipeline the makespan of the animation
// (warm-up frames excluded), per stage and device the median device time (the paper's
// Table 1 for this machine), the ratios baseline/proposed and mono/proposed, and the right
// eye's error against converged references of frame 0 and of the last frame, so every speed
// figure has its error (the last frame's with the denoiser's history behind it).
//
//   build/bench_pipelines --scene atrium --width 160 --height 90 --frames 50 --devices 2
//       --ref-spp 1024 --csv pipelines.csv --summary-csv makespan.csv --frames-csv frames.csv
//
// The CSVs feed scripts/evaluate (Tables 1 and 2 of the paper, and the frame-time plot).
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_bvh_layout.h"
#include "bench_common.h"
#include "cl/device_set.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/path_tracer.h"
#include "render/reference_render.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>

namespace {

using px::bench::median;

struct PipelineResult {
  std::string name;
  double makespan_ms = 0, median_frame_ms = 0, reprojected = 0;
  std::map<std::pair<int, int>, std::vector<double>> stage_ms;  // (stage, device) -> per frame
  double right_psnr = 0, right_rel_mse = 0;                     // frame 0: no history yet
  double last_right_psnr = 0, last_right_rel_mse = 0;           // the last frame, with history
  std::vector<double> frame_ms;                                 // wall time of each timed frame
  int owner = 0;
};

// With --compare-kernels: each scene-dependent kernel's private memory per work-item
// (CL_KERNEL_PRIVATE_MEM_SIZE: on a GPU, registers spilled to memory) built for the scene's
// features and with every feature.
void print_kernel_private_memory(px::DeviceSet& set, px::DeviceScene& ds) {
  const std::pair<const char*, const char*> kernels[] = {{"pathtrace/path_trace.cl", "path_trace"},
                                                         {"pathtrace/path_trace.cl", "path_trace_list"},
                                                         {"pathtrace/wavefront.cl", "wf_shade"},
                                                         {"pipeline/gbuffer.cl", "gbuffer"},
                                                         {"trace/trace_rays.cl", "trace_closest"}};
  const cl::Device& device = set.devices()[0].device;
  std::printf("private memory per work-item (bytes, CL_KERNEL_PRIVATE_MEM_SIZE): scene kernels / general kernels\n");
  const px::KernelChoice before = ds.kernel_choice();
  for (const auto& [path, name] : kernels) {
    std::size_t bytes[2] = {0, 0};
    for (int general = 0; general < 2; ++general) {
      ds.set_kernel_choice(general ? px::KernelChoice::General : px::KernelChoice::Scene);
      cl::Kernel k(set.program(path, ds.kernel_options()), name);
      bytes[general] = k.getWorkGroupInfo<CL_KERNEL_PRIVATE_MEM_SIZE>(device);
    }
    std::printf("  %-18s %8zu / %zu\n", name, bytes[0], bytes[1]);
  }
  ds.set_kernel_choice(before);
}

// A pipeline's name in a 9-character column header.
std::string short_name(const std::string& name) {
  if (name == "proposed-1q") return "p-1q";
  if (name == "proposed-gpass") return "p-gp";
  if (name == "proposed-general") return "p-gen";
  return name.substr(0, 4);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_pipelines: proposed vs baseline vs mono on one camera animation"};
  std::vector<std::string> scenes{"atrium", "cornell"};
  unsigned width = 160, height = 90, frames = 50, warmup = 2, spp = 1, bounces = 6, ref_spp = 1024;
  int devices = 2;
  float fps = 30.0f;
  std::string csv, summary_csv, frames_csv;
  bool compare_overlap = false, compare_gbuffer = false, compare_kernels = false;
  std::string hole_spread = "auto", atrous_tiles = "auto";
  app.add_option("--scene", scenes)->capture_default_str();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--frames", frames, "timed frames of the camera animation")->capture_default_str();
  app.add_option("--warmup", warmup, "untimed frames first (kernel compilation)")->capture_default_str();
  app.add_option("--spp", spp)->capture_default_str();
  app.add_option("--bounces", bounces)->capture_default_str();
  app.add_option("--devices", devices)->capture_default_str();
  std::optional<px::BvhLayout> bvh_layout;
  px::bench::add_bvh_layout_flag(app, bvh_layout);
  px::DirectLight direct_light = px::PathTracer::Options{}.direct_light;
  px::bench::add_direct_light_flag(app, direct_light);
  app.add_option("--fps", fps, "camera-path time step")->capture_default_str();
  app.add_option("--ref-spp", ref_spp, "samples of the frame-0 reference (0 = skip the error figures)")
      ->capture_default_str();
  app.add_option("--csv", csv, "per stage and device medians as CSV (owner = 1 on the owner device)");
  app.add_option("--summary-csv", summary_csv, "per scene and pipeline: makespan, Hz, error vs the reference");
  app.add_option("--frames-csv", frames_csv, "per scene, pipeline and timed frame: wall ms");
  app.add_flag("--compare-overlap", compare_overlap,
               "run proposed with the side queue forced on (on CPUs it is off by default), and again with one "
               "queue per device as pipeline 'proposed-1q', for the side queue's speed-up side by side");
  app.add_flag("--compare-gbuffer", compare_gbuffer,
               "run proposed again with the left eye's G-buffer traced by its own pass (stage 3) instead of "
               "written by the path tracer, as pipeline 'proposed-gpass' (images are identical)");
  app.add_flag("--compare-kernels", compare_kernels,
               "run proposed again with every kernel feature compiled in (--kernels general), as pipeline "
               "'proposed-general', beside the kernels built for the scene's features (images are identical)");
  std::string path_tracer = "megakernel";
  app.add_option("--path-tracer", path_tracer,
                 "stages 2, 5 and 12: megakernel or wavefront (a kernel per path step; images are identical)")
      ->check(CLI::IsMember({"megakernel", "wavefront"}))
      ->capture_default_str();
  app.add_option("--hole-spread", hole_spread,
                 "stage 5's work-items: auto (a (hole, sample) pair each on GPUs at 2-8 spp, else a hole each), "
                 "on, off (images are identical)")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  app.add_option("--atrous-tiles", atrous_tiles,
                 "SVGF's a-trous steps 1-4 from local-memory tiles: auto (on GPUs), on, off (images are identical)")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  using Spread = px::HoleFillStage::SampleSpread;
  const Spread spread = hole_spread == "on" ? Spread::On : hole_spread == "off" ? Spread::Off : Spread::Auto;
  if (frames == 0 || width == 0 || height == 0 || devices < 1) {
    std::fprintf(stderr, "bench_pipelines: --frames, --width, --height and --devices must be positive\n");
    return 1;
  }

  std::ofstream csv_out, summary_out, frames_out;
  if (!csv.empty()) {
    csv_out.open(csv);
    csv_out << "scene,pipeline,stage,stage_name,device,owner,median_device_ms\n";
  }
  if (!summary_csv.empty()) {
    summary_out.open(summary_csv);
    summary_out << "scene,pipeline,devices,device_mode,width,height,spp,bounces,frames,makespan_ms,median_frame_ms,hz,"
                   "reprojected,ref_spp,right_psnr_db,right_rel_mse,last_right_psnr_db,last_right_rel_mse,path_tracer,"
                   "bvh_layout\n";
  }
  if (!frames_csv.empty()) {
    frames_out.open(frames_csv);
    frames_out << "scene,pipeline,frame,wall_ms\n";
  }
  if ((!csv.empty() && !csv_out) || (!summary_csv.empty() && !summary_out) || (!frames_csv.empty() && !frames_out)) {
    std::fprintf(stderr, "bench_pipelines: cannot write a CSV file\n");
    return 1;
  }
  return px::run_guarded([&]() -> int {
    for (const auto& name : scenes) {
      px::SceneOnDevices on_devices(name, {devices, px::DeviceMode::Auto, "", bvh_layout});
      const px::Scene& scene = on_devices.loaded.scene;
      px::DeviceSet& set = on_devices.devices;
      const px::DeviceScene& ds = on_devices.device_scene;
      std::fprintf(stderr, "[bench] %s: %d devices (%s), BVH nodes %s\n", name.c_str(), set.size(),
                   px::to_string(set.mode()), px::to_string(set.bvh_layout()));

      // References of frame 0 and of the last frame (the camera moves between them).
      const unsigned last = warmup + frames - 1;
      std::array<px::ImageRGB, 2> reference, last_reference;
      if (ref_spp > 0) {
        px::PathTracer tracer(set, ds, scene);
        px::ReferenceOptions ref_opt;
        ref_opt.spp = ref_spp;
        ref_opt.bounces = bounces;
        reference = px::render_reference(tracer, 0.0f, 0, width, height, ref_opt, px::eta_printer(name + " reference"));
        last_reference = px::render_reference(tracer, static_cast<float>(last) / fps, last, width, height, ref_opt,
                                              px::eta_printer(name + " reference, last frame"));
      }

      std::vector<PipelineResult> results;
      // Proposed, baseline and mono (results 0-2), then proposed on one queue per device.
      // With --compare-overlap: proposed with the side queue forced on, and proposed-1q without.
      // With --compare-gbuffer: proposed-gpass, whose G-buffer pass traces the left eye too.
      struct Run {
        px::PipelineKind kind;
        px::Overlap overlap = px::Overlap::Auto;
        bool gbuffer_from_path_tracer = true;
        std::string name;
        px::KernelChoice kernels = px::KernelChoice::Scene;
      };
      std::vector<Run> runs;
      for (px::PipelineKind kind : {px::PipelineKind::Proposed, px::PipelineKind::Baseline, px::PipelineKind::Mono})
        runs.push_back({kind, px::Overlap::Auto, true, px::to_string(kind)});
      if (compare_overlap) {
        runs[0].overlap = px::Overlap::On;
        runs.push_back({px::PipelineKind::Proposed, px::Overlap::Off, true, "proposed-1q"});
      }
      if (compare_gbuffer) runs.push_back({px::PipelineKind::Proposed, runs[0].overlap, false, "proposed-gpass"});
      if (compare_kernels)
        runs.push_back(
            {px::PipelineKind::Proposed, runs[0].overlap, true, "proposed-general", px::KernelChoice::General});
      std::fprintf(stderr, "[bench] %s: kernels for the scene's features: %s\n", name.c_str(),
                   px::describe_kernel_features(ds.scene_features()).c_str());
      for (const Run& run : runs) {
        px::StereoPipeline::Options opt;
        opt.pipeline = run.kind;
        opt.trace.spp = spp;
        opt.trace.bounces = bounces;
        opt.trace.direct_light = direct_light;
        opt.overlap = run.overlap;
        opt.gbuffer_from_path_tracer = run.gbuffer_from_path_tracer;
        opt.hole_fill.spread = spread;
        opt.denoise->svgf.atrous_tiles = atrous_tiles == "on" ? 1 : atrous_tiles == "off" ? 0 : -1;
        opt.path_kernel = px::parse_path_trace_kernel(path_tracer);
        // Programs are looked up at each launch with the scene's current choice: set for this run.
        on_devices.device_scene.set_kernel_choice(run.kernels);
        px::StereoPipeline pipeline(set, ds, scene, width, height, opt);
        PipelineResult r;
        r.name = run.name;
        r.owner = pipeline.schedule().tree.root;
        std::vector<double> frame_ms;
        double reprojected = 0;
        for (unsigned f = 0; f < warmup + frames; ++f) {
          const auto st = pipeline.render(f, static_cast<float>(f) / fps);
          if (f == 0 && ref_spp > 0) {
            auto d = px::compare_images(pipeline.radiance()[1], reference[1]);
            r.right_psnr = d.psnr_db;
            r.right_rel_mse = d.rel_mse;
          }
          if (f == last && ref_spp > 0) {
            auto d = px::compare_images(pipeline.radiance()[1], last_reference[1]);
            r.last_right_psnr = d.psnr_db;
            r.last_right_rel_mse = d.rel_mse;
          }
          if (f < warmup) continue;
          frame_ms.push_back(st.wall_ms);
          if (frames_out) frames_out << name << ',' << r.name << ',' << f << ',' << st.wall_ms << '\n';
          r.makespan_ms += st.wall_ms;
          reprojected += st.right_pixels ? double(st.reprojected) / st.right_pixels : 0.0;
          for (const auto& s : st.stages) r.stage_ms[{static_cast<int>(s.stage), s.device}].push_back(s.ms);
        }
        r.median_frame_ms = median(frame_ms);
        r.frame_ms = frame_ms;
        r.reprojected = reprojected / frames;
        std::fprintf(stderr, "[bench] %s %s: makespan %.0f ms over %u frames\n", name.c_str(), r.name.c_str(),
                     r.makespan_ms, frames);
        results.push_back(std::move(r));
      }

      std::printf("\n== %s, %ux%u per eye, %u spp, %u bounces, %d devices (%s), %u frames after %u warm-up ==\n",
                  name.c_str(), width, height, spp, bounces, set.size(), px::to_string(set.mode()), frames, warmup);
      std::printf("%-16s %12s %12s %8s %12s %10s %10s %10s %10s\n", "pipeline", "makespan ms", "median ms", "Hz",
                  "reprojected", "right PSNR", "right rMSE", "last PSNR", "last rMSE");
      for (const auto& r : results)
        std::printf("%-16s %12.0f %12.1f %8.2f %11.1f%% %10.2f %10.4f %10.2f %10.4f\n", r.name.c_str(), r.makespan_ms,
                    r.median_frame_ms, 1000.0 * frames / r.makespan_ms, 100.0 * r.reprojected, r.right_psnr,
                    r.right_rel_mse, r.last_right_psnr, r.last_right_rel_mse);
      if (ref_spp > 0)
        std::printf("error: right eye vs %u-spp references of frame 0 (no history yet) and of frame %u (last)\n",
                    ref_spp, last);
      if (summary_out)
        for (const auto& r : results)
          summary_out << name << ',' << r.name << ',' << set.size() << ',' << px::to_string(set.mode()) << ',' << width
                      << ',' << height << ',' << spp << ',' << bounces << ',' << frames << ',' << r.makespan_ms << ','
                      << r.median_frame_ms << ',' << 1000.0 * frames / r.makespan_ms << ',' << r.reprojected << ','
                      << ref_spp << ',' << r.right_psnr << ',' << r.right_rel_mse << ',' << r.last_right_psnr << ','
                      << r.last_right_rel_mse << ',' << path_tracer << ',' << px::to_string(set.bvh_layout()) << '\n';
      std::printf("speed-up proposed vs baseline: x%.2f (makespan ratio); proposed vs mono: x%.2f\n",
                  results[1].makespan_ms / results[0].makespan_ms, results[2].makespan_ms / results[0].makespan_ms);
      if (compare_kernels) print_kernel_private_memory(set, on_devices.device_scene);
      for (const auto& r : results) {
        if (r.name == "proposed-1q")
          std::printf("side queue: proposed vs proposed-1q: x%.2f (makespan ratio)\n",
                      r.makespan_ms / results[0].makespan_ms);
        if (r.name == "proposed-gpass")
          std::printf("G-buffer from the path tracer: proposed vs proposed-gpass: x%.2f (makespan ratio)\n",
                      r.makespan_ms / results[0].makespan_ms);
        if (r.name == "proposed-general")
          std::printf("kernels for the scene's features (%s): proposed vs proposed-general: x%.2f (makespan ratio)\n",
                      px::describe_kernel_features(ds.scene_features()).c_str(),
                      r.makespan_ms / results[0].makespan_ms);
      }
      std::printf("\nmedian device ms per frame, by stage and device:\n%-22s", "stage");
      for (const auto& r : results)
        for (int d = 0; d < set.size(); ++d)
          std::printf(" %9s", (short_name(r.name) + "/d" + std::to_string(d)).c_str());
      std::printf("\n");
      for (int stage : {2, 12, 3, 4, 5, 6, 7, 8, 9}) {
        std::printf("%-3d %-18s", stage, px::stage_name(static_cast<px::Stage>(stage)));
        for (const auto& r : results)
          for (int d = 0; d < set.size(); ++d) {
            auto it = r.stage_ms.find({stage, d});
            const double m = it == r.stage_ms.end() ? 0.0 : median(it->second);
            std::printf(" %9.2f", m);
            if (csv_out && it != r.stage_ms.end())
              csv_out << name << ',' << r.name << ',' << stage << ',' << px::stage_name(static_cast<px::Stage>(stage))
                      << ',' << d << ',' << (d == r.owner) << ',' << m << '\n';
          }
        std::printf("\n");
      }
    }
    return 0;
  });
}
