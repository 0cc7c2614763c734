// parallax command line: parses flags into the command structs of app/commands.h and runs
// one. No rendering logic lives here.
#include "app/cli_enums.h"
#include "app/commands.h"
#include "app/guarded_main.h"
#include "cluster/cluster.h"

#include <CLI/CLI.hpp>

#include <cstdio>

namespace {

// A flag that takes one of the words of `words` (app/cli_enums.h) and stores the enum value it
// stands for; the help lists the words in the table's order and shows the word of `value`'s
// starting value as the default, as it does for a text flag.
template <typename Enum>
CLI::Option* add_word_option(CLI::App* cmd, const std::string& name, Enum& value, const px::WordTable<Enum>& words,
                             const std::string& help) {
  // transform() puts each validator before those added earlier, so IsMember runs first: an
  // unknown word is refused with the words accepted ("--seams: wobbly not in {halo,...}"),
  // not with CheckedTransformer's message, which lists the enum's numbers too. A known word is
  // then turned into the value; the transformer's own description stays out of the help.
  return cmd->add_option(name, value, help)
      ->type_name("TEXT")
      ->transform(CLI::CheckedTransformer(words).description(""))
      ->transform(CLI::IsMember(words))
      ->default_str(px::cli_word(value));
}

// `builds_kernels`: the command compiles kernels (all but `devices`), so --kernel-build applies.
void add_device_flags(CLI::App* cmd, px::DeviceChoice& d, bool builds_kernels = true) {
  cmd->add_option("--devices", d.count, "number of OpenCL devices the frame is split across")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  add_word_option(cmd, "--device-mode", d.mode, px::device_mode_words(),
                  "how N devices are made: auto (sub-devices of one CPU/GPU while it has enough compute "
                  "units, else the platform's devices, else N queues on one device), subdevices, platform, queues");
  cmd->add_option("--platform", d.platform,
                  "substring of the OpenCL platform name (default: $PARALLAX_PLATFORM, else the first platform "
                  "with a GPU, else the first)");
  // Not add_word_option: CLI11 cannot store a word's value into a std::optional through its transformer.
  cmd->add_option_function<std::string>(
         "--bvh-layout",
         [&d](const std::string& word) {
           for (const auto& [w, layout] : px::bvh_layout_words())
             if (w == word) d.bvh_layout = layout;
         },
         "BVH node layout the devices traverse: auto (binary on GPUs, wide8 on CPUs), binary, wide4, wide8, cwbvh "
         "(every one renders the same image)")
      ->check(CLI::IsMember(px::bvh_layout_words()))
      ->default_str(px::cli_word(d.bvh_layout));
  if (builds_kernels)
    add_word_option(cmd, "--kernel-build", d.kernel_build, px::kernel_build_words(),
                    "how the kernels are compiled: optimized (the fastest kernels), quick (the compiler's "
                    "optimisation off: built in about half the time, about 2-4x slower to run, the same images "
                    "bit for bit) or auto (quick on CPU devices when the run is short enough that the build "
                    "time saved outweighs the slower frames; optimized for open-ended runs (view) and for runs "
                    "that measure speed: --report, --timeline, --target-ms)");
}

void add_size_flags(CLI::App* cmd, px::ImageSize& size) {
  cmd->add_option("--width", size.width, "width of each eye in pixels")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  cmd->add_option("--height", size.height, "height of each eye in pixels")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
}

const char* kSceneHelp =
    "scene: a JSON scene file (scenes/*.json), an OBJ, glTF 2.0 (.gltf) or binary glTF (.glb) "
    "file, or a built-in name (cornell, cornell-glossy, atrium, rooms)";

const char* kAnimationHelp =
    "which of a glTF scene's animation clips play: all, none (the rest pose), a clip's name "
    "or its index; frame f is at time f / fps, and each clip loops over its own length. What can move: "
    "the nodes the clips drive (meshes, emissive ones included: moving lights; skins; the camera; "
    "the directional light that is the sun), and, whatever --animation says, a scene file's "
    "camera_path and sun keys (scenes/README.md)";

// --scene, --sky, --instancing, --kernels and --animation: what every rendering command reads
// its scene with.
void add_scene_flags(CLI::App* cmd, px::SceneChoice& s) {
  cmd->add_option("--scene", s.name, kSceneHelp)->capture_default_str();
  add_word_option(cmd, "--sky", s.load.sky, px::sky_words(),
                  "default sky environment: auto (only for a scene without any light: no emitter, sun or sky), "
                  "on (also beside the scene's own lights, unless it has a sky), off (never; an unlit scene "
                  "renders black)");
  // CLI11 reads on/off as a bool; the check keeps the flag to those two words.
  cmd->add_option("--instancing", s.load.instancing,
                  "glTF scenes: on (a mesh that several nodes draw becomes instances of one copy) or off (flat "
                  "copies, one per node)")
      ->type_name("TEXT")
      ->check(CLI::IsMember({"on", "off"}))
      ->default_str(s.load.instancing ? "on" : "off");
  add_word_option(cmd, "--kernels", s.kernels, px::kernel_words(),
                  "which features the scene-dependent kernels (path tracers, G-buffer, trace, preview) are compiled "
                  "with: scene (only those the loaded scene uses: no texture, cut-out, glass, normal-map, sun or sky "
                  "code where it has none; images are identical) or general (every feature)");
  cmd->add_option("--animation", s.animation, kAnimationHelp)->capture_default_str();
}

// What `render` and `view` share: scene, size, pipeline, quality, denoising, the control loop
// and the devices. The flags fill r.pipeline's stage options in place; --no-denoise, whose
// option this returns, empties r.pipeline.denoise once the flags are parsed (drop_denoiser).
CLI::Option* add_pipeline_flags(CLI::App* cmd, px::RenderCommand& r) {
  px::StereoPipeline::Options& p = r.pipeline;
  px::DenoiseStage::Options& dn = *p.denoise;  // engaged by default: the flags below fill it
  add_scene_flags(cmd, r.scene);
  add_word_option(cmd, "--pipeline", p.pipeline, px::pipeline_words(),
                  "proposed: every stage on every device for its strip; baseline: Tauray-style, path "
                  "tracing distributed, the rest on the owner; mono: both eyes fully path traced");
  add_size_flags(cmd, r.size);
  cmd->add_option("--fps", r.clock.fps,
                  "frame rate: frame f is at time f / fps on the camera path and in the animation")
      ->check(CLI::Range(0.001f, 1e9f))
      ->capture_default_str();
  cmd->add_option("--spp", p.trace.spp, "samples per pixel")->check(CLI::Range(1u, 1u << 20))->capture_default_str();
  cmd->add_option("--bounces", p.trace.bounces, "maximum path length in bounces")
      ->check(CLI::Range(0u, px::PathTracer::kMaxBounces))
      ->capture_default_str();
  cmd->add_option("--rr-start", p.trace.rr_start_bounce, "Russian roulette from this bounce on")->capture_default_str();
  add_word_option(cmd, "--path-tracer", p.path_kernel, px::path_tracer_words(),
                  "megakernel: a work-item traces a pixel's whole paths; wavefront: a kernel per path step over "
                  "all paths, their state in memory between steps (images are identical)");
  add_word_option(cmd, "--light-sampling", p.trace.light_sampling, px::light_sampling_words(),
                  "mis (NEE + BSDF sampling, power heuristic), nee (next-event only), bsdf (BSDF sampling only)");
  add_word_option(cmd, "--direct-light", p.trace.direct_light, px::direct_light_words(),
                  "how next-event estimation picks an emissive triangle: power (in proportion to its power), tree "
                  "(a light tree: in proportion to its estimated contribution at the shading point), restir "
                  "(ReSTIR DI over the tree's candidates)");
  cmd->add_option("--restir-candidates", p.restir.candidates,
                  "with --direct-light restir: light samples resampled per pixel and frame before reuse")
      ->check(CLI::Range(1u, static_cast<unsigned>(PX_RESTIR_MAX_CANDIDATES)))
      ->capture_default_str();
  cmd->add_option("--restir-neighbours", p.restir.neighbours,
                  "with --direct-light restir: neighbours whose reservoirs each pixel reuses (0: no spatial reuse)")
      ->check(CLI::Range(0u, static_cast<unsigned>(PX_RESTIR_MAX_NEIGHBOURS)))
      ->capture_default_str();
  cmd->add_option("--seed", p.trace.seed, "seed of the sample streams")->capture_default_str();
  add_word_option(cmd, "--jitter", p.jitter, px::jitter_words(),
                  "where in each pixel a frame's G-buffer ray and first sample go: halton (a Halton (2,3) point "
                  "that moves every frame, so that the denoiser's accumulation covers the pixel: edges "
                  "anti-alias) or centre (the pixel centre every frame)");
  cmd->add_option("--exposure", p.tonemap.exposure, "scale applied before the sRGB PNG encoding")
      ->capture_default_str();
  CLI::Option* no_denoise =
      cmd->add_flag("--no-denoise")->description("skip SVGF (stages 6-7): write the noisy images");
  cmd->add_option("--svgf-iterations", dn.svgf.iterations, "a-trous iterations")
      ->check(CLI::Range(1u, 8u))
      ->capture_default_str();
  cmd->add_option("--sigma-l", dn.svgf.sigma_l, "SVGF luminance edge-stopping (paper 4, Tauray 10, stereo paper 32)")
      ->capture_default_str();
  cmd->add_option("--sigma-z", dn.svgf.sigma_z, "SVGF depth edge-stopping (paper 1, stereo paper 128)")
      ->capture_default_str();
  cmd->add_option("--sigma-n", dn.svgf.sigma_n, "SVGF normal edge-stopping exponent (paper 128, stereo paper 4)")
      ->capture_default_str();
  cmd->add_option("--alpha", dn.svgf.alpha, "temporal blend floor for colour")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  cmd->add_option("--alpha-moments", dn.svgf.alpha_moments, "temporal blend floor for moments")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  cmd->add_option("--taa-alpha", dn.svgf.taa_alpha,
                  "temporal anti-aliasing after SVGF: blend floor of the current frame against the reprojected, "
                  "neighbourhood-clipped history (1: off)")
      ->check(CLI::Range(0.0f, 1.0f))
      ->capture_default_str();
  cmd->add_option("--motion-edge-samples", dn.motion_edge_samples,
                  "animated scenes: paths added before denoising to each pixel on a moving object's edge or "
                  "within two pixels of it, so that its anti-aliasing need not wait for many frames (0: none)")
      ->check(CLI::Range(0u, 256u))
      ->capture_default_str();
  // CLI11 reads on/off as a bool; the check keeps the flag to those two words.
  cmd->add_option("--temporal-gradients", dn.temporal_gradients,
                  "re-shade one pixel in nine each frame with last frame's random numbers and drop the denoiser's "
                  "history where the lighting changed (a light that moves, switches or changes; A-SVGF), so the "
                  "picture follows it within a frame or two; off: the denoiser as without them")
      ->type_name("TEXT")
      ->check(CLI::IsMember({"on", "off"}))
      ->default_str(dn.temporal_gradients ? "on" : "off");
  add_word_option(cmd, "--seams", dn.seams, px::seam_mode_words(),
                  "strip borders when denoising: halo (exchange neighbour rows; N devices = 1 device), "
                  "independent (each strip alone), bilateral (independent + seam-band filter)");
  cmd->add_option("--target-ms", r.target_ms,
                  "hold the stereo frame time inside LO:HI ms (the paper's window is 11:20) by tuning spp, "
                  "bounces and SVGF iterations between frames; --spp, --bounces and --svgf-iterations are "
                  "the starting values, and bounces and iterations never rise above them (off by default)");
  cmd->add_option("--max-spp", r.max_spp, "with --target-ms: the most samples per pixel the loop may use")
      ->check(CLI::Range(1u, 1048576u))
      ->capture_default_str();
  add_device_flags(cmd, r.devices);
  return no_denoise;
}

// After parsing: --no-denoise leaves the pipeline without denoiser options.
void drop_denoiser(const CLI::Option* no_denoise, px::RenderCommand& r) {
  if (no_denoise->count() > 0) r.pipeline.denoise.reset();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "parallax: stereo path tracing split across OpenCL devices.\n"
      "Output files are never silently mixed: a non-empty --out directory needs --overwrite."};
  app.require_subcommand(1);

  px::DeviceChoice devices_choice;
  auto* devices_cmd = app.add_subcommand("devices", "list OpenCL platforms and devices, and the set --devices N makes");
  add_device_flags(devices_cmd, devices_choice, false);

  px::PreviewCommand preview;
  auto* preview_cmd =
      app.add_subcommand("preview", "shaded primary hits of both eyes (a quick geometry/framing check)");
  add_scene_flags(preview_cmd, preview.scene);
  add_size_flags(preview_cmd, preview.size);
  preview_cmd->add_option("--time", preview.time_s, "time on the camera path and in the animation, seconds")
      ->capture_default_str();
  preview_cmd->add_option("--out", preview.out, "output directory")->capture_default_str();
  preview_cmd->add_flag("--overwrite", preview.overwrite, "allow writing into a non-empty output directory");
  add_device_flags(preview_cmd, preview.devices);

  px::RenderCommand render;
  auto* render_cmd =
      app.add_subcommand("render",
                         "path trace a stereo animation; writes per frame and eye a linear EXR and an sRGB PNG, plus a "
                         "side-by-side stereo PNG (frame_NNNN_{left,right}.{exr,png}, frame_NNNN_stereo.png)");
  const CLI::Option* render_no_denoise = add_pipeline_flags(render_cmd, render);
  render_cmd->add_option("--frames", render.frames, "frames to render along the camera path")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  render_cmd->add_option("--timeline", render.timeline,
                         "write a Chrome trace / Perfetto JSON: one track per device, one slice per OpenCL command "
                         "(from profiling events)");
  render_cmd->add_option("--out", render.out, "output directory")->capture_default_str();
  render_cmd->add_flag(
      "--explain", render.explain,
      "print the schedule (stage x device workload pairs, dependency tree) and the operations a frame runs, and exit");
  render_cmd->add_option("--report", render.report,
                         "write a JSON report: per frame, stage and device the device time (OpenCL profiling), "
                         "wall time, reprojected share, bytes transferred; makespan and Hz");
  render_cmd->add_flag("--no-exr", render.no_exr,
                       "write PNGs only: finished strips then travel to the owner as RGBA8 alone (4 bytes a pixel "
                       "instead of 20; what a display needs, as in the paper)");
  auto* no_overlap = render_cmd->add_flag(
      "--no-overlap", render.no_overlap,
      "one command queue per device: the left eye's denoising, tonemapping and transfer no longer run "
      "on a side queue beside the right eye's reprojection and hole filling (images are identical; "
      "the side queue is used only where a device is a GPU: on CPUs it measured slower)");
  render_cmd
      ->add_flag("--overlap", render.force_overlap,
                 "the side queue on every device, CPUs included (to see the overlap in a --timeline on a machine "
                 "without a GPU; images are identical)")
      ->excludes(no_overlap);
  add_word_option(render_cmd, "--balance", render.balance, px::balance_words(),
                  "strip boundaries between devices: static (even split) or dynamic (moved between frames "
                  "toward equal measured device time; images stay identical; proposed and mono pipelines). Over queues "
                  "on one device (--device-mode queues, or more --devices than compute units) the queues share the "
                  "same compute units: the strips still move, by times that mostly reflect the order the queues "
                  "run in, and the frame gets no faster");
  render_cmd
      ->add_option("--balance-step", render.balance_step,
                   "with --balance dynamic: the most rows a strip boundary moves per frame")
      ->check(CLI::Range(1u, 65535u))
      ->capture_default_str();
  render_cmd->add_option("--video", render.video,
                         "also encode the frames, left and right eye side by side, as an H.264 video (.mp4, .mkv "
                         "or .mov) at --fps, through the ffmpeg program (Debian package ffmpeg)");
  render_cmd
      ->add_option("--aov", render.aov,
                   "also write per frame and eye these auxiliary images as linear float EXRs, a comma list of "
                   "albedo (the path tracer's mean primary albedo, what SVGF demodulates by: "
                   "frame_NNNN_{left,right}_albedo.exr) and normal (the G-buffer's world-space shading normal, 0 "
                   "where the ray missed: frame_NNNN_{left,right}_normal.exr); read back from each device after "
                   "the frame, so not for timing runs")
      ->type_name("LIST")
      ->check([](const std::string& list) -> std::string {
        try {
          px::parse_aov_list(list);
          return "";
        } catch (const std::invalid_argument& e) {
          return e.what();
        }
      });
  render_cmd->add_flag("--overwrite", render.overwrite, "allow writing into a non-empty output directory");

  px::ViewCommand view;
  auto* view_cmd = app.add_subcommand(
      "view",
      "live viewer: a window showing both eyes side by side as frames finish, rendered like `render` "
      "(same pipelines, devices, quality and control-loop flags). Keys: W/A/S/D move, Q/E down/up, "
      "drag with the left mouse button to look around, Space returns to the scene's camera path, "
      "Esc quits");
  const CLI::Option* view_no_denoise = add_pipeline_flags(view_cmd, view.render);
  view_cmd->add_option("--frames", view.frames, "stop after N frames (0: run until the window is closed or Esc)")
      ->capture_default_str();
  view_cmd->add_option("--screenshot", view.screenshot,
                       "when the viewer stops, save the window content (both eyes side by side) as this PNG");
  view_cmd
      ->add_option("--move-speed", view.move_speed,
                   "fly-through speed in scene units per second (0: a quarter of the scene's size)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();

  px::ReferenceCommand reference;
  auto* reference_cmd =
      app.add_subcommand("reference",
                         "progressive converged render of both eyes (ground truth for error figures): "
                         "reference_{left,right}.exr");
  add_scene_flags(reference_cmd, reference.scene);
  add_size_flags(reference_cmd, reference.size);
  reference_cmd->add_option("--spp", reference.spp, "total samples per pixel")
      ->check(CLI::Range(1u, 1u << 24))
      ->capture_default_str();
  reference_cmd->add_option("--pass-spp", reference.pass_spp, "samples per progressive pass")
      ->check(CLI::Range(1u, 4096u))
      ->capture_default_str();
  reference_cmd->add_option("--frame", reference.frame, "frame number on the camera path (time = frame / fps)")
      ->capture_default_str();
  reference_cmd->add_option("--fps", reference.clock.fps, "frame rate of the animation the reference belongs to")
      ->check(CLI::Range(0.001f, 1e9f))
      ->capture_default_str();
  reference_cmd->add_option("--bounces", reference.bounces, "maximum path length")
      ->check(CLI::Range(0u, px::PathTracer::kMaxBounces))
      ->capture_default_str();
  // The word is checked before add_word_option's own checks: restir gets its reason, not a list.
  add_word_option(reference_cmd, "--direct-light", reference.direct_light, px::direct_light_words(),
                  "how next-event estimation picks an emissive triangle: power or tree (the same image, with less "
                  "noise where many lights are out of reach); not restir: a reference is plain path tracing")
      ->transform(CLI::Validator(
          [](std::string& word) {
            return word == "restir" ? std::string(
                                          "restir is not for references, which stay plain path tracing: "
                                          "use power or tree")
                                    : std::string();
          },
          ""));
  reference_cmd->add_option("--exposure", reference.exposure, "PNG preview scale")->capture_default_str();
  reference_cmd->add_option("--out", reference.out, "output directory")->capture_default_str();
  reference_cmd->add_flag("--overwrite", reference.overwrite, "allow writing into a non-empty output directory");
  add_device_flags(reference_cmd, reference.devices);

  px::CompareCommand compare;
  auto* compare_cmd = app.add_subcommand(
      "compare",
      "PSNR, relative MSE and MSE of an image against a reference, or (--exact) whether the pixels are identical");
  compare_cmd->footer(
      "Both images must have the same size. psnr_db = 10 log10(1 / mean squared error of the values "
      "clamped to [0, 1]), as a display shows them (peak 1); rel_mse = mean of (a - r)^2 / (r^2 + 0.01) "
      "and mse = mean of (a - r)^2 on the unclamped radiance. psnr_db inf does not mean equal pixels "
      "(values above 1 are clamped): --exact compares the bit patterns.\n");
  compare_cmd->add_option("image", compare.image, "image (EXR)")->required()->check(CLI::ExistingFile);
  compare_cmd->add_option("reference", compare.reference, "reference (EXR)")->required()->check(CLI::ExistingFile);
  compare_cmd->add_flag("--exact", compare.exact,
                        "compare the float pixel data bit for bit (every channel; -0 vs +0 and NaN payloads differ): "
                        "print 'identical' and exit 0, or the number of differing pixels, the first difference (x, "
                        "y, channel, both values) and the largest absolute difference, and exit 1");

  auto* demo_cmd = app.add_subcommand("demo", "render the default scene as a first look (what scripts/demo runs)");
  std::string demo_out = "out/demo";
  demo_cmd->add_option("--out", demo_out, "output directory (existing demo files are replaced, and said so)")
      ->capture_default_str();

  CLI11_PARSE(app, argc, argv);
  drop_denoiser(render_no_denoise, render);
  drop_denoiser(view_no_denoise, view.render);
  // Joins the MPI job when started by mpirun (a no-op otherwise).
  px::Cluster& cluster = px::Cluster::world();
  const int rc = px::run_guarded([&]() -> int {
    if (cluster.distributed() && !render_cmd->parsed() && !demo_cmd->parsed()) {
      cluster.mark_orderly_exit();
      if (cluster.rank() == 0)
        throw std::invalid_argument("only `render` (and `demo`) run across MPI ranks; run this command without mpirun");
      return 1;
    }
    if (devices_cmd->parsed()) return px::run_devices(devices_choice);
    if (preview_cmd->parsed()) return px::run_preview(preview);
    if (render_cmd->parsed()) return px::run_render(render);
    if (view_cmd->parsed()) return px::run_view(view);
    if (reference_cmd->parsed()) return px::run_reference(reference);
    if (compare_cmd->parsed()) return px::run_compare(compare);
    if (demo_cmd->parsed()) {
      px::RenderCommand demo;
      // A short denoised stereo animation along the Cornell box's camera path: 4 spp per frame,
      // SVGF with seam-free halo exchange, two devices.
      demo.scene.name = "cornell";
      demo.size = {480, 270};
      demo.frames = 12;
      demo.pipeline.trace.spp = 4;
      demo.out = demo_out;
      demo.overwrite = true;
      demo.devices.count = 2;
      return px::run_render(demo);
    }
    return 0;
  });
  // A rank that failed alone (mid-frame) would leave the others waiting for its messages:
  // end the whole job. Failures every rank agreed on exit normally.
  if (rc != 0 && cluster.distributed() && !cluster.orderly_exit()) {
    std::fprintf(stderr, "error: MPI rank %d failed; stopping all %d ranks\n", cluster.rank(), cluster.size());
    cluster.abort(rc);
  }
  return rc;
}
