// The control loop (--target-ms) and dynamic strips (--balance dynamic) end to end: `render` as
// the parallax binary runs it (run_render: the real pipeline on this machine's devices, the
// real controller and balancer fed with measured frames), read back through its --report JSON.
// No time is asserted: every window is derived from frame times measured at the start of the
// test on this machine, and far enough from them that a shared, noisy 2-core machine cannot
// make a correct controller fail; a controller that ignores the window, or strips that never
// move, fail.
#include "app/commands.h"
#include "cl/device_set.h"
#include "image/image_io.h"
#include "image/image_metrics.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace px {
namespace {

struct FrameRecord {
  double wall_ms = 0.0;
  FrameQuality quality;
  std::vector<RowRange> strips;
  std::vector<double> device_ms;  // per device: its stages' device time, transfers left out
};

// Runs `cmd` with its output and report in `dir` (under `name`); the report's frames.
std::vector<FrameRecord> render_with_report(RenderCommand cmd, const test::TempDir& dir, const std::string& name) {
  cmd.out = (dir.path() / name).string();
  cmd.report = (dir.path() / (name + ".json")).string();
  EXPECT_EQ(run_render(cmd), 0) << name;
  std::ifstream in(cmd.report);
  const nlohmann::json report = nlohmann::json::parse(in);
  std::vector<FrameRecord> frames;
  for (const auto& f : report.at("frames")) {
    FrameRecord r;
    r.wall_ms = f.at("wall_ms").get<double>();
    r.quality = {f.at("spp").get<unsigned>(), f.at("bounces").get<unsigned>(), f.at("svgf_iterations").get<unsigned>()};
    for (const auto& s : f.at("strips")) {
      const unsigned row0 = s.at(0).get<unsigned>(), rows = s.at(1).get<unsigned>();
      r.strips.push_back({row0, row0 + rows});
      r.device_ms.push_back(0.0);
    }
    for (const auto& s : f.at("stages")) {
      const int d = s.at("device").get<int>();
      if (s.at("name").get<std::string>() != "transfer" && d >= 0 && d < static_cast<int>(r.device_ms.size()))
        r.device_ms[d] += s.at("device_ms").get<double>();
    }
    frames.push_back(r);
  }
  EXPECT_EQ(frames.size(), cmd.frames) << name;
  return frames;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string describe(const std::vector<FrameRecord>& frames) {
  std::string out;
  char line[96];
  for (std::size_t f = 0; f < frames.size(); ++f) {
    std::snprintf(line, sizeof line, "\n  frame %2zu: %6.1f ms at %u spp, %u bounces, %u iterations", f,
                  frames[f].wall_ms, frames[f].quality.spp, frames[f].quality.bounces,
                  frames[f].quality.svgf_iterations);
    out += line;
  }
  return out;
}

// ---- the control loop ----

// Cornell at 128x96 on one device: at 8 spp, 4 bounces and 3 iterations path tracing is most of
// the frame, so the quality settings span a wide range of frame times (docs/measurements.md,
// control loop end to end).
constexpr FrameQuality kMax{8, 4, 3};

RenderCommand control_command(const FrameQuality& start, unsigned frames, unsigned max_spp = kMax.spp) {
  RenderCommand cmd;
  cmd.scene.name = "cornell";
  cmd.size = {128, 96};
  cmd.frames = frames;
  cmd.pipeline.trace.spp = start.spp;
  cmd.pipeline.trace.bounces = start.bounces;  // the controller's upper limits: these bounces and iterations,
  cmd.pipeline.denoise->svgf.iterations = start.svgf_iterations;
  cmd.max_spp = max_spp;  // and this spp
  cmd.no_exr = true;
  return cmd;
}

// The median frame time at a fixed quality (no control loop), frames 3.. (frame 0 compiles
// kernels, frames 1-2 warm up).
double measured_ms(const FrameQuality& q, const test::TempDir& dir, const std::string& name) {
  const auto frames = render_with_report(control_command(q, 9, q.spp), dir, name);
  std::vector<double> ms;
  for (std::size_t f = 3; f < frames.size(); ++f) ms.push_back(frames[f].wall_ms);
  const double m = median(ms);
  std::printf("[ measure  ] %u spp, %u bounces, %u iterations: median frame %.1f ms\n", q.spp, q.bounces,
              q.svgf_iterations, m);
  return m;
}

std::string window(double lo, double hi) {
  char text[64];
  std::snprintf(text, sizeof text, "%.4f:%.4f", lo, hi);
  return text;
}

TEST(ControlLoopEndToEnd, WindowBelowEveryFrameTimeDrivesQualityToItsMinimumAndHoldsIt) {
  test::TempDir dir;
  const double t_min = measured_ms({1, 1, 1}, dir, "calibrate");
  // A quarter of the minimum quality's frame time and below: no setting reaches it.
  RenderCommand cmd = control_command(kMax, 14);
  cmd.target_ms = window(t_min / 8.0, t_min / 4.0);
  const auto frames = render_with_report(cmd, dir, "below");
  // Frame 1 is the first the controller sees; it lowers one parameter per frame (iterations,
  // then bounces, then spp: 3 frames from the maximum). Allow twice that.
  const FrameQuality least{1, 1, 1};
  for (std::size_t f = 8; f < frames.size(); ++f)
    EXPECT_EQ(frames[f].quality, least) << "frame " << f << " of window " << cmd.target_ms << describe(frames);
}

TEST(ControlLoopEndToEnd, WindowAboveEveryFrameTimeDrivesQualityToItsMaximumAndHoldsIt) {
  test::TempDir dir;
  const double t_max = measured_ms(kMax, dir, "calibrate");
  // Four times the maximum quality's frame time and above: no setting reaches it. The command
  // line's bounces and iterations are the controller's upper limits, so the run starts at the
  // least spp with those, and spp must rise to --max-spp.
  RenderCommand cmd = control_command({1, kMax.bounces, kMax.svgf_iterations}, 12);
  cmd.target_ms = window(4.0 * t_max, 8.0 * t_max);
  const auto frames = render_with_report(cmd, dir, "above");
  for (std::size_t f = 6; f < frames.size(); ++f)
    EXPECT_EQ(frames[f].quality, kMax) << "frame " << f << " of window " << cmd.target_ms << describe(frames);
}

TEST(ControlLoopEndToEnd, ReachableWindowIsHeldFromAboveAndFromBelow) {
  test::TempDir dir;
  // The window lies between the frame times of 1 and 16 spp (4 bounces, 3 iterations), a factor
  // 1.4 either side of their geometric mean: its width (hi / lo ~2) is the paper's (11:20 ms),
  // and several spp settings fall inside it (docs/measurements.md, control loop end to end).
  const FrameQuality least{1, kMax.bounces, kMax.svgf_iterations}, most{16, kMax.bounces, kMax.svgf_iterations};
  const double t_lo = measured_ms(least, dir, "calibrate_least");
  const double t_hi = measured_ms(most, dir, "calibrate_most");
  const double centre = std::sqrt(t_lo * t_hi), lo = centre / 1.4, hi = centre * 1.4;
  // The criterion: after a settling period (frames 10-23; from either start the controller
  // needs 1-4 frames to reach the window), the median frame time lies inside the window, give or
  // take 10%. The median (not every frame, nor the mean) ignores the minority of frames that
  // other processes on a shared 2-core machine slow down; the 10% allows for the controller
  // holding a setting whose smoothed time sits just inside an edge (it acts only once its
  // 3-frame median leaves the window; docs/measurements.md, control loop end to end).
  // A controller that ignores the window keeps its starting quality, whose frames lie outside
  // the window by at least the factor checked here, well beyond the 10%.
  const double apart = 1.35;
  if (t_hi < apart * hi || t_lo > lo / apart)
    GTEST_SKIP() << "frame times at 1 and 16 spp (" << t_lo << ", " << t_hi
                 << " ms) are too close on this machine to place a window between them";
  const std::string target = window(lo, hi);
  for (const FrameQuality& start : {most, least}) {
    RenderCommand cmd = control_command(start, 24, most.spp);
    cmd.target_ms = target;
    const std::string from = start == most ? "above" : "below";
    const auto frames = render_with_report(cmd, dir, from);
    std::vector<double> settled;
    for (std::size_t f = 10; f < frames.size(); ++f) settled.push_back(frames[f].wall_ms);
    const double m = median(settled);
    std::printf("[ measure  ] window %s from %s: median of frames 10-23 %.1f ms, last quality %u/%u/%u\n",
                target.c_str(), from.c_str(), m, frames.back().quality.spp, frames.back().quality.bounces,
                frames.back().quality.svgf_iterations);
    EXPECT_GE(m, lo / 1.1) << "from " << from << ", window " << target << describe(frames);
    EXPECT_LE(m, hi * 1.1) << "from " << from << ", window " << target << describe(frames);
  }
}

// ---- dynamic strips ----

// Cornell seen from above its box: the top half of the image looks past the box into the void
// (one ray a pixel, nothing to shade), the bottom half into the box (4 bounces): the device
// with the bottom strip has several times the work of the other. `box_below` false: the
// camera is lowered instead, and the expensive half is the top.
std::string half_empty_cornell(const test::TempDir& dir, bool box_below) {
  const char* y = box_below ? "560" : "-10";
  return dir
      .write(std::string("cornell_") + (box_below ? "below" : "above") + ".json",
             std::string("{\"generator\": \"cornell\", \"camera\": {\"position\": [278, ") + y +
                 ", -800], \"target\": [278, " + y + ", 0]}, \"camera_path\": []}")
      .string();
}

RenderCommand balance_command(const std::string& scene, StripBalance balance) {
  RenderCommand cmd;
  cmd.scene.name = scene;
  cmd.size = {64, 96};
  cmd.frames = 14;
  cmd.pipeline.trace.spp = 2;
  cmd.pipeline.trace.bounces = 4;
  cmd.pipeline.denoise->svgf.iterations = 2;
  cmd.devices.count = 2;
  cmd.balance = balance;
  return cmd;
}

TEST(DynamicStripsEndToEnd, TheBoundaryMovesTowardTheCheapHalfAndImagesStayBitIdentical) {
  if (DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt}).mode() == DeviceMode::SharedQueues)
    GTEST_SKIP() << "two devices would be queues on one OpenCL device here (one compute unit): their times say "
                    "nothing about their rows";
  if (!image_reading_available()) GTEST_SKIP() << "this build reads no images: the frames cannot be compared";
  test::TempDir dir;
  for (bool box_below : {true, false}) {
    SCOPED_TRACE(box_below ? "expensive bottom half" : "expensive top half");
    const std::string scene = half_empty_cornell(dir, box_below);
    const std::string name = box_below ? "below" : "above";
    const auto frames = render_with_report(balance_command(scene, StripBalance::Dynamic), dir, name + "_dynamic");
    // The boundary is the first row of device 1's strip; it starts at the even split.
    const unsigned even = frames[0].strips[1].begin;
    ASSERT_EQ(even, 48u);
    std::string trace;
    std::vector<double> late;
    for (std::size_t f = 0; f < frames.size(); ++f) {
      const auto& r = frames[f];
      trace += "\n  frame " + std::to_string(f) + ": boundary " + std::to_string(r.strips[1].begin) + ", device ms " +
               std::to_string(r.device_ms[0]) + " / " + std::to_string(r.device_ms[1]);
      if (f >= frames.size() - 4) late.push_back(r.strips[1].begin);
    }
    // The box's half costs its device several times the other's at the even split; the boundary
    // moves 8 rows a frame (--balance-step) toward the cheap half and settles where the devices'
    // times agree within noise (docs/measurements.md, dynamic strips end to end). Asserted: over
    // the last four frames it sits at least 10 rows from the middle, on the cheap side.
    const double boundary = median(late);
    std::printf("[ measure  ] %s: boundary %u -> %.1f (median of the last 4 frames)\n", name.c_str(), even, boundary);
    if (box_below)
      EXPECT_GE(boundary, even + 10.0) << "the expensive bottom strip should shrink" << trace;
    else
      EXPECT_LE(boundary, even - 10.0) << "the expensive top strip should shrink" << trace;
    // Moving strips do not change a bit of any frame: the same run with the even split kept.
    render_with_report(balance_command(scene, StripBalance::Static), dir, name + "_static");
    for (unsigned f = 0; f < frames.size(); ++f)
      for (const char* eye : {"left", "right"}) {
        char file[64];
        std::snprintf(file, sizeof file, "frame_%04u_%s.exr", f, eye);
        const auto moved = read_image_rgb((dir.path() / (name + "_dynamic") / file).string());
        const auto kept = read_image_rgb((dir.path() / (name + "_static") / file).string());
        const ExactDifference d = compare_exact(moved, kept);
        EXPECT_TRUE(d.identical()) << file << ": " << d.differing_pixels << " pixels differ, first at " << d.x << ","
                                   << d.y;
      }
  }
}

}  // namespace
}  // namespace px
