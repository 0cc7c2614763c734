// The OpenCL events of one frame's commands, each under the stage and device it ran for: what
// FrameStats' per-stage timings and the timeline are made from. Every stage unit records here.
#pragma once

#include "cl/cl_error.h"
#include "pipeline/stage.h"

#include <utility>
#include <vector>

namespace px {

class EventLog {
 public:
  struct Entry {
    Stage stage;
    int device;
    cl::Event event;
    const char* pass = nullptr;  // which pass of a multi-pass stage (a static string), or none
    int lane = 0;                // the queue lane it ran on (QueueLanes)
  };
  void record(Stage stage, int device, const cl::Event& e, const char* pass = nullptr) {
    entries_.push_back({stage, device, e, pass, lane_});
  }
  // The lane the executor runs the commands recorded from now on.
  void set_lane(int lane) { lane_ = lane; }
  const std::vector<Entry>& entries() const { return entries_; }
  void clear() { entries_.clear(); }

 private:
  std::vector<Entry> entries_;
  int lane_ = 0;
};

}  // namespace px
