// Stage 2 (and mono's stage 12): path traces an eye's rows on each device, with the megakernel
// (the same launch as the reference renderer, PathTracer::launch) or the wavefront tracer
// (WavefrontPathTracer); the images are the same either way.
#pragma once

#include "pipeline/stages/stage_unit.h"
#include "render/path_tracer.h"
#include "render/wavefront_path_tracer.h"

#include <vector>

namespace px {

class PathTraceStage : public StageUnit {
 public:
  using Options = PathTracer::Options;

  PathTraceStage(StageEnv& env, const Options& options, PathTraceKernel kernel = PathTraceKernel::Megakernel);
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;

  // The control loop changes spp and bounces between frames; hole filling traces with the same.
  Options& options() { return options_; }
  const Options& options() const { return options_; }
  PathTraceKernel kernel() const { return kernel_; }
  // Where a denoised frame's samples go, decided per frame by the pipeline (a still view sends
  // every sample along the G-buffer's ray; a moving one spreads them and counts one kind per
  // pixel): PathTracer::Options::every_sample_on_gbuffer_ray and same_kind_samples.
  void set_sample_placement(bool every_on_gbuffer_ray, bool same_kind) {
    options_.every_sample_on_gbuffer_ray = every_on_gbuffer_ray;
    options_.same_kind_samples = same_kind;
  }
  // The launch constants of `rows` of `eye` in frame `frame`.
  FrameParams frame_params(int eye, RowRange rows, unsigned frame) const;

  // Device d's wavefront buffers, which hole filling shares (both stages run on d's main queue,
  // one after the other).
  WavefrontPathTracer::Scratch& wavefront_scratch(int d) { return scratch_[d]; }
  // Records a wavefront launch's commands under `stage` and device d.
  void record(Stage stage, int d, const std::vector<WavefrontPathTracer::Command>& commands);

 private:
  Options options_;
  PathTraceKernel kernel_;
  std::vector<WavefrontPathTracer::Scratch> scratch_;  // per device, grown on first use
};

}  // namespace px
