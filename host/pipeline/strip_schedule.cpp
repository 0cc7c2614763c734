#include "pipeline/strip_schedule.h"

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <stdexcept>

namespace px {

const char* to_string(PipelineKind p) {
  switch (p) {
    case PipelineKind::Proposed: return "proposed";
    case PipelineKind::Baseline: return "baseline";
    case PipelineKind::Mono: return "mono";
  }
  return "?";
}

std::vector<unsigned> strip_sizes(const std::vector<RowRange>& strips) {
  std::vector<unsigned> sizes;
  for (const RowRange& r : strips) sizes.push_back(r.size());
  return sizes;
}

std::vector<RowRange> strips_from_sizes(const std::vector<unsigned>& sizes) {
  std::vector<RowRange> strips;
  unsigned row = 0;
  for (unsigned n : sizes) {
    strips.push_back({row, row + n});
    row += n;
  }
  return strips;
}

std::vector<RowRange> device_spans(const StageWork& work, int eye) {
  const auto& per_device = eye == 0 ? work.left_rows : work.right_rows;
  std::vector<RowRange> spans(per_device.size());
  for (std::size_t d = 0; d < per_device.size(); ++d)
    if (!per_device[d].empty()) spans[d] = {per_device[d].front().begin, per_device[d].back().end};
  return spans;
}

std::vector<unsigned> bit_reversed_order(unsigned n) {
  unsigned bits = 0;
  while ((1u << bits) < n) ++bits;
  if ((1u << bits) != n) throw std::invalid_argument("bit_reversed_order: n must be a power of two");
  std::vector<unsigned> out(n);
  for (unsigned i = 0; i < n; ++i) {
    unsigned r = 0;
    for (unsigned b = 0; b < bits; ++b)
      if (i & (1u << b)) r |= 1u << (bits - 1 - b);
    out[i] = r;
  }
  return out;
}

const StageWork* FrameSchedule::find(Stage s) const {
  for (const auto& w : stages)
    if (w.stage == s) return &w;
  return nullptr;
}

namespace {

double share(const std::vector<RowRange>& rows, unsigned height) {
  unsigned n = 0;
  for (const auto& r : rows) n += r.size();
  return height ? static_cast<double>(n) / height : 0.0;
}

StageWork work(Stage s, int devices, unsigned height, const std::vector<std::vector<RowRange>>& left,
               const std::vector<std::vector<RowRange>>& right) {
  StageWork w{s, std::vector<Workload>(devices), left, right};
  for (int d = 0; d < devices; ++d) w.per_device[d] = {share(left[d], height), share(right[d], height)};
  return w;
}

// Which rows of an eye each device processes in a stage (strip_schedule.h describes them).
enum class Split { None, Own, Shuffled, Owner };

struct StageRow {
  Stage stage;
  Split left, right;
  bool denoise_only = false;
  TransferPayload payload = TransferPayload::None;
  bool direct_light_only = false;  // scheduled only with ReSTIR DI (`--direct-light restir`)
};

// The pipelines. Adding a stage to one is adding a row here and its unit under stages/.
const std::vector<StageRow>& pipeline_table(PipelineKind pipeline) {
  static const std::vector<StageRow> proposed = {
      {Stage::PathTraceLeft, Split::Own, Split::None},
      {Stage::GBuffer, Split::Own, Split::Own},
      {Stage::DirectLight, Split::Own, Split::None, false, TransferPayload::None, true},
      {Stage::Reproject, Split::None, Split::Own},
      {Stage::HoleFill, Split::None, Split::Own},
      {Stage::DirectLight, Split::None, Split::Own, false, TransferPayload::None, true},
      {Stage::Denoise, Split::Own, Split::Own, true},
      {Stage::Tonemap, Split::Own, Split::Own},
      {Stage::Transfer, Split::Own, Split::Own, false, TransferPayload::FinishedImage},
  };
  static const std::vector<StageRow> baseline = {
      {Stage::PathTraceLeft, Split::Shuffled, Split::None},
      {Stage::Transfer, Split::Shuffled, Split::None, false, TransferPayload::LinearRadiance},
      {Stage::GBuffer, Split::Owner, Split::Owner},
      {Stage::DirectLight, Split::Owner, Split::None, false, TransferPayload::None, true},
      {Stage::Reproject, Split::None, Split::Owner},
      {Stage::HoleFill, Split::None, Split::Owner},
      {Stage::DirectLight, Split::None, Split::Owner, false, TransferPayload::None, true},
      {Stage::Denoise, Split::Owner, Split::Owner, true},
      {Stage::Tonemap, Split::Owner, Split::Owner},
  };
  static const std::vector<StageRow> mono = {
      {Stage::PathTraceLeft, Split::Own, Split::None},
      {Stage::PathTraceRight, Split::None, Split::Own},
      {Stage::DirectLight, Split::Own, Split::Own, false, TransferPayload::None, true},
      {Stage::GBuffer, Split::Own, Split::Own, true},
      {Stage::Denoise, Split::Own, Split::Own, true},
      {Stage::Tonemap, Split::Own, Split::Own},
      {Stage::Transfer, Split::Own, Split::Own, false, TransferPayload::FinishedImage},
  };
  switch (pipeline) {
    case PipelineKind::Proposed: return proposed;
    case PipelineKind::Baseline: return baseline;
    case PipelineKind::Mono: return mono;
  }
  return proposed;
}

}  // namespace

bool has_movable_strips(PipelineKind pipeline) { return pipeline != PipelineKind::Baseline; }

void check_strips(const std::vector<RowRange>& strips, int devices, unsigned height) {
  if (strips.size() != static_cast<std::size_t>(devices))
    throw std::invalid_argument("strips: " + std::to_string(strips.size()) + " strip(s) for " +
                                std::to_string(devices) + " device(s)");
  unsigned row = 0;
  for (std::size_t i = 0; i < strips.size(); ++i) {
    if (strips[i].begin != row || strips[i].end <= strips[i].begin || strips[i].end > height)
      throw std::invalid_argument("strips: strip " + std::to_string(i) + " [" + std::to_string(strips[i].begin) + ", " +
                                  std::to_string(strips[i].end) + ") must start at row " + std::to_string(row) +
                                  ", hold at least one row and end within the " + std::to_string(height) + " rows");
    row = strips[i].end;
  }
  if (row != height)
    throw std::invalid_argument("strips: they end at row " + std::to_string(row) + " of " + std::to_string(height));
}

FrameSchedule make_schedule(PipelineKind pipeline, int devices, unsigned height, bool denoise,
                            const std::vector<RowRange>& strips, bool gbuffer, bool direct_light) {
  if (devices < 1) throw std::invalid_argument("make_schedule: at least one device");
  if (!strips.empty()) {
    if (!has_movable_strips(pipeline))
      throw std::invalid_argument(std::string("the ") + to_string(pipeline) + " pipeline's strips cannot be moved");
    check_strips(strips, devices, height);
  }
  FrameSchedule fs;
  fs.pipeline = pipeline;
  fs.devices = devices;
  fs.height = height;
  fs.tree.root = 0;
  for (int d = 1; d < devices; ++d) fs.tree.children.push_back(d);

  const std::vector<std::vector<RowRange>> none(devices);
  // Each device's own strip (proposed and mono): N contiguous strips, round-robin.
  fs.strips = strips.empty() ? split_rows(height, static_cast<unsigned>(devices)) : strips;
  std::vector<std::vector<RowRange>> own(devices);
  for (int i = 0; i < devices; ++i) {
    fs.strip_device.push_back(i % devices);
    own[i % devices].push_back(fs.strips[i]);
  }
  std::vector<std::vector<RowRange>> owner_all(devices);
  owner_all[fs.tree.root].push_back({0, height});
  std::vector<std::vector<RowRange>> shuffled(devices);
  if (pipeline == PipelineKind::Baseline) {
    // Tauray-style: path tracing balanced over many small strips in bit-reversed order.
    unsigned n = 1;
    while (n < 4u * static_cast<unsigned>(devices)) n <<= 1;
    n = std::min(n, std::max(1u, height));
    while (n & (n - 1)) n &= n - 1;  // a power of two not above the height
    auto small = split_rows(height, n);
    auto order = bit_reversed_order(n);
    fs.strips.clear();
    fs.strip_device.clear();
    for (unsigned i = 0; i < n; ++i) {
      fs.strips.push_back(small[order[i]]);
      fs.strip_device.push_back(static_cast<int>(i % devices));
      shuffled[i % devices].push_back(small[order[i]]);
    }
  }
  auto rows_of = [&](Split split) -> const std::vector<std::vector<RowRange>>& {
    switch (split) {
      case Split::Own: return own;
      case Split::Shuffled: return shuffled;
      case Split::Owner: return owner_all;
      case Split::None: break;
    }
    return none;
  };
  for (const StageRow& row : pipeline_table(pipeline)) {
    if (row.denoise_only && !denoise && !(gbuffer && row.stage == Stage::GBuffer)) continue;
    if (row.direct_light_only && !direct_light) continue;
    fs.stages.push_back(work(row.stage, devices, height, rows_of(row.left), rows_of(row.right)));
    fs.stages.back().payload = row.payload;
  }
  return fs;
}

std::string FrameSchedule::explain() const {
  std::ostringstream out;
  out << "pipeline " << to_string(pipeline) << ", " << devices << " device(s), " << height << " rows, " << strips.size()
      << " strip(s)\n";
  out << "strips (rows -> device):";
  for (std::size_t i = 0; i < strips.size(); ++i)
    out << " [" << strips[i].begin << "," << strips[i].end << ")->" << strip_device[i];
  out << "\n\nworkload pairs (w_left, w_right) per stage and device:\n";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%-4s %-18s", "#", "stage");
  out << buf;
  for (int d = 0; d < devices; ++d) {
    std::snprintf(buf, sizeof buf, " %14s", ("device " + std::to_string(d)).c_str());
    out << buf;
  }
  out << "\n";
  for (const auto& s : stages) {
    std::snprintf(buf, sizeof buf, "%-4d %-18s", static_cast<int>(s.stage), stage_name(s.stage));
    out << buf;
    for (const auto& w : s.per_device) {
      std::snprintf(buf, sizeof buf, " (%5.3f, %5.3f)", w.left, w.right);
      out << buf;
    }
    out << "\n";
  }
  out << "\ndependency tree: device " << tree.root << " (owner, stitches and writes)";
  if (!tree.children.empty()) {
    out << " <- children";
    for (int c : tree.children) out << " " << c;
  }
  if (!find(Stage::Denoise)) out << "\n(denoising off: stage 6 would follow hole filling)";
  out << "\n";
  return out.str();
}

}  // namespace px
