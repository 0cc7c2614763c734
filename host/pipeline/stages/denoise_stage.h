// Stage 6: SVGF on both eyes, every device for its own strip, passes in step across devices.
// The unit owns each device's filter state (SvgfDenoiser per eye), last frame's G-buffer and
// history, and decides which rows cross strip borders:
//   - halo seams: before every pass that reads beyond the strip, the neighbours' rows within
//     that pass's reach are copied in, so N devices give the 1-device image bit for bit;
//   - history follows the strips: when a boundary moved since last frame, the rows a device
//     took over bring their colour and moment history and last frame's G-buffer with them.
// In an animated scene it first adds paths to the pixels at moving objects' edges
// (Options::motion_edge_samples; timed under this stage as "motion edges" and "motion edge
// samples"), which its temporal passes cannot anti-alias from history.
#pragma once

#include "pipeline/stages/path_trace_stage.h"
#include "pipeline/stages/stage_unit.h"
#include "pipeline/stages/svgf_denoiser.h"
#include "pipeline/stages/temporal_gradients.h"

#include <memory>
#include <optional>
#include <string>

namespace px {

// How denoising treats the borders between devices' strips.
enum class SeamMode {
  Independent,  // each strip filtered alone (the paper): seams visible
  Bilateral,    // independent, then the paper's bilateral filter in a band around each seam
  Halo,         // neighbours' rows copied in before every pass that reads across a border:
                // the N-device image equals the 1-device image
};
const char* to_string(SeamMode m);

class DenoiseStage : public StageUnit {
 public:
  struct Options {
    SvgfDenoiser::Options svgf;
    SeamMode seams = SeamMode::Halo;
    unsigned seam_band = 4;  // rows each side of a seam the bilateral seam filter touches
    // Animated scenes: paths added before filtering to each pixel on a moving object's edge or
    // within two pixels of it on the still background (kernels/pipeline/motion_edges.cl), so
    // that such a pixel shows its coverage in one frame instead of over many; 0: none.
    unsigned motion_edge_samples = 8;
    // Temporal gradients (A-SVGF, pipeline/stages/temporal_gradients.h): a pixel in nine is shaded
    // again each frame to see whether the lighting changed, and the histories drop that share, so
    // that a light that moves or switches is followed within a frame or two. Off: the images are
    // those of a denoiser without them, to the bit.
    bool temporal_gradients = true;
  };
  // Throws std::invalid_argument for fewer than one a-trous iteration. `tracer` (the pipeline's
  // path tracing unit, for its launch constants) traces the motion edges' samples; without one
  // there are none.
  DenoiseStage(StageEnv& env, const Options& options, const PathTraceStage* tracer = nullptr);

  // The widest read of this frame's G-buffer beyond the strip. Halo seams: a-trous taps at
  // 2 * 2^(iterations-1), history taps at temporal_rows + 1, the variance estimate at 3, the
  // motion pass at PX_SVGF_NEAR_MOTION_REACH, the temporal gradients at PX_GRADIENT_ROWS, plus one row for the depth
  // gradient and the taps' luminance guide (svgf_luma's 3x3); bilateral seams: the band plus the filter's 3 rows;
  // independent: nothing beyond the strip.
  static unsigned gbuffer_rows_read(const Options& options);
  void run(const std::vector<const Operation*>& ops, const FrameInputs& in) override;
  void end_frame(const FrameInputs& in) override;

  // The control loop's knob: 1 <= n <= the iterations the unit was built with (its halo
  // margins were sized for those); std::invalid_argument otherwise.
  void set_iterations(unsigned n);
  unsigned iterations() const { return options_.svgf.iterations; }
  // The G-buffer of eye `e` the last finished frame was traced into on local device `d`: after
  // end_frame() it is held here as the next frame's history, and the frame images' buffer is
  // the one the next frame overwrites.
  const cl::Buffer& last_gbuffer(int d, int e) const { return dev_[d].gbuffer_prev[e]; }
  // Eye `e`'s temporal gradients on local device `d` (null without them).
  const TemporalGradients* gradients(int d, int e) const { return dev_[d].gradients[e].get(); }
  // How many pixels of eye `e` on this process's devices got the motion edges' samples in the
  // last frame (a blocking read; tests and reports).
  std::size_t motion_edge_pixels(int e);

 private:
  void denoise_eye(int e, const std::vector<RowRange>& strip, const FrameInputs& in);
  // Options::motion_edge_samples more paths for the motion edges of eye e's `rows` on device d.
  void sample_motion_edges(int e, int d, RowRange rows, RowRange readable, const FrameInputs& in);

  struct PerDevice {
    std::array<cl::Buffer, 2> gbuffer_prev;  // last frame's G-buffer (swapped with this frame's)
    std::array<std::unique_ptr<SvgfDenoiser>, 2> svgf;
    std::array<std::unique_ptr<TemporalGradients>, 2> gradients;  // Options::temporal_gradients
    // Per eye (the eyes may be denoised at the same time, on different queue lanes):
    std::array<StagingBuffer, 2> halo;     // float4 rows leaving the device
    std::array<StagingBuffer, 2> gbuffer;  // GBufferTexel rows of last frame's G-buffer when strips move
    // Per eye: the motion edges' pixels (full-frame indices) and their count.
    std::array<cl::Buffer, 2> edge_list, edge_count;
  };
  Options options_;
  unsigned max_iterations_;
  std::vector<PerDevice> dev_;
  const PathTraceStage* tracer_;
  // Per eye, the rows whose history each device holds (the strips it denoised last frame; empty
  // before the first frame) and the strips of the frame being denoised.
  std::array<std::vector<RowRange>, 2> history_strips_, frame_strips_;
  std::optional<std::array<CameraParams, 2>> prev_cams_;
};

}  // namespace px
