// OpenCL error reporting. The C++ bindings are built with CL_HPP_ENABLE_EXCEPTIONS, so every
// call through them is checked and throws cl::Error carrying the failing function's name;
// the few raw C calls go through PX_CL_CHECK. describe() turns either into a readable line.
#pragma once

#include <CL/opencl.hpp>

#include <stdexcept>
#include <string>

namespace px {

// Symbolic name of an OpenCL status code ("CL_OUT_OF_RESOURCES"), or the number.
std::string cl_status_name(cl_int status);

// "clEnqueueNDRangeKernel failed: CL_INVALID_WORK_GROUP_SIZE (-54)".
std::string describe(const cl::Error& e);

// A failure in the OpenCL layer that is not a plain status code (no device, a kernel build
// error with its log).
struct ClFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace px

#define PX_CL_CHECK(call)                                                                         \
  do {                                                                                            \
    cl_int px_status_ = (call);                                                                   \
    if (px_status_ != CL_SUCCESS)                                                                 \
      throw ::px::ClFailure(std::string(#call) + " failed: " + ::px::cl_status_name(px_status_)); \
  } while (0)
