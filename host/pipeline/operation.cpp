#include "pipeline/operation.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

namespace px {

namespace {

// The per-device images operations hand each other (FrameImages), per eye where they have one.
enum class Image { Radiance, Albedo, GBuffer, Rgba, Holes, RightHits };

struct Access {
  int device;
  Image image;
  int eye;  // -1: the hole list and the right eye's hits (one per device)
  bool write;
};

// What an operation reads and writes. Conservative where it is cheap to be: whole images, not
// rows; a transfer touches every image its payload may carry, on both ends.
std::vector<Access> accesses(const Operation& op) {
  const int d = op.device, e = op.eye;
  switch (op.stage) {
    case Stage::PathTraceLeft:
    case Stage::PathTraceRight:
      if (op.writes_gbuffer)
        return {{d, Image::Radiance, e, true}, {d, Image::Albedo, e, true}, {d, Image::GBuffer, e, true}};
      return {{d, Image::Radiance, e, true}, {d, Image::Albedo, e, true}};
    case Stage::GBuffer:
      if (op.shares_hits) return {{d, Image::GBuffer, e, true}, {d, Image::RightHits, -1, true}};
      return {{d, Image::GBuffer, e, true}};
    case Stage::Reproject:
      return {{d, Image::Radiance, 0, false}, {d, Image::GBuffer, 0, false}, {d, Image::GBuffer, 1, false},
              {d, Image::Radiance, 1, true},  {d, Image::Albedo, 1, true},   {d, Image::Holes, -1, true}};
    case Stage::HoleFill:
      if (op.shares_hits)
        return {{d, Image::Holes, -1, false},
                {d, Image::RightHits, -1, false},
                {d, Image::Radiance, 1, true},
                {d, Image::Albedo, 1, true}};
      return {{d, Image::Holes, -1, false}, {d, Image::Radiance, 1, true}, {d, Image::Albedo, 1, true}};
    case Stage::Denoise:
      // Its own strip. The halo rows it exchanges with its neighbours are read and written by
      // commands on the neighbours' queues, by their own denoise operations of the same batch.
      return {{d, Image::Radiance, e, true}, {d, Image::Albedo, e, false}, {d, Image::GBuffer, e, false}};
    case Stage::DirectLight:
      // Adds to the radiance of its rows (the right eye: of its holes).
      if (e == 1) return {{d, Image::Holes, -1, false}, {d, Image::Radiance, e, true}};
      return {{d, Image::Radiance, e, true}};
    case Stage::Tonemap: return {{d, Image::Radiance, e, false}, {d, Image::Rgba, e, true}};
    case Stage::Transfer: {
      std::vector<Access> a;
      for (Image im : {Image::Radiance, Image::Albedo, Image::Rgba}) {
        a.push_back({d, im, e, false});
        a.push_back({op.to, im, e, true});
      }
      return a;
    }
    default: return {};
  }
}

bool is_path_trace(Stage s) { return s == Stage::PathTraceLeft || s == Stage::PathTraceRight; }

// `rows` less every range in `cut`, as ordered disjoint ranges.
std::vector<RowRange> subtract(RowRange rows, std::vector<RowRange> cut) {
  std::sort(cut.begin(), cut.end(), [](RowRange a, RowRange b) { return a.begin < b.begin; });
  std::vector<RowRange> left;
  unsigned at = rows.begin;
  for (const RowRange& c : cut) {
    if (c.end <= at || c.begin >= rows.end) continue;
    if (c.begin > at) left.push_back({at, c.begin});
    at = std::max(at, c.end);
  }
  if (at < rows.end) left.push_back({at, rows.end});
  return left;
}

// The path traces write the G-buffer rows they trace where their device has a G-buffer pass of
// the same eye; those passes keep the rest.
std::vector<Operation> fuse_gbuffer(std::vector<Operation> ops) {
  std::set<std::pair<int, int>> has_pass;  // (device, eye)
  for (const Operation& op : ops)
    if (op.stage == Stage::GBuffer) has_pass.insert({op.device, op.eye});
  std::map<std::pair<int, int>, std::vector<RowRange>> traced;
  for (Operation& op : ops) {
    if (!is_path_trace(op.stage) || !has_pass.count({op.device, op.eye})) continue;
    op.writes_gbuffer = true;
    traced[{op.device, op.eye}].push_back(op.rows);
  }
  std::vector<Operation> out;
  for (const Operation& op : ops) {
    if (op.stage != Stage::GBuffer) {
      out.push_back(op);
      continue;
    }
    for (const RowRange& r : subtract(op.rows, traced[{op.device, op.eye}])) {
      Operation piece = op;
      piece.rows = r;
      out.push_back(piece);
    }
  }
  // Hole filling from the right eye's G-buffer hits, where that device's passes cover its rows.
  std::map<int, std::vector<RowRange>> right_pass;  // device -> rows of its right-eye G-buffer passes
  for (const Operation& op : out)
    if (op.stage == Stage::GBuffer && op.eye == 1) right_pass[op.device].push_back(op.rows);
  std::set<int> sharing;
  for (Operation& op : out)
    if (op.stage == Stage::HoleFill && subtract(op.rows, right_pass[op.device]).empty()) {
      op.shares_hits = true;
      sharing.insert(op.device);
    }
  for (Operation& op : out)
    if (op.stage == Stage::GBuffer && op.eye == 1 && sharing.count(op.device)) op.shares_hits = true;
  return out;
}

}  // namespace

bool on_side_lane(const Operation& op) {
  return op.eye == 0 && (op.stage == Stage::Denoise || op.stage == Stage::Tonemap || op.stage == Stage::Transfer);
}

std::vector<Operation> make_operations(const FrameSchedule& schedule, unsigned gbuffer_margin, bool side_lane,
                                       bool gbuffer_from_path_tracer) {
  std::vector<Operation> ops;
  const int n = schedule.devices;
  auto add = [&](const StageWork& w, int eye, int d, RowRange rows) {
    if (rows.size() == 0) return;
    Operation op;
    op.stage = w.stage;
    op.eye = eye;
    op.device = d;
    op.rows = rows;
    if (w.stage == Stage::GBuffer) op.rows = widen(rows, gbuffer_margin, schedule.height);
    if (w.stage == Stage::Transfer) {
      if (d == schedule.tree.root) return;  // the owner's own rows are already in place
      op.to = schedule.tree.root;
      op.payload = w.payload;
    }
    op.lane = side_lane && on_side_lane(op) ? 1 : 0;
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
  if (gbuffer_from_path_tracer) ops = fuse_gbuffer(std::move(ops));
  // What each waits for (see the header): per image, its last writer and the readers since.
  struct Touches {
    long writer = -1;
    std::vector<std::size_t> readers;  // since the writer
  };
  std::map<std::tuple<int, int, int>, Touches> images;  // (device, image, eye)
  std::map<std::pair<int, int>, long> last_on_lane;     // (device, lane)
  for (std::size_t i = 0; i < ops.size(); ++i) {
    Operation& op = ops[i];
    const std::vector<Access> acc = accesses(op);
    std::set<std::size_t> after;
    auto lane_it = last_on_lane.find({op.device, op.lane});
    if (lane_it != last_on_lane.end()) after.insert(static_cast<std::size_t>(lane_it->second));
    for (const Access& a : acc) {
      Touches& t = images[{a.device, static_cast<int>(a.image), a.eye}];
      if (t.writer >= 0) after.insert(static_cast<std::size_t>(t.writer));
      if (a.write) after.insert(t.readers.begin(), t.readers.end());
    }
    for (const Access& a : acc) {
      Touches& t = images[{a.device, static_cast<int>(a.image), a.eye}];
      if (a.write) {
        t.writer = static_cast<long>(i);
        t.readers.clear();
      } else {
        t.readers.push_back(i);
      }
    }
    after.erase(i);
    op.after.assign(after.begin(), after.end());
    last_on_lane[{op.device, op.lane}] = static_cast<long>(i);
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
    std::snprintf(line, sizeof line, "%4zu  %-17s %-5s %-14s %-4s rows [%u, %u)", i, stage_name(op.stage),
                  op.eye == 0 ? "left" : "right", where.c_str(), op.lane ? "side" : "main", op.rows.begin, op.rows.end);
    out << line;
    if (op.payload == TransferPayload::FinishedImage) out << " finished image";
    if (op.payload == TransferPayload::LinearRadiance) out << " linear radiance";
    if (op.writes_gbuffer) out << " +G-buffer";
    if (op.shares_hits) out << (op.stage == Stage::HoleFill ? " from G-buffer hits" : " +hits");
    if (!op.after.empty()) {
      out << "  after";
      for (std::size_t a : op.after) out << " " << a;
    }
    out << "\n";
  }
  return out.str();
}

}  // namespace px
