#include "cl/launch.h"

#include "cl/pocl_launch_guard.h"

namespace px {

cl::Event launch_1d(const cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t items,
                    const std::vector<cl::Event>* waits) {
  const std::size_t global = round_up(items);
  std::vector<cl::Event> all;
  if (waits) all = *waits;
  // On PoCL CPU devices, launches of one kernel on several queues are ordered where PoCL's
  // work-group-function cache needs it (pocl_launch_guard.h); elsewhere this adds nothing.
  PoclLaunchGuard guard(queue, kernel, global, kLocalSize, all);
  cl::Event done;
  queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(global), cl::NDRange(kLocalSize),
                             all.empty() ? nullptr : &all, &done);
  guard.done(done);
  return done;
}

}  // namespace px
