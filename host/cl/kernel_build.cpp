#include "cl/kernel_build.h"

#include <algorithm>
#include <cstdio>

namespace px {
namespace {

// The model's figures, measured on 2 cores of an Intel Xeon (AVX-512, PoCL 3.1, 2 sub-devices),
// docs/measurements.md "Quick kernel builds for short runs". Costs are per compute unit: the
// frame's kernels spread over every unit, a build runs on one core whatever the machine.
//
// What the quick build adds per pixel sample, in compute-unit microseconds: atrium (6 bounces,
// 1 spp, no denoiser) ran 151 ms a 320x180 stereo frame slower (285 against 134 ms); the other
// scenes measured less (cornell 39 ms, the bunny 26 ms), so auto errs toward the optimised build.
constexpr double kQuickPathUs = 2.6;
constexpr double kMeasuredBounces = 6.0;
// ... and per denoised pixel (SVGF's passes, a frame's temporal and a-trous work): atrium 316 ms
// a frame more beside the path tracing's (cornell 191 ms, the bunny 124 ms).
constexpr double kQuickDenoiseUs = 5.5;
// What the quick build saves, in seconds of a first run: the path tracer's, the reprojection's
// and the tonemapper's kernels build about 1.0 s sooner (atrium at 64x36: 4.6 against 3.4 s and
// 4.5 against 3.5 s), the denoiser's about 1.0 s more (6.6 against 4.4 s, 6.1 against 4.1 s).
constexpr double kQuickSavesS = 1.0;
constexpr double kQuickSavesDenoiserS = 1.0;

}  // namespace

KernelBuildDecision decide_kernel_build(KernelBuild build, const std::optional<KernelWork>& work, bool all_cpus,
                                        int compute_units) {
  KernelBuildDecision d;
  if (build == KernelBuild::Optimized) return d;
  if (build == KernelBuild::Quick) {
    d.quick = true;
    d.why = "as --kernel-build quick asks";
    return d;
  }
  if (!work || !all_cpus) return d;
  const double units = compute_units > 0 ? compute_units : 1;
  // Longer paths than the measured ones cost more in proportion to their vertices (Russian
  // roulette makes it less: an upper bound); shorter ones are not counted cheaper.
  const double longer = std::max(1.0, (work->bounces + 1.0) / (kMeasuredBounces + 1.0));
  d.extra_run_s =
      (work->pixel_samples * kQuickPathUs * longer + work->denoised_pixels * kQuickDenoiseUs) * 1e-6 / units;
  d.build_saved_s = kQuickSavesS + (work->denoised_pixels > 0.0 ? kQuickSavesDenoiserS : 0.0);
  d.quick = d.extra_run_s < d.build_saved_s;
  if (d.quick) {
    char line[256];
    std::snprintf(line, sizeof line,
                  "a short run, whose kernels would run about %.2f s longer in all and build about %.1f s sooner "
                  "(--kernel-build auto; optimized for the fastest kernels)",
                  d.extra_run_s, d.build_saved_s);
    d.why = line;
  }
  return d;
}

}  // namespace px
