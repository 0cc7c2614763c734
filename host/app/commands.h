// The subcommands of the parallax binary. main.cpp parses flags into these option structs
// (words become enums there, through app/cli_enums.h); each run_* function does the work,
// prints progress on stderr and results on stdout, and throws on failure (main turns that into
// a message and exit code 1).
#pragma once

#include "cl/device_set.h"
#include "pipeline/stereo_pipeline.h"
#include "pipeline/strip_schedule.h"
#include "render/path_tracer.h"
#include "scene/scene_loader.h"

#include <string>

namespace px {

struct DeviceChoice {
  int count = 1;
  DeviceMode mode = DeviceMode::Auto;
  std::string platform;
  std::optional<BvhLayout> bvh_layout;  // --bvh-layout (auto: nullopt, the device type's default)
  DeviceOptions options() const;
};

struct PreviewCommand {
  std::string scene = "cornell";
  SkyMode sky = SkyMode::kAuto;  // light for scenes without any (see load_scene)
  KernelChoice kernels = KernelChoice::Scene;  // --kernels: the scene's features or all
  unsigned width = 640, height = 360;
  float time_s = 0.0f;
  std::string animation = "all";  // --animation: which glTF clips play (all, none, a name or index)
  std::string out = "out/preview";
  bool overwrite = false;
  DeviceChoice devices;
};

// How strip boundaries between devices are chosen (render --balance).
enum class StripBalance {
  Static,   // an even split, kept
  Dynamic,  // moved between frames toward equal measured device time
};

struct RenderCommand {
  std::string scene = "cornell";
  SkyMode sky = SkyMode::kAuto;  // light for scenes without any (see load_scene)
  PipelineKind pipeline = PipelineKind::Proposed;
  unsigned width = 640, height = 360;
  unsigned frames = 1;
  float fps = 30.0f;           // camera-path and animation time of frame f is f / fps
  std::string animation = "all";  // --animation: which glTF clips play (all, none, a name or index)
  float exposure = 1.0f;       // PNG preview scale
  PathTracer::Options trace;   // --spp, --bounces, --light-sampling, ...
  PathTraceKernel path_kernel = PathTraceKernel::Megakernel;  // --path-tracer
  KernelChoice kernels = KernelChoice::Scene;                 // --kernels
  PixelJitter jitter = PixelJitter::Halton;                   // --jitter
  std::string out = "out/render";
  bool overwrite = false;
  bool explain = false;        // print the schedule (stage x device workload pairs, tree)
  bool no_denoise = false;
  bool no_exr = false;         // PNGs only: finished strips travel as RGBA8 alone
  bool no_overlap = false;     // one queue per device (no side queue for the left eye)
  bool force_overlap = false;  // the side queue on CPU devices too
  SvgfDenoiser::Options svgf;
  SeamMode seams = SeamMode::Halo;
  unsigned motion_edge_samples = 8;  // --motion-edge-samples (StereoPipeline::Options)
  std::string report;          // JSON report path ("" = none)
  std::string timeline;        // Chrome trace / Perfetto JSON path ("" = none)
  std::string video;           // left|right side by side through ffmpeg ("" = none)
  std::string aov;             // --aov: auxiliary images per frame and eye, "albedo,normal" ("" = none)
  std::string target_ms;       // control-loop window "LO:HI" ("" = off: fixed quality)
  unsigned max_spp = 64;       // control loop: the most spp it may raise to
  StripBalance balance = StripBalance::Static;
  unsigned balance_step = 8;   // dynamic balance: most rows a boundary moves per frame
  DeviceChoice devices;
};

// The live viewer: `render`'s scene, pipeline, quality, devices and control loop (its
// frames / out / report / timeline are unused), shown in a window as frames finish.
struct ViewCommand {
  RenderCommand render;
  unsigned frames = 0;       // stop after this many frames (0: run until the window closes)
  std::string screenshot;    // PNG of the window content when the viewer stops ("" = none)
  float move_speed = 0.0f;   // fly-through speed, scene units per second (0: from the scene size)
};

struct ReferenceCommand {
  std::string scene = "cornell";
  SkyMode sky = SkyMode::kAuto;  // light for scenes without any (see load_scene)
  KernelChoice kernels = KernelChoice::Scene;  // --kernels
  unsigned width = 640, height = 360;
  unsigned spp = 4096;
  unsigned pass_spp = 16;      // samples per progressive pass
  unsigned frame = 0;
  float fps = 30.0f;
  std::string animation = "all";  // --animation, as render's
  unsigned bounces = 6;
  float exposure = 1.0f;
  std::string out = "out/reference";
  bool overwrite = false;
  DeviceChoice devices;
};

struct CompareCommand {
  std::string image, reference;
  bool exact = false;  // bit-for-bit comparison of the pixel data instead of error figures
};

int run_devices(const DeviceChoice& choice);
int run_preview(const PreviewCommand& cmd);
int run_render(const RenderCommand& cmd);
int run_reference(const ReferenceCommand& cmd);
int run_compare(const CompareCommand& cmd);
// Defined in viewer/live_viewer.cpp, which only the parallax executable compiles (GLFW +
// OpenGL stay out of the core library).
int run_view(const ViewCommand& cmd);

}  // namespace px
