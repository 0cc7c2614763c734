// What `render` and `view` share: the pipeline options and control loop a RenderCommand asks
// for, the scene / devices / pipeline built from them, and the per-stage timing summary.
#pragma once

#include "app/commands.h"
#include "app/scene_setup.h"
#include "control/frame_time_controller.h"
#include "pipeline/stereo_pipeline.h"
#include "render/device_scene.h"

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace px {

// The pipeline options and, with --target-ms, the control loop. Throws std::invalid_argument
// for inconsistent flags (a bad --target-ms window, ...). The ranges of single flags
// (--spp, --bounces) are checked where the flags are read (main.cpp) and again by the pipeline.
struct PipelineConfig {
  StereoPipeline::Options options;
  std::optional<FrameTimeController> controller;
  // Settings that are allowed but change what the user gets in a way they may not expect (e.g.
  // no temporal history): one line each, printed once by the caller (rank 0 under MPI).
  std::vector<std::string> warnings;
};
PipelineConfig make_pipeline_config(const RenderCommand& cmd);

void print_device_set(const DeviceSet& set);
// One line: the features the scene-dependent kernels are compiled with (--kernels).
void print_kernel_features(const DeviceScene& scene);
// The log line of a quick kernel build (cl/kernel_build.h); nothing for an optimised one.
void print_kernel_build(const DeviceSet& set);
// One line: the scene's bytes on the devices (one copy per context) and the upload time.
void print_scene_upload(const DeviceScene& scene, int devices);

// Scene, BVH, devices and the stereo pipeline of a RenderCommand, built in that order with
// progress on stderr (the pipeline refers to the scene and devices it is built on).
struct RenderSession : SceneOnDevices {
  RenderSession(const RenderCommand& cmd, const StereoPipeline::Options& options);
  StereoPipeline pipeline;
};

// Per stage, the slowest device's time in one frame (ms): the frame's path through that stage.
std::map<Stage, double> slowest_device_ms(const FrameStats& stats);
// The stage whose slowest device took longest in `stats` (none for a frame without stages).
std::optional<std::pair<Stage, double>> slowest_stage(const FrameStats& stats);

// Medians over frames of each stage's device time, for the end-of-run summary.
class StageSummary {
 public:
  void add(const FrameStats& stats);
  std::size_t frames() const { return wall_ms_.size(); }
  // A table: per stage the median of the slowest device's time and of all devices' summed
  // time, then the frame's wall time; frames before `skip` (kernel compilation) are left out
  // while later frames exist.
  std::string table(std::size_t skip = 1) const;

 private:
  std::map<Stage, std::vector<double>> slowest_, total_;  // per stage, one value per frame
  std::vector<double> wall_ms_;
};

}  // namespace px
