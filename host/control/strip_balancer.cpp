#include "control/strip_balancer.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace px {

StripBalancer::StripBalancer(unsigned height, int devices, Options options)
    : height_(height), devices_(devices), options_(options) {
  if (devices < 1) throw std::invalid_argument("StripBalancer: at least one device");
  if (height < static_cast<unsigned>(devices)) throw std::invalid_argument("StripBalancer: fewer rows than devices");
  if (!(options.gain > 0.0 && options.gain <= 1.0))
    throw std::invalid_argument("StripBalancer: gain must be in (0, 1]");
  if (!(options.smoothing > 0.0 && options.smoothing <= 1.0))
    throw std::invalid_argument("StripBalancer: smoothing must be in (0, 1]");
}

namespace {

// Slowest / mean - 1 of the times `cost[d] * rows[d]`.
double imbalance(const std::vector<double>& cost, const std::vector<unsigned>& rows) {
  double worst = 0.0, sum = 0.0;
  for (std::size_t d = 0; d < rows.size(); ++d) {
    const double t = cost[d] * rows[d];
    worst = std::max(worst, t);
    sum += t;
  }
  return sum > 0.0 ? worst / (sum / static_cast<double>(rows.size())) - 1.0 : 0.0;
}

}  // namespace

std::vector<unsigned> StripBalancer::update(const std::vector<unsigned>& rows, const std::vector<double>& device_ms) {
  const auto n = static_cast<std::size_t>(devices_);
  if (rows.size() != n || device_ms.size() != n)
    throw std::invalid_argument("StripBalancer::update: one row count and one time per device");
  if (std::accumulate(rows.begin(), rows.end(), 0u) != height_)
    throw std::invalid_argument("StripBalancer::update: row counts must add up to the height");
  if (n == 1) return rows;
  for (std::size_t d = 0; d < n; ++d)
    if (rows[d] == 0 || !(device_ms[d] > 0.0) || !std::isfinite(device_ms[d])) return rows;

  // Smoothed per-row cost of each device.
  if (cost_per_row_.empty()) {
    for (std::size_t d = 0; d < n; ++d) cost_per_row_.push_back(device_ms[d] / rows[d]);
  } else {
    for (std::size_t d = 0; d < n; ++d)
      cost_per_row_[d] += options_.smoothing * (device_ms[d] / rows[d] - cost_per_row_[d]);
  }
  imbalance_ = imbalance(cost_per_row_, rows);
  if (imbalance_ < options_.deadband) return rows;

  // The balanced split: rows proportional to 1 / cost, as boundary positions (prefix sums).
  double inv_sum = 0.0;
  for (double c : cost_per_row_) inv_sum += 1.0 / c;
  const unsigned min_rows = std::max(1u, std::min(options_.min_rows, height_ / devices_));
  std::vector<long> boundary(n + 1, 0);  // boundary[i]: first row of strip i
  boundary[n] = height_;
  double target = 0.0;
  long current = 0;
  for (std::size_t i = 1; i < n; ++i) {
    target += height_ * (1.0 / cost_per_row_[i - 1]) / inv_sum;
    current += rows[i - 1];
    const double step = options_.gain * (target - static_cast<double>(current));
    const long move = std::clamp(std::lround(step), -static_cast<long>(options_.max_step_rows),
                                 static_cast<long>(options_.max_step_rows));
    boundary[i] = current + move;
  }
  // Keep every strip at least min_rows, boundaries in order (top to bottom, then bottom up).
  for (std::size_t i = 1; i < n; ++i)
    boundary[i] = std::max(boundary[i], boundary[i - 1] + static_cast<long>(min_rows));
  for (std::size_t i = n - 1; i >= 1; --i)
    boundary[i] = std::min(boundary[i], boundary[i + 1] - static_cast<long>(min_rows));
  std::vector<unsigned> next(n);
  for (std::size_t d = 0; d < n; ++d) next[d] = static_cast<unsigned>(boundary[d + 1] - boundary[d]);
  imbalance_ = imbalance(cost_per_row_, next);
  return next;
}

}  // namespace px
