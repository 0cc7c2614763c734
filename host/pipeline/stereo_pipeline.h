// Runs one FrameSchedule per frame: every stage is a kernel enqueued on the queue of each
// device that has work in it (rows from the schedule), dependencies between devices are
// cl_events, and finished strips travel child -> owner through host-mapped staging buffers
// (CL_MEM_ALLOC_HOST_PTR: device -> host memory -> device, no peer-to-peer).
//
// Every device keeps full-frame buffers and writes only its own rows, so a pixel's index is
// the same everywhere and a strip transfer is one contiguous byte range.
#pragma once

#include "cl/device_set.h"
#include "cluster/cluster.h"
#include "control/frame_time_controller.h"
#include "denoise/svgf_denoiser.h"
#include "image/image_io.h"
#include "pipeline/strip_schedule.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "render/stereo_camera.h"

#include <array>
#include <deque>
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
};

struct FrameStats {
  unsigned frame = 0;
  double wall_ms = 0.0;                 // host time from first enqueue to the owner's last command
  std::vector<StageTiming> stages;
  std::vector<StageSpan> spans;         // every command, for timelines
  std::size_t right_pixels = 0;         // right-eye pixels in the frame
  std::size_t reprojected = 0;          // of those, reprojected from the left eye
  std::size_t bytes_transferred = 0;    // child -> host -> owner, both hops counted once
  std::size_t nonfinite_pixels = 0;     // tonemapped pixels whose radiance was NaN / infinite
  // Across MPI ranks (on rank 0, for every rank; empty in one process): bytes each rank sent
  // to each rank ([from][to]) and each rank's host time in MPI calls.
  std::vector<std::vector<std::uint64_t>> mpi_bytes;
  std::vector<double> mpi_ms;
};

// How denoising treats the borders between devices' strips.
enum class SeamMode {
  Independent,  // each strip filtered alone (the paper): seams visible
  Bilateral,    // independent, then the paper's bilateral filter in a band around each seam
  Halo,         // neighbours' rows copied in before every pass that reads across a border:
                // the N-device image equals the 1-device image
};
const char* to_string(SeamMode m);
SeamMode parse_seam_mode(const std::string& text);  // "independent", "bilateral", "halo"

class StereoPipeline {
 public:
  struct Options {
    PipelineKind pipeline = PipelineKind::Proposed;
    PathTracer::Options trace;
    float exposure = 1.0f;
    bool denoise = true;
    SvgfDenoiser::Options svgf;
    SeamMode seams = SeamMode::Halo;
    unsigned seam_band = 4;  // rows each side of a seam the bilateral seam filter touches
    // The MPI job this pipeline is one rank of (nullptr: this process alone). Every rank drives
    // its DeviceSet's N devices as global devices rank*N .. rank*N+N-1 and must construct the
    // pipeline with the same options; rank 0 holds the owner and the finished frame.
    Cluster* cluster = nullptr;
    // Whether finished strips carry their float radiance to the owner as well as RGBA8 (for
    // radiance(), e.g. EXR files). Off: RGBA8 alone travels (4 instead of 20 bytes a pixel),
    // what a display needs, and radiance() is unavailable.
    bool gather_radiance = true;
  };

  StereoPipeline(DeviceSet& devices, const DeviceScene& device_scene, const Scene& scene, unsigned width,
                 unsigned height, Options options);

  const FrameSchedule& schedule() const { return schedule_; }

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

  // Inspection (tests, debugging; one process): gathered from whichever device owns each row.
  // Per right-eye pixel: 1 if the last frame filled it by path tracing (a hole), else 0.
  std::vector<std::uint8_t> hole_mask();
  std::vector<GBufferTexel> gbuffer_of(int eye);

 private:
  // A device's host-mapped buffer for rows leaving it to a neighbour, and the copies that
  // still read it (the next exchange through it waits for them).
  struct HaloStaging {
    cl::Buffer buffer;
    std::vector<cl::Event> readers;
  };

  struct DeviceBuffers {
    std::array<cl::Buffer, 2> radiance;  // float4, full frame
    std::array<cl::Buffer, 2> albedo;    // float4, full frame: mean primary albedo of the
                                         // samples behind `radiance` (SVGF demodulates by it)
    std::array<cl::Buffer, 2> gbuffer;   // GBufferTexel, full frame
    std::array<cl::Buffer, 2> rgba;      // uchar4, full frame
    cl::Buffer holes;                    // uint, full frame (worst case: every pixel a hole)
    cl::Buffer hole_count;               // uint
    cl::Buffer nonfinite;                // uint
    cl::Buffer nonfinite_pixels;         // uint, counted by the tonemap
    // Host-mapped staging for strips travelling to the owner (children only).
    cl::Buffer staging_radiance, staging_albedo, staging_rgba;
    // Denoising: last frame's G-buffers, one SVGF state per eye, and host-mapped staging for
    // halo rows leaving this device (with the copies still reading it).
    std::array<cl::Buffer, 2> gbuffer_prev;
    std::array<std::unique_ptr<SvgfDenoiser>, 2> svgf;
    HaloStaging staging_halo;     // float4 rows
    HaloStaging staging_gbuffer;  // GBufferTexel rows of last frame's G-buffer when strips move
                                  // (allocated on the first move)
  };

  // Kernel launchers; each records its event under (stage, device).
  void path_trace(int d, int eye, RowRange rows, const CameraParams& cam, unsigned frame, Stage stage);
  void gbuffer(int d, int eye, RowRange rows, const CameraParams& cam);
  void reproject(int d, RowRange rows, const CameraParams& left_cam);
  void fill_holes(int d, RowRange rows, const CameraParams& right_cam, unsigned frame);
  void tonemap(int d, int eye, RowRange rows);
  // Copies rows of `eye` (radiance with its albedo, and/or rgba) from device d to the owner via
  // d's staging buffers.
  void transfer(int d, int eye, RowRange rows, bool radiance, bool rgba);

  void record(Stage stage, int device, const cl::Event& e);
  // Global device d (layout_) on this process: its queue and its index in devices_.
  bool local(int d) const { return layout_.is_local(d); }
  cl::CommandQueue& queue(int d) { return devices_.devices()[layout_.local_index(d)].queue; }
  // Copies `bytes` at `offset` of device `from`'s buffer `src` into device `to`'s `dst` at the
  // same offset, whichever ranks they are on. Within a process through `staging()` (`from`'s
  // host-mapped buffer, at `staging_offset`; `readers`, if given, are the copies still reading
  // it, waited for and replaced); between processes as an MPI message. Records the events.
  template <typename StagingOf>
  void copy_rows(int from, const cl::Buffer& src, int to, const cl::Buffer& dst, std::size_t offset,
                 std::size_t bytes, StagingOf staging, std::size_t staging_offset, std::vector<cl::Event>* readers);
  // Launches `k` over `items` work-items (cl/launch.h) on device d and records it.
  void enqueue(int d, cl::Kernel& k, std::size_t items, Stage stage);
  // Stage 6-7 for every device at once (passes interleave with halo exchanges).
  void denoise(const StageWork& work, const std::array<CameraParams, 2>& cams);
  // Copies into each device's `buffer(d)` the rows within `radius` of its strip `strip[d]`
  // that other devices own, through the owners' host-mapped staging buffers.
  template <typename BufferOf>
  void exchange_halo(BufferOf buffer, const std::vector<RowRange>& strip, unsigned radius);
  // The general form: copies into each device's `buffer(d)` the rows of `needed[d]` that
  // another device `src` holds (`owned[src]`; the owned ranges are disjoint), `texel` bytes per
  // pixel, through the source's `staging` buffer. With owned = last frame's strips and needed
  // = this frame's, it moves history to the new owner of rows whose strip changed.
  template <typename BufferOf>
  void exchange_rows(BufferOf buffer, const std::vector<RowRange>& owned, const std::vector<RowRange>& needed,
                     std::size_t texel, HaloStaging DeviceBuffers::*staging);
  // `strip` widened by `radius` rows each side, clipped to the image.
  std::vector<RowRange> widen(const std::vector<RowRange>& strip, unsigned radius) const;
  // Rows beyond its strip that each device's G-buffer covers, so that every pass of a halo
  // exchange finds normals and depths of the rows it reads without transferring them.
  unsigned gbuffer_margin() const;
  FrameParams frame_params(int eye, RowRange rows, unsigned frame) const;

  DeviceSet& devices_;
  Cluster* cluster_;
  DeviceLayout layout_;
  std::deque<std::vector<unsigned char>> message_rows_;  // host copies of this frame's MPI messages
  const DeviceScene& device_scene_;
  const Scene& scene_;
  unsigned width_, height_;
  Options options_;
  FrameSchedule schedule_;
  unsigned max_svgf_iterations_;  // the halo margins and exchanges are sized for up to these
  std::vector<DeviceBuffers> buffers_;
  std::vector<std::pair<std::pair<Stage, int>, cl::Event>> events_;  // this frame's, for timing
  std::vector<cl::Event> owner_waits_;                                // cross-device dependencies
  std::size_t bytes_this_frame_ = 0;
  std::optional<std::array<CameraParams, 2>> prev_cams_;
  // Per eye, the strips whose rows of SVGF history (and last G-buffer) each device holds: the
  // strips it denoised last frame. Empty before the first denoised frame.
  std::array<std::vector<RowRange>, 2> history_strips_;
  std::uint64_t nonfinite_total_ = 0;
};

}  // namespace px
