#include "pipeline/queue_lanes.h"

namespace px {

bool wants_side_queue(Overlap overlap, const DeviceSet& devices) {
  if (overlap != Overlap::Auto) return overlap == Overlap::On;
  for (const ComputeDevice& d : devices.devices())
    if (d.is_gpu()) return true;
  return false;
}

QueueLanes::QueueLanes(DeviceSet& devices, bool side) : devices_(devices) {
  if (!side) return;
  for (const ComputeDevice& d : devices.devices())
    side_.emplace_back(devices.context(), d.device, CL_QUEUE_PROFILING_ENABLE);
}

cl::CommandQueue& QueueLanes::lane(int local, int lane) {
  if (lane == kSide && has_side()) return side_[static_cast<std::size_t>(local)];
  return devices_.devices()[static_cast<std::size_t>(local)].queue;
}

void QueueLanes::finish_all() {
  devices_.finish_all();
  for (auto& q : side_) q.finish();
}

}  // namespace px
