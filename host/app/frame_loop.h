// The frame loop of `render` as one unit. A frame of `render` is more than pipeline.render:
// under MPI the ranks first agree that there is a next frame and with what quality and strips;
// the animated scene is posed at the frame's time; after it the control loop and the strip
// balancer steer the next frame, the image is checked for NaNs and written, and the report,
// timeline, video and progress line record it. Those steps depend on each other's order (the
// balancer reads the strips the frame was rendered with, the report the prediction made before
// it), so they live together here, behind one clock, instead of inside the command's argument
// handling: app/commands.cpp parses and dispatches, this file renders frames.
#pragma once

#include "app/commands.h"
#include "app/frame_report.h"
#include "app/output_dir.h"
#include "app/render_setup.h"
#include "app/scene_setup.h"
#include "app/video_writer.h"
#include "control/strip_balancer.h"
#include "pipeline/stereo_pipeline.h"
#include "render/scene_animator.h"

#include <optional>
#include <vector>

namespace px {

class Cluster;

// `render`'s frames, start to summary. Every rank of an MPI run builds one with the same
// command and steps it in lockstep; rank 0 owns the frame: it decides whether there is a next
// one and with what quality and strips, and it alone writes files and prints.
//
// Built in place and never moved: the pipeline refers to the devices and scene it holds.
class RenderLoop {
 public:
  // `config` has been checked and completed by the caller (its options name `cluster`).
  // `cmd` and `cluster` must outlive the loop.
  RenderLoop(const RenderCommand& cmd, PipelineConfig config, Cluster& cluster);
  RenderLoop(const RenderLoop&) = delete;
  RenderLoop& operator=(const RenderLoop&) = delete;

  // Opens the outputs (rank 0; the report, timeline and video are opened before anything
  // renders, so that an unwritable path fails at once), loads the scene onto the devices and
  // builds the pipeline, then checks every frame's camera. Under MPI a rank that cannot start
  // stops every rank with its reason: rank 0 throws with all ranks' reasons, the others get an
  // exit status back. Nothing (std::nullopt) when the loop is ready to run.
  std::optional<int> start();

  // Renders frames 0 .. cmd.frames - 1, or until interrupted (Ctrl-C, SIGTERM; under MPI rank
  // 0's interrupt stops every rank before the same frame). An exit status when the run ends
  // without a frame (interrupted before the first); nothing when finish() is next.
  std::optional<int> run();

  // Rank 0: closes the report, video and timeline, prints the end-of-run summary on stdout,
  // and gives the exit status. Other ranks: 0.
  int finish();

 private:
  // Whether to render the next frame, and with what. Under MPI, rank 0 decides (its interrupt,
  // its control loop's quality, its balancer's strips) and every rank follows.
  bool next_frame_agreed();
  // Frame `f`: posed, rendered and (on rank 0) steered, checked, written and recorded.
  void step(unsigned f);
  void print_summary() const;

  const RenderCommand& cmd_;
  PipelineConfig config_;  // the options the report refers to, and the control loop
  Cluster& cluster_;
  const FrameClock clock_;
  const bool distributed_, root_, dynamic_strips_;

  // Rank 0's outputs, in the order they are opened.
  std::optional<OutputDir> out_dir_;
  std::optional<RenderReport> report_;
  std::optional<RenderTimeline> timeline_;
  std::optional<VideoWriter> video_;

  std::optional<SceneOnDevices> on_devices_;
  std::optional<SceneAnimator> animator_;
  std::optional<StereoPipeline> pipeline_;
  std::optional<StripBalancer> balancer_;  // --balance dynamic over more than one device
  int all_devices_ = 0;                    // every rank's devices together

  // Over the frames written (on rank 0), for the summary.
  StageSummary stages_;
  RenderTotals totals_;
  AnimationTotals animation_totals_;
  FrameQuality last_quality_;           // the quality of the last frame rendered
  std::optional<double> predicted_ms_;  // the control loop's prediction for the coming frame
  unsigned done_ = 0;                   // frames finished
};

}  // namespace px
