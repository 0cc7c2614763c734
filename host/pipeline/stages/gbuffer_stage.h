// Stage 3: the primary hit (depth, normal, material) of every pixel of an eye's rows — what
// reprojection and SVGF read. Its operations already carry the rows beyond the strip that the
// readers declared (StageUnit::gbuffer_rows_read), so the G-buffer itself never travels.
#pragma once

#include "pipeline/stages/stage_unit.h"

namespace px {

class GBufferStage : public StageUnit {
 public:
  using StageUnit::StageUnit;
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;
};

}  // namespace px
