// bench_bvh_build: build_bvh (with and without spatial splits, and with splits on trial) against Embree's own BVH build
// of the same triangles (an RTCScene with one triangle geometry, rtcCommitScene), side by side in one process. Embree's
// scene build is the reference for what a build of this input should cost on this machine: `high`
// (RTC_BUILD_QUALITY_HIGH, its spatial-split builder) is the counterpart of build_bvh with splits, `medium` (binned
// SAH) of build_bvh without.
//
// Scenes: any scene spec load_scene accepts (cornell, atrium, a file), and `slivers`: N long
// thin triangles all crossing the unit cube (a user's file of ~101k overlapping slivers once
// took 14 s to build). The builds of one scene are interleaved, round after round, so
// load from other processes on a shared machine hits them alike; medians are printed.
//
// Speed against quality: the SAH cost of each tree, and (unless --no-trace) the trace speed of
// the split and the binned tree of every scene with a camera (not `slivers`), on the same rays
// (its primary rays and one diffuse bounce) with the traversal kernel on one OpenCL device,
// interleaved round after round.
//
//   build/bench_bvh_build --scene cornell --scene atrium --scene slivers --slivers 101000 --repeats 5
//   [--unbounded: also time spatial splits without the split budget] [--csv F]
//   [--no-trace] [--trace-width 320 --trace-height 180]
#include "app/guarded_main.h"
#include "bench_bvh_layout.h"
#include "bench_common.h"
#include "bvh/bvh_builder.h"
#include "bvh/bvh_layout.h"
#include "bvh/embree_reference.h"
#include "bvh/flat_bvh.h"
#include "bvh/wide_bvh.h"
#include "cl/device_set.h"
#include "ray_sets.h"
#include "render/device_scene.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"
#include "trace/ray_batch_tracer.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <random>
#include <stdexcept>
#include <utility>

namespace {

using clock_type = std::chrono::steady_clock;
using px::bench::bounce_rays;
using px::bench::median;
using px::bench::primary_rays;

// Embree's own build of the triangles: scene + geometry creation, copy, rtcCommitScene.
double embree_build_ms(const std::vector<px::SceneTriangle>& triangles, RTCBuildQuality quality) {
  RTCDevice device = px::embree_device();
  const auto t0 = clock_type::now();
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(scene, quality);
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(geometry, quality);
  const std::size_t n = triangles.size();
  auto* vertices = static_cast<float*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
  auto* indices = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
  if (!vertices || !indices) throw std::runtime_error("Embree: allocating geometry buffers failed");
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < 3; ++c) vertices[9 * i + 3 * k + c] = triangles[i].p[k][c];
      indices[3 * i + k] = static_cast<unsigned>(3 * i + k);
    }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene);
  const double ms = std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
  const std::string error = px::take_embree_error();
  rtcReleaseScene(scene);
  if (!error.empty()) throw std::runtime_error("Embree: " + error);
  return ms;
}

struct Row {
  std::string scene;
  std::size_t triangles = 0;
  double split_ms = 0, binned_ms = 0, high_ms = 0, medium_ms = 0, unbounded_ms = 0, trial_ms = 0;
  double collapse_ms = 0;  // the share of split_ms spent collapsing to the wide layout
  px::BvhBuildStats split, binned, unbounded, trial;
  // The last round's split and binned trees, which the trace speed measures.
  px::FlatBvh split_tree, binned_tree;
};

Row measure(const std::string& name, const std::vector<px::SceneTriangle>& tris, int repeats, bool with_unbounded,
            px::BvhLayout layout) {
  Row row;
  row.scene = name;
  row.triangles = tris.size();
  px::BvhBuildOptions split_options, binned_options;
  split_options.spatial_splits = true;
  binned_options.spatial_splits = false;
  // split and binned as asked at every size; trial: the large-scene rule (binned first, splits
  // tried on every 16th triangle) forced at every size, to check its prediction against both.
  split_options.split_trial_triangles = binned_options.split_trial_triangles = 0;
  px::BvhBuildOptions trial_options;
  trial_options.split_trial_triangles = 1;
  px::BvhBuildOptions unbounded_options = split_options;
  unbounded_options.split_calls_per_triangle = 0;
  std::vector<double> split_ms, binned_ms, high_ms, medium_ms, unbounded_ms, collapse_ms, trial_ms;
  for (int r = 0; r < repeats; ++r) {
    if (with_unbounded) {
      const px::FlatBvh unbounded = px::build_bvh(tris, unbounded_options, layout);
      unbounded_ms.push_back(unbounded.stats.build_ms);
      row.unbounded = unbounded.stats;
    }
    row.split_tree = px::build_bvh(tris, split_options, layout);
    split_ms.push_back(row.split_tree.stats.build_ms);
    collapse_ms.push_back(row.split_tree.stats.collapse_ms);
    row.split = row.split_tree.stats;
    row.binned_tree = px::build_bvh(tris, binned_options, layout);
    binned_ms.push_back(row.binned_tree.stats.build_ms);
    row.binned = row.binned_tree.stats;
    const px::FlatBvh trial = px::build_bvh(tris, trial_options, layout);
    trial_ms.push_back(trial.stats.build_ms);
    row.trial = trial.stats;
    high_ms.push_back(embree_build_ms(tris, RTC_BUILD_QUALITY_HIGH));
    medium_ms.push_back(embree_build_ms(tris, RTC_BUILD_QUALITY_MEDIUM));
    std::fprintf(stderr,
                 "[bench] %s round %d: split %.1f ms, binned %.1f ms, trial %.1f ms, embree high %.1f ms, "
                 "medium %.1f ms\n",
                 name.c_str(), r + 1, split_ms.back(), binned_ms.back(), trial_ms.back(), high_ms.back(),
                 medium_ms.back());
  }
  row.split_ms = median(split_ms);
  row.binned_ms = median(binned_ms);
  row.high_ms = median(high_ms);
  row.medium_ms = median(medium_ms);
  row.unbounded_ms = median(unbounded_ms);
  row.collapse_ms = median(collapse_ms);
  row.trial_ms = median(trial_ms);
  return row;
}

// Trace speed of the split and the binned tree of one scene, Mrays/s from the kernel's device
// time (medians), on the primary rays and one diffuse bounce; `differ`: rays whose closest hit
// is another triangle in the two trees (ties at equal distance may go either way).
struct TraceRow {
  std::string scene;
  double split_primary = 0, binned_primary = 0, split_bounce = 0, binned_bounce = 0;
  std::size_t primary_rays = 0, bounce_rays = 0;
  int differ = 0;
};

// `split` and `binned`: the scene's trees (measure()'s last round), moved onto the device.
TraceRow trace_speed(px::DeviceSet& set, const std::string& name, const px::Scene& scene, px::FlatBvh split,
                     px::FlatBvh binned, unsigned width, unsigned height, int repeats) {
  px::ensure_layout(split, set.bvh_layout());
  px::ensure_layout(binned, set.bvh_layout());
  const px::DeviceScene split_scene(set, scene, std::move(split)), binned_scene(set, scene, std::move(binned));
  px::RayBatchTracer split_tracer(set, split_scene), binned_tracer(set, binned_scene);
  TraceRow row;
  row.scene = name;
  const std::vector<px::Ray> primary = primary_rays(scene, width, height);
  const std::vector<px::Hit> hits = split_tracer.closest(primary);
  const std::vector<px::Ray> bounce = bounce_rays(scene, primary, hits, split_tracer);
  row.primary_rays = primary.size();
  row.bounce_rays = bounce.size();
  auto time = [&](const std::vector<px::Ray>& rays, double* split_mrays, double* binned_mrays) {
    std::vector<double> split_ms, binned_ms;
    std::vector<px::Hit> a = split_tracer.closest(rays), b = binned_tracer.closest(rays);  // warm-up
    for (std::size_t i = 0; i < rays.size(); ++i)
      if (a[i].prim != b[i].prim) ++row.differ;
    for (int r = 0; r < repeats; ++r) {
      split_tracer.closest(rays);
      split_ms.push_back(split_tracer.last_kernel_ms());
      binned_tracer.closest(rays);
      binned_ms.push_back(binned_tracer.last_kernel_ms());
    }
    *split_mrays = static_cast<double>(rays.size()) * 1e-3 / median(split_ms);
    *binned_mrays = static_cast<double>(rays.size()) * 1e-3 / median(binned_ms);
  };
  time(primary, &row.split_primary, &row.binned_primary);
  time(bounce, &row.split_bounce, &row.binned_bounce);
  std::fprintf(stderr, "[bench] %s traced: split %.2f / %.2f Mrays/s, binned %.2f / %.2f (primary / bounce)\n",
               name.c_str(), row.split_primary, row.split_bounce, row.binned_primary, row.binned_bounce);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_bvh_build: build_bvh vs Embree's own BVH build of the same triangles"};
  std::vector<std::string> scenes{"cornell", "atrium", "slivers"};
  std::size_t sliver_count = 101000;
  int repeats = 5;
  std::string csv;
  bool unbounded = false;
  app.add_flag("--unbounded", unbounded, "also time spatial splits without the split budget (the behaviour before it)");
  app.add_option("--scene", scenes, "scenes to measure (repeatable; `slivers` is generated)")->capture_default_str();
  app.add_option("--slivers", sliver_count, "triangles in the `slivers` scene")->capture_default_str();
  app.add_option("--repeats", repeats, "timed rounds (median reported)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--csv", csv, "also write the table as CSV");
  std::optional<px::BvhLayout> requested;  // --bvh-layout: the trees are collapsed into it and traced in it
  px::bench::add_bvh_layout_flag(app, requested);
  bool no_trace = false;
  unsigned trace_width = 320, trace_height = 180;
  app.add_flag("--no-trace", no_trace, "skip the trace speed of the split and binned trees");
  app.add_option("--trace-width", trace_width, "primary rays per row for the trace speed")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  app.add_option("--trace-height", trace_height, "rows of primary rays for the trace speed")
      ->check(CLI::Range(1u, 16384u))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  return px::run_guarded([&]() -> int {
    std::vector<Row> rows;
    std::vector<TraceRow> traces;
    std::optional<px::DeviceSet> set;
    // Every tree is collapsed into the layout the device traces (the build times include it).
    px::BvhLayout layout = requested.value_or(px::bvh_layout_for(/*all_gpus=*/false));
    if (!no_trace) {
      set.emplace(px::DeviceSet::create({1, px::DeviceMode::Auto, "", requested}));
      layout = set->bvh_layout();
    }
    for (const auto& name : scenes) {
      std::vector<px::SceneTriangle> tris;
      px::Scene scene;
      if (name == "slivers") {
        px::append_slivers(tris, sliver_count, 14);
      } else {
        scene = px::load_scene(name);
        tris = scene.triangles;
      }
      embree_build_ms(tris, RTC_BUILD_QUALITY_HIGH);  // warm-up: TBB threads, first-touch
      rows.push_back(measure(name, tris, repeats, unbounded, layout));
      Row& row = rows.back();
      if (set && name != "slivers")
        traces.push_back(trace_speed(*set, name, scene, std::move(row.split_tree), std::move(row.binned_tree),
                                     trace_width, trace_height, repeats));
    }
    std::printf("\n%-10s %8s | %10s %10s %10s %10s | %8s %8s | %9s %9s %9s %6s %9s %8s\n", "scene", "tris", "px split",
                "px binned", "emb high", "emb med", "split/hi", "bin/med", "SAH split", "SAH bin", "refs/tri", "depth",
                "calls/tri", "fallback");
    for (const auto& r : rows)
      std::printf("%-10s %8zu | %10.1f %10.1f %10.1f %10.1f | %8.2f %8.2f | %9.2f %9.2f %9.3f %6d %9.1f %8s\n",
                  r.scene.c_str(), r.triangles, r.split_ms, r.binned_ms, r.high_ms, r.medium_ms, r.split_ms / r.high_ms,
                  r.binned_ms / r.medium_ms, r.split.sah_cost, r.binned.sah_cost,
                  double(r.split.leaf_triangles) / double(r.triangles), r.split.depth,
                  double(r.split.split_calls) / double(r.triangles), r.split.split_budget_exceeded ? "binned" : "-");
    std::printf(
        "\nbuild ms, medians of %d interleaved rounds; px = build_bvh (validation not "
        "included), emb = Embree rtcCommitScene of one triangle geometry at build quality "
        "high (spatial splits) / medium (binned SAH); refs/tri = leaf references per scene "
        "triangle with spatial splits; calls/tri = split-callback calls per triangle of the (last) spatial-split "
        "attempt; fallback = binned: the split budget ran out and build_bvh rebuilt with binned SAH (so px split "
        "includes the cancelled attempt)\n",
        repeats);
    std::printf("\nBVH layout %s: px split/binned include collapsing the binary tree into it:\n",
                px::to_string(layout));
    for (const auto& r : rows)
      std::printf("%-10s collapse %.2f ms of px split %.1f ms (%.1f%%)\n", r.scene.c_str(), r.collapse_ms, r.split_ms,
                  r.split_ms > 0 ? 100.0 * r.collapse_ms / r.split_ms : 0.0);
    std::printf(
        "\nspatial splits on trial (the rule for scenes of %zu triangles or more, forced here): binned "
        "first, splits tried on every 16th triangle, the scene rebuilt with them if they gain %.0f%% there\n",
        px::BvhBuildOptions{}.split_trial_triangles, 100.0 * px::BvhBuildOptions{}.split_min_gain);
    std::printf("%-10s %10s %9s %10s %10s %10s %9s %9s\n", "scene", "trial ms", "trial/hi", "sampled", "gain there",
                "gain whole", "splits?", "SAH");
    for (const auto& r : rows)
      std::printf("%-10s %10.1f %9.2f %10zu %9.1f%% %9.1f%% %9s %9.2f\n", r.scene.c_str(), r.trial_ms,
                  r.trial_ms / r.high_ms, r.trial.split_trial_sampled, 100.0 * r.trial.split_trial_gain,
                  r.binned.sah_cost > 0 ? 100.0 * (1.0 - r.split.sah_cost / r.binned.sah_cost) : 0.0,
                  r.trial.split_trial_taken ? "yes" : "no", r.trial.sah_cost);
    if (unbounded) {
      std::printf("\n%-10s %12s %12s %10s %11s %11s\n", "scene", "unbounded ms", "bounded ms", "emb high", "unbnd/high",
                  "bound/high");
      for (const auto& r : rows)
        std::printf(
            "%-10s %12.1f %12.1f %10.1f %11.2f %11.2f   (unbounded: SAH %.2f, %.1f "
            "calls/tri, refs/tri %.3f)\n",
            r.scene.c_str(), r.unbounded_ms, r.split_ms, r.high_ms, r.unbounded_ms / r.high_ms, r.split_ms / r.high_ms,
            r.unbounded.sah_cost, double(r.unbounded.split_calls) / double(r.triangles),
            double(r.unbounded.leaf_triangles) / double(r.triangles));
    }
    if (!traces.empty()) {
      std::printf(
          "\ntrace speed of the two trees (%s layout, one device, %ux%u primary rays and one diffuse bounce; "
          "Mrays/s from device time, medians of %d):\n",
          px::to_string(set->bvh_layout()), trace_width, trace_height, repeats);
      std::printf("%-10s %9s %9s | %10s %10s %8s | %10s %10s %8s | %7s\n", "scene", "SAH split", "SAH bin",
                  "split prim", "bin prim", "split/bin", "split bnc", "bin bnc", "split/bin", "differ");
      for (const auto& t : traces) {
        const auto it = std::find_if(rows.begin(), rows.end(), [&](const Row& r) { return r.scene == t.scene; });
        std::printf("%-10s %9.2f %9.2f | %10.2f %10.2f %8.3f | %10.2f %10.2f %8.3f | %7d\n", t.scene.c_str(),
                    it->split.sah_cost, it->binned.sah_cost, t.split_primary, t.binned_primary,
                    t.split_primary / t.binned_primary, t.split_bounce, t.binned_bounce,
                    t.split_bounce / t.binned_bounce, t.differ);
      }
      std::printf(
          "differ: rays (primary and bounce) whose closest hit is another triangle in the two trees: "
          "ties at equal distance\n");
    }
    if (!csv.empty()) {
      std::ofstream out(csv);
      out << "scene,triangles,px_split_ms,px_binned_ms,embree_high_ms,embree_medium_ms,"
             "split_over_high,binned_over_medium,sah_split,sah_binned,refs_per_triangle,depth,"
             "split_calls_per_triangle,split_budget_exceeded,trial_ms,trial_sampled,trial_gain,"
             "trial_took_splits,sah_trial\n";
      for (const auto& r : rows)
        out << r.scene << ',' << r.triangles << ',' << r.split_ms << ',' << r.binned_ms << ',' << r.high_ms << ','
            << r.medium_ms << ',' << r.split_ms / r.high_ms << ',' << r.binned_ms / r.medium_ms << ','
            << r.split.sah_cost << ',' << r.binned.sah_cost << ','
            << double(r.split.leaf_triangles) / double(r.triangles) << ',' << r.split.depth << ','
            << double(r.split.split_calls) / double(r.triangles) << ',' << r.split.split_budget_exceeded << ','
            << r.trial_ms << ',' << r.trial.split_trial_sampled << ',' << r.trial.split_trial_gain << ','
            << r.trial.split_trial_taken << ',' << r.trial.sah_cost << '\n';
    }
    return 0;
  });
}
