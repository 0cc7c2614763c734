// A pipeline stage as a unit: it owns the buffers only it uses, keeps its options, binds its
// kernels' arguments and records the events of its commands. A stage that reads this frame's
// G-buffer beyond its own rows declares how far (a static `gbuffer_rows_read`): every G-buffer
// pass covers the largest such margin, so no G-buffer row ever travels between devices. StereoPipeline builds one unit
// per stage and runs the schedule's operations through them (pipeline/operation.h) without knowing what any stage does.
#pragma once

#include "cl/device_set.h"
#include "cluster/cluster.h"
#include "pipeline/event_log.h"
#include "pipeline/frame_images.h"
#include "pipeline/operation.h"
#include "pipeline/queue_lanes.h"
#include "pipeline/row_transfer.h"
#include "render/device_scene.h"
#include "scene/scene.h"
#include "shared/types.h"

#include <array>
#include <vector>

namespace px {

// What every unit works with, owned by the pipeline. `images` has one entry per device of the
// whole frame (all ranks); only this process's devices (layout.is_local) have buffers.
struct StageEnv {
  DeviceSet& devices;
  const DeviceLayout& layout;
  const DeviceScene& device_scene;
  const Scene& scene;
  unsigned width, height;
  std::vector<FrameImages>& images;
  EventLog& log;
  RowTransfer& transfer;
  QueueLanes& lanes;  // queue(d) is the lane the executor selected

  bool local(int d) const { return layout.is_local(d); }
  cl::CommandQueue& queue(int d) const { return lanes.queue(layout.local_index(d)); }
  const DeviceSceneBuffers& scene_on(int d) const { return device_scene.on(layout.local_index(d)); }
  std::size_t pixels(RowRange rows) const { return static_cast<std::size_t>(rows.size()) * width; }
  // Whether device d is one of this process's and a GPU (stages pick their kernel variant by it).
  bool is_gpu(int d) const { return local(d) && devices.devices()[layout.local_index(d)].is_gpu(); }
  // Whether device d is one of this process's and a CPU: where PathTracer runs every mode of
  // path_trace_pixels (its launches test the queue's device type the same way).
  bool is_cpu(int d) const { return local(d) && devices.devices()[layout.local_index(d)].is_cpu(); }
};

// Per frame: its number (selects the sample stream) and both eyes' cameras (stage 1's output).
struct FrameInputs {
  unsigned frame = 0;
  std::array<CameraParams, 2> cams;
};

class StageUnit {
 public:
  explicit StageUnit(StageEnv& env) : env_(env) {}
  virtual ~StageUnit() = default;
  StageUnit(const StageUnit&) = delete;
  StageUnit& operator=(const StageUnit&) = delete;

  // Enqueues `ops` (this stage's consecutive operations of the frame, every device's, this
  // rank's or not: a unit skips devices that are not local, except where it exchanges rows
  // with them).
  virtual void run(const std::vector<const Operation*>& ops, const FrameInputs& in) = 0;
  // After every queue finished the frame (history becomes last frame's).
  virtual void end_frame(const FrameInputs&) {}

 protected:
  // The rows each device's operation of eye `eye` among `ops` covers (empty for a device without
  // one); empty altogether where no operation is of that eye.
  std::vector<RowRange> eye_rows(const std::vector<const Operation*>& ops, int eye) const {
    std::vector<RowRange> rows(env_.layout.count());
    bool any = false;
    for (const Operation* op : ops)
      if (op->eye == eye) {
        rows[op->device] = op->rows;
        any = true;
      }
    return any ? rows : std::vector<RowRange>{};
  }

  StageEnv& env_;
};

}  // namespace px
