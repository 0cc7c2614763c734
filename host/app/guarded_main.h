// One place that turns exceptions into a user-facing "error: ..." line and exit code 1, for
// the parallax binary and the benchmark binaries alike.
#pragma once

#include "cl/cl_error.h"

#include <cstdio>
#include <exception>

namespace px {

template <typename Body>
int run_guarded(Body&& body) {
  try {
    return body();
  } catch (const cl::Error& e) {
    std::fprintf(stderr, "error: OpenCL: %s\n", describe(e).c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
  }
  return 1;
}

}  // namespace px
