// The image-parallel stereo pipeline: the scheduler's tables, device-count invariance,
// baseline == proposed, reprojection correctness (against an independent visibility check
// with Embree and against the path tracer's own values), and hole bookkeeping.
#include "app/scene_setup.h"
#include "bvh/embree_reference.h"
#include "cl/launch.h"
#include "image/srgb_thresholds.h"
#include "pipeline/stereo_pipeline.h"
#include "pipeline/strip_schedule.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <set>

namespace px {
namespace {

// ---- scheduler ----

TEST(StripSchedule, PaperFourDeviceExample) {
  auto fs = make_schedule(PipelineKind::Proposed, 4, 720);
  for (int d = 0; d < 4; ++d) {
    EXPECT_DOUBLE_EQ(fs.find(Stage::PathTraceLeft)->per_device[d].left, 0.25);
    EXPECT_DOUBLE_EQ(fs.find(Stage::PathTraceLeft)->per_device[d].right, 0.0);
    EXPECT_DOUBLE_EQ(fs.find(Stage::HoleFill)->per_device[d].left, 0.0);
    EXPECT_DOUBLE_EQ(fs.find(Stage::HoleFill)->per_device[d].right, 0.25);
    EXPECT_DOUBLE_EQ(fs.find(Stage::Tonemap)->per_device[d].left, 0.25);
    EXPECT_DOUBLE_EQ(fs.find(Stage::Tonemap)->per_device[d].right, 0.25);
  }
  EXPECT_EQ(fs.tree.root, 0);
  EXPECT_EQ(fs.tree.children, (std::vector<int>{1, 2, 3}));
  EXPECT_NE(fs.explain().find("(0.250, 0.000)"), std::string::npos);
}

TEST(StripSchedule, StripsCoverEveryRowOnceForAnyHeightAndCount) {
  for (auto kind : {PipelineKind::Proposed, PipelineKind::Baseline, PipelineKind::Mono})
    for (int n = 1; n <= 5; ++n)
      for (unsigned h : {1u, 2u, 7u, 100u, 101u, 719u}) {
        if (static_cast<unsigned>(n) > h && kind != PipelineKind::Baseline) continue;
        auto fs = make_schedule(kind, n, h);
        const StageWork* pt = fs.find(Stage::PathTraceLeft);
        std::vector<int> seen(h, 0);
        for (int d = 0; d < n; ++d)
          for (auto r : pt->left_rows[d])
            for (unsigned y = r.begin; y < r.end; ++y) seen[y]++;
        for (unsigned y = 0; y < h; ++y)
          ASSERT_EQ(seen[y], 1) << to_string(kind) << " n=" << n << " h=" << h << " row " << y;
      }
  auto rows = split_rows(10, 4);
  EXPECT_EQ(rows[0].size(), 3u);
  EXPECT_EQ(rows[3].size(), 2u);
}

TEST(StripSchedule, BitReversedOrderIsAPermutation) {
  EXPECT_EQ(bit_reversed_order(8), (std::vector<unsigned>{0, 4, 2, 6, 1, 5, 3, 7}));
  auto o = bit_reversed_order(64);
  EXPECT_EQ(std::set<unsigned>(o.begin(), o.end()).size(), 64u);
  EXPECT_THROW(bit_reversed_order(6), std::invalid_argument);
}

TEST(StripSchedule, BaselineRunsEverythingAfterTransferOnTheOwner) {
  auto fs = make_schedule(PipelineKind::Baseline, 3, 90);
  for (Stage s : {Stage::GBuffer, Stage::Reproject, Stage::HoleFill, Stage::Tonemap}) {
    const StageWork* w = fs.find(s);
    ASSERT_NE(w, nullptr);
    EXPECT_DOUBLE_EQ(w->per_device[0].right, 1.0) << stage_name(s);
    for (int d = 1; d < 3; ++d) EXPECT_DOUBLE_EQ(w->per_device[d].right, 0.0) << stage_name(s);
  }
  // Path tracing is spread: every device gets a share.
  for (int d = 0; d < 3; ++d) EXPECT_GT(fs.find(Stage::PathTraceLeft)->per_device[d].left, 0.2);
}

// ---- operations ----

// The rows of `eye` the operations of `stage` cover, counted per row.
std::vector<int> coverage(const std::vector<Operation>& ops, Stage stage, int eye, unsigned h) {
  std::vector<int> seen(h, 0);
  for (const Operation& op : ops)
    if (op.stage == stage && op.eye == eye)
      for (unsigned y = op.rows.begin; y < op.rows.end; ++y) seen[y]++;
  return seen;
}

TEST(Operations, CoverEveryScheduledRowOnceAndWaitOnlyOnEarlierOperations) {
  for (auto kind : {PipelineKind::Proposed, PipelineKind::Baseline, PipelineKind::Mono})
    for (bool denoise : {false, true})
      for (int n = 1; n <= 4; ++n) {
        const unsigned h = 37, margin = 5;
        const FrameSchedule fs = make_schedule(kind, n, h, denoise);
        for (int variant = 0; variant < 4; ++variant) {
          const bool side = variant & 1, fuse = variant & 2;
          const std::vector<Operation> ops = make_operations(fs, margin, side, fuse);
          const std::string what = std::string(to_string(kind)) + (denoise ? " denoised" : "") +
                                   " n=" + std::to_string(n) + (side ? " side lane" : "") +
                                   (fuse ? " G-buffer from path tracing" : "");
          // Per device and eye, the G-buffer rows written there: by the G-buffer passes, and by the
          // path traces that write theirs. With and without fusion the same rows, each once.
          const std::vector<Operation> plain = make_operations(fs, margin, side, false);
          int fused_ops = 0;
          for (int d = 0; d < n; ++d)
            for (int eye = 0; eye < 2; ++eye) {
              std::vector<int> got(h, 0), want(h, 0);
              for (const Operation& op : ops) {
                if (op.device != d || op.eye != eye) continue;
                const bool writes = op.stage == Stage::GBuffer || op.writes_gbuffer;
                if (op.writes_gbuffer) {
                  ASSERT_TRUE(fuse) << what;
                  ASSERT_TRUE(op.stage == Stage::PathTraceLeft || op.stage == Stage::PathTraceRight) << what;
                  ++fused_ops;
                }
                if (writes)
                  for (unsigned y = op.rows.begin; y < op.rows.end; ++y) got[y]++;
              }
              for (const Operation& op : plain)
                if (op.device == d && op.eye == eye && op.stage == Stage::GBuffer)
                  for (unsigned y = op.rows.begin; y < op.rows.end; ++y) want[y]++;
              for (unsigned y = 0; y < h; ++y)
                ASSERT_EQ(got[y], want[y]) << what << " device " << d << " eye " << eye << " G-buffer row " << y;
            }
          // Proposed and mono path trace each device's strip of the left eye where its G-buffer is
          // (mono has a G-buffer only for the denoiser).
          if (fuse && (kind == PipelineKind::Proposed || (kind == PipelineKind::Mono && denoise))) {
            EXPECT_GE(fused_ops, n) << what;
          }
          // Hole filling starts from the right-eye G-buffer pass's hits (proposed: on every device).
          for (const Operation& op : ops) {
            if (!op.shares_hits) continue;
            ASSERT_TRUE(fuse) << what;
            ASSERT_TRUE((op.stage == Stage::GBuffer && op.eye == 1) || op.stage == Stage::HoleFill) << what;
            if (op.stage != Stage::HoleFill) continue;
            std::vector<int> hit_rows(h, 0);
            for (const Operation& g : ops)
              if (g.stage == Stage::GBuffer && g.shares_hits && g.device == op.device)
                for (unsigned y = g.rows.begin; y < g.rows.end; ++y) hit_rows[y] = 1;
            for (unsigned y = op.rows.begin; y < op.rows.end; ++y)
              ASSERT_EQ(hit_rows[y], 1) << what << ": hole filling row " << y << " has no G-buffer hit";
          }
          if (fuse && kind == PipelineKind::Proposed) {
            EXPECT_EQ(std::count_if(ops.begin(), ops.end(),
                                    [](const Operation& op) { return op.stage == Stage::HoleFill && op.shares_hits; }),
                      n)
                << what;
          }
          for (const StageWork& w : fs.stages)
            for (int eye = 0; eye < 2; ++eye) {
              // Independently of make_operations: the rows the schedule gives this stage and eye.
              std::vector<int> want(h, 0), want_device(h, -1);
              for (int d = 0; d < n; ++d)
                for (const RowRange& r : eye == 0 ? w.left_rows[d] : w.right_rows[d])
                  for (unsigned y = r.begin; y < r.end; ++y) want[y]++, want_device[y] = d;
              const std::vector<int> got = coverage(ops, w.stage, eye, h);
              for (unsigned y = 0; y < h; ++y) {
                if (w.stage == Stage::Transfer) {
                  // The owner's rows stay where they are; every other scheduled row travels once.
                  ASSERT_EQ(got[y], want[y] && want_device[y] != fs.tree.root ? 1 : 0) << what << " row " << y;
                } else if (w.stage == Stage::GBuffer) {
                  // Each device's G-buffer also covers `margin` rows beyond its strip (fused: the
                  // pass's rows and the path traced rows that write theirs, checked above).
                  if (fuse) continue;
                  bool near = false;
                  for (unsigned z = y > margin ? y - margin : 0; z <= std::min(h - 1, y + margin); ++z)
                    near |= want[z] > 0;
                  ASSERT_EQ(got[y] > 0, near) << what << " g-buffer row " << y;
                } else {
                  ASSERT_EQ(got[y], want[y]) << what << " " << stage_name(w.stage) << " eye " << eye << " row " << y;
                }
              }
            }
          std::vector<long> last(2 * n, -1);                      // per (device, lane)
          std::vector<std::set<std::size_t>> before(ops.size());  // everything an operation waits for, transitively
          for (std::size_t i = 0; i < ops.size(); ++i) {
            const Operation& op = ops[i];
            ASSERT_EQ(op.lane,
                      side && op.eye == 0 &&
                              (op.stage == Stage::Denoise || op.stage == Stage::Tonemap || op.stage == Stage::Transfer)
                          ? 1
                          : 0)
                << what << " op " << i;
            for (std::size_t a : op.after) {
              ASSERT_LT(a, i) << what;
              before[i].insert(a);
              before[i].insert(before[a].begin(), before[a].end());
            }
            // Queue order: the previous operation on the device's lane is always among the waits.
            const long prev = last[2 * op.device + op.lane];
            if (prev >= 0) {
              ASSERT_NE(std::find(op.after.begin(), op.after.end(), static_cast<std::size_t>(prev)), op.after.end())
                  << what << " op " << i;
            }
            last[2 * op.device + op.lane] = static_cast<long>(i);
            if (op.stage == Stage::Transfer) {
              EXPECT_EQ(op.to, fs.tree.root) << what;
              EXPECT_NE(op.device, fs.tree.root) << what;
              EXPECT_NE(op.payload, TransferPayload::None) << what;
            }
          }
          // The hazards the side lane creates, checked on the stages themselves: the left eye's
          // denoising rewrites left radiance in place, so it must come after every reprojection
          // (which reads it) and every path tracing of the left eye on its device; tonemapping
          // after denoising; a transfer after the tonemap of its rows.
          for (std::size_t i = 0; i < ops.size(); ++i)
            for (std::size_t j = 0; j < i; ++j) {
              const Operation &a = ops[j], &b = ops[i];
              const bool same_device = a.device == b.device;
              auto must = [&](bool cond, const char* why) {
                if (cond) {
                  ASSERT_TRUE(before[i].count(j))
                      << what << ": op " << i << " must wait for op " << j << " (" << why << ")";
                }
              };
              must(same_device && b.stage == Stage::Denoise && b.eye == 0 &&
                       (a.stage == Stage::Reproject || a.stage == Stage::PathTraceLeft),
                   "denoising rewrites the radiance they read or write");
              must(same_device && a.writes_gbuffer &&
                       (b.stage == Stage::Reproject || (b.stage == Stage::Denoise && a.eye == b.eye)),
                   "they read the G-buffer the path trace wrote");
              must(same_device && a.stage == Stage::GBuffer && a.shares_hits && b.stage == Stage::HoleFill &&
                       b.shares_hits,
                   "hole filling starts from the hits the G-buffer pass wrote");
              must(same_device && b.stage == Stage::Tonemap && a.stage == Stage::Denoise && a.eye == b.eye,
                   "tonemap reads denoised radiance");
              must(same_device && b.stage == Stage::Tonemap && a.stage == Stage::HoleFill && b.eye == 1,
                   "tonemap reads the filled right eye");
              must(same_device && b.stage == Stage::Transfer && a.stage == Stage::Tonemap && a.eye == b.eye,
                   "a finished strip travels after its tonemap");
              must(b.stage != Stage::Transfer && a.stage == Stage::Transfer && a.to == b.device && a.eye == b.eye &&
                       b.stage != Stage::GBuffer,
                   "what arrives is read after it arrived");
            }
        }
      }
}

// ---- pipeline runs ----

struct PipelineRun {
  std::array<ImageRGB, 2> radiance;
  std::vector<std::uint8_t> holes;
  std::vector<GBufferTexel> gright;
  FrameStats stats;
};

PipelineRun run(const LoadedScene& loaded, PipelineKind kind, int devices, unsigned w, unsigned h, unsigned spp,
                std::uint32_t seed = 0, unsigned frame = 0,
                HoleFillStage::SampleSpread spread = HoleFillStage::SampleSpread::Auto) {
  DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  StereoPipeline::Options opt;
  opt.pipeline = kind;
  opt.trace.spp = spp;
  opt.trace.bounces = 4;
  opt.trace.seed = seed;
  opt.denoise.reset();  // these tests are about stages 2-5; SVGF has its own suite
  opt.hole_fill.spread = spread;
  StereoPipeline p(set, ds, loaded.scene, w, h, opt);
  PipelineRun r;
  r.stats = p.render(frame, 0.1f * frame);
  r.radiance = p.radiance();
  r.holes = p.hole_mask();
  r.gright = p.gbuffer_of(1);
  return r;
}

bool same_bits(const ImageRGB& a, const ImageRGB& b) {
  return a.rgb.size() == b.rgb.size() && std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

const LoadedScene& glossy_cornell() {
  static LoadedScene s = load_and_build("cornell-glossy", true);
  return s;
}

TEST(StereoPipeline, ProposedIsBitIdenticalForOneToEightDevices) {
  const auto& scene = glossy_cornell();
  const unsigned w = 48, h = 37;  // 37 rows: divisible by none of 2, 3, 4, 6, 8
  auto one = run(scene, PipelineKind::Proposed, 1, w, h, 2, 0, 1);
  for (int n : {2, 3, 4, 6, 8}) {
    auto many = run(scene, PipelineKind::Proposed, n, w, h, 2, 0, 1);
    EXPECT_TRUE(same_bits(one.radiance[0], many.radiance[0])) << n << " devices, left eye";
    EXPECT_TRUE(same_bits(one.radiance[1], many.radiance[1])) << n << " devices, right eye";
    EXPECT_EQ(one.holes, many.holes) << n << " devices";
  }
}

TEST(StereoPipeline, BaselineGivesTheSameImagesAsProposed) {
  const auto& scene = glossy_cornell();
  auto proposed = run(scene, PipelineKind::Proposed, 2, 40, 30, 2);
  auto baseline = run(scene, PipelineKind::Baseline, 3, 40, 30, 2);
  EXPECT_TRUE(same_bits(proposed.radiance[0], baseline.radiance[0]));
  EXPECT_TRUE(same_bits(proposed.radiance[1], baseline.radiance[1]));
  EXPECT_GT(baseline.stats.bytes_transferred, 0u);
}

TEST(StereoPipeline, EveryOperationIsExecutedAndTimed) {
  // Each operation's stage shows device time on its device (a transfer: on both ends), and no
  // stage shows time that no operation accounts for.
  const auto& scene = glossy_cornell();
  for (auto kind : {PipelineKind::Proposed, PipelineKind::Baseline, PipelineKind::Mono}) {
    DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
    DeviceScene ds(set, scene.scene, scene.bvh);
    StereoPipeline::Options opt;
    opt.pipeline = kind;
    opt.trace.bounces = 2;
    StereoPipeline p(set, ds, scene.scene, 24, 17, opt);
    const std::vector<Operation> ops = p.operations();
    const FrameStats stats = p.render(0, 0.0f);
    std::set<std::pair<int, int>> expected, timed;
    for (const Operation& op : ops) {
      expected.insert({static_cast<int>(op.stage), op.device});
      if (op.stage == Stage::Transfer) expected.insert({static_cast<int>(op.stage), op.to});
      // Inside the denoise unit: the history copies (stage 7) and the temporal gradients.
      if (op.stage == Stage::Denoise) {
        expected.insert({static_cast<int>(Stage::RecordPrevious), op.device});
        expected.insert({static_cast<int>(Stage::TemporalGradient), op.device});
      }
    }
    for (const StageTiming& t : stats.stages) timed.insert({static_cast<int>(t.stage), t.device});
    // Halo exchanges of the denoiser are transfers between neighbours that no transfer
    // operation names.
    if (kind != PipelineKind::Baseline)
      for (int d = 0; d < 2; ++d) expected.insert({static_cast<int>(Stage::Transfer), d});
    EXPECT_EQ(timed, expected) << to_string(kind);
  }
}

TEST(StereoPipeline, HolesAreExactlyThePathTracedRightPixels) {
  // Every right pixel is reprojected or filled, never neither: a hole holds exactly what the
  // mono pipeline path traces there (same sample streams), and a reprojected pixel is a
  // diffuse surface or background.
  const auto& scene = glossy_cornell();
  // Large enough that the ring of holes around every silhouette (pixels whose footprint holds
  // two surfaces) stays a minority.
  auto proposed = run(scene, PipelineKind::Proposed, 2, 96, 72, 2);
  auto mono = run(scene, PipelineKind::Mono, 2, 96, 72, 2);
  EXPECT_TRUE(same_bits(proposed.radiance[0], mono.radiance[0])) << "left eyes should match";
  int holes = 0, reprojected = 0;
  for (std::size_t i = 0; i < proposed.holes.size(); ++i) {
    const auto cls = proposed.gright[i].material_class;
    for (int c = 0; c < 3; ++c) ASSERT_TRUE(std::isfinite(proposed.radiance[1].rgb[i * 3 + c]));
    if (proposed.holes[i]) {
      ++holes;
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(proposed.radiance[1].rgb[i * 3 + c], mono.radiance[1].rgb[i * 3 + c]) << "hole pixel " << i;
    } else {
      ++reprojected;
      EXPECT_TRUE(cls == PX_CLASS_DIFFUSE || cls == PX_CLASS_MISS) << "pixel " << i << " class " << cls;
    }
    // Glossy, mirror and emissive surfaces are view-dependent: always holes.
    if (cls == PX_CLASS_GLOSSY || cls == PX_CLASS_MIRROR || cls == PX_CLASS_EMISSIVE) {
      EXPECT_TRUE(proposed.holes[i]) << "pixel " << i << " class " << cls;
    }
  }
  EXPECT_GT(reprojected, holes) << "most of a diffuse scene should be reprojected";
  EXPECT_EQ(proposed.stats.reprojected, static_cast<std::size_t>(reprojected));
}

TEST(StereoPipeline, HoleSamplesSpreadOverWorkItemsGiveTheSameImages) {
  // A work-item per (hole, sample) pair and a resolve pass (what GPUs run at 2-8 spp) against a
  // work-item per hole: the same samples summed in the same order, so the same bits, and the
  // holes still hold exactly what mono path traces there. 3 spp: not a power of two.
  const auto& scene = glossy_cornell();
  using Spread = HoleFillStage::SampleSpread;
  for (int devices : {1, 2}) {
    auto spread = run(scene, PipelineKind::Proposed, devices, 64, 48, 3, 7, 1, Spread::On);
    auto per_hole = run(scene, PipelineKind::Proposed, devices, 64, 48, 3, 7, 1, Spread::Off);
    auto mono = run(scene, PipelineKind::Mono, devices, 64, 48, 3, 7, 1);
    EXPECT_TRUE(same_bits(spread.radiance[1], per_hole.radiance[1])) << devices << " devices";
    EXPECT_TRUE(same_bits(spread.radiance[0], per_hole.radiance[0])) << devices << " devices";
    EXPECT_EQ(spread.holes, per_hole.holes);
    int holes = 0;
    for (std::size_t i = 0; i < spread.holes.size(); ++i) {
      if (!spread.holes[i]) continue;
      ++holes;
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(spread.radiance[1].rgb[i * 3 + c], mono.radiance[1].rgb[i * 3 + c]) << "hole pixel " << i;
    }
    EXPECT_GT(holes, 200) << "glossy surfaces and silhouettes should leave holes";
  }
}

TEST(StereoPipeline, GlassIsNeverReprojected) {
  // What a dielectric shows depends on the eye (it refracts the scene behind it): its G-buffer
  // class is PX_CLASS_DIELECTRIC, and every right pixel on it is path traced, holding what
  // the mono pipeline computes there.
  Scene s;
  Material white;
  white.diffuse = glm::vec3(0.7f);
  Material light = white;
  light.emission = glm::vec3(5.0f);
  Material glass;
  glass.dielectric = true;
  glass.ior = 1.5f;
  s.materials = {white, light, glass};
  append_quad(s.triangles, {-3, -2, 4}, {3, -2, 4}, {3, 2, 4}, {-3, 2, 4}, 0);            // back wall
  append_quad(s.triangles, {-1, 1.9f, 2}, {1, 1.9f, 2}, {1, 1.9f, 3}, {-1, 1.9f, 3}, 1);  // light
  append_icosphere(s.triangles, {0.0f, 0.0f, 2.0f}, 0.8f, 3, 2);
  s.camera.position = {0.0f, 0.0f, -1.0f};
  s.camera.target = {0.0f, 0.0f, 4.0f};
  s.camera.vfov_deg = 60.0f;
  LoadedScene loaded{s, build_bvh(s.triangles), {}};
  auto proposed = run(loaded, PipelineKind::Proposed, 2, 48, 36, 2);
  auto mono = run(loaded, PipelineKind::Mono, 2, 48, 36, 2);
  int glass_pixels = 0, reprojected = 0;
  for (std::size_t i = 0; i < proposed.holes.size(); ++i) {
    reprojected += !proposed.holes[i];
    if (proposed.gright[i].material_class != PX_CLASS_DIELECTRIC) continue;
    ++glass_pixels;
    ASSERT_TRUE(proposed.holes[i]) << "glass pixel " << i << " was reprojected";
    for (int c = 0; c < 3; ++c)
      ASSERT_EQ(proposed.radiance[1].rgb[i * 3 + c], mono.radiance[1].rgb[i * 3 + c]) << "glass pixel " << i;
  }
  EXPECT_GT(glass_pixels, 100) << "the sphere should cover a good part of the image";
  EXPECT_GT(reprojected, 100) << "the diffuse wall around it is still reprojected";
}

TEST(StereoPipeline, ReprojectedSurfacesAreVisibleFromTheLeftEye) {
  // Independent check of disocclusion handling: for every reprojected right pixel, Embree casts
  // a ray from the left eye to that surface point; it must arrive unblocked (else the left eye
  // never saw it and reusing its radiance would be wrong).
  Scene s;
  Material white;
  white.diffuse = glm::vec3(0.7f);
  Material light = white;
  light.emission = glm::vec3(5.0f);
  s.materials = {white, light};
  append_quad(s.triangles, {-3, -2, 4}, {3, -2, 4}, {3, 2, 4}, {-3, 2, 4}, 0);            // back wall
  append_box(s.triangles, {-0.3f, -0.6f, 0.8f}, {0.3f, 0.6f, 1.2f}, 0);                   // near occluder
  append_quad(s.triangles, {-1, 1.9f, 2}, {1, 1.9f, 2}, {1, 1.9f, 3}, {-1, 1.9f, 3}, 1);  // light
  s.camera.position = {0.0f, 0.0f, -1.0f};
  s.camera.target = {0.0f, 0.0f, 4.0f};
  s.camera.vfov_deg = 60.0f;
  s.ipd_m = 0.25f;  // wide eyes: large disocclusions beside the occluder
  LoadedScene loaded{s, build_bvh(s.triangles), {}};
  auto r = run(loaded, PipelineKind::Proposed, 2, 64, 48, 1);
  const glm::vec3 left_eye = s.camera.position - glm::vec3(-1, 0, 0) * (0.5f * s.ipd_units());  // right = -x here
  EmbreeReference embree(s.triangles);
  int checked = 0, disoccluded_holes = 0;
  for (std::size_t i = 0; i < r.holes.size(); ++i) {
    const auto& g = r.gright[i];
    if (g.material_class != PX_CLASS_DIFFUSE) continue;
    const glm::vec3 p(g.pos[0], g.pos[1], g.pos[2]);
    const glm::vec3 to = p - left_eye;
    const float dist = glm::length(to);
    Ray ray{};
    for (int k = 0; k < 3; ++k) {
      ray.org[k] = left_eye[k];
      ray.dir[k] = to[k] / dist;
    }
    ray.tmin = 0.0f;
    ray.tmax = dist * 0.999f;
    const bool blocked = embree.occluded(ray);
    if (!r.holes[i]) {
      ++checked;
      EXPECT_FALSE(blocked) << "pixel " << i << " reprojected but hidden from the left eye";
    } else if (blocked) {
      ++disoccluded_holes;
    }
  }
  EXPECT_GT(checked, 500);
  EXPECT_GT(disoccluded_holes, 10) << "the scene should have disocclusions (else the test says nothing)";
}

// 4x4 block means over blocks whose pixels were all reprojected.
double reprojected_block_mse(const ImageRGB& a, const ImageRGB& b, const std::vector<std::uint8_t>& holes,
                             int* blocks) {
  double s = 0;
  int n = 0;
  for (int by = 0; by + 4 <= a.height; by += 4)
    for (int bx = 0; bx + 4 <= a.width; bx += 4) {
      bool all = true;
      for (int y = by; y < by + 4; ++y)
        for (int x = bx; x < bx + 4; ++x) all = all && !holes[y * a.width + x];
      if (!all) continue;
      for (int c = 0; c < 3; ++c) {
        double ma = 0, mb = 0;
        for (int y = by; y < by + 4; ++y)
          for (int x = bx; x < bx + 4; ++x) {
            ma += a.rgb[(y * a.width + x) * 3 + c] / 16.0;
            mb += b.rgb[(y * a.width + x) * 3 + c] / 16.0;
          }
        s += (ma - mb) * (ma - mb);
        ++n;
      }
    }
  *blocks = n / 3;
  return n ? s / n : 0.0;
}

// An object against the sky and in front of a diffuse wall: silhouettes over background and
// over another diffuse surface, in both eyes.
Scene silhouettes_scene() {
  Scene s;
  Material white, red;
  white.diffuse = glm::vec3(0.7f);
  red.diffuse = glm::vec3(0.8f, 0.15f, 0.1f);
  s.materials = {white, red};
  append_quad_facing(s.triangles, {-4, -2, 6}, {4, -2, 6}, {4, 0.2f, 6}, {-4, 0.2f, 6}, {0, 0, -1}, 0);  // low wall
  append_icosphere(s.triangles, {0.0f, 0.1f, 3.0f}, 0.6f, 3, 1);  // straddles the wall's top edge
  s.sky.enabled = true;
  s.sky.zenith = glm::vec3(0.3f, 0.5f, 1.0f);
  s.sky.horizon = glm::vec3(0.8f, 0.85f, 0.9f);
  s.sky.ground = s.sky.horizon;  // no step at the horizon: smooth background everywhere
  s.camera.position = {0.0f, 0.3f, 0.0f};
  s.camera.target = {0.0f, 0.2f, 3.0f};
  s.camera.vfov_deg = 40.0f;
  s.ipd_m = 0.1f;
  return s;
}

// The wavefront tracer against the megakernel: the same vertex code, the same additions in the
// same order, the same per-pixel sums, so the same bits in every pipeline and on 1 and 2
// devices. Glossy cornell (emitters, Russian roulette from bounce 3, glossy holes) and an object
// under the sky (environment MIS, rays that escape at the first vertex); 3 spp (not a power of
// two); 0 bounces (no shadow rays at all) and 5; the non-finite counts too.
// silhouettes_scene() with its BVH, built once.
const LoadedScene& silhouettes() {
  static const LoadedScene s = [] {
    Scene scene = silhouettes_scene();
    auto bvh = build_bvh(scene.triangles);
    return LoadedScene{std::move(scene), std::move(bvh), {}};
  }();
  return s;
}

TEST(StereoPipeline, WavefrontPathTracerGivesTheMegakernelsImages) {
  const LoadedScene& sky_built = silhouettes();
  struct Case {
    const LoadedScene* scene;
    PipelineKind kind;
    int devices;
    unsigned bounces;
  };
  const std::vector<Case> cases{
      {&glossy_cornell(), PipelineKind::Proposed, 1, 5}, {&glossy_cornell(), PipelineKind::Proposed, 2, 5},
      {&glossy_cornell(), PipelineKind::Baseline, 2, 5}, {&glossy_cornell(), PipelineKind::Mono, 2, 0},
      {&sky_built, PipelineKind::Proposed, 2, 5},        {&sky_built, PipelineKind::Mono, 1, 5}};
  for (const Case& c : cases) {
    std::array<std::array<ImageRGB, 2>, 2> images;
    std::array<std::uint64_t, 2> nonfinite{};
    std::array<std::size_t, 2> reprojected{};
    for (int k = 0; k < 2; ++k) {
      DeviceSet set = DeviceSet::create({c.devices, DeviceMode::Auto, "", std::nullopt});
      DeviceScene ds(set, c.scene->scene, c.scene->bvh);
      StereoPipeline::Options opt;
      opt.pipeline = c.kind;
      opt.trace.spp = 3;
      opt.trace.bounces = c.bounces;
      opt.denoise.reset();
      opt.path_kernel = k == 0 ? PathTraceKernel::Megakernel : PathTraceKernel::Wavefront;
      StereoPipeline p(set, ds, c.scene->scene, 56, 40, opt);
      for (unsigned f = 0; f < 2; ++f) reprojected[k] += p.render(f, 0.1f * f).reprojected;
      nonfinite[k] = p.nonfinite_paths();
      images[k] = p.radiance();
    }
    const std::string what = std::string(to_string(c.kind)) + ", " + std::to_string(c.devices) + " device(s), " +
                             std::to_string(c.bounces) + " bounces, " + c.scene->scene.name;
    EXPECT_TRUE(same_bits(images[0][0], images[1][0])) << what << ": left eye";
    EXPECT_TRUE(same_bits(images[0][1], images[1][1])) << what << ": right eye";
    EXPECT_EQ(nonfinite[0], nonfinite[1]) << what;
    EXPECT_EQ(reprojected[0], reprojected[1]) << what;
    double sum = 0;
    for (float v : images[1][1].rgb) sum += v;
    EXPECT_GT(sum, 0.0) << what << ": a black image would match a black image";
  }
}

bool same_gbuffer(const std::vector<GBufferTexel>& a, const std::vector<GBufferTexel>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(GBufferTexel)) == 0;
}

TEST(StereoPipeline, CentreRaysTracedOnceGiveTheGBufferPassesTexelsAndTheSameImages) {
  // The path tracers' first sample (the G-buffer's ray) writes the G-buffer of the rows they trace, and hole
  // filling starts its first sample (the G-buffer's ray) from the right-eye G-buffer pass's hits; with that
  // off, the G-buffer pass (an independent kernel) traces every texel and hole filling every
  // camera ray. Denoised, over two frames, so that SVGF reads the G-buffer (margins included)
  // and its history.
  const LoadedScene& sky_built = silhouettes();
  struct Case {
    const LoadedScene* scene;
    PipelineKind kind;
    int devices;
    PathTraceKernel kernel;
    HoleFillStage::SampleSpread spread = HoleFillStage::SampleSpread::Off;
  };
  using Spread = HoleFillStage::SampleSpread;
  const std::vector<Case> cases{{&glossy_cornell(), PipelineKind::Proposed, 1, PathTraceKernel::Megakernel},
                                {&glossy_cornell(), PipelineKind::Proposed, 3, PathTraceKernel::Megakernel, Spread::On},
                                {&glossy_cornell(), PipelineKind::Proposed, 2, PathTraceKernel::Wavefront},
                                {&glossy_cornell(), PipelineKind::Baseline, 2, PathTraceKernel::Megakernel},
                                {&sky_built, PipelineKind::Mono, 2, PathTraceKernel::Wavefront},
                                {&sky_built, PipelineKind::Proposed, 2, PathTraceKernel::Megakernel}};
  for (const Case& c : cases) {
    std::array<std::array<ImageRGB, 2>, 2> images;
    std::array<std::array<std::vector<GBufferTexel>, 2>, 2> gbuffers;
    std::array<std::vector<std::uint8_t>, 2> holes;
    int fused_ops = 0, hole_fills_from_hits = 0;
    for (int k = 0; k < 2; ++k) {
      DeviceSet set = DeviceSet::create({c.devices, DeviceMode::Auto, "", std::nullopt});
      DeviceScene ds(set, c.scene->scene, c.scene->bvh);
      StereoPipeline::Options opt;
      opt.pipeline = c.kind;
      opt.trace.spp = 2;
      opt.trace.bounces = 3;
      opt.path_kernel = c.kernel;
      opt.gbuffer_from_path_tracer = k == 1;
      opt.hole_fill.spread = c.spread;
      StereoPipeline p(set, ds, c.scene->scene, 48, 37, opt);
      for (const Operation& op : p.operations()) {
        fused_ops += op.writes_gbuffer;
        hole_fills_from_hits += op.stage == Stage::HoleFill && op.shares_hits;
      }
      for (unsigned f = 0; f < 2; ++f) p.render(f, 0.1f * f);
      images[k] = p.radiance();
      holes[k] = p.hole_mask();
      for (int e = 0; e < 2; ++e) gbuffers[k][e] = p.gbuffer_of(e);
    }
    const std::string what = std::string(to_string(c.kind)) + ", " + std::to_string(c.devices) + " device(s), " +
                             to_string(c.kernel) + ", " + c.scene->scene.name;
    EXPECT_GT(fused_ops, 0) << what << ": no path trace wrote the G-buffer";
    if (c.kind != PipelineKind::Mono) {
      EXPECT_GT(hole_fills_from_hits, 0) << what << ": no hole filling started from the G-buffer's hits";
      EXPECT_GT(std::count(holes[1].begin(), holes[1].end(), 1), 0) << what << ": no holes";
    }
    EXPECT_EQ(holes[0], holes[1]) << what;
    for (int e = 0; e < 2; ++e) {
      EXPECT_TRUE(same_gbuffer(gbuffers[0][e], gbuffers[1][e])) << what << ": G-buffer of eye " << e;
      EXPECT_TRUE(same_bits(images[0][e], images[1][e])) << what << ": image of eye " << e;
    }
    std::size_t hits = 0;
    for (const GBufferTexel& t : gbuffers[1][0]) hits += t.prim != PX_NO_HIT;
    EXPECT_GT(hits, gbuffers[1][0].size() / 4) << what << ": an empty G-buffer would match an empty one";
  }
}

TEST(StereoPipeline, RightEyeMatchesMonoPerPixelOnBackgroundAndWithinNoiseElsewhere) {
  // Per pixel, not in the mean: a left pixel whose centre sees the sky may owe part of its
  // radiance to the object covering a corner of its footprint; copied into the right eye that
  // paints a dotted ghost of the object's left-eye outline over the background. Reference: the
  // mono pipeline path traces the right eye (same seed, so holes are bit-identical to it; a
  // second seed gives the noise level).
  static LoadedScene loaded = [] {
    Scene s = silhouettes_scene();
    return LoadedScene{s, build_bvh(s.triangles), {}};
  }();
  const unsigned w = 120, h = 68, spp = 8;
  auto proposed = run(loaded, PipelineKind::Proposed, 2, w, h, spp, 5);
  auto mono = run(loaded, PipelineKind::Mono, 2, w, h, spp, 5);
  auto mono_b = run(loaded, PipelineKind::Mono, 2, w, h, spp, 6);
  auto lum = [](const ImageRGB& img, std::size_t i) {
    return (img.rgb[i * 3] + img.rgb[i * 3 + 1] + img.rgb[i * 3 + 2]) / 3.0;
  };
  int background = 0, background_off = 0, background_noise = 0, off = 0, noise = 0;
  for (std::size_t i = 0; i < proposed.holes.size(); ++i) {
    const double m = lum(mono.radiance[1], i), p = lum(proposed.radiance[1], i), b = lum(mono_b.radiance[1], i);
    const bool p_off = std::abs(p - m) > 0.1 * m, b_off = std::abs(b - m) > 0.1 * m;
    if (proposed.gright[i].material_class == PX_CLASS_MISS) {
      // Background pixels whose footprint holds only the sky: two mono seeds agree to 1%
      // (those the object covers in part are noisy in mono too, and holes here anyway).
      if (std::abs(b - m) > 0.01 * m) {
        ++background_noise;
        continue;
      }
      ++background;
      background_off += p_off;
    } else {
      off += p_off;
      noise += b_off;
    }
  }
  std::printf("[ measure  ] background %d px (+%d partly covered): %d off by >10%%; surfaces: %d vs mono-vs-mono %d\n",
              background, background_noise, background_off, off, noise);
  EXPECT_GT(background, 1000);
  EXPECT_EQ(background_off, 0) << "background pixels differ from the path-traced right eye";
  // Surfaces: reprojected pixels carry the left eye's noise instead of the right's, no more.
  EXPECT_LE(off, 1.25 * noise + 10);
  int blocks = 0;
  const double diff = reprojected_block_mse(proposed.radiance[1], mono.radiance[1], proposed.holes, &blocks);
  const double floor = reprojected_block_mse(mono_b.radiance[1], mono.radiance[1], proposed.holes, &blocks);
  EXPECT_LT(diff, 3.0 * floor + 1e-7);
}

TEST(StereoPipeline, ReprojectionEqualsPathTracingInExpectation) {
  // Diffuse scene, many samples: the reprojected right eye and the path-traced right eye
  // (mono) differ by noise only. Noise floor: two mono renders with different seeds. At frames
  // whose jitter point (pixel_jitter.h) lies off the pixel centre in x, where reprojection must
  // take it out of the left eye's pixel coordinates: frame 0 (0.5, 1/3), 2 (0.75, 1/9) and
  // 5 (0.375, 2/9).
  static LoadedScene cornell = load_and_build("cornell", true);
  const unsigned w = 64, h = 48, spp = 64;
  for (unsigned frame : {0u, 2u, 5u}) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    auto proposed = run(cornell, PipelineKind::Proposed, 2, w, h, spp, 1, frame);
    auto mono_a = run(cornell, PipelineKind::Mono, 2, w, h, spp, 2, frame);
    auto mono_b = run(cornell, PipelineKind::Mono, 2, w, h, spp, 3, frame);
    int blocks = 0;
    const double noise = reprojected_block_mse(mono_a.radiance[1], mono_b.radiance[1], proposed.holes, &blocks);
    const double diff = reprojected_block_mse(proposed.radiance[1], mono_a.radiance[1], proposed.holes, &blocks);
    std::printf("[ measure  ] frame %u: reprojected vs path traced %.3g, path traced vs path traced %.3g\n", frame,
                diff, noise);
    EXPECT_GT(blocks, 50);
    // Reprojection adds the left estimate's own noise and a half-pixel resampling blur.
    EXPECT_LT(diff, 3.0 * noise + 1e-7) << "noise floor " << noise << " over " << blocks << " blocks";
  }
}

// ---- stage 8 ----

TEST(Tonemap, BytesAreTheCorrectlyRoundedSrgbEncodingAndNonFinitePixelsAreCounted) {
  // The kernel's threshold search against the sRGB curve written out here in double precision:
  // every byte must be round(255 * srgb(exposure * c)), values on both sides of every step.
  auto srgb = [](double c) {
    c = std::clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
  };
  auto inverse = [](double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); };
  std::vector<float> values;
  for (int k = 1; k < 256; ++k) {
    const float edge = static_cast<float>(inverse((k - 0.5) / 255.0));
    float c = edge;
    for (int s = 0; s < 4; ++s) c = std::nextafter(c, 0.0f);
    for (int s = 0; s < 9; ++s, c = std::nextafter(c, 2.0f)) values.push_back(c);
  }
  for (int i = 0; i <= 4000; ++i) values.push_back(1.5f * static_cast<float>(i) / 4000.0f);
  for (float v : {-1.0f, -0.0f, 0.0f, 1e-9f, 1.0f, 1.0000001f, 7.0f, 3e38f}) values.push_back(v);
  const std::size_t finite = values.size();
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<cl_float4> pixels;
  for (std::size_t i = 0; i < finite; ++i)
    pixels.push_back({{values[i], values[(i + 7) % finite], values[(i * 13) % finite], 1.0f}});
  pixels.push_back({{inf, 0.5f, 0.5f, 1.0f}});
  pixels.push_back({{0.5f, nan, 0.5f, 1.0f}});
  pixels.push_back({{0.5f, 0.5f, -inf, 1.0f}});

  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  const auto& queue = set.devices()[0].queue;
  const auto n = static_cast<cl_uint>(pixels.size());
  const auto table = srgb8_thresholds();
  cl::Buffer radiance(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, n * sizeof(cl_float4), pixels.data());
  cl::Buffer thresholds(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof(table),
                        const_cast<float*>(table.data()));
  cl::Buffer rgba(set.context(), CL_MEM_WRITE_ONLY, n * sizeof(cl_uchar4));
  cl_uint zero = 0;
  cl::Buffer bad(set.context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, sizeof(cl_uint), &zero);
  for (float exposure : {1.0f, 0.37f}) {
    cl::Kernel k(set.program("pipeline/tonemap.cl"), "tonemap");
    k.setArg(0, rgba);
    k.setArg(1, radiance);
    k.setArg(2, cl_uint(0));
    k.setArg(3, n);
    k.setArg(4, exposure);
    k.setArg(5, bad);
    k.setArg(6, thresholds);
    launch_1d(queue, k, n);
    std::vector<cl_uchar4> out(n);
    queue.enqueueReadBuffer(rgba, CL_TRUE, 0, n * sizeof(cl_uchar4), out.data());
    for (std::size_t i = 0; i < finite; ++i)
      for (int c = 0; c < 3; ++c) {
        const double v = static_cast<double>(exposure * pixels[i].s[c]);  // the kernel's float product
        ASSERT_EQ(int(out[i].s[c]), int(std::lround(255.0 * srgb(v))))
            << "value " << pixels[i].s[c] << " x " << exposure;
      }
    for (std::size_t i = finite; i < n; ++i)
      for (int c = 0; c < 3; ++c) EXPECT_EQ(int(out[i].s[c]), 0) << "non-finite pixel " << i << " is written black";
  }
  cl_uint counted = 0;
  queue.enqueueReadBuffer(bad, CL_TRUE, 0, sizeof(cl_uint), &counted);
  EXPECT_EQ(counted, 2u * 3u);
}

}  // namespace
}  // namespace px
