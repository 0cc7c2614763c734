// bench_animation: what a frame of an animated scene costs before it renders. N copies of a
// 12-triangle cube, each on its own node, all turning and sliding (one clip, 2N channels), are
// posed, their BVH refitted (or rebuilt, binned SAH, when the refit's SAH cost has grown too
// much), and the geometry rewritten on the devices, as SceneAnimator does between frames.
// Prints per N the median of each step, how many timed frames rebuilt, the bytes sent per
// frame, and the first update's full build beside them.
//
// Two ways, side by side per N: `posed` (every cube's triangles posed into the world's, one
// tree refitted over them: what an animated file's skins get, and everything with
// --instancing off) and `instances` (one cube mesh stored once, each node an instance: only
// the matrices change, the top level over them is rebuilt and the instance buffer rewritten;
// what the loader makes of rigid meshes on moving nodes).
//
//   build/bench_animation --counts 1,1000,100000 --frames 8 --devices 2
#include "app/guarded_main.h"
#include "bench_common.h"
#include "bvh/scene_bvhs.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/scene_animator.h"
#include "scene/scene_rig.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>

namespace {

using namespace px;

// N cubes on a square grid, one shared primitive, each node sliding 0.25 units and turning a
// quarter turn about y over 2 s.
Scene cube_field(std::size_t n, bool instances) {
  auto rig = std::make_shared<SceneRig>();
  rig->primitives.push_back(cube_primitive(0.4f));
  AnimationClip clip;
  clip.name = "field";
  clip.duration = 2.0;
  const std::size_t side = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(n))));
  for (std::size_t i = 0; i < n; ++i) {
    RigNode node;
    node.translation = glm::dvec3(static_cast<double>(i % side), 0.0, static_cast<double>(i / side));
    add_rig_node(*rig, node, 0);
    AnimationChannel slide;
    slide.node = static_cast<int>(i);
    slide.path = TrsPath::Translation;
    slide.track.times = {0.0, 2.0};
    slide.track.values = {glm::dvec4(node.translation, 0.0),
                          glm::dvec4(node.translation + glm::dvec3(0.25, 0, 0), 0.0)};
    clip.channels.push_back(slide);
    AnimationChannel turn;
    turn.node = static_cast<int>(i);
    turn.path = TrsPath::Rotation;
    turn.track.times = {0.0, 2.0};
    turn.track.values = {glm::dvec4(0, 0, 0, 1), glm::dvec4(0, std::sin(M_PI / 4), 0, std::cos(M_PI / 4))};
    clip.channels.push_back(turn);
  }
  rig->clips.push_back(clip);
  if (!instances) return rig_scene(rig, "cube field");
  // As the loader does for rigid meshes on moving nodes: the cube stored once, N instances.
  for (RigMeshInstance& inst : rig->instances) inst.instance = 0;
  std::vector<SceneTriangle> meshes;
  SceneInstancing instancing;
  SceneStats stats;
  settle_rig_instances(*rig, meshes, stats, nullptr, instancing);
  Scene scene = rig_scene(rig, "cube field (instances)");  // no world triangles of its own
  const std::size_t world = scene.triangles.size();
  scene.triangles.insert(scene.triangles.end(), meshes.begin(), meshes.end());
  for (InstancedMesh& m : instancing.meshes) m.first += world;
  instancing.world_triangles = world;
  scene.instancing = std::move(instancing);
  return scene;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_animation: per-frame cost of posing, rebuilding and uploading an animated scene"};
  std::string counts = "1,1000,100000";
  unsigned frames = 8;
  int devices = 2;
  app.add_option("--counts", counts, "comma list of cube counts (12 triangles each)")->capture_default_str();
  app.add_option("--frames", frames, "updates timed per count (after one untimed)")
      ->check(CLI::Range(1u, 1000u))
      ->capture_default_str();
  app.add_option("--devices", devices, "OpenCL devices")->check(CLI::Range(1, 64))->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  return run_guarded([&] {
    DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
    std::printf("%10s %10s %12s %10s %10s %10s %10s %9s %12s %12s %14s\n", "cubes", "as", "triangles", "pose ms",
                "bvh ms", "upload ms", "total ms", "rebuilds", "MiB/frame", "ns/triangle", "first bvh ms");
    std::stringstream list(counts);
    for (std::string item; std::getline(list, item, ',');)
      for (const bool instances : {false, true}) {
        const std::size_t n = std::stoul(item);
        Scene scene = cube_field(n, instances);
        const std::size_t drawn = 12 * n;
        DeviceScene ds(set, scene, build_world_bvh(scene));
        SceneAnimator animator(scene, "all");
        // Untimed: the first update builds the tree and allocates.
        const double first_bvh_ms = animator.update(0.0, set, ds).bvh_ms;
        std::vector<double> pose, build, upload, total;
        std::size_t bytes = 0;
        unsigned rebuilds = 0;
        for (unsigned f = 1; f <= frames; ++f) {
          const SceneAnimator::Update u = animator.update(f / 30.0, set, ds);
          pose.push_back(u.pose_ms);
          build.push_back(u.bvh_ms);
          upload.push_back(u.upload_ms);
          total.push_back(u.pose_ms + u.bvh_ms + u.upload_ms);
          bytes = u.bytes;
          rebuilds += u.rebuilt ? 1u : 0u;
        }
        const double t = bench::median(total);
        std::printf("%10zu %10s %12zu %10.2f %10.2f %10.2f %10.2f %5u/%-3u %12.2f %12.1f %14.2f\n", n,
                    instances ? "instances" : "posed", drawn, bench::median(pose), bench::median(build),
                    bench::median(upload), t, rebuilds, frames, static_cast<double>(bytes) / (1024.0 * 1024.0),
                    t * 1e6 / static_cast<double>(drawn), first_bvh_ms);
      }
    return 0;
  });
}
