#include "pipeline/operation.h"

#include <cstdio>
#include <sstream>

namespace px {

std::vector<Operation> make_operations(const FrameSchedule& schedule, unsigned gbuffer_margin) {
  std::vector<Operation> ops;
  const int n = schedule.devices;
  auto add = [&](const StageWork& w, int eye, int d, RowRange rows) {
    if (rows.size() == 0) return;
    Operation op{w.stage, eye, d, rows};
    if (w.stage == Stage::GBuffer) op.rows = widen(rows, gbuffer_margin, schedule.height);
    if (w.stage == Stage::Transfer) {
      if (d == schedule.tree.root) return;  // the owner's own rows are already in place
      op.to = schedule.tree.root;
      op.payload = w.payload;
    }
    ops.push_back(op);
  };
  for (const StageWork& w : schedule.stages) {
    if (w.stage == Stage::Denoise) {
      for (int e = 0; e < 2; ++e) {
        const std::vector<RowRange> spans = device_spans(w, e);
        for (int d = 0; d < n; ++d) add(w, e, d, spans[d]);
      }
      continue;
    }
    for (int d = 0; d < n; ++d) {
      for (const RowRange& r : w.left_rows[d]) add(w, 0, d, r);
      for (const RowRange& r : w.right_rows[d]) add(w, 1, d, r);
    }
  }
  // What each waits for: the previous operation on its device, and the transfers that arrived
  // there since.
  std::vector<long> last_on(n, -1);
  std::vector<std::vector<std::size_t>> arrived(n);
  for (std::size_t i = 0; i < ops.size(); ++i) {
    Operation& op = ops[i];
    if (last_on[op.device] >= 0) op.after.push_back(static_cast<std::size_t>(last_on[op.device]));
    op.after.insert(op.after.end(), arrived[op.device].begin(), arrived[op.device].end());
    arrived[op.device].clear();
    last_on[op.device] = static_cast<long>(i);
    if (op.stage == Stage::Transfer) arrived[op.to].push_back(i);
  }
  return ops;
}

std::string explain_operations(const std::vector<Operation>& operations) {
  std::ostringstream out;
  out << "operations in enqueue order (" << operations.size() << "):\n";
  char line[160];
  for (std::size_t i = 0; i < operations.size(); ++i) {
    const Operation& op = operations[i];
    std::string where = "device " + std::to_string(op.device);
    if (op.to >= 0) where += " -> " + std::to_string(op.to);
    std::snprintf(line, sizeof line, "%4zu  %-17s %-5s %-14s rows [%u, %u)", i, stage_name(op.stage),
                  op.eye == 0 ? "left" : "right", where.c_str(), op.rows.begin, op.rows.end);
    out << line;
    if (op.payload == TransferPayload::FinishedImage) out << " finished image";
    if (op.payload == TransferPayload::LinearRadiance) out << " linear radiance";
    if (!op.after.empty()) {
      out << "  after";
      for (std::size_t a : op.after) out << " " << a;
    }
    out << "\n";
  }
  return out.str();
}

}  // namespace px
