#include "pipeline/stages/transfer_stage.h"

namespace px {

TransferStage::TransferStage(StageEnv& env, const Options& options)
    : StageUnit(env), options_(options), staging_(env.layout.count()) {}

void TransferStage::run(const std::vector<const Operation*>& ops, const FrameInputs&) {
  const std::size_t pixels = static_cast<std::size_t>(env_.width) * env_.height;
  for (const Operation* op : ops) {
    const int from = op->device, to = op->to, e = op->eye;
    const bool finished = op->payload == TransferPayload::FinishedImage;
    const std::size_t first = static_cast<std::size_t>(op->rows.begin) * env_.width, count = env_.pixels(op->rows);
    auto hop = [&](std::array<cl::Buffer, 2> FrameImages::*image, StagingBuffer& staging, std::size_t texel) {
      const cl::Buffer& src = env_.local(from) ? (env_.images[from].*image)[e] : RowTransfer::absent();
      const cl::Buffer& dst = env_.local(to) ? (env_.images[to].*image)[e] : RowTransfer::absent();
      env_.transfer.copy(from, src, to, dst, first * texel, count * texel, staging, 2 * pixels * texel,
                         (static_cast<std::size_t>(e) * pixels + first) * texel, false);
    };
    if (!finished || options_.gather_radiance) {
      hop(&FrameImages::radiance, staging_[from].radiance, sizeof(cl_float4));
      if (!finished && options_.with_albedo) hop(&FrameImages::albedo, staging_[from].albedo, sizeof(cl_float4));
    }
    if (finished) hop(&FrameImages::rgba, staging_[from].rgba, sizeof(cl_uchar4));
  }
}

}  // namespace px
