// The control loop that holds the stereo frame time inside a window [lo, hi] ms by tuning
// samples per pixel, bounces and SVGF iterations between frames.
//
// Predictor (after the stereo paper): for a parameter p at value x_p, the stages that depend
// on it cost T_p in total (spp and bounces: path tracing and hole filling; SVGF iterations:
// denoising), so one unit of p costs T_p / x_p, and changing p alone to x' predicts
//     T'(x') = T - T_p + (T_p / x_p) x'.
// Inside the window nothing changes. Above it, the parameters are lowered in the order SVGF
// iterations, bounces, spp; below it they are raised in the opposite order (quality first: spp
// before bounces before iterations). One parameter moves per frame, to the value whose
// prediction lands nearest the middle of the window within its limits; the next frame's
// measurement corrects the rest.
//
// Measurements are smoothed per unit: the median of the last three frames' T_p / x_p (and of
// the rest of the frame). One slow frame is ignored outright, a lasting change of scene cost
// is followed after two frames, and a change of a parameter does not look like a change of the
// scene.
#pragma once

#include <array>
#include <string>

namespace px {

// What the controller tunes. No defaults of its own: a quality is always read from the pipeline
// (StereoPipeline::quality, whose options hold the one default of each) or written out in full.
struct FrameQuality {
  unsigned spp = 0;
  unsigned bounces = 0;
  unsigned svgf_iterations = 0;
  bool operator==(const FrameQuality&) const = default;
};

// One frame's measured cost, split by what depends on which parameter (ms, the frame's
// critical path: for several devices, the slowest device's stage times).
struct FrameCost {
  double trace_ms = 0.0;    // path tracing + hole filling: depends on spp and bounces
  double denoise_ms = 0.0;  // SVGF: depends on its iterations
  double other_ms = 0.0;    // everything else (G-buffer, reprojection, tonemap, transfers, host)
  double total() const { return trace_ms + denoise_ms + other_ms; }
};

class FrameTimeController {
 public:
  struct Range {
    unsigned min, max;
  };
  struct Options {
    double lo_ms = 11.0, hi_ms = 20.0;  // the paper's window
    Range spp{1, 64};
    Range bounces{1, 6};
    Range svgf_iterations{1, 5};
  };

  explicit FrameTimeController(Options options);

  // Feeds the cost measured for a frame rendered at `used`; returns the quality for the next
  // frame. `used` must lie within the limits.
  FrameQuality update(const FrameQuality& used, const FrameCost& measured);

  // The smoothed frame time predicted for the quality update() last returned (ms).
  double predicted_ms() const { return predicted_ms_; }
  const Options& options() const { return options_; }

  // "LO:HI" in ms, 0 < LO < HI; throws std::invalid_argument with a clear message otherwise.
  static std::pair<double, double> parse_window(const std::string& text);

 private:
  double predict(const FrameQuality& q) const;

  Options options_;
  // The last three frames' per-unit costs: trace per (spp x bounces), denoise per iteration,
  // and the rest of the frame; `count_` of them are filled (up to 3).
  struct UnitCosts {
    double trace, denoise, other;
  };
  std::array<UnitCosts, 3> recent_{};
  int count_ = 0, next_slot_ = 0;
  UnitCosts smoothed_{};
  double predicted_ms_ = 0.0;
};

}  // namespace px
