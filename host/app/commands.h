// The subcommands of the parallax binary. main.cpp parses flags into these option structs
// (words become enums there, through app/cli_enums.h); each run_* function does the work,
// prints progress on stderr and results on stdout, and throws on failure (main turns that into
// a message and exit code 1).
#pragma once

#include "cl/device_set.h"
#include "pipeline/stereo_pipeline.h"
#include "pipeline/strip_schedule.h"
#include "render/path_tracer.h"
#include "render/reference_render.h"
#include "scene/scene_loader.h"

#include <string>

namespace px {

struct DeviceChoice {
  int count = 1;
  DeviceMode mode = DeviceMode::Auto;
  std::string platform;
  std::optional<BvhLayout> bvh_layout;           // --bvh-layout (auto: nullopt, the device type's default)
  KernelBuild kernel_build = KernelBuild::Auto;  // --kernel-build
  // `work`: what the command will render, which --kernel-build auto decides by (none, as for
  // `view`, whose length is open: optimised kernels).
  DeviceOptions options(std::optional<KernelWork> work = std::nullopt) const;
};

// What every command that renders a scene reads it with: --scene, --sky, --instancing,
// --kernels and --animation (main.cpp binds them with one helper).
struct SceneChoice {
  // A JSON scene file (scenes/*.json), an OBJ, glTF or binary glTF file, or a built-in name.
  std::string name = "cornell";
  // --sky (light for scenes without any) and --instancing (glTF: a mesh that several nodes draw
  // becomes instances of one copy; off: flat copies), with the loaders' defaults.
  SceneLoadOptions load;
  KernelChoice kernels = KernelChoice::Scene;  // the scene's features or all
  std::string animation = "all";               // which glTF clips play (all, none, a name or index)

  const SceneLoadOptions& load_options() const { return load; }
};

// Pixels of each eye (--width, --height).
struct ImageSize {
  unsigned width = 640, height = 360;
};

// The one clock of `render`, `reference`, `view --frames` and every MPI rank: frame f is at
// f / fps seconds, for the camera path and the animation alike. Every place that turns a frame
// number into a time goes through here, so that a reference of frame f shows the scene
// `render` showed at frame f, and every rank poses the same triangles bit for bit.
//
// The two times are one instant in the types their consumers take: evaluate_camera a float,
// SceneAnimator a double. Each quotient is formed in its own type, not one rounded from the
// other: the double rounded to float can differ from the float quotient by an ulp, which would
// move the camera and every image with it.
struct FrameClock {
  float fps = 30.0f;  // --fps

  // Frame `frame`'s time for the animation (SceneAnimator::update).
  double time_s(unsigned frame) const { return static_cast<double>(frame) / fps; }
  // Frame `frame`'s time on the camera path (evaluate_camera, StereoPipeline::render).
  float camera_time_s(unsigned frame) const { return static_cast<float>(frame) / fps; }
};

struct PreviewCommand {
  SceneChoice scene;
  ImageSize size;
  float time_s = 0.0f;
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
  SceneChoice scene;
  ImageSize size;
  unsigned frames = 1;
  FrameClock clock;  // camera-path and animation time of frame f is f / fps
  // The pipeline as the flags ask for it: --pipeline, --spp, --bounces, ... (trace),
  // --path-tracer, --jitter, --exposure (tonemap), the denoiser's flags (denoise; --no-denoise
  // leaves it empty). make_pipeline_config completes it (--aov, the control loop's checks).
  StereoPipeline::Options pipeline;
  std::string out = "out/render";
  bool overwrite = false;
  bool explain = false;        // print the schedule (stage x device workload pairs, tree)
  bool no_exr = false;         // PNGs only: finished strips travel as RGBA8 alone
  bool no_overlap = false;     // one queue per device (no side queue for the left eye)
  bool force_overlap = false;  // the side queue on CPU devices too
  std::string report;          // JSON report path ("" = none)
  std::string timeline;        // Chrome trace / Perfetto JSON path ("" = none)
  std::string video;           // left|right side by side through ffmpeg ("" = none)
  std::string aov;             // --aov: auxiliary images per frame and eye, "albedo,normal" ("" = none)
  std::string target_ms;       // control-loop window "LO:HI" ("" = off: fixed quality)
  unsigned max_spp = 64;       // control loop: the most spp it may raise to
  StripBalance balance = StripBalance::Static;
  unsigned balance_step = 8;  // dynamic balance: most rows a boundary moves per frame
  DeviceChoice devices;
};

// What `render` will trace and denoise in this process, for --kernel-build auto (cl/kernel_build.h):
// its frames' share of `ranks` processes. None where the run measures speed (--report,
// --timeline) or holds a frame time (--target-ms): those need the optimised kernels.
std::optional<KernelWork> render_kernel_work(const RenderCommand& cmd, int ranks);

// The live viewer: `render`'s scene, pipeline, quality, devices and control loop (its
// frames / out / report / timeline are unused), shown in a window as frames finish.
struct ViewCommand {
  RenderCommand render;
  unsigned frames = 0;      // stop after this many frames (0: run until the window closes)
  std::string screenshot;   // PNG of the window content when the viewer stops ("" = none)
  float move_speed = 0.0f;  // fly-through speed, scene units per second (0: from the scene size)
};

struct ReferenceCommand {
  SceneChoice scene;
  ImageSize size;
  unsigned spp = ReferenceOptions{}.spp;
  unsigned pass_spp = 16;  // samples per progressive pass (smaller than ReferenceOptions' for progress output)
  unsigned frame = 0;
  FrameClock clock;  // the animation the reference belongs to
  unsigned bounces = PathTracer::Options{}.bounces;
  DirectLight direct_light = ReferenceOptions{}.direct_light;  // power or tree (a reference is plain path tracing)
  float exposure = TonemapStage::Options{}.exposure;           // PNG preview scale, as render's
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
