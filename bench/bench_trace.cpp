// bench_trace: the OpenCL traversal kernel against Embree's rtcIntersect1 on identical ray
// sets, side by side in one process (Embree on the same rays is the practical limit for
// single-ray traversal on a CPU, so the kernel's rate is reported as a ratio to it).
//
// Ray sets: (1) primary rays of the scene camera's left eye, in image order (coherent);
// (2) one bounce: cosine-distributed diffuse rays from the primary hits, leaving from the
// kernels' offset origins (incoherent). Each is timed `--repeats` times; medians are printed.
// Alpha cut-outs are off on both sides, so both trace exactly the same geometry.
//
// With several --layout values, each BVH node layout gets its own row, timed interleaved with
// the others and with Embree in the same process.
//
//   build/bench_trace --scene atrium --width 640 --height 360 --devices 1 --repeats 7 [--csv F]
//   build/bench_trace --layout binary --layout wide4 --layout wide8 --layout cwbvh
// Each layout's node memory (nodes, and the leaf blocks the wide layouts append) goes to stderr.
// --counters also traces each wide layout's ray sets once with a kernel built with
// PX_TRACE_COUNTERS (kernels/trace/traverse.h) and prints the mean nodes, leaf blocks, child
// boxes hit and stack pushes per ray (untimed).
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_common.h"
#include "ray_sets.h"
#include "bvh/embree_reference.h"
#include "bvh/wide_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/stereo_camera.h"
#include "scene/primitives.h"
#include "trace/ray_batch_tracer.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstring>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>
#include <thread>

namespace {

using clock_type = std::chrono::steady_clock;
using px::bench::bounce_rays;
using px::bench::median;
using px::bench::primary_rays;

// Bytes of the nodes proper and of the leaf blocks in the node buffer `layout` uploads.
std::pair<std::size_t, std::size_t> node_memory(const px::FlatBvh& bvh, px::BvhLayout layout) {
  switch (layout) {
    case px::BvhLayout::Binary: return {bvh.nodes.size() * sizeof(px::BvhNode), 0};
    case px::BvhLayout::Wide4: return {bvh.nodes4.size() * sizeof(px::Bvh4Node), 0};
    case px::BvhLayout::Wide8: return {bvh.nodes8.size() * sizeof(px::Bvh8Node), 0};
    case px::BvhLayout::Compressed8: return {bvh.cnodes.size() * sizeof(px::CompressedBvh8Node), 0};
  }
  return {0, 0};
}

struct Row {
  std::string scene, set, layout;
  std::size_t rays = 0;
  double kernel_mrays = 0, kernel_wall_mrays = 0, embree_mrays = 0, embree1_mrays = 0;
  double single_mrays = 0;  // the kernel with one ray a work-item (trace_closest)
  int mismatches = 0;
  int pair_diffs = 0;  // rays whose hit from the pair kernel differs in any bit from the single kernel's
  int passes = 1;      // times the set was traced back to back in each timed sample
};

// One tracer per BVH layout, all on the same rays; every repeat times each layout and Embree
// back to back, so machine noise hits them alike. A sample traces the set `passes` times in a row
// where one pass is shorter than `min_sample_ms` (every tracer and Embree the same number): a
// launch of a few milliseconds measures mostly the waking of the device's and Embree's threads
// (on a VM, of its virtual CPUs), which is not traversal (docs/measurements.md, "Short samples").
std::vector<Row> measure(const std::string& scene_name, const std::string& set_name, const std::vector<px::Ray>& rays,
                         std::vector<px::RayBatchTracer*>& tracers, const std::vector<px::BvhLayout>& layouts,
                         const px::EmbreeReference& embree, int repeats, int threads, double min_sample_ms) {
  const std::size_t n = tracers.size();
  std::vector<std::vector<double>> k_ms(n), kw_ms(n), k1_ms(n);
  std::vector<double> e_ms, e1_ms;
  std::vector<std::vector<px::Hit>> khits(n), k1hits(n);
  std::vector<px::Hit> ehits;
  // Warm-up, and the shortest pass of any tracer, which sets the passes a sample.
  double shortest_ms = 1e30;
  for (std::size_t l = 0; l < n; ++l) {
    khits[l] = tracers[l]->closest(rays);
    shortest_ms = std::min(shortest_ms, tracers[l]->last_kernel_ms());
    k1hits[l] = tracers[l]->closest_one_per_item(rays);
    shortest_ms = std::min(shortest_ms, tracers[l]->last_kernel_ms());
  }
  {
    const auto t0 = clock_type::now();
    embree.intersect_all(rays, ehits, threads);
    shortest_ms = std::min(shortest_ms, std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
  }
  const int passes = static_cast<int>(std::clamp(std::ceil(min_sample_ms / std::max(shortest_ms, 1e-3)), 1.0, 64.0));
  for (int i = 0; i < repeats; ++i) {
    for (std::size_t l = 0; l < n; ++l) {
      double kernel = 0.0, single = 0.0;
      const auto t0 = clock_type::now();
      for (int p = 0; p < passes; ++p) {
        khits[l] = tracers[l]->closest(rays);
        kernel += tracers[l]->last_kernel_ms();
      }
      kw_ms[l].push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
      k_ms[l].push_back(kernel);
      for (int p = 0; p < passes; ++p) {
        k1hits[l] = tracers[l]->closest_one_per_item(rays);
        single += tracers[l]->last_kernel_ms();
      }
      k1_ms[l].push_back(single);
    }
    auto t0 = clock_type::now();
    for (int p = 0; p < passes; ++p) embree.intersect_all(rays, ehits, threads);
    e_ms.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
    t0 = clock_type::now();
    for (int p = 0; p < passes; ++p) embree.intersect_all(rays, ehits, 1);
    e1_ms.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
  }
  const double mr = static_cast<double>(rays.size()) * passes * 1e-3;  // rays/ms -> Mrays/s
  std::vector<Row> rows;
  for (std::size_t l = 0; l < n; ++l) {
    Row row{scene_name, set_name, px::to_string(layouts[l]), rays.size()};
    row.passes = passes;
    for (std::size_t i = 0; i < rays.size(); ++i)
      if ((khits[l][i].prim == PX_NO_HIT) != (ehits[i].prim == PX_NO_HIT) ||
          (khits[l][i].prim != ehits[i].prim &&
           std::abs(khits[l][i].t - ehits[i].t) > 1e-4f * std::max(1.0f, ehits[i].t)))
        ++row.mismatches;
    for (std::size_t i = 0; i < rays.size(); ++i)
      if (std::memcmp(&khits[l][i], &k1hits[l][i], sizeof(px::Hit)) != 0) ++row.pair_diffs;
    row.kernel_mrays = mr / median(k_ms[l]);
    row.single_mrays = mr / median(k1_ms[l]);
    row.kernel_wall_mrays = mr / median(kw_ms[l]);
    row.embree_mrays = mr / median(e_ms);
    row.embree1_mrays = mr / median(e1_ms);
    rows.push_back(row);
  }
  return rows;
}

// Mean per-ray traversal counters of a PX_TRACE_COUNTERS kernel's hits (types in traverse.h).
void print_counters(const std::string& scene, const std::string& set, const char* layout,
                    const std::vector<px::Hit>& hits) {
  double sum[4] = {0, 0, 0, 0};
  for (const px::Hit& h : hits)
    for (int k = 0; k < 4; ++k) sum[k] += (h.inst >> (8 * k)) & 255u;
  const double n = std::max<double>(1.0, static_cast<double>(hits.size()));
  std::printf("counters %-10s %-15s %-7s nodes %.2f leaves %.2f child-hits %.2f pushes %.2f per ray\n", scene.c_str(),
              set.c_str(), layout, sum[0] / n, sum[1] / n, sum[2] / n, sum[3] / n);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_trace: OpenCL BVH traversal vs Embree rtcIntersect1 on the same rays"};
  std::vector<std::string> scenes{"cornell", "atrium"};
  unsigned width = 640, height = 360;
  int devices = 1, repeats = 7;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::string csv;
  std::vector<std::string> layout_names;
  app.add_option("--scene", scenes, "scenes to measure (repeatable)")->capture_default_str();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--devices", devices, "OpenCL devices the rays are split across")->capture_default_str();
  app.add_option("--repeats", repeats, "timed repetitions (median reported)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--threads", threads, "Embree threads (std::thread chunks)")->capture_default_str();
  app.add_option("--csv", csv, "also write the table as CSV");
  double min_sample_ms = 25.0;
  app.add_option("--min-sample-ms", min_sample_ms,
                 "a timed sample traces a ray set as many times in a row as it takes to last this long (0: once)")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  bool counters = false;
  app.add_flag("--counters", counters,
               "also print the wide layouts' mean nodes, leaf blocks, child hits and pushes per ray (a counting "
               "kernel build, untimed)");
  app.add_option("--layout", layout_names,
                 "BVH node layouts to trace, side by side (binary, wide4, wide8, cwbvh; repeatable; default: the "
                 "device type's)");
  CLI11_PARSE(app, argc, argv);

  return px::run_guarded([&]() -> int {
    std::vector<Row> rows;
    std::vector<px::BvhLayout> layouts;
    for (const auto& l : layout_names) layouts.push_back(px::parse_bvh_layout(l));
    // One device set per layout (the layout is the set's), used for every scene; without
    // --layout, one set in its own layout (by device type).
    std::vector<std::unique_ptr<px::DeviceSet>> sets;
    if (layouts.empty()) {
      sets.push_back(
          std::make_unique<px::DeviceSet>(px::DeviceSet::create({devices, px::DeviceMode::Auto, "", std::nullopt})));
      layouts.push_back(sets.back()->bvh_layout());
    } else {
      for (px::BvhLayout layout : layouts)
        sets.push_back(
            std::make_unique<px::DeviceSet>(px::DeviceSet::create({devices, px::DeviceMode::Auto, "", layout})));
    }
    const px::DeviceSet& first = *sets.front();
    std::fprintf(stderr, "[bench] %d device(s), %s mode: %s\n", first.size(), px::to_string(first.mode()),
                 first.devices()[0].description.c_str());
    for (const auto& name : scenes) {
      auto loaded = px::load_and_build(name, false, {}, false, layouts[0]);
      // Pure geometry on both sides: Embree's reference has no alpha-test filter, so the kernel's
      // cut-outs are switched off too (they are tested in test_trace_kernels).
      for (auto& m : loaded.scene.materials) m.alpha_texture = -1;
      px::EmbreeReference embree(loaded.scene.triangles);
      // Each layout's DeviceScene and tracer on that layout's set.
      std::vector<std::unique_ptr<px::DeviceScene>> scenes_per_layout;
      std::vector<std::unique_ptr<px::RayBatchTracer>> tracer_storage;
      std::vector<px::RayBatchTracer*> tracers;
      for (std::size_t l = 0; l < layouts.size(); ++l) {
        const px::BvhLayout layout = layouts[l];
        px::DeviceSet& set = *sets[l];
        px::ensure_layout(loaded.bvh, layout);
        auto [node_bytes, block_bytes] = node_memory(loaded.bvh, layout);
        if (layout != px::BvhLayout::Binary)
          block_bytes = px::device_wide_nodes(loaded.bvh, layout).size() * 4 - node_bytes;
        std::fprintf(stderr, "[bench] %s %s: nodes %.1f KiB, leaf blocks %.1f KiB\n", name.c_str(),
                     px::to_string(layout), node_bytes / 1024.0, block_bytes / 1024.0);
        scenes_per_layout.push_back(std::make_unique<px::DeviceScene>(set, loaded.scene, loaded.bvh));
        tracer_storage.push_back(std::make_unique<px::RayBatchTracer>(set, *scenes_per_layout.back()));
        tracers.push_back(tracer_storage.back().get());
        tracers.back()->closest(primary_rays(loaded.scene, 8, 8));  // builds this layout's kernels now
      }
      auto primary = primary_rays(loaded.scene, width, height);
      auto phits = tracers[0]->closest(primary);
      auto bounce = bounce_rays(loaded.scene, primary, phits, *tracers[0]);
      for (auto& r : measure(name, "primary", primary, tracers, layouts, embree, repeats, threads, min_sample_ms))
        rows.push_back(r);
      for (auto& r : measure(name, "diffuse-bounce", bounce, tracers, layouts, embree, repeats, threads, min_sample_ms))
        rows.push_back(r);
      for (std::size_t l = 0; counters && l < layouts.size(); ++l) {
        if (layouts[l] == px::BvhLayout::Binary) continue;
        px::RayBatchTracer counting(*sets[l], *scenes_per_layout[l], "-DPX_TRACE_COUNTERS=1");
        print_counters(name, "primary", px::to_string(layouts[l]), counting.closest(primary));
        print_counters(name, "diffuse-bounce", px::to_string(layouts[l]), counting.closest(bounce));
      }
    }
    std::printf("\n%-10s %-15s %-7s %9s %12s %12s %12s %12s %12s %8s %8s %6s %6s %6s\n", "scene", "rays", "layout",
                "count", "kernel", "kernel+io", "kernel-1", "embree", "embree-1t", "ratio", "ratio-1", "diff", "pair",
                "passes");
    std::printf("%-10s %-15s %-7s %9s %12s %12s %12s %12s %12s %8s %8s %6s %6s %6s\n", "", "", "", "", "Mrays/s",
                "Mrays/s", "Mrays/s", ("Mrays/s " + std::to_string(threads) + "t").c_str(), "Mrays/s", "k/e", "k1/e",
                "", "diff", "");
    for (const auto& r : rows)
      std::printf("%-10s %-15s %-7s %9zu %12.2f %12.2f %12.2f %12.2f %12.2f %8.3f %8.3f %6d %6d %6d\n", r.scene.c_str(),
                  r.set.c_str(), r.layout.c_str(), r.rays, r.kernel_mrays, r.kernel_wall_mrays, r.single_mrays,
                  r.embree_mrays, r.embree1_mrays, r.kernel_mrays / r.embree_mrays, r.single_mrays / r.embree_mrays,
                  r.mismatches, r.pair_diffs, r.passes);
    std::printf(
        "\nmedians of %d runs; kernel = device time from profiling events (on CPUs trace_closest_pairs: two "
        "rays a work-item, their walks in step), kernel+io = host wall time including ray upload and hit download, "
        "kernel-1 = the same walk one ray a work-item (trace_closest); ratio = kernel / embree (%d threads), "
        "ratio-1 = kernel-1 / embree; diff = rays whose closest hit differs from Embree's; pair diff = rays "
        "whose hit from the two kernels differs in any bit (0: the pairing changes no hit); passes = times each "
        "sample traced the set in a row (a sample lasts at least --min-sample-ms = %g ms)\n",
        repeats, threads, min_sample_ms);
    if (!csv.empty()) {
      std::ofstream out(csv);
      out << "scene,rays,layout,count,kernel_mrays,kernel_io_mrays,kernel_single_mrays,embree_mrays,embree_1t_mrays,"
             "ratio,ratio_single,mismatches,pair_diffs,passes\n";
      for (const auto& r : rows)
        out << r.scene << ',' << r.set << ',' << r.layout << ',' << r.rays << ',' << r.kernel_mrays << ','
            << r.kernel_wall_mrays << ',' << r.single_mrays << ',' << r.embree_mrays << ',' << r.embree1_mrays << ','
            << r.kernel_mrays / r.embree_mrays << ',' << r.single_mrays / r.embree_mrays << ',' << r.mismatches << ','
            << r.pair_diffs << ',' << r.passes << '\n';
    }
    return 0;
  });
}
