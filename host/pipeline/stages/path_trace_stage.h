// Stage 2 (and mono's stage 12): path traces an eye's rows on each device, through the same
// launcher as the reference renderer (PathTracer::launch).
#pragma once

#include "pipeline/stages/stage_unit.h"
#include "render/path_tracer.h"

namespace px {

class PathTraceStage : public StageUnit {
 public:
  using Options = PathTracer::Options;

  PathTraceStage(StageEnv& env, const Options& options) : StageUnit(env), options_(options) {}
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;

  // The control loop changes spp and bounces between frames; hole filling traces with the same.
  Options& options() { return options_; }
  const Options& options() const { return options_; }
  // The launch constants of `rows` of `eye` in frame `frame`.
  FrameParams frame_params(int eye, RowRange rows, unsigned frame) const;

 private:
  Options options_;
};

}  // namespace px
