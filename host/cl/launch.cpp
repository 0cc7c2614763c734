#include "cl/launch.h"

namespace px {

cl::Event launch_1d(const cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t items,
                    const std::vector<cl::Event>* waits) {
  cl::Event done;
  queue.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(round_up(items)), cl::NDRange(kLocalSize),
                             waits && !waits->empty() ? waits : nullptr, &done);
  return done;
}

}  // namespace px
