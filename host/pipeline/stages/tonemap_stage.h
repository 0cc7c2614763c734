// Stage 8: linear radiance to sRGB RGBA8 for an eye's rows, counting non-finite pixels.
#pragma once

#include "pipeline/stages/stage_unit.h"

namespace px {

class TonemapStage : public StageUnit {
 public:
  struct Options {
    float exposure = 1.0f;  // scale applied before the sRGB encoding
  };
  TonemapStage(StageEnv& env, const Options& options);
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;

 private:
  Options options_;
  cl::Buffer thresholds_;  // srgb8_thresholds(), 256 floats, read by every device
};

}  // namespace px
