#include "app/scene_setup.h"

#include "bvh/bvh_builder.h"
#include "bvh/bvh_cache.h"
#include "bvh/bvh_validator.h"
#include "bvh/scene_bvhs.h"
#include "bvh/wide_bvh.h"
#include "image/image_io.h"
#include "io/free_heap.h"
#include "render/device_layout_cache.h"
#include "scene/instancing.h"
#include "io/progress_ticker.h"
#include "scene/scene_loader.h"

#include <chrono>
#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <utility>

namespace px {

namespace {
// Below this a BVH builds in well under the time it takes to read it back.
constexpr std::size_t kBvhCacheMinTriangles = 20000;

using Clock = std::chrono::steady_clock;
double ms(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }

// VmRSS of this process in MiB (0 without /proc).
double resident_mib() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (!f) return 0.0;
  char line[256];
  double kib = 0.0;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "VmRSS: %lf kB", &kib) == 1) break;
  std::fclose(f);
  return kib / 1024.0;
}

// The world tree of `out` over `tree_triangles` (every triangle, or the world's own with instances):
// read from the disk cache or built (and cached), validated, its build and validation times in
// out.times.
// `collapse_later`: the wide nodes are left to the device scene (a static scene without
// instances in a wide layout), which makes them once the scene's triangles have become shading
// records; here the binary tree alone is validated (and cached).
void build_world_tree(LoadedScene& out, const TriangleSource& tree_triangles, bool quiet, bool collapse_later = false) {
  using clock = Clock;
  const BvhLayout layout = out.bvh_layout;
  const std::optional<BvhLayout> made_here = collapse_later ? std::nullopt : std::optional<BvhLayout>(layout);
  // Large scenes go through the disk cache (small ones build faster than a file is read).
  const BvhBuildOptions build_options;
  const bool cacheable = tree_triangles.size() >= kBvhCacheMinTriangles;
  const BvhCache cache(cacheable ? BvhCache::default_dir() : std::string());
  const auto t2 = clock::now();
  std::optional<FlatBvh> cached;
  std::uint32_t validated_layouts = 0;
  std::uint64_t key = 0;  // the cache's key for these triangles (set by a load that looked)
  {
    const ProgressTicker ticker(quiet || !cacheable ? "" : "[bvh] still reading the BVH cache");
    cached = cache.load(tree_triangles, build_options, &validated_layouts, &key);
  }
  const bool from_cache = cached.has_value();
  if (from_cache) {
    out.bvh = std::move(*cached);
  } else {
    const ProgressTicker ticker(
        quiet ? "" : "[bvh] still building the BVH of " + std::to_string(tree_triangles.size()) + " triangles");
    out.bvh = build_bvh(tree_triangles, build_options, made_here);
  }
  // The cache holds the binary tree; the wide nodes the kernels traverse are collapsed from it
  // (a few percent of a build), so that the validator below checks them too.
  if (from_cache && !collapse_later) ensure_layout(out.bvh, layout);
  // A cached tree was built with the options of its key: the leaves' sizing follows from them.
  if (from_cache) out.bvh.stats.block_leaves = build_options.block_leaves(tree_triangles.size());
  out.times.bvh_ms = ms(t2, clock::now());
  out.times.bvh_from_cache = from_cache;
  const auto& bs = out.bvh.stats;
  if (!quiet)
    std::fprintf(
        stderr, "[bvh] %zu nodes, %zu leaf triangles, depth %d, SAH %.1f (%s)%s%s%s\n", bs.nodes, bs.leaf_triangles,
        bs.depth, bs.sah_cost,
        from_cache
            ? ("read from the cache in " +
               std::to_string(static_cast<long>(std::chrono::duration<double, std::milli>(clock::now() - t2).count())) +
               " ms; built in " + std::to_string(static_cast<long>(bs.build_ms)) + " ms")
                  .c_str()
            : (std::to_string(static_cast<long>(bs.build_ms)) + " ms").c_str(),
        layout == BvhLayout::Binary ? ""
        : collapse_later ? (std::string("; ") + to_string(layout) + " nodes made with the device layout").c_str()
                         : (std::string("; ") + to_string(layout) + ", " +
                            std::to_string(layout == BvhLayout::Wide4   ? out.bvh.nodes4.size()
                                           : layout == BvhLayout::Wide8 ? out.bvh.nodes8.size()
                                                                        : out.bvh.cnodes.size()) +
                            " nodes")
                               .c_str(),
        bs.split_budget_exceeded ? "; spatial splits stopped at their budget (heavily overlapping "
                                   "triangles): binned SAH instead"
                                 : "",
        bs.block_leaves ? ("; leaves sized for 4-triangle blocks (" + std::to_string(build_options.block_leaves_from) +
                           " triangles or more)")
                              .c_str()
                        : "");
  if (!quiet && bs.split_trial && !from_cache)
    std::fprintf(stderr,
                 "[bvh] spatial splits on trial (%zu triangles or more): on %zu sampled triangles they lower the SAH "
                 "by %.1f%% (%.0f ms); %s %.0f%%\n",
                 build_options.split_trial_triangles, bs.split_trial_sampled, 100.0 * bs.split_trial_gain,
                 bs.split_trial_ms,
                 bs.split_trial_taken ? "the scene is built with them, as the gain is at least"
                                      : "binned SAH kept, as splits are worth their time from",
                 100.0 * build_options.split_min_gain);
  // A tree is validated before the cache stores it, with the wide nodes it carried, and the
  // file's checksum and key (the triangles, the options, the builder's, collapser's and
  // validator's sources) guard it since (bvh_cache.h): read back, its wide nodes collapse to the
  // very nodes validated then, so a layout recorded as validated is not checked again (a large
  // scene's warm start loses its validation time: docs/measurements.md, Start at paper scale);
  // another layout's nodes, collapsed from it for the first time, are.
  const auto t3 = clock::now();
  BvhValidation check;
  const bool validated_when_cached = from_cache && (validated_layouts & bvh_layout_bit(layout)) != 0;
  if (!validated_when_cached) {
    const ProgressTicker ticker(quiet ? "" : "[bvh] still validating the BVH");
    check = validate_bvh(out.bvh, tree_triangles, /*binary_tree=*/!from_cache);
  }
  out.times.validate_ms = ms(t3, clock::now());
  out.times.bvh_validated_when_cached = validated_when_cached;
  // The validator's tables are freed into the heap: handed back before the device layout is
  // made beside the tree.
  give_back_free_heap(tree_triangles.size());
  if (!check.ok && from_cache) {
    // A cached file that passed its checksum but not the validator (a builder bug fixed since,
    // with the same sources hash?): rebuild rather than fail.
    if (!quiet) std::fprintf(stderr, "[bvh] the cached BVH failed validation: rebuilding\n");
    const auto t5 = clock::now();
    out.bvh = build_bvh(tree_triangles, build_options, made_here);
    out.times.bvh_ms += ms(t5, clock::now());
    out.times.bvh_from_cache = false;
    const auto t6 = clock::now();
    check = validate_bvh(out.bvh, tree_triangles);
    out.times.validate_ms += ms(t6, clock::now());
    cached.reset();
  }
  if (!check.ok) {
    std::string msg = "internal error: BVH failed validation:";
    for (const auto& e : check.errors) msg += "\n  " + e;
    throw std::runtime_error(msg);
  }
  if (cacheable && !from_cache && !BvhCache::default_dir().empty()) {
    // What the file holds points into the tree's arrays; its key was made by the load above
    // (the triangles may be gone by the time it is written).
    const BvhCache::Contents contents = BvhCache::contents_of(out.bvh);
    const std::size_t scene_triangles = tree_triangles.size();
    const auto write = [cache, contents, key, scene_triangles, quiet] {
      std::string why;
      const auto t = Clock::now();
      const std::string path = cache.store(contents, key, scene_triangles, &why);
      if (!quiet && !path.empty())
        std::fprintf(stderr, "[bvh] cached in %s for the next run (%.0f ms)\n", path.c_str(), ms(t, Clock::now()));
      if (!quiet && path.empty()) std::fprintf(stderr, "[bvh] warning: could not cache the BVH (%s)\n", why.c_str());
    };
    if (out.cache_writes) {
      // On the writer's thread from now, beside the device set's creation and the wide nodes'
      // collapse; the device scene waits for it before it changes the tree
      // (DeviceLayoutStore::before_tree_changes).
      out.tree_write = out.cache_writes->submit(write, BackgroundWrites::Start::Now);
    } else {
      const auto t4 = clock::now();
      {
        const ProgressTicker ticker(quiet ? "" : "[bvh] still writing the BVH cache");
        write();
      }
      out.times.cache_store_ms = ms(t4, clock::now());
    }
  }
}

// Whether the device scene will make the wide nodes (DeviceScene: a static scene without
// instances whose triangles SceneOnDevices hands over, in a wide layout): then the start never
// holds them beside the scene's triangles (docs/measurements.md, Start at paper scale).
bool collapse_later(const LoadedScene& out, bool for_devices) {
  return for_devices && out.scene.instancing.empty() && !out.scene.rig &&
         (out.bvh_layout == BvhLayout::Wide4 || out.bvh_layout == BvhLayout::Wide8);
}

// What hands a static scene's triangles over to the device scene (DeviceScene's take_triangles):
// they leave the scene, and with them the vertex colours, which the tables have taken in.
std::function<std::vector<SceneTriangle>()> take_static_triangles(Scene& scene) {
  return [&scene] {
    std::vector<std::array<glm::vec3, 3>>().swap(scene.vertex_colours);
    return std::exchange(scene.triangles, {});
  };
}

}  // namespace

// load_and_build without the image reader's preload.
static LoadedScene load_and_build_tree(const std::string& spec, bool quiet, const SceneLoadOptions& options,
                                       bool map_device_layout, std::optional<BvhLayout> requested_layout) {
  using clock = Clock;
  LoadedScene out;
  out.bvh_layout = requested_layout.value_or(bvh_layout_for(/*all_gpus=*/false));
  if (map_device_layout) out.cache_writes = std::make_shared<BackgroundWrites>();
  auto t0 = clock::now();
  if (!quiet) std::fprintf(stderr, "[scene] loading %s ...\n", spec.c_str());
  {
    // Every long step of the start says it is still running (progress_ticker.h); quiet: none.
    const ProgressTicker ticker(quiet ? "" : "[scene] still loading " + spec);
    out.scene = load_scene(spec, options);
  }
  // What the loader freed (decoded attributes, index buffers) is in the heap: handed back before
  // the shading records are made beside the scene's triangles.
  give_back_free_heap(out.scene.triangles.size());
  const auto& st = out.scene.stats;
  out.triangle_count = drawn_triangle_count(out.scene);
  if (!out.scene.triangles.empty()) {
    const DrawnBounds bounds = drawn_bounds(out.scene);
    if (bounds.any) {
      out.bounds_lo = bounds.lo;
      out.bounds_hi = bounds.hi;
    }
  }
  auto t1 = clock::now();
  out.times.load_ms = ms(t0, t1);
  if (!quiet) {
    std::fprintf(stderr, "[scene] %s: %zu triangles, %zu materials, %zu textures (%.0f ms)\n", out.scene.name.c_str(),
                 out.scene.triangles.size(), out.scene.materials.size(), out.scene.textures.size(),
                 std::chrono::duration<double, std::milli>(t1 - t0).count());
    // Dropped triangles are reported once, by the loader's warnings (which name the file).
    for (const auto& w : st.warnings) std::fprintf(stderr, "[scene] warning: %s\n", w.c_str());
    const SceneInstancing& in = out.scene.instancing;
    if (!in.empty())
      std::fprintf(stderr,
                   "[scene] instances: %zu instances of %zu mesh(es) draw %zu of the %zu triangles; %zu triangles "
                   "stored (--instancing off stores a copy per instance)\n",
                   in.instances.size(), in.meshes.size(), out.triangle_count - in.world_triangles, out.triangle_count,
                   out.scene.triangles.size());
  }
  // The world tree goes through the cache and the validator below: over every triangle, or, with
  // instances, over the world's own (a copy of that part, dropped after the start). The
  // instanced meshes' trees are built after it (small as a rule; validated by build_mesh_bvhs),
  // the instances' top level with the upload (DeviceScene).
  const bool instanced = !out.scene.instancing.empty();
  std::vector<SceneTriangle> world_part;
  if (instanced) world_part = triangle_range(out.scene, 0, out.scene.instancing.world_triangles);
  const std::vector<SceneTriangle>& tree_triangles = instanced ? world_part : out.scene.triangles;
  out.quiet = quiet;
  // A large static scene without instances may have its whole device layout cached: then no
  // tree is read (device_layout_cache.h).
  if (map_device_layout && !instanced && !out.scene.rig && tree_triangles.size() >= kBvhCacheMinTriangles &&
      !DeviceLayoutCache::default_dir().empty()) {
    const auto t = clock::now();
    out.content_key = scene_content_key(out.scene);
    out.times.scene_hash_ms = ms(t, clock::now());
    // The devices are not made yet: the CPU sets' layout (or the one requested) first, then the
    // GPU sets' (a GPU machine's cache holds that one only). make_device_scene sorts out a
    // mapping in another layout than the set's.
    const DeviceLayoutCache cache(DeviceLayoutCache::default_dir());
    for (const BvhLayout layout : {out.bvh_layout, requested_layout.value_or(bvh_layout_for(/*all_gpus=*/true))})
      if (!out.device_layout)
        out.device_layout = cache.open(out.content_key, layout, BvhBuildOptions{}, out.scene.triangles.size());
    if (out.device_layout) {
      out.times.bvh_ms = ms(t, clock::now());
      out.times.bvh_from_cache = out.times.bvh_validated_when_cached = out.times.device_layout_from_cache = true;
      out.bvh.stats = out.device_layout->stats();
      const auto& bs = out.bvh.stats;
      if (!quiet)
        std::fprintf(stderr,
                     "[bvh] %zu nodes, %zu leaf triangles, depth %d, SAH %.1f (built in %.0f ms); %s, %zu nodes: the "
                     "device layout mapped from the cache in %.0f ms (%.0f MiB, %s)\n",
                     bs.nodes, bs.leaf_triangles, bs.depth, bs.sah_cost, bs.build_ms,
                     to_string(out.device_layout->layout()), out.device_layout->layout_nodes(), out.times.bvh_ms,
                     static_cast<double>(out.device_layout->file_bytes()) / (1024.0 * 1024.0),
                     out.device_layout->path().c_str());
      return out;
    }
  }
  // A static scene on its way to the devices makes its shading records now (flat or indexed
  // ones), and its tree from the 40-byte corners packed where its 100-byte triangles were
  // (prepare_host_before_tree).
  DeviceScene::BuildCorners corners;
  if (map_device_layout && !instanced && !out.scene.rig && !out.scene.triangles.empty())
    out.host_part = DeviceScene::prepare_host_before_tree(out.scene, take_static_triangles(out.scene), corners);
  const TriangleSource tree_source = out.host_part ? corners.source() : TriangleSource(tree_triangles);
  if (!tree_source.empty()) build_world_tree(out, tree_source, quiet, collapse_later(out, map_device_layout));
  if (instanced) {
    const ProgressTicker ticker(quiet ? "" : "[bvh] still building the instanced meshes' BVHs");
    const auto t = clock::now();
    out.mesh_bvhs = build_mesh_bvhs(out.scene, out.bvh_layout);
    const double mesh_ms = ms(t, clock::now());
    out.times.bvh_ms += mesh_ms;
    if (!quiet) {
      std::size_t nodes = 0;
      for (const FlatBvh& tree : out.mesh_bvhs) nodes += tree.stats.nodes;
      std::fprintf(stderr, "[bvh] %zu instanced mesh(es): %zu nodes (%.0f ms)%s\n", out.mesh_bvhs.size(), nodes,
                   mesh_ms, tree_triangles.empty() ? "; the world has no triangles of its own" : "");
    }
  }
  return out;
}

LoadedScene load_and_build(const std::string& spec, bool quiet, const SceneLoadOptions& options, bool map_device_layout,
                           std::optional<BvhLayout> bvh_layout) {
  LoadedScene out = load_and_build_tree(spec, quiet, options, map_device_layout, bvh_layout);
  // The frames' files are written without the image reader (image_io.h), so a scene without
  // textures never loads OpenImageIO's libraries and heap (docs/measurements.md, "Frames written
  // without OpenImageIO"). A scene with textures has loaded the reader at its first
  // texture; the preload only makes sure of it, after the start's highest points (here, or for
  // SceneOnDevices once the scene is on the devices).
  if (!map_device_layout && !out.scene.textures.empty()) preload_image_codec();
  return out;
}

SceneOnDevices::SceneOnDevices(const std::string& spec, const DeviceOptions& device_options, bool quiet,
                               const SceneLoadOptions& options, KernelChoice kernels, StartBuilds builds)
    : SceneOnDevices(load_and_build(spec, quiet, options, /*map_device_layout=*/true, device_options.bvh_layout),
                     device_options, kernels, builds) {}

namespace {

// The device-independent part of a static scene's layout, made before the devices (null for
// other scenes and for a layout mapped from the cache).
std::shared_ptr<DeviceScene::HostPart> prepare_host_part(LoadedScene& loaded) {
  if (loaded.host_part) return std::exchange(loaded.host_part, {});
  Scene& scene = loaded.scene;
  if (loaded.device_layout || scene.rig || !scene.instancing.empty() || scene.triangles.empty() ||
      loaded.bvh.nodes.empty())
    return nullptr;
  return DeviceScene::prepare_host(scene, take_static_triangles(scene));
}

// The scene on `devices`: from the mapped device layout when the cache held one in the set's
// layout, else laid out from the tree (read or built now if the start had mapped another
// layout: a GPU set's) and the host part when there is one, and stored for the next start when
// the scene is cacheable.
DeviceScene make_device_scene(DeviceSet& devices, LoadedScene& loaded,
                              std::shared_ptr<DeviceScene::HostPart>& host_part) {
  const BvhLayout layout = devices.bvh_layout();
  if (loaded.device_layout && loaded.device_layout->layout() != layout) {
    loaded.device_layout = DeviceLayoutCache(DeviceLayoutCache::default_dir())
                               .open(loaded.content_key, layout, BvhBuildOptions{}, loaded.scene.triangles.size());
    if (!loaded.device_layout) {
      if (!loaded.quiet)
        std::fprintf(stderr, "[bvh] the cached device layout is not in this device set's %s layout: making it\n",
                     to_string(layout));
      loaded.times.device_layout_from_cache = false;
      build_world_tree(loaded, loaded.scene.triangles, loaded.quiet, collapse_later(loaded, true));
    }
  }
  if (loaded.device_layout) return DeviceScene(devices, loaded.scene, std::move(loaded.device_layout));
  const DeviceLayoutCache cache(loaded.content_key != 0 ? DeviceLayoutCache::default_dir() : std::string());
  DeviceLayoutStore store;
  store.cache = &cache;
  store.content_key = loaded.content_key;
  store.quiet = loaded.quiet;
  store.background = loaded.cache_writes.get();
  if (loaded.cache_writes && loaded.tree_write)
    store.before_tree_changes = [writes = loaded.cache_writes, ticket = *loaded.tree_write] {
      writes->wait_for(ticket);
    };
  if (host_part) return DeviceScene(devices, std::exchange(host_part, {}), loaded.scene, std::move(loaded.bvh), store);
  // The tree's host copy is not needed once its nodes are on the devices, nor a static scene's
  // triangles once the device scene has made what it makes of them (before its largest part).
  // An animated scene's triangles are posed again every frame (SceneAnimator): they stay.
  Scene& scene = loaded.scene;
  std::function<std::vector<SceneTriangle>()> take_triangles;
  if (!scene.rig) take_triangles = take_static_triangles(scene);
  return DeviceScene(devices, loaded.scene, std::move(loaded.bvh), std::move(loaded.mesh_bvhs), store, take_triangles);
}

}  // namespace

SceneOnDevices::SceneOnDevices(LoadedScene scene, const DeviceOptions& device_options, KernelChoice kernels,
                               StartBuilds builds)
    : loaded(std::move(scene)),
      host_part(prepare_host_part(loaded)),
      devices([&] {
        // `loaded` is made first (member order): its start times take the device set's too.
        const auto t = Clock::now();
        DeviceSet set = DeviceSet::create(device_options);
        loaded.times.devices_ms = ms(t, Clock::now());
        // A static scene with its host part knows its kernels' options now: PoCL builds them on a
        // thread of their own while the scene is laid out for the devices (single-threaded,
        // about 0.3 s at 4M triangles) and the pipeline is made, instead of at the first frame's
        // first launch. Not beside the tree's build: that uses every core, and the compiler's
        // memory would stand beside the build's arrays (docs/measurements.md, "The scene's
        // kernels built while the scene is laid out").
        if (host_part) {
          set.prebuild("pathtrace/path_trace.cl",
                       DeviceScene::kernel_options_for(*host_part, set.bvh_layout(), kernels));
          // The frame's other kernels after them (prebuilds run in turn): a large scene's layout
          // outlasts the scene's build (1.5 s at 10M triangles against about 1 s), and they were
          // built at the first frame (docs/measurements.md, "The frame's kernels built during
          // the layout too").
          if (builds == StartBuilds::Frames) set.prebuild(DeviceSet::kFrameKernels);
        }
        return set;
      }()),
      device_scene(make_device_scene(devices, loaded, host_part)) {
  device_scene.set_kernel_choice(kernels);
  if (!loaded.scene.rig) {
    std::vector<SceneTriangle>().swap(loaded.scene.triangles);
    std::vector<std::array<glm::vec3, 3>>().swap(loaded.scene.vertex_colours);
  }
  // What the device layout freed (its temporaries, the tree's binary nodes) goes back before the
  // first frame's buffers and PoCL's work-group memory come.
  give_back_free_heap(loaded.triangle_count);
  loaded.times.host_rss_after_start_mib = resident_mib();
  if (!loaded.scene.textures.empty()) preload_image_codec();  // see load_and_build
}

void SceneOnDevices::first_frame_on_its_way() {
  if (loaded.cache_writes) loaded.cache_writes->first_frame_on_its_way();
}

void SceneOnDevices::wait_for_cache_writes() {
  if (!loaded.cache_writes) return;
  loaded.cache_writes->wait();
  loaded.times.background_cache_write_ms = loaded.cache_writes->busy_ms();
}

}  // namespace px
