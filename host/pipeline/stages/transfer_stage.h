// Stage 9: a child device's rows travel to the owner (the dependency tree's root) through the
// child's host-mapped staging buffers (pipeline/row_transfer.h). What travels is the
// operation's payload: the finished image, or (baseline) linear radiance to be finished there.
#pragma once

#include "pipeline/stages/stage_unit.h"

namespace px {

class TransferStage : public StageUnit {
 public:
  struct Options {
    // A finished image carries its float radiance as well as RGBA8 (for EXR files); off: RGBA8
    // alone, 4 instead of 20 bytes a pixel.
    bool gather_radiance = true;
    // Linear radiance carries its albedo too (the owner denoises it, and SVGF demodulates).
    bool with_albedo = false;
  };
  TransferStage(StageEnv& env, const Options& options);
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;

 private:
  // Per device, staging for rows leaving it; each eye has its own half, and every row range
  // travels once a frame, so no two copies share staging bytes.
  struct Staging {
    StagingBuffer radiance, albedo, rgba;
  };
  Options options_;
  std::vector<Staging> staging_;
};

}  // namespace px
