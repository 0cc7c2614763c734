// The schedule as the executor runs it: a flat list of operations, one per stage, eye and
// device with work, in enqueue order. StereoPipeline hands each stage unit its consecutive
// operations and does nothing else per stage; `render --explain` prints the list.
//
// Dependencies. Each device has one in-order queue, so an operation waits for every earlier
// operation on its device without being told; across devices the only data that moves is a
// transfer's rows (and the halo rows a stage exchanges between its own passes), whose receiving
// copy waits for the sending copy's event. `after` names these waits for reading: the earlier
// operation on the same device, and the transfers that arrived at the device since.
#pragma once

#include "pipeline/strip_schedule.h"

#include <cstddef>
#include <string>
#include <vector>

namespace px {

struct Operation {
  Stage stage;
  int eye = 0;          // 0 left, 1 right
  int device = 0;       // where it runs (a transfer: the sending device)
  RowRange rows;        // rows it writes (a G-buffer pass: with the margin its readers need)
  int to = -1;          // a transfer: the receiving device
  TransferPayload payload = TransferPayload::None;
  std::vector<std::size_t> after;  // indices of the operations it waits for (see above)
};

// The operations of `schedule`, G-buffer rows widened by `gbuffer_margin` (the largest number
// of rows beyond its strip that any stage reading the G-buffer declares; clipped to the image).
// Order: stage by stage as scheduled; within a stage device by device, left eye before right;
// a denoise stage eye by eye (its passes run all devices of one eye in step, exchanging halo
// rows between them).
std::vector<Operation> make_operations(const FrameSchedule& schedule, unsigned gbuffer_margin);

// One line per operation: index, stage, eye, device (-> receiver), rows, what it waits for.
std::string explain_operations(const std::vector<Operation>& operations);

}  // namespace px
