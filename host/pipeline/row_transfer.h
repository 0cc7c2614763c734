// The one way rows move between devices: strips travelling to the owner, halo rows before a
// filter pass, SVGF history following a moved strip boundary. Every device keeps full-frame
// buffers, so rows sit at the same byte offset everywhere and a move is one contiguous range.
//
// Within a process a move is two copies through the source device's host-mapped staging buffer
// (CL_MEM_ALLOC_HOST_PTR: device -> host memory -> device, no peer-to-peer), the second waiting
// for the first's event. Between MPI ranks it is a blocking read, a message, and a write on the
// receiver's queue behind the commands already there.
#pragma once

#include "cl/device_set.h"
#include "cluster/cluster.h"
#include "image/row_range.h"
#include "pipeline/event_log.h"
#include "pipeline/queue_lanes.h"

#include <deque>
#include <functional>
#include <vector>

namespace px {

// A host-mapped buffer rows leave a device through, and the copies that still read it (the next
// move through the same bytes waits for them). Allocated on first use.
struct StagingBuffer {
  cl::Buffer buffer;
  std::vector<cl::Event> readers;
};

class RowTransfer {
 public:
  RowTransfer(DeviceSet& devices, const DeviceLayout& layout, Cluster* cluster, unsigned width, unsigned height,
              EventLog& log, QueueLanes& lanes);

  // Copies `bytes` at `offset` of device `from`'s `src` into device `to`'s `dst` at the same
  // offset, whichever ranks they are on (a buffer of another rank's device is never touched).
  // Within a process through `staging` (allocated with `staging_bytes` on first use) at
  // `staging_offset`; with `track_readers`, the copy waits for the staging's earlier readers and
  // becomes its reader (for staging bytes that several moves in one frame reuse).
  void copy(int from, const cl::Buffer& src, int to, const cl::Buffer& dst, std::size_t offset, std::size_t bytes,
            StagingBuffer& staging, std::size_t staging_bytes, std::size_t staging_offset, bool track_readers);

  // Copies into each device's `buffer(d)` the rows of `needed[d]` that another device `src`
  // holds (`owned[src]`; the owned ranges are disjoint, so rows a device holds itself are never
  // overwritten), `texel` bytes per pixel, through the source's `staging(src)`. With owned =
  // the strips and needed = the strips widened by a filter's radius this is a halo exchange;
  // with owned = last frame's strips and needed = this frame's, it moves history to the new
  // owner of rows whose strip changed.
  using BufferOf = std::function<const cl::Buffer&(int device)>;
  using StagingOf = std::function<StagingBuffer&(int device)>;
  void exchange(const BufferOf& buffer, const std::vector<RowRange>& owned, const std::vector<RowRange>& needed,
                std::size_t texel, const StagingOf& staging);

  // Waits for sends still in flight and frees this frame's message copies (after the queues
  // finished).
  void end_frame();
  // Bytes that arrived on this process's devices this frame (each move counted once).
  std::size_t bytes_this_frame() const { return bytes_; }
  void reset_bytes() { bytes_ = 0; }

  // What a caller passes for a buffer of another rank's device, which has no buffer here (copy
  // and exchange never touch it).
  static const cl::Buffer& absent() {
    static const cl::Buffer none;
    return none;
  }

  bool local(int d) const { return layout_.is_local(d); }
  cl::CommandQueue& queue(int d) { return lanes_.queue(layout_.local_index(d)); }

 private:
  DeviceSet& devices_;
  const DeviceLayout& layout_;
  Cluster* cluster_;
  unsigned width_, height_;
  EventLog& log_;
  QueueLanes& lanes_;                                    // transfers run on the lane the executor selected
  std::deque<std::vector<unsigned char>> message_rows_;  // host copies of this frame's MPI messages
  std::size_t bytes_ = 0;
};

}  // namespace px
