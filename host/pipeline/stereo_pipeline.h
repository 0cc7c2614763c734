// Wires the stage units (pipeline/stages/) to a FrameSchedule and runs it: each frame the
// schedule becomes a list of operations (pipeline/operation.h), and each run of consecutive
// operations of one stage goes to that stage's unit. The pipeline knows no stage's buffers,
// kernels or halo radii; what differs between proposed, baseline and mono is the schedule's
// table (pipeline/strip_schedule.cpp).
#pragma once

#include "cl/device_set.h"
#include "cluster/cluster.h"
#include "control/frame_time_controller.h"
#include "image/image_io.h"
#include "pipeline/event_log.h"
#include "pipeline/frame_images.h"
#include "pipeline/operation.h"
#include "pipeline/queue_lanes.h"
#include "pipeline/row_transfer.h"
#include "pipeline/stages/denoise_stage.h"
#include "pipeline/stages/direct_light_stage.h"
#include "pipeline/stages/hole_fill_stage.h"
#include "pipeline/stages/path_trace_stage.h"
#include "pipeline/stages/stage_unit.h"
#include "pipeline/stages/tonemap_stage.h"
#include "pipeline/strip_schedule.h"
#include "render/device_scene.h"
#include "render/pixel_jitter.h"
#include "render/stereo_camera.h"

#include <array>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <vector>

namespace px {

struct StageTiming {
  Stage stage;
  int device;
  double ms;  // summed device time of the stage's commands on that device (profiling events)
};

// One command's execution on a device, from its OpenCL profiling timestamps (ns, device clock).
struct StageSpan {
  Stage stage;
  int device;
  std::uint64_t start_ns, end_ns;
  const char* pass = nullptr;  // EventLog::Entry::pass: the timeline names the slice by it
  int lane = 0;                // QueueLanes lane: the timeline's track within the device
};

struct FrameStats {
  unsigned frame = 0;
  double wall_ms = 0.0;  // host time from first enqueue to the owner's last command
  std::vector<StageTiming> stages;
  std::vector<StageSpan> spans;       // every command, for timelines
  std::size_t right_pixels = 0;       // right-eye pixels in the frame
  std::size_t reprojected = 0;        // of those, reprojected from the left eye
  std::size_t bytes_transferred = 0;  // child -> host -> owner, both hops counted once
  std::size_t nonfinite_pixels = 0;   // tonemapped pixels whose radiance was NaN / infinite
  // Across MPI ranks (on rank 0, for every rank; empty in one process): bytes each rank sent
  // to each rank ([from][to]) and each rank's host time in MPI calls.
  std::vector<std::vector<std::uint64_t>> mpi_bytes;
  std::vector<double> mpi_ms;
};

class StereoPipeline {
 public:
  struct Options {
    PipelineKind pipeline = PipelineKind::Proposed;
    PathTracer::Options trace;
    // Stages 2, 5 and 12: the megakernel or the wavefront tracer (same images).
    PathTraceKernel path_kernel = PathTraceKernel::Megakernel;
    TonemapStage::Options tonemap;
    // Stages 6-7 (SVGF, seams, the motion edges' extra paths): present = denoising, empty = the
    // noisy images.
    std::optional<DenoiseStage::Options> denoise = DenoiseStage::Options{};
    // The MPI job this pipeline is one rank of (nullptr: this process alone). Every rank drives
    // its DeviceSet's N devices as global devices rank*N .. rank*N+N-1 and must construct the
    // pipeline with the same options; rank 0 holds the owner and the finished frame.
    Cluster* cluster = nullptr;
    // Whether finished strips carry their float radiance to the owner as well as RGBA8 (for
    // radiance(), e.g. EXR files). Off: RGBA8 alone travels (4 instead of 20 bytes a pixel),
    // what a display needs, and radiance() is unavailable.
    bool gather_radiance = true;
    // A side queue per device for the left eye's denoising, tonemapping and transfer, so that
    // they overlap the right eye's reprojection and hole filling (queue_lanes.h; Auto: on GPUs).
    // Images are identical either way. Off under MPI (one queue per device there).
    Overlap overlap = Overlap::Auto;
    // Stage 5's work-items: a hole each, or a (hole, sample) pair each on GPUs (hole_fill_stage.h).
    HoleFillStage::Options hole_fill;
    // Stage 14, with trace.direct_light = restir: ReSTIR DI's candidates and reuse.
    DirectLightStage::Options restir;
    // Where in each pixel the frame's G-buffer ray and first sample go (pixel_jitter.h): a
    // Halton (2, 3) point per frame, so that accumulation over frames covers the pixel, or
    // always the centre.
    PixelJitter jitter = PixelJitter::Halton;
    // Where a device path traces an eye's rows (stage 2; mono's 12 too), its first sample (the
    // G-buffer's ray) writes their G-buffer, and stage 3 traces only the margin rows beyond them (needs
    // trace.first_sample_on_gbuffer_ray; ignored without). Images are identical either way: the texels
    // are the G-buffer pass's to the last bit.
    bool gbuffer_from_path_tracer = true;
    // Auxiliary images read back after every frame (render --aov; an output option, not the
    // real-time path: blocking reads from the device that wrote each row). albedo: the path
    // tracer's per-pixel mean primary albedo, the one SVGF demodulates by (the right eye's
    // reprojected pixels: the reprojected albedo). normal: the G-buffer's world-space shading
    // normal (facing the eye; 0 where the centre ray missed). `normal` also schedules mono's
    // G-buffer without denoising (its path traces write it: images unchanged).
    struct Aovs {
      bool albedo = false, normal = false;
      bool any() const { return albedo || normal; }
    };
    Aovs aovs;
  };

  StereoPipeline(DeviceSet& devices, const DeviceScene& device_scene, const Scene& scene, unsigned width,
                 unsigned height, Options options);

  const FrameSchedule& schedule() const { return schedule_; }
  // The operations the next frame runs (the schedule with this frame's G-buffer margins).
  std::vector<Operation> operations() const {
    return make_operations(schedule_, gbuffer_margin(schedule_, options_), lanes_.has_side(), fuses_gbuffer(options_));
  }
  // Whether path traces write the G-buffer of their rows (Options::gbuffer_from_path_tracer).
  static bool fuses_gbuffer(const Options& options) {
    return options.gbuffer_from_path_tracer && options.trace.first_sample_on_gbuffer_ray;
  }
  // The rows beyond its strip that each G-buffer pass of `schedule` covers: the most any
  // scheduled stage declares it reads (a static gbuffer_rows_read of its unit).
  static unsigned gbuffer_margin(const FrameSchedule& schedule, const Options& options);

  // Each device's strip (device i owns strips()[i] in proposed and mono), top to bottom.
  const std::vector<RowRange>& strips() const { return schedule_.strips; }
  // Moves the strip boundaries for the frames rendered from now on (dynamic load balancing).
  // The images stay bit-identical to one device's: the next frame first sends the rows whose
  // owner changed — their SVGF history and last frame's G-buffer — to their new owner.
  // Throws std::invalid_argument for the baseline pipeline or strips check_strips refuses.
  void set_strips(const std::vector<RowRange>& strips);

  // What the control loop tunes, for the frames rendered from now on. Throws
  // std::invalid_argument outside what the pipeline was built for (spp >= 1, bounces within
  // the kernel's limit, 1 <= iterations <= the iterations it was constructed with, since the
  // halo margins were sized for those).
  void set_quality(const FrameQuality& q);
  FrameQuality quality() const;
  // A frame's cost as the control loop splits it: the slowest device's time in the stages
  // each parameter drives, and the rest of the wall time.
  static FrameCost frame_cost(const FrameStats& stats);
  // Each device's busy time in a frame: its stages' device time, strip and halo transfers left
  // out (they follow the strip borders, not the rows). What the strip balancer equalises.
  static std::vector<double> device_busy_ms(const FrameStats& stats, int devices);

  // Renders frame `frame` at camera-path time `time_s`. The finished images are on the owner
  // device afterwards; fetch them with images().
  FrameStats render(unsigned frame, float time_s);
  // The same with the centre camera given (a viewer's fly-through camera) instead of taken
  // from the scene's camera path.
  FrameStats render(unsigned frame, const Camera& centre);

  // Devices of the whole frame (over all ranks) and which of them this process drives.
  const DeviceLayout& layout() const { return layout_; }
  // Whether this process holds the finished frame (rank 0; always true in one process).
  bool holds_frame() const { return layout_.is_local(schedule_.tree.root); }

  // Linear radiance of both eyes from the owner (blocking read). Only where holds_frame().
  std::array<ImageRGB, 2> radiance();
  // Tonemapped RGBA8 of both eyes from the owner (blocking read).
  std::array<std::vector<std::uint8_t>, 2> rgba8();

  std::uint64_t nonfinite_paths() const { return nonfinite_total_; }

  // The last frame's auxiliary images of both eyes (Options::aovs; one process only, the
  // constructor refuses them under MPI): RGB albedo and world-space normal, read from the
  // device that wrote each row before the frame ended. Empty images where not asked for.
  const std::array<ImageRGB, 2>& albedo_aov() const { return albedo_aov_; }
  const std::array<ImageRGB, 2>& normal_aov() const { return normal_aov_; }
  // Whether `options` schedule the G-buffer stage where denoising alone would not (mono).
  static bool wants_gbuffer(const Options& options) { return options.aovs.normal; }
  // ReSTIR DI (stage 14) runs where the path tracer leaves each pixel's first vertex to it.
  static bool wants_direct_light_stage(const Options& options) {
    return options.trace.direct_light == DirectLight::Restir && options.trace.light_sampling == LightSampling::Mis &&
           options.trace.first_sample_on_gbuffer_ray;
  }

  // Inspection (tests, debugging; one process): gathered from whichever device owns each row.
  // Per right-eye pixel: 1 if the last frame filled it by path tracing (a hole), else 0.
  std::vector<std::uint8_t> hole_mask();
  // The G-buffer eye `eye` of the last frame was traced into.
  std::vector<GBufferTexel> gbuffer_of(int eye);
  // Pixels of eye `eye` that got the motion edges' extra samples in the last frame
  // (DenoiseStage::Options::motion_edge_samples; 0 without denoising or motion).
  std::size_t motion_edge_pixels(int eye) { return denoise_ ? denoise_->motion_edge_pixels(eye) : 0; }
  DeviceSet& devices() const { return devices_; }
  // The temporal gradients of eye `eye` on device `d` after the last frame (null: none there).
  const TemporalGradients* temporal_gradients(int d, int eye) const {
    return denoise_ ? denoise_->gradients(d, eye) : nullptr;
  }

 private:
  // The unit that runs `stage`'s operations (std::logic_error if the schedule names a stage no
  // unit runs).
  StageUnit& unit(Stage stage);
  // Builds a unit of type U (constructed from the pipeline's StageEnv and `args`) for `stages`.
  template <typename U, typename... Args>
  U& add_unit(std::initializer_list<Stage> stages, Args&&... args) {
    auto unit = std::make_unique<U>(env_, std::forward<Args>(args)...);
    U& ref = *unit;
    for (Stage s : stages) unit_of_[s] = &ref;
    units_.push_back(std::move(unit));
    return ref;
  }

  // Reads Options::aovs of this frame into albedo_aov_ / normal_aov_ (after its queues
  // finished, before the units' end_frame swaps this frame's G-buffer away).
  void capture_aovs();
  // Per row of `eye`, the device whose buffer holds its final value of the image that
  // `writes` stages write (the last scheduled such stage with that row wins).
  std::vector<int> row_owners(int eye, std::initializer_list<Stage> writes) const;
  bool local(int d) const { return layout_.is_local(d); }
  // Whether this frame, at `centre`, shows what the last one did from where it did: the camera
  // unmoved and no animation in the scene.
  bool still_view(const Camera& centre) const;
  // Device d's main-lane queue (not the selected lane's: see QueueLanes::main).
  cl::CommandQueue& main_queue(int d) { return lanes_.main(layout_.local_index(d)); }

  DeviceSet& devices_;
  Cluster* cluster_;
  DeviceLayout layout_;
  const Scene& scene_;
  unsigned width_, height_;
  Options options_;
  FrameSchedule schedule_;
  std::vector<FrameImages> images_;  // per device of the frame; empty entries for other ranks
  QueueLanes lanes_;
  EventLog log_;
  RowTransfer transfer_;
  StageEnv env_;
  // The stage units (only what the options need: no SVGF state without denoising), the unit
  // of each stage, and the two the control loop tunes.
  std::vector<std::unique_ptr<StageUnit>> units_;
  std::map<Stage, StageUnit*> unit_of_;
  PathTraceStage* path_trace_ = nullptr;
  DenoiseStage* denoise_ = nullptr;
  // The last frame's centre camera: a frame whose view has not moved since (and whose scene
  // does not move) sends every sample along the G-buffer's ray (render, still_view).
  std::optional<Camera> last_centre_;
  std::uint64_t nonfinite_total_ = 0;
  std::array<ImageRGB, 2> albedo_aov_, normal_aov_;
};

}  // namespace px
