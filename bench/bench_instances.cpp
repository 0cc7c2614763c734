// bench_instances: what instances (a mesh stored once, placed by a two-level BVH) cost and save.
//
// (a) Per-frame top-level cost: if instances moved, each frame would rebuild the top level
//     and re-send the instance buffer (instance_buffer_words: header, top-level nodes and one
//     record per instance). Median time of build_top_level alone and of instance_buffer_words
//     as a whole, and the bytes that buffer holds, at N instances of one mesh.
// (b) Trace speed: RayBatchTracer::closest on the two-level scene against the same scene
//     flattened (flatten_instances: world-space copies, one BVH), same random rays, one
//     device, timed interleaved in one process. Medians in Mrays/s and their ratio, and how
//     well the two agree: the fraction of rays with the same hit/miss answer and the largest
//     relative difference in t where both hit.
// (c) Device memory: DeviceScene::bytes_in_context at a few instance counts of the same mesh,
//     and each count's ratio to the first.
//
//   build/bench_instances
//   build/bench_instances --counts 1,1000,100000 --repeats 9 --rays 400000 --trace-repeats 7
#include "app/guarded_main.h"
#include "bench_bvh_layout.h"
#include "bench_common.h"
#include "bvh/bvh_layout.h"
#include "bvh/scene_bvhs.h"
#include "bvh/top_level_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "scene/instancing.h"
#include "scene/primitives.h"
#include "trace/ray_batch_tracer.h"

#include <CLI/CLI.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

using namespace px;
using clock_type = std::chrono::steady_clock;
using bench::median;

double ms_since(clock_type::time_point t0) {
  return std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
}

std::vector<std::size_t> parse_counts(const std::string& list) {
  std::vector<std::size_t> out;
  std::stringstream in(list);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(std::stoul(item));
  return out;
}

glm::vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<float> n;
  glm::vec3 v;
  do v = glm::vec3(n(rng), n(rng), n(rng));
  while (glm::dot(v, v) < 1e-6f);
  return glm::normalize(v);
}

// `count` instances of one icosphere (20 * 4^subdivisions triangles, plus a fin so that it is
// not symmetric) on a square grid of spacing 2, each turned about a random axis and scaled
// non-uniformly, over a ground quad (the world's own two triangles) unless `ground` is false.
Scene instanced_field(std::size_t count, int subdivisions, bool ground, std::uint32_t seed) {
  Scene s;
  s.name = "instance field";
  Material grey, red;
  grey.diffuse = glm::vec3(0.6f);
  red.diffuse = glm::vec3(0.7f, 0.3f, 0.2f);
  s.materials = {grey, red};
  const std::size_t side = std::max<std::size_t>(1, std::size_t(std::ceil(std::sqrt(double(count)))));
  const float half = float(side);  // grid of spacing 2 centred on the origin
  if (ground)
    append_quad(s.triangles, {-half - 1, -1.0f, -half - 1}, {half + 1, -1.0f, -half - 1}, {half + 1, -1.0f, half + 1},
                {-half - 1, -1.0f, half + 1}, 0);
  SceneInstancing in;
  in.world_triangles = s.triangles.size();
  InstancedMesh mesh;
  mesh.first = s.triangles.size();
  append_icosphere(s.triangles, glm::vec3(0.0f), 0.6f, subdivisions, 1);
  append_triangle(s.triangles, {0.0f, 0.5f, 0.0f}, {0.9f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.9f}, 1);
  mesh.count = s.triangles.size() - mesh.first;
  in.meshes.push_back(mesh);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), sc(0.6f, 1.1f);
  for (std::size_t i = 0; i < count; ++i) {
    const glm::vec3 at(2.0f * float(i % side) - half + 1.0f, 0.0f, 2.0f * float(i / side) - half + 1.0f);
    glm::mat4 m = glm::translate(glm::mat4(1.0f), at + 0.2f * glm::vec3(u(rng), u(rng), u(rng)));
    m = glm::rotate(m, 3.14159265f * u(rng), random_unit(rng));
    m = glm::scale(m, glm::vec3(sc(rng), sc(rng), sc(rng)));
    in.instances.push_back({0, m});
  }
  s.instancing = std::move(in);
  s.sky.enabled = true;
  s.sky.zenith = glm::vec3(1.0f);
  s.sky.horizon = glm::vec3(0.8f);
  s.sky.ground = glm::vec3(0.3f);
  s.camera.position = glm::vec3(0.0f, half + 2.0f, 2.0f * half + 4.0f);
  s.camera.target = glm::vec3(0.0f);
  return s;
}

// Random rays: origins uniform in the scene's box grown by 20 %, directions uniform.
std::vector<Ray> random_rays(const Scene& flat, std::size_t count, std::uint32_t seed) {
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const SceneTriangle& t : flat.triangles)
    for (const glm::vec3& p : t.p) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const glm::vec3 c = 0.5f * (lo + hi), h = 0.6f * (hi - lo);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Ray> rays(count);
  for (Ray& r : rays) {
    const glm::vec3 o = c + h * glm::vec3(u(rng), u(rng), u(rng)), d = random_unit(rng);
    for (int a = 0; a < 3; ++a) r.org[a] = o[a], r.dir[a] = d[a];
    r.tmin = 0.0f;
    r.tmax = INFINITY;
  }
  return rays;
}

void top_level_cost(const std::vector<std::size_t>& counts, int subdivisions, unsigned repeats) {
  std::printf("(a) per-frame top level: instances of one %d-triangle mesh, median of %u\n",
              20 * (1 << (2 * subdivisions)) + 1, repeats);
  std::printf("%10s %14s %18s %14s %12s %12s\n", "instances", "top nodes", "build_top_level ms", "buffer ms",
              "KiB/frame", "ns/instance");
  for (const std::size_t n : counts) {
    const Scene scene = instanced_field(n, subdivisions, false, 1);
    const std::vector<MeshPlacement> placements(scene.instancing.meshes.size());
    // The boxes build_top_level takes (instance_buffer_words computes them itself each call).
    const InstancedMesh& mesh = scene.instancing.meshes[0];
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (std::size_t i = mesh.first; i < mesh.first + mesh.count; ++i)
      for (const glm::vec3& p : scene.triangles[i].p) lo = glm::min(lo, p), hi = glm::max(hi, p);
    std::vector<InstanceBox> boxes;
    for (const MeshInstance& inst : scene.instancing.instances)
      boxes.push_back(place_box(lo, hi, inst.object_to_world));
    std::vector<double> build_ms, buffer_ms;
    std::size_t bytes = 0, nodes = 0;
    for (unsigned r = 0; r <= repeats; ++r) {  // r = 0: untimed warm-up
      auto t0 = clock_type::now();
      const TopLevelBvh top = build_top_level(boxes);
      const double b = ms_since(t0);
      t0 = clock_type::now();
      const std::vector<std::uint32_t> words = instance_buffer_words(scene, placements, 0);
      const double w = ms_since(t0);
      if (r == 0) continue;
      build_ms.push_back(b);
      buffer_ms.push_back(w);
      bytes = words.size() * 4;
      nodes = top.nodes.size();
    }
    const double w = median(buffer_ms);
    std::printf("%10zu %14zu %18.4f %14.4f %12.1f %12.1f\n", n, nodes, median(build_ms), w, double(bytes) / 1024.0,
                w * 1e6 / double(n));
  }
}

void trace_speed(DeviceSet& set, std::size_t instances, int subdivisions, std::size_t ray_count, unsigned repeats) {
  const Scene scene = instanced_field(instances, subdivisions, true, 2);
  Scene flat = scene;
  flatten_instances(flat);
  std::printf(
      "\n(b) trace: %zu instances of a %zu-triangle mesh + ground quad (%zu triangles stored, %zu drawn), "
      "%zu random rays, 1 device, layout %s, median of %u\n",
      instances, scene.instancing.meshes[0].count, scene.triangles.size(), flat.triangles.size(), ray_count,
      to_string(set.bvh_layout()), repeats);
  auto t0 = clock_type::now();
  DeviceScene inst_dev(set, scene, build_world_bvh(scene));
  const double inst_setup = ms_since(t0);
  t0 = clock_type::now();
  DeviceScene flat_dev(set, flat, build_world_bvh(flat));
  const double flat_setup = ms_since(t0);
  RayBatchTracer inst_tracer(set, inst_dev), flat_tracer(set, flat_dev);
  const std::vector<Ray> rays = random_rays(flat, ray_count, 3);
  std::vector<Hit> ih = inst_tracer.closest(rays), fh = flat_tracer.closest(rays);  // warm-up: builds kernels
  std::vector<double> inst_rate, flat_rate, inst_kernel, flat_kernel;
  for (unsigned r = 0; r < repeats; ++r) {  // interleaved
    t0 = clock_type::now();
    ih = inst_tracer.closest(rays);
    inst_rate.push_back(double(ray_count) / (ms_since(t0) * 1e3));
    inst_kernel.push_back(double(ray_count) / (inst_tracer.last_kernel_ms() * 1e3));
    t0 = clock_type::now();
    fh = flat_tracer.closest(rays);
    flat_rate.push_back(double(ray_count) / (ms_since(t0) * 1e3));
    flat_kernel.push_back(double(ray_count) / (flat_tracer.last_kernel_ms() * 1e3));
  }
  std::size_t agree = 0, both = 0, over = 0;
  double max_rel = 0.0, max_abs = 0.0, worst_t = 0.0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const bool a = ih[i].prim != PX_NO_HIT, b = fh[i].prim != PX_NO_HIT;
    agree += a == b ? 1u : 0u;
    if (!(a && b)) continue;
    ++both;
    const double rel = std::fabs(double(ih[i].t) - double(fh[i].t)) / std::max(double(fh[i].t), 1e-30);
    if (rel > max_rel) max_rel = rel, worst_t = fh[i].t;
    max_abs = std::max(max_abs, std::fabs(double(ih[i].t) - double(fh[i].t)) / std::max(double(fh[i].t), 1.0));
    over += rel > 1e-4 ? 1u : 0u;
  }
  std::printf("%12s %12s %16s %14s %14s %12s\n", "scene", "Mrays/s", "kernel Mrays/s", "setup ms", "device MiB",
              "ratio");
  const double mi = median(inst_rate), mf = median(flat_rate);
  std::printf("%12s %12.2f %16.2f %14.0f %14.2f %12.3f\n", "two-level", mi, median(inst_kernel), inst_setup,
              double(inst_dev.bytes_in_context()) / 1048576.0, mi / mf);
  std::printf("%12s %12.2f %16.2f %14.0f %14.2f %12.3f\n", "flattened", mf, median(flat_kernel), flat_setup,
              double(flat_dev.bytes_in_context()) / 1048576.0, 1.0);
  std::printf(
      "agreement: hit/miss same for %.6f of rays (%zu differ); both hit %zu: max |dt|/t %.3g (at t = %.3g), "
      "%zu over 1e-4; max |dt|/max(t, 1) %.3g\n",
      double(agree) / double(rays.size()), rays.size() - agree, both, max_rel, worst_t, over, max_abs);
}

void device_bytes(DeviceSet& set, const std::vector<std::size_t>& counts, int subdivisions) {
  std::printf("\n(c) device memory: bytes_in_context, instances of one %d-triangle mesh + ground quad\n",
              20 * (1 << (2 * subdivisions)) + 1);
  std::printf("%10s %16s %16s %14s %12s\n", "instances", "bytes", "instance bytes", "drawn tris", "ratio");
  double first = 0.0;
  for (const std::size_t n : counts) {
    const Scene scene = instanced_field(n, subdivisions, true, 4);
    const DeviceScene ds(set, scene, build_world_bvh(scene));
    const double b = double(ds.bytes_in_context());
    if (first == 0.0) first = b;
    std::printf("%10zu %16zu %16zu %14zu %12.3f\n", n, ds.bytes_in_context(), ds.instance_bytes(),
                drawn_triangle_count(scene), b / first);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "bench_instances: per-frame top-level cost, two-level vs flattened trace speed, device bytes of instances"};
  std::string counts = "1,1000,100000", byte_counts = "1,1024";
  unsigned repeats = 9, trace_repeats = 9;
  int top_subdiv = 3, trace_subdiv = 4, devices = 1;
  std::size_t trace_instances = 64, rays = 300000;
  bool skip_a = false, skip_b = false, skip_c = false;
  app.add_option("--counts", counts, "(a) comma list of instance counts")->capture_default_str();
  app.add_option("--repeats", repeats, "(a) timed repeats per count (after one untimed)")
      ->check(CLI::Range(1u, 10000u))
      ->capture_default_str();
  app.add_option("--mesh-subdiv", top_subdiv, "(a) icosphere subdivisions of the mesh (3: 1,281 triangles)")
      ->check(CLI::Range(0, 7))
      ->capture_default_str();
  app.add_option("--trace-instances", trace_instances, "(b) instances traced")
      ->check(CLI::Range(1, 1 << 20))
      ->capture_default_str();
  app.add_option("--trace-subdiv", trace_subdiv, "(b, c) icosphere subdivisions (4: 5,121 triangles)")
      ->check(CLI::Range(0, 7))
      ->capture_default_str();
  app.add_option("--rays", rays, "(b) random rays per trace")->check(CLI::Range(1, 1 << 26))->capture_default_str();
  app.add_option("--trace-repeats", trace_repeats, "(b) timed traces of each scene, interleaved (after one untimed)")
      ->check(CLI::Range(1u, 1000u))
      ->capture_default_str();
  app.add_option("--byte-counts", byte_counts, "(c) comma list of instance counts; ratios are to the first")
      ->capture_default_str();
  app.add_option("--devices", devices, "(b, c) OpenCL devices")->check(CLI::Range(1, 64))->capture_default_str();
  std::optional<BvhLayout> bvh_layout;
  bench::add_bvh_layout_flag(app, bvh_layout);
  app.add_flag("--skip-a", skip_a, "skip the top-level cost");
  app.add_flag("--skip-b", skip_b, "skip the trace comparison");
  app.add_flag("--skip-c", skip_c, "skip the device bytes");
  CLI11_PARSE(app, argc, argv);
  return run_guarded([&] {
    if (!skip_a) top_level_cost(parse_counts(counts), top_subdiv, repeats);
    if (skip_b && skip_c) return 0;
    DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", bvh_layout});
    if (!skip_b) trace_speed(set, trace_instances, trace_subdiv, rays, trace_repeats);
    if (!skip_c) device_bytes(set, parse_counts(byte_counts), trace_subdiv);
    return 0;
  });
}
