// Stage 4: reprojects the left eye's diffuse radiance into the right eye's rows; pixels it
// cannot fill are appended to the hole list (FrameImages::holes) for stage 5.
#pragma once

#include "pipeline/stages/stage_unit.h"

namespace px {

class ReprojectStage : public StageUnit {
 public:
  using StageUnit::StageUnit;
  // Each pixel's test reads the 3x3 neighbourhood of its G-buffer texel in both eyes.
  static constexpr unsigned gbuffer_rows_read() { return 1; }
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;
};

}  // namespace px
