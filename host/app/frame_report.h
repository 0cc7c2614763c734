// What `render` records about its frames: the totals behind the end-of-run summary, the JSON
// report (--report) and the Chrome trace (--timeline). The two files are streamed frame by
// frame into their temporary files, so a long run holds no per-frame records, and appear under
// their names only when the run ends (io/atomic_file.h). scripts/plot_report, scripts/evaluate
// and tests/cli_smoke.sh read both formats: keep them as they are.
#pragma once

#include "app/commands.h"
#include "app/scene_setup.h"
#include "cl/device_set.h"
#include "control/frame_time_controller.h"
#include "io/atomic_file.h"
#include "pipeline/stereo_pipeline.h"
#include "render/scene_animator.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace px {

// Sums over the frames written.
struct RenderTotals {
  unsigned frames = 0;
  double makespan_ms = 0.0, first_frame_ms = 0.0;
  std::size_t reprojected = 0, right_pixels = 0, bytes_transferred = 0;

  void add(const FrameStats& stats);
  // The first frame compiles the kernels (seconds on PoCL): Hz over the frames after it says
  // what the pipeline sustains; with one frame there is nothing else to measure.
  unsigned hz_frames() const { return frames > 1 ? frames - 1 : frames; }
  double hz() const;
};

// An animated scene's per-frame updates (SceneAnimator::Update), for the summary line.
struct AnimationTotals {
  unsigned frames = 0;
  std::size_t bytes_last = 0;  // bytes the last frame wrote to the devices
  std::vector<SceneAnimator::Update> updates;

  void add(const SceneAnimator::Update& u);
  // The median over frames of one of Update's times (ms; util/statistics.h: an even count gives
  // the mean of the two middle frames).
  double median(double SceneAnimator::Update::*field) const;
};

// --report: one line per frame under "frames", then the run's summary.
class RenderReport {
 public:
  // Opens the file now, so an unwritable path fails before any rendering. `cmd` and `options`
  // must outlive the report.
  RenderReport(const RenderCommand& cmd, const StereoPipeline::Options& options, int ranks);

  // Frame `frame` as rendered: the strips and quality it was rendered with, and the control
  // loop's prediction for it (none: no control loop, or no prediction yet).
  // `update`: what posing an animated scene for this frame cost (null: a static scene; the
  // frame's "scene_update" is then null).
  void add_frame(unsigned frame, const FrameStats& stats, const std::vector<RowRange>& strips,
                 const FrameQuality& quality, std::optional<double> predicted_ms,
                 const SceneAnimator::Update* update = nullptr);
  // The summary, then the file appears under its name.
  // `quick_kernels`: the kernels were built with the optimiser off (cl/kernel_build.h).
  void finish(const RenderTotals& totals, int devices, DeviceMode device_mode, BvhLayout bvh_layout,
              const DeviceScene& scene, const StartTimes& start, std::uint64_t nonfinite_paths,
              const BvhBuildStats& bvh, bool quick_kernels);

 private:
  const RenderCommand& cmd_;
  const StereoPipeline::Options& options_;
  int ranks_;
  AtomicFileWriter file_;
  bool first_frame_ = true;
};

// --timeline: a Chrome trace / Perfetto JSON with one track (tid) per device and one slice per
// OpenCL command (from its profiling events). Device clocks are made relative to the run's
// first command; devices that do not share a clock (separate GPUs) are only comparable within
// their own track. A frame's events (~100 commands) are written with one write().
class RenderTimeline {
 public:
  // Opens the file now, so an unwritable path fails before any rendering.
  explicit RenderTimeline(const std::string& path);

  // Names the tracks; called once, before the first frame.
  void name_devices(const DeviceSet& devices);
  void add_frame(unsigned frame, const FrameStats& stats);
  // Closes the event list; the file appears under its name.
  void finish();

 private:
  void event(const nlohmann::json& e);
  void flush();

  AtomicFileWriter file_;
  std::string chunk_;  // events not yet written
  bool first_event_ = true;
  std::uint64_t origin_ns_ = 0;  // the earliest command of the first frame: time 0 of the trace
};

}  // namespace px
