// The stages of a stereo frame, numbered after the stereo paper's pipeline (1 scene update ...
// 11 output) so reports and tables can be set beside its figures; 12 is ours (mono's full
// right-eye trace). No schedule lists stages 1, 7, 10 and 11: stage 1 is the host computing the
// cameras, 10 is the owner's image being whole once every strip arrived, 11 the file writes, and
// stage 7 happens inside the denoise unit (its SVGF history copies are timed under stage 7, the
// G-buffer becoming last frame's is a handle swap).
#pragma once

namespace px {

enum class Stage : int {
  SceneUpdate = 1,
  PathTraceLeft = 2,
  GBuffer = 3,
  Reproject = 4,
  HoleFill = 5,
  Denoise = 6,  // SVGF, both eyes
  RecordPrevious = 7,
  Tonemap = 8,
  Transfer = 9,  // strips to the owner, halo rows and history between neighbours
  Stitch = 10,
  Output = 11,
  PathTraceRight = 12,  // mono pipeline only: the right eye path traced in full
  // Ours, inside the denoise unit like stage 7: the temporal gradients' shading and filtering
  // (pipeline/stages/temporal_gradients.h), timed apart from SVGF's own passes.
  TemporalGradient = 13,
  // Ours: ReSTIR DI at the first hit (pipeline/stages/direct_light_stage.h), with
  // `--direct-light restir`: after stage 2 (or 12) for its eye, after stage 5 for the right eye's holes.
  DirectLight = 14,
};
const char* stage_name(Stage s);

}  // namespace px
