// The command queues a frame runs on: per device of this process, the main queue (lane 0, the
// DeviceSet's own) and a side queue (lane 1). Work on the side lane overlaps what the main lane
// runs meanwhile: the left eye's denoising, tonemapping and transfer run beside the right eye's
// reprojection and hole filling (operation.h says which operation takes which lane and what it
// waits for). The executor selects the lane of the operations it hands a unit; units, the SVGF
// passes and row transfers enqueue on `queue(local device)`, i.e. on the selected lane.
#pragma once

#include "cl/device_set.h"

#include <vector>

namespace px {

// Whether a pipeline uses the side queue. Auto: only where a device is a GPU. On PoCL's CPU
// devices the side queue measured slower (bench_pipelines --compare-overlap, cornell 320x180,
// 4 spp, one device of 2 compute units: x0.81-0.92): a kernel there already uses every core,
// so running two at once only adds contention.
enum class Overlap { Auto, On, Off };

// The side queue's use for `overlap` on `devices`.
bool wants_side_queue(Overlap overlap, const DeviceSet& devices);

class QueueLanes {
 public:
  static constexpr int kMain = 0, kSide = 1;

  // `side`: make the side queues (without them every lane is the main queue).
  QueueLanes(DeviceSet& devices, bool side);
  QueueLanes(const QueueLanes&) = delete;
  QueueLanes& operator=(const QueueLanes&) = delete;

  void select(int lane) { selected_ = has_side() ? lane : kMain; }
  int selected() const { return selected_; }
  bool has_side() const { return !side_.empty(); }

  // The selected lane's queue of local device `local` (DeviceLayout::local_index).
  cl::CommandQueue& queue(int local) { return lane(local, selected_); }
  cl::CommandQueue& lane(int local, int lane);
  // The main lane's queue, whichever lane is selected: where per-frame bookkeeping (counters,
  // read-backs) goes, in the order the frame's main work runs.
  cl::CommandQueue& main(int local) { return lane(local, kMain); }

  // Finishes every queue of every lane.
  void finish_all();

 private:
  DeviceSet& devices_;
  std::vector<cl::CommandQueue> side_;
  int selected_ = kMain;
};

}  // namespace px
