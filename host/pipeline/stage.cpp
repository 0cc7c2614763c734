#include "pipeline/stage.h"

namespace px {

const char* stage_name(Stage s) {
  switch (s) {
    case Stage::SceneUpdate: return "scene update";
    case Stage::PathTraceLeft: return "path trace left";
    case Stage::GBuffer: return "g-buffer";
    case Stage::Reproject: return "reprojection";
    case Stage::HoleFill: return "hole filling";
    case Stage::Denoise: return "denoise";
    case Stage::RecordPrevious: return "record previous";
    case Stage::Tonemap: return "tonemap";
    case Stage::Transfer: return "transfer";
    case Stage::Stitch: return "stitch";
    case Stage::Output: return "output";
    case Stage::PathTraceRight: return "path trace right";
    case Stage::TemporalGradient: return "temporal gradient";
    case Stage::DirectLight: return "direct light";
  }
  return "?";
}

}  // namespace px
