// The task-scheduling structure: for every stage and device, the workload pair
// (w_left, w_right) — the share of each eye's rows that device processes — and the rows it
// implies; plus the two-level dependency tree that decides where strips travel (children send
// to the owner at the root). The pipelines are built from this data, never from ad-hoc logic.
#pragma once

#include "image/row_range.h"
#include "pipeline/stage.h"

#include <string>
#include <vector>

namespace px {

enum class PipelineKind { Proposed, Baseline, Mono };
const char* to_string(PipelineKind p);

struct Workload {
  double left = 0.0, right = 0.0;  // shares of each eye's rows, in [0, 1]
};

// What a transfer stage carries to the owner.
enum class TransferPayload {
  None,
  FinishedImage,   // tonemapped RGBA8, plus the linear radiance where the owner keeps it (EXR)
  LinearRadiance,  // radiance to be finished on the owner (baseline), with its albedo when the
                   // owner denoises
};

struct StageWork {
  Stage stage;
  std::vector<Workload> per_device;                 // indexed by device
  std::vector<std::vector<RowRange>> left_rows;     // per device: rows of the left eye
  std::vector<std::vector<RowRange>> right_rows;    // per device: rows of the right eye
  TransferPayload payload = TransferPayload::None;  // Stage::Transfer only
};

// Owner at the root, every other device its child: strips travel child -> owner.
struct DependencyTree {
  int root = 0;
  std::vector<int> children;
};

struct FrameSchedule {
  PipelineKind pipeline = PipelineKind::Proposed;
  int devices = 1;
  unsigned height = 0;
  std::vector<RowRange> strips;   // the image-space decomposition, top to bottom
  std::vector<int> strip_device;  // device of each strip
  std::vector<StageWork> stages;  // in execution order
  DependencyTree tree;

  const StageWork* find(Stage s) const;
  // Stage x device table of workload pairs and the tree, for `render --explain`.
  std::string explain() const;
};

// Row counts of contiguous strips, and contiguous strips from row 0 with these row counts
// (what the strip balancer works on, and what it hands back).
std::vector<unsigned> strip_sizes(const std::vector<RowRange>& strips);
std::vector<RowRange> strips_from_sizes(const std::vector<unsigned>& sizes);
// Per device, the range from its first to its last row of `eye` (0 left, 1 right) in `work`
// (empty where it has none).
std::vector<RowRange> device_spans(const StageWork& work, int eye);

// Bit-reversal permutation of 0..n-1 for n a power of two (Tauray's "shuffled strips").
std::vector<unsigned> bit_reversed_order(unsigned n);

// The three pipelines are tables (strip_schedule.cpp): per stage, which rows of each eye every
// device processes —
//   own      each device its own contiguous strip (an even split, or `strips`);
//   shuffled 4N (rounded up to a power of two) small strips in bit-reversed order, dealt
//            round-robin (Tauray's load balancing of path tracing);
//   owner    the whole image on the owner (device 0), nothing elsewhere.
// proposed: PT (own, -), G-buffer (own, own), reprojection and hole filling (-, own), [SVGF
//   (own, own)], tonemap (own, own), transfer of finished strips to the owner.
// baseline: PT (shuffled, -), transfer of the left radiance, then everything on the owner.
// mono: PT left (own, -), PT right (-, own), [G-buffer, SVGF], tonemap, transfer.
// Bracketed stages are scheduled only with `denoise`; mono's G-buffer also with `gbuffer`
// (render --aov normal: a G-buffer without denoising). With `direct_light` (ReSTIR DI), stage 14
// follows each eye's path tracing where its pixels get their final radiance: proposed (own, -)
// after the G-buffer and (-, own) after hole filling; baseline the same on the owner; mono (own,
// own) after both path traces.
// `strips` (proposed and mono only): the per-device strips to use instead of the even split,
// strip i on device i — what a load balancer moves between frames. They must be contiguous,
// top to bottom, cover every row once and give each device at least one row
// (std::invalid_argument otherwise; check_strips says why).
FrameSchedule make_schedule(PipelineKind pipeline, int devices, unsigned height, bool denoise = false,
                            const std::vector<RowRange>& strips = {}, bool gbuffer = false, bool direct_light = false);

// Whether a pipeline's strips can move between frames: proposed and mono give each device one
// strip of every per-pixel stage; baseline's many shuffled strips are balanced by construction.
bool has_movable_strips(PipelineKind pipeline);
// Throws std::invalid_argument unless `strips` are `devices` contiguous non-empty ranges
// covering [0, height) in order.
void check_strips(const std::vector<RowRange>& strips, int devices, unsigned height);

}  // namespace px
