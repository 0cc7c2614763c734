// One place that turns exceptions into a user-facing "error: ..." line and exit code 1, for
// the parallax binary and the benchmark binaries alike.
#pragma once

#include "cl/cl_error.h"
#include "io/interrupt.h"

#include <cstdio>
#include <exception>
#include <string>

namespace px {

// Standard output is flushed before the status is returned: what a command printed must not
// depend on the exit path. Under LeakSanitizer, its tracer now and then crashes at exit (while
// stopping PoCL's threads), after the program finished and before stdio's buffers were flushed:
// piped output was lost whole.
//
// An error raised after a SIGINT / SIGTERM is reported as the interruption it follows from (exit
// 128 + signal, the error named after it): LLVM, which PoCL runs in-process to build kernels,
// removes its temporary files when the signal arrives, so a Ctrl-C during a kernel build makes
// that build fail; the user asked the run to stop, and it stopped.
template <typename Body>
int run_guarded(Body&& body) {
  int rc = 1;
  std::string error;
  try {
    rc = body();
  } catch (const cl::Error& e) {
    error = "OpenCL: " + describe(e);
  } catch (const std::exception& e) {
    error = e.what();
  }
  if (!error.empty()) {
    if (interrupted()) {
      std::fprintf(stderr, "interrupted (%s); then: %s\n", interrupt_signal_name(), error.c_str());
      rc = interrupt_exit_code();
    } else {
      std::fprintf(stderr, "error: %s\n", error.c_str());
    }
  }
  std::fflush(stdout);
  return rc;
}

}  // namespace px
