// The control loop on a synthetic cost model (no rendering, no clocks): stage times are a
// known function of the quality, with noise and a step change in scene cost. The controller
// must enter the frame-time window within a few frames from either side, stay put once inside
// (no oscillation), and respect its limits.
#include "control/frame_time_controller.h"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>

namespace px {
namespace {

// Ground truth of the synthetic renderer: path tracing costs `trace` ms per spp x bounce, SVGF
// `denoise` ms per iteration, `other` ms the rest; every stage time is jittered by +-noise.
struct SyntheticRenderer {
  double trace = 0.4, denoise = 0.6, other = 2.0, noise = 0.08;
  std::mt19937 rng{7};
  FrameCost render(const FrameQuality& q) {
    std::uniform_real_distribution<double> jitter(1.0 - noise, 1.0 + noise);
    return {trace * q.spp * q.bounces * jitter(rng), denoise * q.svgf_iterations * jitter(rng), other * jitter(rng)};
  }
  double true_ms(const FrameQuality& q) const {
    return trace * q.spp * q.bounces + denoise * q.svgf_iterations + other;
  }
};

struct Trace {
  std::vector<FrameQuality> quality;
  std::vector<double> ms;
};

Trace run(FrameTimeController& c, SyntheticRenderer& r, FrameQuality q, int frames, int step_at = -1,
          double step_factor = 1.0) {
  Trace t;
  for (int f = 0; f < frames; ++f) {
    if (f == step_at) r.trace *= step_factor;
    const FrameCost cost = r.render(q);
    t.quality.push_back(q);
    t.ms.push_back(r.true_ms(q));
    const auto& o = c.options();
    q = c.update(q, cost);
    EXPECT_GE(q.spp, o.spp.min);
    EXPECT_LE(q.spp, o.spp.max);
    EXPECT_GE(q.bounces, o.bounces.min);
    EXPECT_LE(q.bounces, o.bounces.max);
    EXPECT_GE(q.svgf_iterations, o.svgf_iterations.min);
    EXPECT_LE(q.svgf_iterations, o.svgf_iterations.max);
  }
  return t;
}

// First frame from which the true frame time stays inside [lo, hi] to the end (or -1).
int settled_from(const Trace& t, double lo, double hi, int begin, int end) {
  int first = -1;
  for (int f = begin; f < end; ++f) {
    const bool inside = t.ms[f] >= lo && t.ms[f] <= hi;
    if (inside && first < 0) first = f;
    if (!inside) first = -1;
  }
  return first;
}

int changes(const Trace& t, int begin, int end) {
  int n = 0;
  for (int f = begin + 1; f < end; ++f) n += !(t.quality[f] == t.quality[f - 1]);
  return n;
}

FrameTimeController::Options window(double lo, double hi) {
  FrameTimeController::Options o;
  o.lo_ms = lo;
  o.hi_ms = hi;
  return o;
}

TEST(FrameTimeController, EntersTheWindowFromAboveLoweringIterationsThenBouncesThenSpp) {
  FrameTimeController c(window(11.0, 20.0));
  SyntheticRenderer r;
  // 16 spp x 6 bounces: ~43 ms, far above the window.
  const Trace t = run(c, r, {16, 6, 5}, 40);
  const int settled = settled_from(t, 11.0, 20.0, 0, 40);
  ASSERT_GE(settled, 0);
  EXPECT_LE(settled, 6) << "took " << settled << " frames";
  EXPECT_EQ(changes(t, settled, 40), 0) << "oscillates inside the window";
  // Lowering starts with the least important parameter: SVGF iterations go first.
  EXPECT_LT(t.quality[1].svgf_iterations, 5u);
  EXPECT_EQ(t.quality[1].spp, 16u);
}

TEST(FrameTimeController, EntersTheWindowFromBelowRaisingSppFirst) {
  FrameTimeController c(window(11.0, 20.0));
  SyntheticRenderer r;
  const Trace t = run(c, r, {1, 6, 5}, 40);  // ~7.4 ms: below the window
  const int settled = settled_from(t, 11.0, 20.0, 0, 40);
  ASSERT_GE(settled, 0);
  EXPECT_LE(settled, 4);
  EXPECT_EQ(changes(t, settled, 40), 0);
  EXPECT_GT(t.quality.back().spp, 1u) << "quality first: spp rises";
  EXPECT_EQ(t.quality.back().bounces, 6u);
}

TEST(FrameTimeController, FollowsAStepInSceneCostAndSettlesAgain) {
  FrameTimeController c(window(11.0, 20.0));
  SyntheticRenderer r;
  // The scene gets 3x costlier at frame 30 (the camera turns to the foliage), then cheap again.
  Trace t = run(c, r, {4, 6, 5}, 30);
  const int before = settled_from(t, 11.0, 20.0, 0, 30);
  ASSERT_GE(before, 0);
  Trace after = run(c, r, t.quality.back(), 40, 0, 3.0);
  const int settled = settled_from(after, 11.0, 20.0, 0, 40);
  ASSERT_GE(settled, 0);
  EXPECT_LE(settled, 8);
  EXPECT_EQ(changes(after, settled, 40), 0);
  Trace back = run(c, r, after.quality.back(), 40, 0, 1.0 / 3.0);
  const int again = settled_from(back, 11.0, 20.0, 0, 40);
  ASSERT_GE(again, 0);
  EXPECT_LE(again, 8);
}

TEST(FrameTimeController, OneSlowFrameChangesNothing) {
  FrameTimeController c(window(11.0, 20.0));
  FrameQuality q{4, 6, 5};  // 4 x 6 x 0.4 + 5 x 0.6 + 2 = 14.6 ms: inside
  for (int f = 0; f < 10; ++f) {
    // Frame 5 is a hiccup (another process took the device): every stage twice as slow.
    const double k = f == 5 ? 2.0 : 1.0;
    q = c.update(q, {k * 9.6, k * 3.0, k * 2.0});
    EXPECT_EQ(q, (FrameQuality{4, 6, 5})) << "frame " << f;
  }
}

TEST(FrameTimeController, RespectsItsLimitsWhenTheWindowIsOutOfReach) {
  // Unreachable from above: even the minimum quality costs more than the window allows.
  FrameTimeController::Options o = window(1.0, 2.0);
  o.spp = {2, 8};
  o.bounces = {3, 6};
  o.svgf_iterations = {2, 5};
  FrameTimeController slow(o);
  SyntheticRenderer r;
  Trace t = run(slow, r, {8, 6, 5}, 30);
  EXPECT_EQ(t.quality.back(), (FrameQuality{2, 3, 2}));
  // Unreachable from below: the maximum quality is still faster than the window.
  FrameTimeController::Options f = window(500.0, 900.0);
  f.spp = {1, 16};
  FrameTimeController fast(f);
  Trace u = run(fast, r, {1, 2, 1}, 30);
  EXPECT_EQ(u.quality.back(), (FrameQuality{16, 6, 5}));
}

TEST(FrameTimeController, PredictionIsTheLinearModelOfTheMeasurement) {
  FrameTimeController c(window(11.0, 20.0));
  // Noise-free measurement at 2 spp x 4 bounces, 3 iterations: trace 8 ms, denoise 3 ms, rest 2 ms.
  const FrameQuality next = c.update({2, 4, 3}, {8.0, 3.0, 2.0});
  EXPECT_DOUBLE_EQ(c.predicted_ms(), 1.0 * next.spp * next.bounces + 1.0 * next.svgf_iterations + 2.0);
  EXPECT_EQ(next, (FrameQuality{2, 4, 3})) << "13 ms is inside the window: nothing changes";
}

TEST(FrameTimeController, WindowParsing) {
  EXPECT_EQ(FrameTimeController::parse_window("11:20"), (std::pair<double, double>{11.0, 20.0}));
  EXPECT_EQ(FrameTimeController::parse_window("0.5:2.5"), (std::pair<double, double>{0.5, 2.5}));
  for (const char* bad : {"", "11", "20:11", "0:5", "-1:5", "a:b", "11:20x", "11:inf", "nan:20"})
    EXPECT_THROW(FrameTimeController::parse_window(bad), std::invalid_argument) << bad;
}

}  // namespace
}  // namespace px
