// bench_trace: the OpenCL traversal kernel against Embree's rtcIntersect1 on identical ray
// sets, side by side in one process (Embree on the same rays is the practical limit for
// single-ray traversal on a CPU, so the kernel's rate is reported as a ratio to it).
//
// Ray sets: (1) primary rays of the scene camera's left eye, in image order (coherent);
// (2) one bounce: cosine-distributed diffuse rays from the primary hits, leaving from the
// kernels' offset origins (incoherent). Each is timed `--repeats` times; medians are printed.
// Alpha cut-outs are off on both sides, so both trace exactly the same geometry.
//
//   build/bench_trace --scene atrium --width 640 --height 360 --devices 1 --repeats 7 [--csv F]
#include "app/guarded_main.h"
#include "app/scene_setup.h"
#include "bench_common.h"
#include "bvh/embree_reference.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/stereo_camera.h"
#include "scene/primitives.h"
#include "trace/ray_batch_tracer.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <thread>

namespace {

using clock_type = std::chrono::steady_clock;
using px::bench::median;

std::vector<px::Ray> primary_rays(const px::Scene& scene, unsigned w, unsigned h) {
  const auto cam = px::make_eye_camera(px::evaluate_camera(scene, 0.0f), px::Eye::Left, scene.ipd_units(), w, h);
  const glm::vec3 f(cam.forward[0], cam.forward[1], cam.forward[2]);
  const glm::vec3 r(cam.right[0], cam.right[1], cam.right[2]);
  const glm::vec3 u(cam.up[0], cam.up[1], cam.up[2]);
  std::vector<px::Ray> rays;
  rays.reserve(static_cast<std::size_t>(w) * h);
  for (unsigned y = 0; y < h; ++y)
    for (unsigned x = 0; x < w; ++x) {
      const float sx = ((x + 0.5f) / w * 2.0f - 1.0f) * cam.tan_half_fov_y * cam.aspect;
      const float sy = (1.0f - (y + 0.5f) / h * 2.0f) * cam.tan_half_fov_y;
      const glm::vec3 d = glm::normalize(f + sx * r + sy * u);
      px::Ray ray{};
      for (int i = 0; i < 3; ++i) {
        ray.org[i] = cam.origin[i];
        ray.dir[i] = d[i];
      }
      ray.tmin = 0.0f;
      ray.tmax = INFINITY;
      rays.push_back(ray);
    }
  return rays;
}

// Cosine-weighted directions around each primary hit's geometric normal (facing the viewer).
std::vector<px::Ray> bounce_rays(const px::Scene& scene, const std::vector<px::Ray>& primary,
                                 const std::vector<px::Hit>& hits, px::RayBatchTracer& tracer) {
  std::vector<glm::vec3> points, normals;
  for (std::size_t i = 0; i < hits.size(); ++i) {
    if (hits[i].prim == PX_NO_HIT) continue;
    const auto& t = scene.triangles[hits[i].prim];
    const float w = 1.0f - hits[i].u - hits[i].v;
    points.push_back(w * t.p[0] + hits[i].u * t.p[1] + hits[i].v * t.p[2]);
    glm::vec3 n = px::geometric_normal(t);
    if (glm::dot(n, glm::vec3(primary[i].dir[0], primary[i].dir[1], primary[i].dir[2])) > 0.0f) n = -n;
    normals.push_back(n);
  }
  auto origins = tracer.offset_origins(points, normals);
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<px::Ray> rays;
  for (std::size_t i = 0; i < origins.size(); ++i) {
    const glm::vec3 n = normals[i];
    const glm::vec3 a = std::abs(n.x) > 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    const glm::vec3 t = glm::normalize(glm::cross(a, n)), b = glm::cross(n, t);
    const float r = std::sqrt(u01(rng)), phi = 6.2831853f * u01(rng);
    const glm::vec3 d = glm::normalize(r * std::cos(phi) * t + r * std::sin(phi) * b +
                                       std::sqrt(std::max(0.0f, 1.0f - r * r)) * n);
    px::Ray ray{};
    for (int k = 0; k < 3; ++k) {
      ray.org[k] = origins[i][k];
      ray.dir[k] = d[k];
    }
    ray.tmin = 0.0f;
    ray.tmax = INFINITY;
    rays.push_back(ray);
  }
  return rays;
}

struct Row {
  std::string scene, set;
  std::size_t rays = 0;
  double kernel_mrays = 0, kernel_wall_mrays = 0, embree_mrays = 0, embree1_mrays = 0;
  int mismatches = 0;
};

Row measure(const std::string& scene_name, const std::string& set_name, const std::vector<px::Ray>& rays,
            px::RayBatchTracer& tracer, const px::EmbreeReference& embree, int repeats, int threads) {
  Row row{scene_name, set_name, rays.size()};
  std::vector<double> k_ms, kw_ms, e_ms, e1_ms;
  std::vector<px::Hit> khits, ehits;
  khits = tracer.closest(rays);  // warm-up: kernel compilation, first-touch of buffers
  for (int i = 0; i < repeats; ++i) {
    auto t0 = clock_type::now();
    khits = tracer.closest(rays);
    kw_ms.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
    k_ms.push_back(tracer.last_kernel_ms());
    t0 = clock_type::now();
    embree.intersect_all(rays, ehits, threads);
    e_ms.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
    t0 = clock_type::now();
    embree.intersect_all(rays, ehits, 1);
    e1_ms.push_back(std::chrono::duration<double, std::milli>(clock_type::now() - t0).count());
  }
  for (std::size_t i = 0; i < rays.size(); ++i)
    if ((khits[i].prim == PX_NO_HIT) != (ehits[i].prim == PX_NO_HIT) ||
        (khits[i].prim != ehits[i].prim && std::abs(khits[i].t - ehits[i].t) > 1e-4f * std::max(1.0f, ehits[i].t)))
      ++row.mismatches;
  const double mr = static_cast<double>(rays.size()) * 1e-3;  // rays/ms -> Mrays/s
  row.kernel_mrays = mr / median(k_ms);
  row.kernel_wall_mrays = mr / median(kw_ms);
  row.embree_mrays = mr / median(e_ms);
  row.embree1_mrays = mr / median(e1_ms);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_trace: OpenCL BVH traversal vs Embree rtcIntersect1 on the same rays"};
  std::vector<std::string> scenes{"cornell", "atrium"};
  unsigned width = 640, height = 360;
  int devices = 1, repeats = 7;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::string csv;
  app.add_option("--scene", scenes, "scenes to measure (repeatable)")->capture_default_str();
  app.add_option("--width", width)->capture_default_str();
  app.add_option("--height", height)->capture_default_str();
  app.add_option("--devices", devices, "OpenCL devices the rays are split across")->capture_default_str();
  app.add_option("--repeats", repeats, "timed repetitions (median reported)")->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--threads", threads, "Embree threads (std::thread chunks)")->capture_default_str();
  app.add_option("--csv", csv, "also write the table as CSV");
  CLI11_PARSE(app, argc, argv);

  return px::run_guarded([&]() -> int {
    std::vector<Row> rows;
    for (const auto& name : scenes) {
      auto loaded = px::load_and_build(name);
      // Pure geometry on both sides: Embree's reference has no alpha-test filter, so the kernel's
      // cut-outs are switched off too (they are tested in test_trace_kernels).
      for (auto& m : loaded.scene.materials) m.alpha_texture = -1;
      px::EmbreeReference embree(loaded.scene.triangles);
      auto set = px::DeviceSet::create({devices, px::DeviceMode::Auto, ""});
      std::fprintf(stderr, "[bench] %d device(s), %s mode: %s\n", set.size(), px::to_string(set.mode()),
                   set.devices()[0].description.c_str());
      px::DeviceScene ds(set, loaded.scene, loaded.bvh);
      px::RayBatchTracer tracer(set, ds);
      auto primary = primary_rays(loaded.scene, width, height);
      auto phits = tracer.closest(primary);
      auto bounce = bounce_rays(loaded.scene, primary, phits, tracer);
      rows.push_back(measure(name, "primary", primary, tracer, embree, repeats, threads));
      rows.push_back(measure(name, "diffuse-bounce", bounce, tracer, embree, repeats, threads));
    }
    std::printf("\n%-10s %-15s %9s %12s %12s %12s %12s %8s %6s\n", "scene", "rays", "count", "kernel", "kernel+io",
                "embree", "embree-1t", "ratio", "diff");
    std::printf("%-10s %-15s %9s %12s %12s %12s %12s %8s %6s\n", "", "", "", "Mrays/s", "Mrays/s",
                ("Mrays/s " + std::to_string(threads) + "t").c_str(), "Mrays/s", "k/e", "");
    for (const auto& r : rows)
      std::printf("%-10s %-15s %9zu %12.2f %12.2f %12.2f %12.2f %8.3f %6d\n", r.scene.c_str(), r.set.c_str(), r.rays,
                  r.kernel_mrays, r.kernel_wall_mrays, r.embree_mrays, r.embree1_mrays, r.kernel_mrays / r.embree_mrays,
                  r.mismatches);
    std::printf("\nmedians of %d runs; kernel = device time from profiling events, kernel+io = host wall time "
                "including ray upload and hit download; ratio = kernel / embree (%d threads); diff = rays whose "
                "closest hit differs from Embree's\n",
                repeats, threads);
    if (!csv.empty()) {
      std::ofstream out(csv);
      out << "scene,rays,count,kernel_mrays,kernel_io_mrays,embree_mrays,embree_1t_mrays,ratio,mismatches\n";
      for (const auto& r : rows)
        out << r.scene << ',' << r.set << ',' << r.rays << ',' << r.kernel_mrays << ',' << r.kernel_wall_mrays << ','
            << r.embree_mrays << ',' << r.embree1_mrays << ',' << r.kernel_mrays / r.embree_mrays << ','
            << r.mismatches << '\n';
    }
    return 0;
  });
}
