#include "pipeline/strip_schedule.h"

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

PipelineKind parse_pipeline(const std::string& text) {
  if (text == "proposed") return PipelineKind::Proposed;
  if (text == "baseline") return PipelineKind::Baseline;
  if (text == "mono") return PipelineKind::Mono;
  throw std::invalid_argument("unknown pipeline '" + text + "' (expected proposed, baseline or mono)");
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

}  // namespace

bool has_movable_strips(PipelineKind pipeline) { return pipeline != PipelineKind::Baseline; }

void check_strips(const std::vector<RowRange>& strips, int devices, unsigned height) {
  if (strips.size() != static_cast<std::size_t>(devices))
    throw std::invalid_argument("strips: " + std::to_string(strips.size()) + " strip(s) for " + std::to_string(devices) +
                                " device(s)");
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
                            const std::vector<RowRange>& strips) {
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

  switch (pipeline) {
    case PipelineKind::Proposed:
      fs.stages.push_back(work(Stage::PathTraceLeft, devices, height, own, none));
      fs.stages.push_back(work(Stage::GBuffer, devices, height, own, own));
      fs.stages.push_back(work(Stage::Reproject, devices, height, none, own));
      fs.stages.push_back(work(Stage::HoleFill, devices, height, none, own));
      if (denoise) {
        fs.stages.push_back(work(Stage::Denoise, devices, height, own, own));
        fs.stages.push_back(work(Stage::RecordPrevious, devices, height, own, own));
      }
      fs.stages.push_back(work(Stage::Tonemap, devices, height, own, own));
      fs.stages.push_back(work(Stage::Transfer, devices, height, own, own));
      fs.stages.push_back(work(Stage::Stitch, devices, height, owner_all, owner_all));
      break;
    case PipelineKind::Baseline: {
      // Tauray-style: path tracing balanced over many small strips in bit-reversed order.
      unsigned n = 1;
      while (n < 4u * static_cast<unsigned>(devices)) n <<= 1;
      n = std::min(n, std::max(1u, height));
      while (n & (n - 1)) n &= n - 1;  // a power of two not above the height
      auto small = split_rows(height, n);
      auto order = bit_reversed_order(n);
      fs.strips.clear();
      fs.strip_device.clear();
      std::vector<std::vector<RowRange>> shuffled(devices);
      for (unsigned i = 0; i < n; ++i) {
        fs.strips.push_back(small[order[i]]);
        fs.strip_device.push_back(static_cast<int>(i % devices));
        shuffled[i % devices].push_back(small[order[i]]);
      }
      fs.stages.push_back(work(Stage::PathTraceLeft, devices, height, shuffled, none));
      fs.stages.push_back(work(Stage::Transfer, devices, height, shuffled, none));
      fs.stages.push_back(work(Stage::Stitch, devices, height, owner_all, none));
      fs.stages.push_back(work(Stage::GBuffer, devices, height, owner_all, owner_all));
      fs.stages.push_back(work(Stage::Reproject, devices, height, none, owner_all));
      fs.stages.push_back(work(Stage::HoleFill, devices, height, none, owner_all));
      if (denoise) {
        fs.stages.push_back(work(Stage::Denoise, devices, height, owner_all, owner_all));
        fs.stages.push_back(work(Stage::RecordPrevious, devices, height, owner_all, owner_all));
      }
      fs.stages.push_back(work(Stage::Tonemap, devices, height, owner_all, owner_all));
      break;
    }
    case PipelineKind::Mono:
      fs.stages.push_back(work(Stage::PathTraceLeft, devices, height, own, none));
      fs.stages.push_back(work(Stage::PathTraceRight, devices, height, none, own));
      if (denoise) {
        fs.stages.push_back(work(Stage::GBuffer, devices, height, own, own));
        fs.stages.push_back(work(Stage::Denoise, devices, height, own, own));
        fs.stages.push_back(work(Stage::RecordPrevious, devices, height, own, own));
      }
      fs.stages.push_back(work(Stage::Tonemap, devices, height, own, own));
      fs.stages.push_back(work(Stage::Transfer, devices, height, own, own));
      fs.stages.push_back(work(Stage::Stitch, devices, height, owner_all, owner_all));
      break;
  }
  return fs;
}

std::string FrameSchedule::explain() const {
  std::ostringstream out;
  out << "pipeline " << to_string(pipeline) << ", " << devices << " device(s), " << height << " rows, "
      << strips.size() << " strip(s)\n";
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
  if (!find(Stage::Denoise)) out << "\n(denoising off: stages 6-7 would follow hole filling)";
  out << "\n";
  return out.str();
}

}  // namespace px
