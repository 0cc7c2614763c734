// How a DeviceSet compiles its kernels: optimised, or quickly with the compiler's optimisation
// off (`-cl-opt-disable`), and the rule `--kernel-build auto` decides by.
//
// On PoCL's CPU devices a program is compiled in the run that first needs it, on one core at a
// time (PoCL holds one lock over every build and work-group function in a process), and a short
// run spends most of its time there: a first run of a 1-frame render waits about 2 s for the
// frame's kernels, 3 s with the denoiser. With optimisation off the same kernels build in a
// little over half that time and run about 2-4x slower. They compute the same images bit for
// bit: without fast-math options the optimiser may not change a floating-point result, whether
// a*b+c becomes one fma is the front end's choice (made the same at both levels), and PoCL's
// built-in library is the same code. tests/test_kernel_features.cpp holds the two builds to that
// (AQuickBuildRendersTheOptimisedBuildsImages).
//
// So a short run is done sooner with the quick build, and a long one with the optimised build.
// `auto` estimates both sides from the run's size (what the command will render) and builds
// quickly only where the kernels' extra running time is the smaller. Each build is cached by
// PoCL under its own options; the choice depends on the run alone, not on what is cached, so
// one command always runs the same kernels at the same speed.
#pragma once

#include <optional>
#include <string>

namespace px {

enum class KernelBuild {
  Auto,       // Quick where every device is a CPU and the run is short enough (decide_kernel_build)
  Quick,      // optimisation off: built in about half the time, same images, slower kernels
  Optimized,  // the compiler's full optimisation: the fastest kernels
};

// What a run will render, for `auto`: totals over the run's frames and both eyes.
struct KernelWork {
  double pixel_samples = 0.0;    // frames x 2 eyes x width x height x spp
  double denoised_pixels = 0.0;  // frames x 2 eyes x width x height when the denoiser runs, else 0
  unsigned bounces = 6;          // the paths' longest (the costs were measured at 6)
};

struct KernelBuildDecision {
  bool quick = false;
  // For `auto` on CPUs: the estimates it compared (seconds); 0 where no estimate was made.
  double extra_run_s = 0.0;    // how much longer the run's kernels would take built quickly
  double build_saved_s = 0.0;  // how much sooner the quick build is done
  std::string why;             // one line for the log; empty for an optimised build
};

// `build` for a set whose devices are all CPUs (`all_cpus`) with `compute_units` in all.
// Auto without `work` (a command whose length is open, such as `view`) and Auto on a GPU build
// optimised: GPU drivers build differently, and their quick builds were never measured.
KernelBuildDecision decide_kernel_build(KernelBuild build, const std::optional<KernelWork>& work, bool all_cpus,
                                        int compute_units);

}  // namespace px
