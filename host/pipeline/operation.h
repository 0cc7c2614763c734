// The schedule as the executor runs it: a flat list of operations, one per stage, eye and
// device with work, in enqueue order. StereoPipeline hands each stage unit its consecutive
// operations and does nothing else per stage; `render --explain` prints the list.
//
// Queues. Each device has two in-order queues, lanes (queue_lanes.h): the left eye's denoising,
// tonemapping and transfer take the side lane, everything else the main lane, so that the left
// eye is filtered while the right eye's holes are traced. (One lane when the side lane is off:
// then the list is exactly the in-order sequence the queue runs.)
//
// Dependencies. An operation reads and writes per-device images (radiance, albedo, G-buffer and
// RGBA8 per eye, the hole list); `after` lists, for every image it touches on any device, the
// latest earlier operation touching that image there where either writes, plus the previous
// operation on its own lane. Waits on the same lane of the same device are kept by the queue's
// order; the executor turns the others into event waits (a barrier on the lane before the
// operation). Within a transfer and within a denoise operation's halo exchanges, the receiving
// copy waits for the sending copy's event.
#pragma once

#include "pipeline/strip_schedule.h"

#include <cstddef>
#include <string>
#include <vector>

namespace px {

struct Operation {
  Stage stage;
  int eye = 0;     // 0 left, 1 right
  int device = 0;  // where it runs (a transfer: the sending device)
  RowRange rows;   // rows it writes (a G-buffer pass: with the margin its readers need)
  int to = -1;     // a transfer: the receiving device
  TransferPayload payload = TransferPayload::None;
  int lane = 0;  // QueueLanes::kMain or kSide
  // A path trace that also writes its rows' G-buffer texels (its first sample is the G-buffer's
  // ray, PathTracer::Options::first_sample_on_gbuffer_ray); the G-buffer pass then skips those rows.
  bool writes_gbuffer = false;
  // The right eye's G-buffer pass keeps its rays' hits (FrameImages::right_hits), and hole
  // filling starts each hole's first sample (the G-buffer's ray) from them instead of tracing it again.
  bool shares_hits = false;
  std::vector<std::size_t> after;  // indices of the operations it waits for (see above)
};

// The operations of `schedule`, G-buffer rows widened by `gbuffer_margin` (the largest number
// of rows beyond its strip that any stage reading the G-buffer declares; clipped to the image).
// Order: stage by stage as scheduled; within a stage device by device, left eye before right;
// a denoise stage eye by eye (its passes run all devices of one eye in step, exchanging halo
// rows between them).
// `side_lane`: give the left eye's denoising, tonemapping and transfer the side lane.
// `gbuffer_from_path_tracer` (each pixel's centre ray traced once a frame): a path trace writes
// the G-buffer of its rows where its device has a G-buffer pass of the same eye, and that pass
// keeps only the rows no such path trace covers (the margins; none where a device path traces
// all it needs), split into ranges if need be; and a hole filling whose rows its device's
// right-eye G-buffer passes cover starts from their hits (shares_hits on all of them).
std::vector<Operation> make_operations(const FrameSchedule& schedule, unsigned gbuffer_margin, bool side_lane = true,
                                       bool gbuffer_from_path_tracer = false);

// Whether operation `op` takes the side lane (when there is one).
bool on_side_lane(const Operation& op);

// One line per operation: index, stage, eye, device (-> receiver), rows, what it waits for.
std::string explain_operations(const std::vector<Operation>& operations);

}  // namespace px
