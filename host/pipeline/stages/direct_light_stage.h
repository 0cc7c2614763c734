// Stage 14 (ours): ReSTIR DI at the first hit of every traced pixel (kernels/restir/restir_di.cl),
// scheduled with `--direct-light restir`. The path tracer leaves out next-event estimation at the
// first vertex of each pixel's G-buffer ray (sample 0); this unit adds that vertex's direct light
// from reservoirs resampled from the light sampler's candidates, last frame's reservoir at the
// surface's previous pixel (temporal reuse) and a few neighbours' (spatial reuse).
//
// Where it runs: the left eye (and mono's right eye) over each device's strip, before
// reprojection copies left pixels into the right eye; the right eye of the stereo pipelines over
// the hole list alone, after hole filling (a reprojected pixel already carries its left pixel's
// direct light). Holes get temporal reuse but no spatial reuse: their neighbours are mostly
// reprojected pixels, which have no reservoir of their own.
//
// Rows: the spatial taps of a strip's pixels reach `radius` rows beyond it; the unit computes the
// candidates and temporal reuse of those margin rows itself (from the same sample streams, so they
// equal the neighbour's), and fetches from the neighbours last frame's reservoirs and
// surfaces within radius + temporal_rows of the strip (and, when strips moved, the rows it took
// over). N devices and MPI ranks therefore give one device's image bit for bit.
#pragma once

#include "pipeline/stages/path_trace_stage.h"
#include "pipeline/stages/stage_unit.h"
#include "restir/restir_params.h"

#include <array>
#include <optional>
#include <vector>

namespace px {

class DirectLightStage : public StageUnit {
 public:
  struct Options {
    // Light samples resampled per pixel and frame; more did not pay on CPUs (docs/measurements.md,
    // Many lights).
    unsigned candidates = 1;
    unsigned neighbours = 3;      // spatial reuse: reservoirs of this many neighbours (<= PX_RESTIR_MAX_NEIGHBOURS)
    unsigned radius = 16;         // spatial reuse: neighbours within this many pixels
    bool temporal = true;         // reuse last frame's reservoir at the surface's previous pixel
    float max_history = 20.0f;    // a reused reservoir's confidence cap, in frames' worth of candidates
    unsigned temporal_rows = 16;  // largest vertical offset of the previous pixel (as SVGF's)
    // The right eye's holes also reuse the left eye's reservoir where the left eye sees the same
    // surface (glossy surfaces, which reprojection leaves to the holes).
    bool stereo_reuse = true;
  };
  // `tracer`: the path tracing unit whose frame parameters (lights, seed, frame) the passes share.
  // `right_eye_holes`: the right eye's operations cover its hole list (stereo pipelines), not rows.
  // Throws std::invalid_argument for options out of range.
  DirectLightStage(StageEnv& env, const Options& options, const PathTraceStage& tracer, bool right_eye_holes);

  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;
  void end_frame(const FrameInputs& in) override;

  const Options& options() const { return options_; }

 private:
  void run_eye(int e, const std::vector<RowRange>& strip, const FrameInputs& in);
  RestirParams params(RowRange rows, RowRange readable, unsigned frame) const;

  struct PerEye {
    // After temporal reuse (2 float4 a pixel), what spatial reuse and next frame read:
    // [parity_] this frame's, the other last frame's.
    std::array<cl::Buffer, 2> reservoirs;
    std::array<cl::Buffer, 2> hits;  // the pixels' G-buffer hits (uint4 a pixel), as `reservoirs`
    StagingBuffer staging;           // rows leaving the device
  };
  Options options_;
  const PathTraceStage& tracer_;
  bool right_eye_holes_;
  std::vector<std::array<PerEye, 2>> dev_;  // per device (local ones allocated), per eye
  int parity_ = 0;
  // Per eye: the strips whose reservoirs each device holds from last frame (empty: none), this
  // frame's, the tag they were written with (frame + 1; 0: none) and last frame's camera.
  std::array<std::vector<RowRange>, 2> history_strips_, frame_strips_;
  std::array<unsigned, 2> history_tag_{0, 0}, frame_tag_{0, 0};
  std::array<std::optional<CameraParams>, 2> prev_cam_, frame_cam_;
};

}  // namespace px
