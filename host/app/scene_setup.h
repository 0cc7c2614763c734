// What every command and bench does before it renders: load the scene, report what the loader
// repaired, build and validate the BVH, all with progress on stderr; then make the devices and
// upload the scene to them.
#pragma once

#include "bvh/bvh_layout.h"
#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "io/background_writes.h"
#include "render/device_scene.h"
#include "scene/scene.h"
#include "scene/scene_loader.h"

#include <memory>
#include <optional>
#include <string>

namespace px {

// Where a start's time went, ms (render's summary and report).
struct StartTimes {
  double load_ms = 0.0;  // reading and converting the scene file(s)
  double bvh_ms = 0.0;   // building the BVH, or reading it from the cache
  bool bvh_from_cache = false;
  double validate_ms = 0.0;  // the BVH validator
  double devices_ms = 0.0;   // making the OpenCL device set (DeviceSet::create)
  // The tree came from the cache with its wide nodes validated when it was stored (bvh_cache.h):
  // not validated again.
  bool bvh_validated_when_cached = false;
  double cache_store_ms = 0.0;  // writing the BVH cache before the start went on
  // The cache files written on their own thread (LoadedScene::cache_writes): that thread's time,
  // known once they are done (SceneOnDevices::wait_for_cache_writes).
  double background_cache_write_ms = 0.0;
  // The tree came as its device layout, mapped from the device layout cache
  // (device_layout_cache.h): no tree was read, laid out or validated. bvh_ms is then the time to
  // hash the scene and map the file.
  bool device_layout_from_cache = false;
  double scene_hash_ms = 0.0;  // the cache key (scene_content_key), ms
  // The process's resident memory once the scene is on the devices and the host's copies are
  // released (VmRSS, MiB; 0 where /proc is not there): what rendering starts with.
  double host_rss_after_start_mib = 0.0;
};

struct LoadedScene {
  Scene scene;
  FlatBvh bvh;                     // the world tree (scene_bvhs.h): every triangle's in a scene without instances
  std::vector<FlatBvh> mesh_bvhs;  // one per instanced mesh (Scene::instancing), else none
  // The node layout the start made the trees' nodes in: the one requested (load_and_build's
  // bvh_layout), else a CPU set's default (bvh_layout_for(false)). A set in another layout has
  // its device scene make its own.
  BvhLayout bvh_layout = bvh_layout_for(/*all_gpus=*/false);
  // A large static scene without instances, with a cache folder: scene_content_key (0: none of
  // that), and the device layout the cache held for it in `bvh_layout` (or a GPU set's; null:
  // none; `bvh` is then empty). SceneOnDevices uploads the mapping, or stores the layout it makes.
  std::uint64_t content_key = 0;
  std::shared_ptr<const MappedDeviceLayout> device_layout{};
  bool quiet = false;
  StartTimes times{};
  // A static scene loaded for the devices (map_device_layout) and not mapped from the cache:
  // its shading records, made before its tree (DeviceScene::prepare_host_before_tree), the triangles
  // gone since; SceneOnDevices hands it to the device scene. Null for every other scene.
  std::shared_ptr<DeviceScene::HostPart> host_part{};
  // The triangles' count and bounds, kept when SceneOnDevices releases the triangles.
  std::size_t triangle_count = 0;
  glm::vec3 bounds_lo{0.0f}, bounds_hi{0.0f};
  // A start for the devices (load_and_build's map_device_layout) writes its cache files on a
  // thread of their own (background_writes.h): the BVH cache at once, from `bvh`'s arrays
  // (`tree_write`; the device scene waits for it before it changes the tree), the device layout
  // once the first frame is on its way. Null for other callers: they write before returning.
  // Declared last, so destroyed first: a tree is never freed under its write.
  std::optional<BackgroundWrites::Ticket> tree_write{};
  std::shared_ptr<BackgroundWrites> cache_writes{};
};

// Throws SceneError / std::runtime_error with a user-facing message on failure.
// `map_device_layout`: a caller that uploads through SceneOnDevices lets a large static scene
// come as its cached device layout, without a tree (LoadedScene::device_layout), and a flat
// static scene come with its shading records made and its triangles gone
// (LoadedScene::host_part); every other caller gets the tree and the triangles.
// `bvh_layout`: the layout the devices were asked for (DeviceOptions::bvh_layout); nullopt: each
// device type's default.
LoadedScene load_and_build(const std::string& spec, bool quiet = false, const SceneLoadOptions& options = {},
                           bool map_device_layout = false, std::optional<BvhLayout> bvh_layout = std::nullopt);

// A scene on a set of devices: loaded and its BVH built (load_and_build), the devices made
// (DeviceSet::create), the scene uploaded to every one of them. Members in dependency order;
// built in place and never moved, since what renders on them refers to `devices` and
// `device_scene`. Says nothing about the devices: callers print them as they see fit.
// `loaded.bvh` is moved into the upload: empty afterwards (the devices hold the nodes). So are
// the host's triangles of a static scene (about 100 bytes each: 1 GB at 10M triangles), which
// nothing reads once the devices have them; `loaded.triangle_count` and the bounds stay. An
// animated scene (Scene::rig) keeps them: they are posed anew every frame.
//
// A static scene's start builds its kernels while the scene is laid out (DeviceSet::prebuild):
// the scene's, and, for a start that renders frames (`render`, `view`: StartBuilds::Frames), the
// frame's other kernels after them, which are otherwise built at the first frame.
enum class StartBuilds { SceneKernels, Frames };
struct SceneOnDevices {
  SceneOnDevices(const std::string& spec, const DeviceOptions& device_options, bool quiet = false,
                 const SceneLoadOptions& options = {}, KernelChoice kernels = KernelChoice::Scene,
                 StartBuilds builds = StartBuilds::SceneKernels);
  // A scene loaded before: a bench that runs one scene on several device sets loads it once.
  SceneOnDevices(LoadedScene scene, const DeviceOptions& device_options, KernelChoice kernels = KernelChoice::Scene,
                 StartBuilds builds = StartBuilds::SceneKernels);
  SceneOnDevices(const SceneOnDevices&) = delete;
  SceneOnDevices& operator=(const SceneOnDevices&) = delete;

  // Lets the cache writes held for the first frame run (render calls it as its first frame
  // goes out), and waits for all of them (the summary reports their time; the destructor waits
  // too). No-ops without any.
  void first_frame_on_its_way();
  void wait_for_cache_writes();

  LoadedScene loaded;
  // A static scene without instances (not mapped from the cache): its shading records are made
  // from its triangles before the devices are (DeviceScene::prepare_host), so that the
  // triangles (about 100 bytes each) are gone when PoCL's device set comes; handed to the
  // device scene and released (null) afterwards.
  std::shared_ptr<DeviceScene::HostPart> host_part;
  DeviceSet devices;
  DeviceScene device_scene;
};

}  // namespace px
