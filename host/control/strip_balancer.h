// Dynamic load balancing: moves the boundaries between the devices' strips from frame to frame
// so that every device finishes its strip at the same time.
//
// Model: device d's time is proportional to its rows, at a per-row cost c_d = ms_d / rows_d
// measured on its current strip (which folds in both the device's speed and the cost of the
// scene content in its rows). Equal times need rows_d proportional to 1 / c_d; each boundary
// moves `gain` of the way toward that split, at most `max_step_rows` per frame, so a boundary
// never jumps past content whose cost it has not measured yet and the estimate is corrected
// every frame (a damped fixed-point iteration: the costs of the rows it moves are re-measured
// on their new owner). Costs are smoothed (exponential average) so one slow frame does not
// move anything far, and nothing moves while the predicted slowest device is within
// `deadband` of the mean (no dithering around the balance).
//
// Works on row counts of contiguous strips in device order; the caller turns them into rows.
#pragma once

#include <vector>

namespace px {

class StripBalancer {
 public:
  struct Options {
    unsigned max_step_rows = 8;  // a boundary moves at most this far per frame
    unsigned min_rows = 4;       // no strip shrinks below this (or height / devices if less)
    double gain = 0.5;           // fraction of the way to the predicted balance moved per frame
    double deadband = 0.03;      // leave the boundaries while max / mean predicted time - 1 < this
    double smoothing = 0.5;      // weight of the newest per-row cost in its running average
  };

  StripBalancer(unsigned height, int devices, Options options);

  // Feeds one frame: `rows[d]` the rows device d rendered, `device_ms[d]` its measured busy
  // time. Returns the row counts for the next frame (same sum). Non-positive or non-finite
  // times leave the strips as they are.
  std::vector<unsigned> update(const std::vector<unsigned>& rows, const std::vector<double>& device_ms);

  // The predicted imbalance of the strips update() last returned: slowest device's predicted
  // time over the mean, minus one (0 = balanced).
  double predicted_imbalance() const { return imbalance_; }

  const Options& options() const { return options_; }

 private:
  unsigned height_;
  int devices_;
  Options options_;
  std::vector<double> cost_per_row_;  // smoothed, per device; empty before the first frame
  double imbalance_ = 0.0;
};

}  // namespace px
