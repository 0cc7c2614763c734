// Timings from OpenCL profiling events (every queue is created with profiling enabled).
#pragma once

#include "cl/cl_error.h"

namespace px {

// Milliseconds between an event's CL_PROFILING_COMMAND_START and _END (0 if the clock went
// backwards, which some drivers report for zero-length commands).
double event_ms(const cl::Event& e);

}  // namespace px
