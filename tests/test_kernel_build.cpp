// `--kernel-build auto` (cl/kernel_build.h): when a run builds its kernels quickly. The images of
// the two builds are compared in test_kernel_features.cpp (AQuickBuildRendersTheOptimisedBuildsImages).
#include "cl/device_set.h"
#include "cl/kernel_build.h"

#include <gtest/gtest.h>

namespace px {
namespace {

// A run of `frames` stereo frames of width x height at `spp` and `bounces`, denoised or not.
KernelWork run_of(unsigned frames, unsigned width, unsigned height, unsigned spp, bool denoised, unsigned bounces = 6) {
  const double pixels = 2.0 * frames * width * height;
  return {pixels * spp, denoised ? pixels : 0.0, bounces};
}

TEST(KernelBuild, AnAskedForBuildIsTheOneMade) {
  const KernelWork tiny = run_of(1, 8, 8, 1, false);
  for (const bool cpus : {true, false}) {
    EXPECT_TRUE(decide_kernel_build(KernelBuild::Quick, tiny, cpus, 2).quick);
    EXPECT_TRUE(decide_kernel_build(KernelBuild::Quick, std::nullopt, cpus, 2).quick);
    EXPECT_FALSE(decide_kernel_build(KernelBuild::Optimized, tiny, cpus, 2).quick);
    EXPECT_FALSE(decide_kernel_build(KernelBuild::Optimized, std::nullopt, cpus, 2).quick);
  }
  EXPECT_FALSE(decide_kernel_build(KernelBuild::Quick, tiny, true, 2).why.empty());
  EXPECT_TRUE(decide_kernel_build(KernelBuild::Optimized, tiny, true, 2).why.empty());
}

TEST(KernelBuild, AutoBuildsOptimisedWithoutAnEstimateAndOnGpus) {
  EXPECT_FALSE(decide_kernel_build(KernelBuild::Auto, std::nullopt, true, 2).quick) << "view: open-ended";
  EXPECT_FALSE(decide_kernel_build(KernelBuild::Auto, run_of(1, 8, 8, 1, false), false, 132).quick)
      << "GPUs' quick builds were never measured";
}

// The rule, written out again: the quick build's extra running time (2.6 compute-unit
// microseconds a pixel sample of paths up to 6 bounces, in proportion for longer ones; 5.5 a
// denoised pixel) against the build time it saves (1 s, 2 s with the denoiser).
bool quick_by_hand(const KernelWork& w, int units) {
  const double longer = w.bounces > 6 ? (w.bounces + 1) / 7.0 : 1.0;
  const double extra = (2.6 * w.pixel_samples * longer + 5.5 * w.denoised_pixels) * 1e-6 / units;
  return extra < (w.denoised_pixels > 0 ? 2.0 : 1.0);
}

TEST(KernelBuild, AutoBuildsQuicklyForShortRunsOnCpus) {
  struct Case {
    KernelWork work;
    int units;
    bool quick;
    const char* what;
  };
  const Case cases[] = {
      {run_of(1, 320, 180, 1, false), 2, true, "one raw frame, as the scale series starts"},
      {run_of(4, 320, 180, 1, true), 2, true, "four small denoised frames: 1.87 s more, 2 s saved"},
      {run_of(12, 480, 270, 4, true), 2, false, "the demo: 12 frames at 4 spp"},
      {run_of(1, 640, 360, 256, false), 2, false, "a 256-spp reference"},
      {run_of(20, 320, 180, 1, false), 2, false, "20 raw frames on 2 units: 3 s more"},
      {run_of(20, 320, 180, 1, false), 16, true, "the same on 16 units: 0.37 s more"},
      {run_of(4, 320, 180, 1, false), 2, true, "four raw frames at 6 bounces: 0.6 s more"},
      {run_of(4, 320, 180, 1, false, 20), 2, false, "the same at 20 bounces: 1.8 s more"},
      {run_of(4, 320, 180, 1, false, 1), 2, true, "at 1 bounce: counted as 6"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const KernelBuildDecision d = decide_kernel_build(KernelBuild::Auto, c.work, true, c.units);
    EXPECT_EQ(d.quick, c.quick) << "extra " << d.extra_run_s << " s, saved " << d.build_saved_s << " s";
    EXPECT_EQ(d.quick, quick_by_hand(c.work, c.units));
    EXPECT_EQ(d.quick, !d.why.empty());
  }
}

TEST(KernelBuild, MoreWorkNeverTurnsAnOptimisedChoiceQuick) {
  bool was_quick = true;
  for (unsigned frames = 1; frames <= 64; ++frames) {
    const bool quick = decide_kernel_build(KernelBuild::Auto, run_of(frames, 320, 180, 1, true), true, 2).quick;
    EXPECT_FALSE(quick && !was_quick) << "frame " << frames;
    was_quick = quick;
  }
  EXPECT_FALSE(was_quick);
}

// The set carries the decision, and a quick set builds its programs with the optimiser off.
TEST(KernelBuild, AQuickSetBuildsWithTheOptimiserOff) {
  DeviceOptions options{1, DeviceMode::Auto, "", std::nullopt};
  options.kernel_build = KernelBuild::Quick;
  DeviceSet quick = DeviceSet::create(options);
  ASSERT_TRUE(quick.kernel_build().quick);
  const cl::Program& p = quick.program("pipeline/tonemap.cl");
  const std::string built_with = p.getBuildInfo<CL_PROGRAM_BUILD_OPTIONS>(quick.devices()[0].device);
  EXPECT_NE(built_with.find("-cl-opt-disable"), std::string::npos) << built_with;
  options.kernel_build = KernelBuild::Optimized;
  DeviceSet optimised = DeviceSet::create(options);
  EXPECT_FALSE(optimised.kernel_build().quick);
  const std::string plain =
      optimised.program("pipeline/tonemap.cl").getBuildInfo<CL_PROGRAM_BUILD_OPTIONS>(optimised.devices()[0].device);
  EXPECT_EQ(plain.find("-cl-opt-disable"), std::string::npos) << plain;
}

}  // namespace
}  // namespace px
