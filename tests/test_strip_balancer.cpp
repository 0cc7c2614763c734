// The strip balancer on a synthetic cost model: rows of unequal cost (a bottom-heavy scene),
// devices of unequal speed, measurement noise and a step change of the scene. The optimum it
// should approach is found by brute force over every boundary placement. No time is measured.
#include "control/strip_balancer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace px {
namespace {

struct CostModel {
  std::vector<double> row_cost;  // ms per row on a speed-1 device
  std::vector<double> speed;     // per device

  double time(int d, unsigned begin, unsigned end) const {
    double t = 0.0;
    for (unsigned y = begin; y < end; ++y) t += row_cost[y];
    return t / speed[d];
  }
  double makespan(const std::vector<unsigned>& rows) const {
    double worst = 0.0;
    unsigned y = 0;
    for (std::size_t d = 0; d < rows.size(); ++d) {
      worst = std::max(worst, time(static_cast<int>(d), y, y + rows[d]));
      y += rows[d];
    }
    return worst;
  }
  // Brute force over every split into 2 or 3 non-empty strips.
  double best_makespan() const {
    const unsigned h = static_cast<unsigned>(row_cost.size());
    double best = 1e300;
    if (speed.size() == 2) {
      for (unsigned a = 1; a < h; ++a) best = std::min(best, makespan({a, h - a}));
    } else {
      for (unsigned a = 1; a < h; ++a)
        for (unsigned b = 1; a + b < h; ++b) best = std::min(best, makespan({a, b, h - a - b}));
    }
    return best;
  }
};

CostModel bottom_heavy(unsigned h, std::vector<double> speed) {
  CostModel m;
  m.speed = std::move(speed);
  for (unsigned y = 0; y < h; ++y) {
    const double v = static_cast<double>(y) / h;
    m.row_cost.push_back(0.1 * (1.0 + 5.0 * v * v));  // the floor of a scene costs 6x its sky
  }
  return m;
}

std::vector<unsigned> even(unsigned h, int n) {
  std::vector<unsigned> rows(n, h / n);
  for (unsigned i = 0; i < h % n; ++i) ++rows[i];
  return rows;
}

// Runs `frames` frames from `rows`, feeding noisy measured times; checks the per-frame limits
// and returns the strips after every frame.
std::vector<std::vector<unsigned>> simulate(StripBalancer& b, const CostModel& m, std::vector<unsigned> rows,
                                            unsigned frames, double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-noise, noise);
  std::vector<std::vector<unsigned>> out;
  const unsigned h = static_cast<unsigned>(m.row_cost.size());
  for (unsigned f = 0; f < frames; ++f) {
    std::vector<double> ms;
    unsigned y = 0;
    for (std::size_t d = 0; d < rows.size(); ++d) {
      ms.push_back(m.time(static_cast<int>(d), y, y + rows[d]) * (1.0 + u(rng)));
      y += rows[d];
    }
    auto next = b.update(rows, ms);
    EXPECT_EQ(std::accumulate(next.begin(), next.end(), 0u), h);
    unsigned before = 0, after = 0;
    for (std::size_t d = 0; d + 1 < rows.size(); ++d) {
      before += rows[d];
      after += next[d];
      EXPECT_LE(std::abs(static_cast<int>(after) - static_cast<int>(before)),
                static_cast<int>(b.options().max_step_rows))
          << "frame " << f << ": boundary " << d << " moved too far";
    }
    for (unsigned r : next) EXPECT_GE(r, b.options().min_rows) << "frame " << f;
    rows = next;
    out.push_back(rows);
  }
  return out;
}

// The largest movement of any boundary over the given frames (max - min of its row).
unsigned boundary_wander(const std::vector<std::vector<unsigned>>& history, std::size_t from) {
  unsigned worst = 0;
  for (std::size_t i = 0; i + 1 < history[0].size(); ++i) {
    unsigned lo = ~0u, hi = 0;
    for (std::size_t f = from; f < history.size(); ++f) {
      const unsigned b = std::accumulate(history[f].begin(), history[f].begin() + i + 1, 0u);
      lo = std::min(lo, b);
      hi = std::max(hi, b);
    }
    worst = std::max(worst, hi - lo);
  }
  return worst;
}

TEST(StripBalancer, ConvergesOnASkewedSceneForTwoAndThreeDevices) {
  for (int n : {2, 3}) {
    const unsigned h = 240;
    const CostModel m = bottom_heavy(h, std::vector<double>(n, 1.0));
    StripBalancer b(h, n, {});
    std::mt19937 rng(7);
    const auto start = even(h, n);
    const auto history = simulate(b, m, start, 60, 0.03, rng);
    const double best = m.best_makespan(), first = m.makespan(start), last = m.makespan(history.back());
    std::printf("[ measure  ] %d devices: makespan even %.3f -> balanced %.3f (optimum %.3f)\n", n, first, last, best);
    EXPECT_GT(first, 1.15 * best) << "the even split should be clearly unbalanced for this test to mean anything";
    EXPECT_LT(last, 1.06 * best) << n << " devices";
    // Settled: after convergence the boundaries stay within a few rows despite 3% noise.
    EXPECT_LE(boundary_wander(history, 40), 4u) << n << " devices";
  }
}

TEST(StripBalancer, GivesAFasterDeviceMoreRows) {
  const unsigned h = 300;
  CostModel m;
  m.speed = {1.0, 2.0};
  m.row_cost.assign(h, 0.05);
  StripBalancer b(h, 2, {});
  std::mt19937 rng(3);
  const auto history = simulate(b, m, even(h, 2), 60, 0.02, rng);
  // Equal times: the device twice as fast takes two thirds of the rows.
  EXPECT_NEAR(static_cast<double>(history.back()[1]) / h, 2.0 / 3.0, 0.03);
}

TEST(StripBalancer, FollowsAStepChangeOfTheScene) {
  const unsigned h = 200;
  CostModel m = bottom_heavy(h, {1.0, 1.0});
  StripBalancer b(h, 2, {});
  std::mt19937 rng(11);
  auto history = simulate(b, m, even(h, 2), 40, 0.03, rng);
  // The camera turns: the costly rows are now at the top.
  std::reverse(m.row_cost.begin(), m.row_cost.end());
  const double after_step = m.makespan(history.back());
  const auto more = simulate(b, m, history.back(), 40, 0.03, rng);
  const double best = m.best_makespan();
  EXPECT_GT(after_step, 1.3 * best) << "the step should unbalance the strips";
  EXPECT_LT(m.makespan(more.back()), 1.06 * best);
  EXPECT_LE(boundary_wander(more, 30), 4u);
}

TEST(StripBalancer, LeavesBalancedStripsAndBadMeasurementsAlone) {
  StripBalancer b(100, 2, {});
  // Equal per-row costs on an even split: nothing to do, whatever the noise inside the deadband.
  EXPECT_EQ(b.update({50, 50}, {10.0, 10.2}), (std::vector<unsigned>{50, 50}));
  EXPECT_EQ(b.update({50, 50}, {0.0, 10.0}), (std::vector<unsigned>{50, 50}));
  EXPECT_EQ(b.update({50, 50}, {std::nan(""), 10.0}), (std::vector<unsigned>{50, 50}));
  EXPECT_THROW(b.update({50, 49}, {1.0, 1.0}), std::invalid_argument);
  EXPECT_THROW(b.update({100}, {1.0}), std::invalid_argument);
  EXPECT_THROW(StripBalancer(1, 2, {}), std::invalid_argument);
  // One device: nothing to balance.
  StripBalancer one(10, 1, {});
  EXPECT_EQ(one.update({10}, {5.0}), (std::vector<unsigned>{10}));
}

}  // namespace
}  // namespace px
