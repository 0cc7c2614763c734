#include "cl/launch.h"

#include "cl/pocl_launch_guard.h"

namespace px {

cl::Event launch_1d(const cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t items,
                    const std::vector<cl::Event>* waits) {
  const std::size_t global = round_up(items);
  // On PoCL CPU devices, launches of one kernel on several queues are ordered where PoCL's
  // work-group-function cache needs it (pocl_launch_guard.h); elsewhere this adds nothing.
  std::vector<cl::Event> guard_waits;
  PoclLaunchGuard guard(queue, kernel, global, kLocalSize, guard_waits);
  const std::vector<cl::Event>* all = waits && !waits->empty() ? waits : nullptr;
  if (!guard_waits.empty()) {
    if (all) guard_waits.insert(guard_waits.end(), all->begin(), all->end());
    all = &guard_waits;
  }
  cl::Event done;
  queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(global), cl::NDRange(kLocalSize), all, &done);
  guard.done(done);
  return done;
}

bool runs_on_cpu(const cl::CommandQueue& queue) {
  return (queue.getInfo<CL_QUEUE_DEVICE>().getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_CPU) != 0;
}

}  // namespace px
