// Temporal gradients (A-SVGF) of one eye on one device, part of the denoise stage: each frame one
// pixel of every 3x3 stratum is shaded again, last frame's surface point in this frame's scene
// with last frame's random numbers (kernels/denoise/temporal_gradient.cl), and the differences
// are spread by a few edge-stopped a-trous steps on the strata grid (gradient_filter.cl). SVGF's
// temporal pass and its anti-aliasing read the result (lambda(), a float4 per stratum) and drop
// that share of their history, so a light that moves, switches or changes is followed within a
// frame or two instead of trailing for as long as the history lasts. Where nothing changed the two
// shades are the same path, lambda is 0 and the histories are what they are without gradients.
//
// Rows: the unit shades and filters the strata of its strip and PX_GRADIENT_REACH strata beyond
// (kernels/denoise/svgf_constants.h), from G-buffer rows the denoise stage's margin holds, so every
// device computes the strata it reads itself and N devices give one device's lambda bit for bit.
// Timed as its own stage (Stage::TemporalGradient).
#pragma once

#include "cl/device_set.h"
#include "image/row_range.h"
#include "pipeline/queue_lanes.h"
#include "pipeline/stages/svgf_denoiser.h"
#include "render/device_scene.h"
#include "shared/types.h"

#include <vector>

namespace px {

class TemporalGradients {
 public:
  // `device` is a local device index; `lanes` as SvgfDenoiser's.
  TemporalGradients(DeviceSet& devices, int device, unsigned width, unsigned height, QueueLanes* lanes = nullptr);

  // The strata rows a strip reads (its own, then PX_GRADIENT_REACH more each way): what shade()
  // must cover for the strip's lambda. In strata, clipped to the image.
  RowRange strata_of(RowRange strip) const;
  static unsigned strata_count(unsigned pixels) { return (pixels + PX_GRADIENT_STRATUM - 1) / PX_GRADIENT_STRATUM; }

  // Shades the strata around `strip` (strata_of), picking pixels within the G-buffer rows
  // `gbuffer_rows` (which must hold the strip's margin of PX_GRADIENT_ROWS where neighbours'
  // rows are exchanged), then filters them; lambda() then holds the strip's strata. `fp` is the
  // path tracer's frame parameters for this eye (bounces, light sampling, seed, frame);
  // `scene` the scene on this device. Without last frame's shades (the first frame, or after
  // reset()) every stratum's lambda is 0.
  void run(const cl::Program& shading, const DeviceSceneBuffers& scene, const cl::Buffer& gbuf,
           const cl::Buffer& prev_gbuf, const cl::Buffer& nonfinite, const FrameParams& fp, const CameraParams& cam,
           RowRange strip, RowRange gbuffer_rows);

  // The filtered strata: (difference, larger shade, share of valid picks, 0) per stratum; lambda
  // = |x| / y (svgf_common.h, px_gradient_lambda).
  const cl::Buffer& lambda() const { return filtered_[final_]; }
  // The unfiltered strata of the last run (tests compare the filter with a host one).
  const cl::Buffer& raw() const { return raw_; }
  unsigned strata_width() const { return strata_w_; }
  unsigned strata_height() const { return strata_h_; }
  // This frame's shades of this frame's picks (a float4 per pixel at the picked pixels), and last
  // frame's, which a device that took over rows from a neighbour must fetch with them.
  const cl::Buffer& shades() const { return shades_[parity_]; }
  const cl::Buffer& previous_shades() const { return shades_[1 - parity_]; }

  // This frame's shades become last frame's (once per frame, after every device read them).
  void end_frame();

  struct PassEvent {
    cl::Event event;
    const char* pass;
  };
  std::vector<PassEvent> take_events();

 private:
  GradientParams params(RowRange write, RowRange read, RowRange gbuffer_rows, unsigned step,
                        const FrameParams& fp) const;
  cl::CommandQueue& queue() { return lanes_ ? lanes_->queue(device_) : devices_.devices()[device_].queue; }

  DeviceSet& devices_;
  int device_;
  QueueLanes* lanes_;
  unsigned width_, height_;
  unsigned strata_w_, strata_h_;
  cl::Buffer shades_[2];    // float4 per pixel: [parity_] written this frame
  cl::Buffer raw_;          // float4 per stratum: the unfiltered differences
  cl::Buffer filtered_[2];  // float4 per stratum: the a-trous steps' ping-pong
  int final_ = 0;           // which of filtered_ holds the last step's output
  int parity_ = 0;
  bool have_history_ = false;
  std::vector<PassEvent> events_;
};

}  // namespace px
