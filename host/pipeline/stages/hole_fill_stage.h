// Stage 5: path traces the right-eye pixels reprojection left in the hole list, with the path
// tracing stage's options (the same spp and bounces as the left eye) and its kind of tracer
// (with the wavefront tracer, `spread` does not apply: its paths are work-items already).
#pragma once

#include "pipeline/stages/path_trace_stage.h"

#include <vector>

namespace px {

class HoleFillStage : public StageUnit {
 public:
  // How a hole's samples map to work-items. Off: a work-item per hole, its spp samples in a loop
  // (path_trace_list). On: a work-item per (hole, sample) pair, then a pass that averages them
  // (path_trace_list_samples + resolve_hole_samples): spp times the items, for a GPU that a
  // frame's holes alone cannot fill. Same images either way. Auto: On for GPU devices at 2 to
  // kMaxSpreadSpp samples, else Off (on a CPU a work-item per hole already keeps every core busy,
  // and the samples would only make a round trip through memory).
  enum class SampleSpread { Auto, On, Off };
  struct Options {
    SampleSpread spread = SampleSpread::Auto;
  };
  // The scratch buffer holds two float4 per (pixel, sample) of the frame: 128 MB at 1280x720 and
  // 4 spp. Beyond this many samples, Auto keeps a work-item per hole.
  static constexpr unsigned kMaxSpreadSpp = 8;

  HoleFillStage(StageEnv& env, PathTraceStage& tracer, const Options& options);
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;

  // Whether device `d` spreads samples at `spp` (options().spread resolved for its type).
  bool spreads(int d, unsigned spp) const;
  const Options& options() const { return options_; }

 private:
  struct Scratch {
    cl::Buffer samples;
    std::size_t bytes = 0;
  };
  PathTraceStage& tracer_;  // its options, and its wavefront buffers
  Options options_;
  std::vector<Scratch> scratch_;  // per device, grown to the frame's pixels x spp on first use
};

}  // namespace px
