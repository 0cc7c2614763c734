#include "control/frame_time_controller.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace px {

namespace {

// Median of the first n (1..3) values.
double median(double a, double b, double c, int n) {
  if (n == 1) return a;
  if (n == 2) return 0.5 * (a + b);
  return std::max(std::min(a, b), std::min(std::max(a, b), c));
}

}  // namespace

FrameTimeController::FrameTimeController(Options options) : options_(options) {
  if (!(options_.lo_ms > 0.0 && options_.hi_ms > options_.lo_ms))
    throw std::invalid_argument("frame-time window needs 0 < lo < hi");
  for (const Range* r : {&options_.spp, &options_.bounces, &options_.svgf_iterations})
    if (r->min < 1 || r->min > r->max) throw std::invalid_argument("controller limits need 1 <= min <= max");
}

std::pair<double, double> FrameTimeController::parse_window(const std::string& text) {
  const auto colon = text.find(':');
  auto fail = [&]() -> std::pair<double, double> {
    throw std::invalid_argument("--target-ms expects LO:HI in milliseconds with 0 < LO < HI (e.g. 11:20), got '" +
                                text + "'");
  };
  if (colon == std::string::npos) return fail();
  double lo = 0.0, hi = 0.0;
  try {
    std::size_t used_lo = 0, used_hi = 0;
    lo = std::stod(text.substr(0, colon), &used_lo);
    hi = std::stod(text.substr(colon + 1), &used_hi);
    if (used_lo != colon || used_hi != text.size() - colon - 1) return fail();
  } catch (const std::logic_error&) {
    return fail();
  }
  if (!(std::isfinite(lo) && std::isfinite(hi) && lo > 0.0 && hi > lo)) return fail();
  return {lo, hi};
}

// The trace stages scale with spp x bounces (each path costs about one trace per bounce), the
// denoiser with its iterations; the paper's per-parameter predictor is this product model
// with one factor changed at a time.
double FrameTimeController::predict(const FrameQuality& q) const {
  return smoothed_.other + smoothed_.trace * q.spp * q.bounces + smoothed_.denoise * q.svgf_iterations;
}

FrameQuality FrameTimeController::update(const FrameQuality& used, const FrameCost& measured) {
  recent_[next_slot_] = {std::max(0.0, measured.trace_ms) / (double(used.spp) * used.bounces),
                         std::max(0.0, measured.denoise_ms) / used.svgf_iterations, std::max(0.0, measured.other_ms)};
  next_slot_ = (next_slot_ + 1) % 3;
  count_ = std::min(count_ + 1, 3);
  // The oldest-first order does not matter to a median; unfilled slots are never read.
  const UnitCosts& a = recent_[0];
  const UnitCosts& b = recent_[1];
  const UnitCosts& c = recent_[2];
  smoothed_ = {median(a.trace, b.trace, c.trace, count_), median(a.denoise, b.denoise, c.denoise, count_),
               median(a.other, b.other, c.other, count_)};

  const double lo = options_.lo_ms, hi = options_.hi_ms, middle = 0.5 * (lo + hi);
  FrameQuality next = used;
  const double now = predict(used);
  if (now >= lo && now <= hi) {
    predicted_ms_ = now;
    return next;  // inside the window: leave everything alone
  }
  struct Knob {
    unsigned FrameQuality::*value;
    Range range;
  };
  // Quality order: spp first, then bounces, then SVGF iterations.
  const std::array<Knob, 3> raise_order = {Knob{&FrameQuality::spp, options_.spp},
                                           Knob{&FrameQuality::bounces, options_.bounces},
                                           Knob{&FrameQuality::svgf_iterations, options_.svgf_iterations}};
  const bool too_slow = now > hi;
  for (int k = 0; k < 3; ++k) {
    const Knob& knob = raise_order[too_slow ? 2 - k : k];
    const unsigned current = used.*knob.value;
    const unsigned limit = too_slow ? knob.range.min : knob.range.max;
    if (current == limit) continue;
    // The value whose prediction is nearest the middle of the window, stepping from the
    // current value toward the limit (the predictor is linear in each parameter).
    unsigned best = current;
    double best_distance = std::abs(now - middle);
    for (unsigned v = current; v != limit;) {
      v = too_slow ? v - 1 : v + 1;
      FrameQuality trial = used;
      trial.*knob.value = v;
      const double t = predict(trial);
      // Raising never aims past the window, and keeps a tenth of it as headroom: a value
      // predicted right at its top edge would leave it on the next slow frame and come back
      // down, an oscillation.
      if (!too_slow && t > hi - 0.1 * (hi - lo)) break;
      if (std::abs(t - middle) < best_distance) {
        best = v;
        best_distance = std::abs(t - middle);
      }
    }
    if (best != current) {
      next.*knob.value = best;
      break;
    }
  }
  predicted_ms_ = predict(next);
  return next;
}

}  // namespace px
