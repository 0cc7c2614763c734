// Stage 5: path traces the right-eye pixels reprojection left in the hole list, with the path
// tracing stage's options (the same spp and bounces as the left eye).
#pragma once

#include "pipeline/stages/path_trace_stage.h"

namespace px {

class HoleFillStage : public StageUnit {
 public:
  HoleFillStage(StageEnv& env, const PathTraceStage& tracer) : StageUnit(env), tracer_(tracer) {}
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;

 private:
  const PathTraceStage& tracer_;
};

}  // namespace px
