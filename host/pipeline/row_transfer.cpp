#include "pipeline/row_transfer.h"

#include <algorithm>

namespace px {

RowTransfer::RowTransfer(DeviceSet& devices, const DeviceLayout& layout, Cluster* cluster, unsigned width,
                         unsigned height, EventLog& log, QueueLanes& lanes)
    : devices_(devices), layout_(layout), cluster_(cluster), width_(width), height_(height), log_(log), lanes_(lanes) {}

void RowTransfer::copy(int from, const cl::Buffer& src, int to, const cl::Buffer& dst, std::size_t offset,
                       std::size_t bytes, StagingBuffer& staging, std::size_t staging_bytes, std::size_t staging_offset,
                       bool track_readers) {
  if (local(from) && local(to)) {
    if (!staging.buffer())
      staging.buffer = cl::Buffer(devices_.context(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, staging_bytes);
    cl::Event out, in;
    const std::vector<cl::Event> wait = track_readers ? staging.readers : std::vector<cl::Event>{};
    queue(from).enqueueCopyBuffer(src, staging.buffer, offset, staging_offset, bytes, wait.empty() ? nullptr : &wait,
                                  &out);
    const std::vector<cl::Event> after{out};
    queue(to).enqueueCopyBuffer(staging.buffer, dst, staging_offset, offset, bytes, &after, &in);
    if (track_readers) staging.readers = {in};
    log_.record(Stage::Transfer, from, out);
    log_.record(Stage::Transfer, to, in);
    bytes_ += bytes;
  } else if (local(from)) {
    // To another rank: read the rows (waiting for the commands that write them), then send.
    auto& host = message_rows_.emplace_back(bytes);
    cl::Event out;
    queue(from).enqueueReadBuffer(src, CL_TRUE, offset, bytes, host.data(), nullptr, &out);
    log_.record(Stage::Transfer, from, out);
    cluster_->send(layout_.rank_of(to), host.data(), bytes);
  } else if (local(to)) {
    // From another rank: the message arrives in schedule order; write it behind the commands
    // already queued on `to` (the host copy lives until the frame is finished).
    auto& host = message_rows_.emplace_back(bytes);
    cluster_->recv(layout_.rank_of(from), host.data(), bytes);
    cl::Event in;
    queue(to).enqueueWriteBuffer(dst, CL_FALSE, offset, bytes, host.data(), nullptr, &in);
    log_.record(Stage::Transfer, to, in);
    bytes_ += bytes;
  }
}

void RowTransfer::exchange(const BufferOf& buffer, const std::vector<RowRange>& owned,
                           const std::vector<RowRange>& needed, std::size_t texel, const StagingOf& staging) {
  const int n = layout_.count();
  const std::size_t frame_bytes = static_cast<std::size_t>(width_) * height_ * texel;
  for (int d = 0; d < n; ++d) {
    if (needed[d].size() == 0) continue;
    for (int src = 0; src < n; ++src) {
      if (src == d || owned[src].size() == 0 || (!local(d) && !local(src))) continue;
      const unsigned a = std::max(needed[d].begin, owned[src].begin), b = std::min(needed[d].end, owned[src].end);
      if (a >= b) continue;
      const std::size_t off = static_cast<std::size_t>(a) * width_ * texel;
      const std::size_t len = static_cast<std::size_t>(b - a) * width_ * texel;
      copy(src, local(src) ? buffer(src) : absent(), d, local(d) ? buffer(d) : absent(), off, len, staging(src),
           frame_bytes, off, true);
    }
  }
}

void RowTransfer::end_frame() {
  if (cluster_) cluster_->wait_sends();
  message_rows_.clear();
}

}  // namespace px
