// One place that turns exceptions into a user-facing "error: ..." line and exit code 1, for
// the parallax binary and the benchmark binaries alike.
#pragma once

#include "cl/cl_error.h"

#include <cstdio>
#include <exception>

namespace px {

// Standard output is flushed before the status is returned: what a command printed must not
// depend on the exit path. Under LeakSanitizer, its tracer now and then crashes at exit (while
// stopping PoCL's threads), after the program finished and before stdio's buffers were flushed:
// piped output was lost whole.
template <typename Body>
int run_guarded(Body&& body) {
  int rc = 1;
  try {
    rc = body();
  } catch (const cl::Error& e) {
    std::fprintf(stderr, "error: OpenCL: %s\n", describe(e).c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
  }
  std::fflush(stdout);
  return rc;
}

}  // namespace px
