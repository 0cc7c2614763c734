#include "render/device_scene.h"

#include "render/device_buffers.h"
#include "render/indexed_shading.h"
#include "render/light_tree.h"

#include "bvh/bvh_validator.h"
#include "bvh/scene_bvhs.h"
#include "bvh/top_level_bvh.h"
#include "bvh/wide_bvh.h"
#include "io/environment.h"
#include "io/progress_ticker.h"
#include "scene/instancing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>

#include <sys/mman.h>
#include <unistd.h>

namespace px {

using namespace scene_buffers;

// The small tables made from the scene beside the three large buffers.
struct DeviceScene::SceneTables {
  std::vector<GpuMaterial> materials;
  std::vector<LightTriangle> lights;
  std::vector<cl_float4> colours;
  std::vector<TextureInfo> infos;
  std::vector<cl_float4> texels;
  std::size_t light_count = 0;
  std::uint32_t features = PX_FEATURES_ALL;  // the kernel features the scene uses
};

cl_uint DeviceSceneBuffers::bind(cl::Kernel& kernel, cl_uint first) const {
  for (const cl::Buffer* b :
       {&nodes, &triangles, &shading, &materials, &textures, &texels, &lights, &colours, &instances})
    kernel.setArg(first++, *b);
  return first;
}

namespace {

// Hands the whole pages of block [bytes + used, bytes + size) back to the system (MADV_DONTNEED:
// a block that large is a private mapping of its own), from `from` bytes (8 MiB: a smaller
// block may share its pages with others).
void release_tail(unsigned char* bytes, std::size_t used, std::size_t size, std::size_t from = std::size_t{8} << 20) {
  const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
  const auto begin = (reinterpret_cast<std::uintptr_t>(bytes + used) + page - 1) / page * page;
  const auto end = reinterpret_cast<std::uintptr_t>(bytes + size) / page * page;
  if (end > begin && end - begin >= from) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
}

// What `make` makes of each of `triangles` (Record: TriangleShading, FlatTriangleShading when
// every triangle is flat, or a BuildTriangle's corners), written over the triangles
// themselves, in order: record i (64, 16 or 40 bytes at that many times i) is written after
// triangle i (100 bytes at 100 i) is read, and ends before triangle i + 1 begins, so nothing is overwritten before it
// is read. The whole pages past the last record go back to the system (MADV_DONTNEED): those the
// pass has read as it goes, so that what `make` builds (indexed records) never stands beside the
// whole block (docs/measurements.md, "What is resident at each highest point"), the rest at the
// end; none under the records, so none is touched twice. The result owns the triangles' block.
template <typename Record, typename Make>
SceneBytes records_in_place(std::vector<SceneTriangle>&& triangles, Make make) {
  static_assert(sizeof(Record) <= sizeof(SceneTriangle), "records must fit where the triangles were");
  static_assert(std::is_trivially_copyable_v<SceneTriangle> && std::is_trivially_copyable_v<Record>);
  constexpr std::size_t kReleaseStep = std::size_t{1} << 16;     // triangles (6.4 MB) between hand-backs
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;  // whole ones: none is split
  auto owner = std::make_shared<std::vector<SceneTriangle>>(std::move(triangles));
  const std::size_t n = owner->size();
  auto* bytes = reinterpret_cast<unsigned char*>(owner->data());
  const std::size_t records_end = n * sizeof(Record), block_end = n * sizeof(SceneTriangle);
  // Under 8 MiB, none go (release_tail); whole huge pages past the records up to `released` have.
  const bool as_it_goes = block_end >= (std::size_t{8} << 20);
  std::size_t released = records_end;
  for (std::size_t i = 0; i < n; ++i) {
    SceneTriangle t;
    std::memcpy(&t, bytes + i * sizeof(SceneTriangle), sizeof t);
    const Record s = make(t);
    std::memcpy(bytes + i * sizeof(Record), &s, sizeof s);
    if (as_it_goes && (i + 1) % kReleaseStep == 0) {
      const auto base = reinterpret_cast<std::uintptr_t>(bytes);
      const std::uintptr_t begin = (base + released + kHugePage - 1) & ~(kHugePage - 1);
      const std::uintptr_t end = (base + (i + 1) * sizeof(SceneTriangle)) & ~(kHugePage - 1);
      if (end > begin) {
        madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
        released = end - base;
      }
    }
  }
  // The rest: from the records' end (the pages up to the first whole huge page past it too).
  release_tail(bytes, records_end, block_end, as_it_goes ? 1 : std::size_t{8} << 20);
  return {bytes, n * sizeof(Record), sizeof(Record), owner};
}

SceneBytes shading_in_place(std::vector<SceneTriangle>&& triangles) {
  return records_in_place<TriangleShading>(std::move(triangles), shading_of);
}

SceneBytes flat_shading_in_place(std::vector<SceneTriangle>&& triangles) {
  return records_in_place<FlatTriangleShading>(std::move(triangles), flat_shading_of);
}

void require_static_scene(const Scene& scene, const std::function<std::vector<SceneTriangle>()>& take_triangles) {
  if (!scene.instancing.empty() || scene.rig || !take_triangles)
    throw std::logic_error("DeviceScene::prepare_host: a static scene without instances, its triangles handed over");
}

// Whether a static scene's leaf triangles go to the devices as BvhLeafRef records in `layout`:
// the wide layouts', whose leaf blocks hold the vertices (lay_out_static).
bool leaf_refs_in(BvhLayout layout) { return layout == BvhLayout::Wide4 || layout == BvhLayout::Wide8; }

// The kernels' build options for a scene on a set of devices (DeviceScene::kernel_options).
std::string format_kernel_options(BvhLayout layout, std::uint32_t features, bool leaf_refs, ShadingRecords records) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%03x", features);
  return "-DPX_BVH_WIDTH=" + std::to_string(bvh_layout_width(layout)) + " -DPX_FEATURES=" + text +
         (leaf_refs ? " -DPX_LEAF_REFS=1" : "") + (records == ShadingRecords::Flat ? " -DPX_FLAT_SHADING=1" : "") +
         (records == ShadingRecords::Indexed ? " -DPX_INDEXED_SHADING=1" : "");
}

}  // namespace

std::string DeviceScene::kernel_options() const {
  return format_kernel_options(layout_, kernel_features(), leaf_refs_, shading_records_);
}

namespace {

// Frees `tree`'s node arrays but those of `keep` (none: all of them).
void release_nodes(FlatBvh& tree, std::optional<BvhLayout> keep) {
  if (keep != BvhLayout::Binary) std::vector<BvhNode>().swap(tree.nodes);
  if (keep != BvhLayout::Wide4) std::vector<Bvh4Node>().swap(tree.nodes4);
  if (keep != BvhLayout::Wide8) std::vector<Bvh8Node>().swap(tree.nodes8);
  if (keep != BvhLayout::Compressed8) {
    std::vector<CompressedBvh8Node>().swap(tree.cnodes);
    std::vector<std::uint32_t>().swap(tree.cleaf_first);
  }
}

// The flagged tree `tree` in `layout`, its nodes made and validated against `tris` if the caller's
// tree did not carry them (a cwbvh set given the tree load_and_build collapsed for CPUs: nodes
// made here have not met the validator the loader ran).
void prepare_tree(FlatBvh& tree, BvhLayout layout, const std::vector<SceneTriangle>& tris, const char* what) {
  if (has_layout(tree, layout)) return;
  ensure_layout(tree, layout);
  const BvhValidation check = validate_bvh(tree, tris);
  if (!check.ok)
    throw std::runtime_error(std::string("internal error: the ") + to_string(layout) + " nodes of " + what +
                             " failed validation: " + (check.errors.empty() ? "" : check.errors.front()));
}

// The words of `tree`'s nodes as the set's kernels read them.
std::vector<std::uint32_t> node_words(const FlatBvh& tree, BvhLayout layout) {
  if (layout != BvhLayout::Binary) return device_wide_nodes(tree, layout);
  std::vector<std::uint32_t> words(tree.nodes.size() * sizeof(BvhNode) / 4);
  std::memcpy(words.data(), tree.nodes.data(), words.size() * 4);
  return words;
}

}  // namespace

std::vector<MeshPlacement> DeviceScene::assemble_instanced(const FlatBvh* world, std::vector<std::uint32_t>& words,
                                                           std::vector<BvhTriangle>& triangles) const {
  words.clear();
  triangles.clear();
  if (world) {
    words = node_words(*world, layout_);
    triangles = world->triangles;
  } else {
    words.assign(sizeof(BvhNode) / 4, 0u);  // a placeholder the kernels never enter
  }
  std::vector<MeshPlacement> placements(mesh_words_.size());
  for (std::size_t k = 0; k < mesh_words_.size(); ++k) {
    words.resize((words.size() + 15) / 16 * 16, 0u);
    placements[k].node_offset = static_cast<std::uint32_t>(words.size());
    placements[k].triangle_offset = static_cast<std::uint32_t>(triangles.size());
    words.insert(words.end(), mesh_words_[k].begin(), mesh_words_[k].end());
    triangles.insert(triangles.end(), mesh_triangles_[k].begin(), mesh_triangles_[k].end());
    if (words.size() >= 0xffffffffu || triangles.size() >= kWideIndexLimit)
      throw std::runtime_error("the scene's instanced meshes hold more nodes or triangles than the kernels address");
  }
  return placements;
}

DeviceScene::DeviceScene(DeviceSet& devices, const Scene& scene, FlatBvh bvh, std::vector<FlatBvh> mesh_bvhs,
                         const DeviceLayoutStore& store,
                         const std::function<std::vector<SceneTriangle>()>& take_triangles) {
  const auto layout_start = std::chrono::steady_clock::now();
  const bool instanced = !scene.instancing.empty();
  // This constructor changes the tree from its first step (a BVH cache write may read it).
  if (store.before_tree_changes && (instanced || scene.rig || !take_triangles)) store.before_tree_changes();
  if (!instanced && !scene.rig && take_triangles) {
    std::shared_ptr<HostPart> host = prepare_host(scene, take_triangles);
    // lay_out_static counts the host part's time itself.
    lay_out_static(devices, scene, std::move(bvh), std::move(host), store, std::chrono::steady_clock::now());
    return;
  }
  FlatBvh& flagged = bvh;
  const std::vector<std::uint32_t> tri_flags = triangle_flags(scene);
  const BvhLayout layout = devices.bvh_layout();
  layout_ = layout;
  const std::size_t scene_triangles = scene.triangles.size();
  // Without instances: the one tree's nodes (binary: flagged.nodes as they are), its leaf
  // triangles, and an instance buffer that says "none". With instances: the world tree, then
  // each mesh's tree at a 64-byte aligned word offset, and their leaf triangles likewise back
  // to back (types.h: the instance buffer).
  std::vector<std::uint32_t> wide_words;
  std::vector<BvhTriangle> instanced_triangles;
  std::vector<std::uint32_t> instance_words;
  // The tree's node count in the layout (the cache records it), before the static case below
  // frees those nodes.
  std::size_t layout_nodes = 0;
  // A static scene without instances that keeps its triangles (a handed-over one took
  // lay_out_static above) makes its wide words last, from nodes it frees as it goes
  // (device_wide_nodes_from).
  bool words_last = false;
  const bool static_wide = !instanced && !scene.rig && (layout == BvhLayout::Wide4 || layout == BvhLayout::Wide8);
  if (!instanced) {
    set_triangle_flags(flagged, tri_flags);
    prepare_tree(flagged, layout, scene.triangles, "the scene's BVH");
    layout_nodes = layout == BvhLayout::Wide4         ? flagged.nodes4.size()
                   : layout == BvhLayout::Wide8       ? flagged.nodes8.size()
                   : layout == BvhLayout::Compressed8 ? flagged.cnodes.size()
                                                      : flagged.nodes.size();
    // Nothing rewrites a static scene's buffers, so its host nodes go as early as they may:
    // those the layout's device words are not made from at once (the 10M heightfield: 79 MiB of
    // binary nodes), the rest while the words are made. Binary nodes are uploaded as they are.
    if (!scene.rig) release_nodes(flagged, layout);
    words_last = static_wide;
    if (layout != BvhLayout::Binary && !words_last) wide_words = device_wide_nodes(flagged, layout);
    if (!scene.rig && layout == BvhLayout::Compressed8) release_nodes(flagged, std::nullopt);
    instance_words = instance_buffer_words(scene, {}, scene_triangles);
  } else {
    check_instancing(scene);
    const SceneInstancing& in = scene.instancing;
    for (std::size_t i = in.world_triangles; i < scene.triangles.size(); ++i)
      if (tri_flags[i] & PX_TRI_EMISSIVE)
        throw std::logic_error(
            "DeviceScene: an instanced mesh emits light (the light table holds world triangles only)");
    if (mesh_bvhs.empty()) mesh_bvhs = build_mesh_bvhs(scene, layout);
    if (mesh_bvhs.size() != in.meshes.size())
      throw std::logic_error("DeviceScene: " + std::to_string(mesh_bvhs.size()) + " mesh trees for " +
                             std::to_string(in.meshes.size()) + " instanced meshes");
    if (in.world_triangles > 0 && flagged.nodes.empty()) flagged = build_world_bvh(scene);
    if (in.world_triangles > 0) {
      set_triangle_flags(flagged, tri_flags);
      prepare_tree(flagged, layout, triangle_range(scene, 0, in.world_triangles), "the world's BVH");
    }
    mesh_words_.assign(in.meshes.size(), {});
    mesh_triangles_.assign(in.meshes.size(), {});
    for (std::size_t k = 0; k < in.meshes.size(); ++k) {
      FlatBvh& tree = mesh_bvhs[k];
      const InstancedMesh& m = in.meshes[k];
      const std::vector<std::uint32_t> flags(tri_flags.begin() + std::ptrdiff_t(m.first),
                                             tri_flags.begin() + std::ptrdiff_t(m.first + m.count));
      set_triangle_flags(tree, flags);
      prepare_tree(tree, layout, triangle_range(scene, m.first, m.count), "an instanced mesh's BVH");
      mesh_words_[k] = node_words(tree, layout);
      mesh_triangles_[k] = std::move(tree.triangles);
      for (BvhTriangle& t : mesh_triangles_[k]) t.prim += static_cast<std::uint32_t>(m.first);
    }
    std::vector<FlatBvh>().swap(mesh_bvhs);
    const std::vector<MeshPlacement> placements =
        assemble_instanced(in.world_triangles > 0 ? &flagged : nullptr, wide_words, instanced_triangles);
    instance_words = instance_buffer_words(scene, placements, in.world_triangles);
    if (!scene.rig) {  // nothing moves: the meshes' parts are on the devices for good
      std::vector<std::vector<std::uint32_t>>().swap(mesh_words_);
      std::vector<std::vector<BvhTriangle>>().swap(mesh_triangles_);
    }
  }
  auto& triangles = instanced ? instanced_triangles : flagged.triangles;
  SceneTables tables = make_tables(scene, tri_flags, instanced);
  light_count_ = tables.light_count;
  scene_features_ = tables.features;
  HostBytes shading;
  if (take_triangles) {  // scene.triangles are gone from here on (an animated or instanced scene's)
    std::vector<SceneTriangle> taken = take_triangles();
    if (taken.size() != scene_triangles)
      throw std::logic_error("DeviceScene: take_triangles handed over " + std::to_string(taken.size()) +
                             " triangles, not the scene's " + std::to_string(scene_triangles));
    shading = shading_in_place(std::move(taken));
  } else {
    shading = owned_bytes(make_triangle_shading(scene));
  }
  DeviceWords words_made_last;
  if (words_last) words_made_last = device_wide_nodes_from(flagged, layout);
  const std::uint32_t* words = words_last ? words_made_last.data() : wide_words.data();
  const std::size_t word_count = words_last ? words_made_last.size() : wide_words.size();
  const bool binary_nodes = layout == BvhLayout::Binary && !instanced;  // else the nodes are words
  if (store.cache && store.cache->enabled() && !instanced && !scene.rig) {
    // The layout as it goes to the devices, for the next start to map (device_layout_cache.h).
    DeviceLayoutParts parts;
    parts.layout = layout;
    parts.stats = flagged.stats;
    parts.layout_nodes = layout_nodes;
    parts.nodes = binary_nodes ? static_cast<const void*>(flagged.nodes.data()) : words;
    parts.node_bytes = binary_nodes ? flagged.nodes.size() * sizeof(BvhNode) : word_count * 4;
    parts.triangles = triangles.data();
    parts.triangle_count = triangles.size();
    parts.triangle_size = sizeof(BvhTriangle);
    parts.shading = shading.data;
    parts.shading_count = shading.bytes / sizeof(TriangleShading);
    store_layout(store, parts, scene_triangles);
  }
  HostBytes node_bytes = binary_nodes ? owned_bytes(std::move(flagged.nodes))
                         : words_last ? owned_bytes(std::move(words_made_last))
                                      : owned_bytes(std::move(wide_words));
  upload_all(devices, scene, std::move(node_bytes), owned_bytes(std::move(triangles)), std::move(shading),
             std::move(instance_words), std::move(tables), tri_flags, layout_start);
}

// The device-independent part of a static scene's layout (prepare_host).
struct DeviceScene::HostPart {
  // A static scene's triangle flags follow from their materials (triangle_flags): kept per
  // material, not per triangle, and set on the leaf triangles by their material.
  std::vector<std::uint32_t> material_flags;
  SceneTables tables;
  HostBytes shading;  // the records (and an indexed one's vertex table)
  ShadingRecords records = ShadingRecords::Full;
  std::size_t scene_triangles = 0;
  double ms = 0.0;  // the time it took, counted in layout_ms()
};

std::string DeviceScene::kernel_options_for(const HostPart& host, BvhLayout layout, KernelChoice choice) {
  // What the constructor from the host part sets (lay_out_static): leaf references by the
  // layout, the part's features and records.
  const std::uint32_t features = choice == KernelChoice::General ? PX_FEATURES_ALL : host.tables.features;
  return format_kernel_options(layout, features, leaf_refs_in(layout), host.records);
}

std::shared_ptr<DeviceScene::HostPart> DeviceScene::prepare_host(
    const Scene& scene, const std::function<std::vector<SceneTriangle>()>& take_triangles) {
  require_static_scene(scene, take_triangles);
  return make_host_part(scene, take_triangles, nullptr);
}

std::shared_ptr<DeviceScene::HostPart> DeviceScene::prepare_host_before_tree(
    const Scene& scene, const std::function<std::vector<SceneTriangle>()>& take_triangles, BuildCorners& corners) {
  require_static_scene(scene, take_triangles);
  if (!environment().indexed_shading && !has_flat_shading(scene.triangles)) return nullptr;
  return make_host_part(scene, take_triangles, &corners);
}

std::shared_ptr<DeviceScene::HostPart> DeviceScene::make_host_part(
    const Scene& scene, const std::function<std::vector<SceneTriangle>()>& take_triangles, BuildCorners* corners) {
  const auto start = std::chrono::steady_clock::now();
  auto host = std::make_shared<HostPart>();
  host->scene_triangles = scene.triangles.size();
  host->material_flags = material_triangle_flags(scene);
  host->tables = make_tables(scene, {used_triangle_flags(scene, host->material_flags)}, false);
  std::vector<SceneTriangle> taken = take_triangles();  // scene.triangles are gone from here on
  const std::size_t n = taken.size();
  if (n != host->scene_triangles)
    throw std::logic_error("DeviceScene: take_triangles handed over " + std::to_string(n) +
                           " triangles, not the scene's " + std::to_string(host->scene_triangles));
  const bool flat = has_flat_shading(taken);
  const bool indexed = !flat && environment().indexed_shading;
  const auto corner_of = [](const SceneTriangle& t) { return BuildTriangle{{t.p[0], t.p[1], t.p[2]}, t.material}; };
  if (corners && flat) {
    // The records to a block of their own, the corners over the triangles (in the order
    // records_in_place reads them).
    auto records = std::make_shared<std::vector<FlatTriangleShading>>();
    records->reserve(n);
    const HostBytes packed = records_in_place<BuildTriangle>(std::move(taken), [&](const SceneTriangle& t) {
      records->push_back(flat_shading_of(t));
      return corner_of(t);
    });
    host->shading = {records->data(), n * sizeof(FlatTriangleShading), sizeof(FlatTriangleShading), records};
    host->records = ShadingRecords::Flat;
    *corners = {packed.owner, static_cast<const BuildTriangle*>(packed.data), n};
  } else if (indexed) {
    IndexedShadingBuilder builder(n);
    if (corners) {
      const HostBytes packed = records_in_place<BuildTriangle>(std::move(taken), [&](const SceneTriangle& t) {
        builder.add(t);
        return corner_of(t);
      });
      *corners = {packed.owner, static_cast<const BuildTriangle*>(packed.data), n};
    } else {
      for (const SceneTriangle& t : taken) builder.add(t);
      std::vector<SceneTriangle>().swap(taken);
    }
    IndexedShadingBuilder::Result made = builder.finish();
    host->shading = std::move(made.bytes);
    host->records = made.indexed ? ShadingRecords::Indexed : ShadingRecords::Full;
  } else if (flat) {
    host->shading = flat_shading_in_place(std::move(taken));
    host->records = ShadingRecords::Flat;
  } else {
    if (corners) throw std::logic_error("DeviceScene: corners asked for full records");
    host->shading = shading_in_place(std::move(taken));
  }
  host->ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return host;
}

DeviceScene::DeviceScene(DeviceSet& devices, std::shared_ptr<HostPart> host, const Scene& scene, FlatBvh bvh,
                         const DeviceLayoutStore& store) {
  const auto layout_start = std::chrono::steady_clock::now();
  if (!host) {
    if (store.before_tree_changes) store.before_tree_changes();
    throw std::logic_error("DeviceScene: no host part");
  }
  lay_out_static(devices, scene, std::move(bvh), std::move(host), store, layout_start);
}

void DeviceScene::lay_out_static(DeviceSet& devices, const Scene& scene, FlatBvh bvh, std::shared_ptr<HostPart> host,
                                 const DeviceLayoutStore& store, std::chrono::steady_clock::time_point layout_start) {
  const BvhLayout layout = devices.bvh_layout();
  layout_ = layout;
  const std::size_t scene_triangles = host->scene_triangles;
  // A BVH cache write may be reading the tree (store.before_tree_changes): nothing below changes
  // or frees it before that write is done, nor does a throw free it before.
  struct TreeReaders {
    const std::function<void()>& done;
    ~TreeReaders() {
      if (done) done();
    }
  } tree_readers{store.before_tree_changes};
  // The scene's triangles are shading records now: nodes the tree lacks (load_and_build leaves
  // the wide ones to here) are made and validated against the leaf triangles, which the loader's
  // validator has found to be copies of the scene's. Neither reads the triangles' flags.
  if (!has_layout(bvh, layout)) {
    ensure_layout(bvh, layout);
    const BvhValidation check = validate_layout_from_leaves(bvh, scene_triangles);
    if (!check.ok)
      throw std::runtime_error(
          std::string("internal error: the ") + to_string(layout) +
          " nodes of the scene's BVH failed validation: " + (check.errors.empty() ? "" : check.errors.front()));
  }
  if (store.before_tree_changes) store.before_tree_changes();
  set_triangle_flags_by_material(bvh, host->material_flags);
  const std::size_t layout_nodes = layout == BvhLayout::Wide4         ? bvh.nodes4.size()
                                   : layout == BvhLayout::Wide8       ? bvh.nodes8.size()
                                   : layout == BvhLayout::Compressed8 ? bvh.cnodes.size()
                                                                      : bvh.nodes.size();
  // Nothing rewrites a static scene's buffers, so its host nodes go as early as they may: those
  // the layout's device words are not made from at once, the rest while the words are made.
  release_nodes(bvh, layout);
  // Wide4 / Wide8: the leaf triangles go as BvhLeafRef records (the blocks hold the vertices),
  // made as the blocks are written. Binary nodes are uploaded as they are.
  leaf_refs_ = leaf_refs_in(layout);
  LeafRefs refs;
  HostBytes node_bytes;
  if (leaf_refs_) {
    node_bytes = owned_bytes(device_wide_nodes_from(bvh, layout, &refs));
  } else if (layout == BvhLayout::Compressed8) {
    node_bytes = owned_bytes(device_wide_nodes(bvh, layout));
    release_nodes(bvh, std::nullopt);
  }
  const BvhBuildStats stats = bvh.stats;
  if (layout == BvhLayout::Binary) node_bytes = owned_bytes(std::move(bvh.nodes));
  HostBytes triangle_bytes;
  if (leaf_refs_) {
    auto owner = std::make_shared<LeafRefs>(std::move(refs));
    triangle_bytes = {owner->data(), owner->bytes(), sizeof(BvhLeafRef), owner};
  } else {
    triangle_bytes = owned_bytes(std::move(bvh.triangles));
  }
  if (store.cache && store.cache->enabled()) {
    // The layout as it goes to the devices, for the next start to map (device_layout_cache.h).
    DeviceLayoutParts parts;
    parts.layout = layout;
    parts.stats = stats;
    parts.layout_nodes = layout_nodes;
    parts.nodes = node_bytes.data;
    parts.node_bytes = node_bytes.bytes;
    parts.triangles = triangle_bytes.data;
    parts.triangle_size = triangle_bytes.element;
    parts.triangle_count = triangle_bytes.bytes / triangle_bytes.element;
    parts.shading = host->shading.data;
    parts.shading_size = host->shading.element;
    parts.shading_count = scene_triangles;
    parts.shading_records = host->records;
    parts.shading_bytes = host->shading.bytes;
    store_layout(store, parts, scene_triangles, {node_bytes.owner, triangle_bytes.owner, host->shading.owner});
  }
  light_count_ = host->tables.light_count;
  scene_features_ = host->tables.features;
  shading_records_ = host->records;
  // The host part's time (made before the devices, when it was) is part of the layout's.
  host_part_ms_ = host->ms;
  layout_start -= std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double, std::milli>(host->ms));
  upload_all(devices, scene, std::move(node_bytes), std::move(triangle_bytes), std::move(host->shading),
             instance_buffer_words(scene, {}, scene_triangles), std::move(host->tables), /*tri_flags=*/{},
             layout_start);
}

DeviceScene::DeviceScene(DeviceSet& devices, const Scene& scene, std::shared_ptr<const MappedDeviceLayout> mapped) {
  const auto layout_start = std::chrono::steady_clock::now();
  if (!mapped) throw std::logic_error("DeviceScene: no mapped layout");
  layout_ = devices.bvh_layout();
  if (mapped->layout() != layout_)
    throw std::logic_error(std::string("DeviceScene: a mapped ") + to_string(mapped->layout()) + " layout for a " +
                           to_string(layout_) + " device set");
  if (!scene.instancing.empty() || scene.rig || mapped->shading_count() != scene.triangles.size())
    throw std::logic_error(
        "DeviceScene: a mapped layout serves a static scene without instances, of its own triangles");
  layout_from_cache_ = true;
  const std::vector<std::uint32_t> tri_flags = triangle_flags(scene);
  std::vector<std::uint32_t> instance_words = instance_buffer_words(scene, {}, scene.triangles.size());
  // The three sections, each kept alive by the mapping.
  const std::shared_ptr<const void> owner = mapped;
  HostBytes nodes{mapped->node_bytes(), mapped->node_byte_count(), layout_ == BvhLayout::Binary ? sizeof(BvhNode) : 4,
                  owner};
  leaf_refs_ = mapped->triangle_size() == sizeof(BvhLeafRef);
  HostBytes triangles{mapped->triangles(), mapped->triangle_count() * mapped->triangle_size(), mapped->triangle_size(),
                      owner};
  shading_records_ = mapped->shading_records();
  HostBytes shading{mapped->shading(), mapped->shading_bytes(), mapped->shading_size(), owner};
  SceneTables tables = make_tables(scene, tri_flags, false);
  light_count_ = tables.light_count;
  scene_features_ = tables.features;
  upload_all(devices, scene, std::move(nodes), std::move(triangles), std::move(shading), std::move(instance_words),
             std::move(tables), tri_flags, layout_start);
}

DeviceScene::SceneTables DeviceScene::make_tables(const Scene& scene, const std::vector<std::uint32_t>& tri_flags,
                                                  bool instanced) {
  SceneTables t;
  t.materials = make_gpu_materials(scene);
  // The table and its light tree, one buffer (types.h, LightTreeNode).
  t.lights = make_light_buffer(scene, t.light_count);
  FrameParams light_params{};
  fill_light_params(scene, t.light_count, light_params);
  const bool punctual = std::any_of(t.lights.begin(), t.lights.begin() + std::ptrdiff_t(t.light_count),
                                    [](const LightTriangle& l) { return l.prim >= PX_LIGHT_PUNCTUAL; });
  t.features =
      px::kernel_features(t.materials, tri_flags, light_params, !scene.vertex_colours.empty(), instanced, punctual);
  if (!scene.vertex_colours.empty()) {
    if (scene.vertex_colours.size() != scene.triangles.size())
      throw std::logic_error("DeviceScene: " + std::to_string(scene.vertex_colours.size()) +
                             " vertex colour entries for " + std::to_string(scene.triangles.size()) + " triangles");
    t.colours.reserve(3 * scene.vertex_colours.size());
    for (const auto& tri : scene.vertex_colours)
      for (const glm::vec3& c : tri) t.colours.push_back({{c.x, c.y, c.z, 1.0f}});
  } else {
    // The placeholder says "none" (w = 0) to kernels built with every feature.
    t.colours.push_back({{1.0f, 1.0f, 1.0f, 0.0f}});
  }
  for (const auto& tex : scene.textures) {
    TextureInfo info{};
    info.offset = static_cast<std::uint32_t>(t.texels.size());
    info.width = static_cast<std::uint32_t>(tex.width);
    info.height = static_cast<std::uint32_t>(tex.height);
    t.infos.push_back(info);
    for (std::size_t i = 0; i < tex.rgba.size() / 4; ++i)
      t.texels.push_back({{tex.rgba[4 * i], tex.rgba[4 * i + 1], tex.rgba[4 * i + 2], tex.rgba[4 * i + 3]}});
  }
  return t;
}

void DeviceScene::upload_all(DeviceSet& devices, const Scene& scene, HostBytes nodes, HostBytes triangles,
                             HostBytes shading, std::vector<std::uint32_t> instance_words, SceneTables tables,
                             const std::vector<std::uint32_t>& tri_flags,
                             std::chrono::steady_clock::time_point layout_start) {
  auto& materials = tables.materials;
  auto& lights = tables.lights;
  auto& colours = tables.colours;
  auto& infos = tables.infos;
  auto& texels = tables.texels;
  // One copy per OpenCL context: every ComputeDevice of a set (sub-devices, queues or platform
  // devices) shares the set's context, and a read-only buffer serves all of them. Devices that
  // share memory (sub-devices, queues: PoCL) then share the one copy; separate GPUs of a
  // platform each get their copy from the runtime on first use.
  const auto upload_start = std::chrono::steady_clock::now();
  layout_ms_ = std::chrono::duration<double, std::milli>(upload_start - layout_start).count() - layout_store_ms_;
  const AllocationLimits limits = allocation_limits(devices);
  // The whole scene against the device's memory first, before anything is allocated.
  const auto size_of = [](const auto& v) { return std::max<std::size_t>(1, v.size()) * sizeof(v[0]); };
  const auto host_size = [](const HostBytes& h) { return std::max(h.element, h.bytes); };
  const std::size_t total = host_size(nodes) + host_size(triangles) + host_size(shading) + size_of(materials) +
                            size_of(infos) + size_of(texels) + size_of(lights) + size_of(colours) +
                            size_of(instance_words);
  if (total > limits.global_mem)
    throw std::runtime_error("the scene needs " + mib(total) + " of device memory, more than the device has: " +
                             mib(limits.global_mem) + " (CL_DEVICE_GLOBAL_MEM_SIZE)");
  auto& queue = devices.devices().front().queue;
  const cl::Context& ctx = devices.context();
  instance_count_ = scene.instancing.instances.size();
  instance_bytes_ = size_of(instance_words);
  capacity_.nodes = host_size(nodes);
  capacity_.triangles = host_size(triangles);
  capacity_.shading = host_size(shading);
  capacity_.lights = size_of(lights);
  capacity_.instances = size_of(instance_words);
  // CPU devices read the host's memory: their buffers are the host arrays themselves. Not for an
  // animated scene, whose buffers update_geometry rewrites and may replace.
  host_backed_ = !scene.rig && std::all_of(devices.devices().begin(), devices.devices().end(),
                                           [](const ComputeDevice& d) { return d.is_cpu(); });
  std::vector<std::shared_ptr<const void>>* keep = host_backed_ ? &host_arrays_ : nullptr;
  std::size_t bytes = 0;
  DeviceSceneBuffers b;
  b.nodes = upload("BVH node", ctx, queue, nodes, limits, bytes, keep);
  b.triangles = upload("triangle", ctx, queue, triangles, limits, bytes, keep);
  b.shading = upload("shading", ctx, queue, shading, limits, bytes, keep);
  b.materials = upload("material", ctx, queue, owned_bytes(std::move(materials)), limits, bytes, keep);
  b.textures = upload("texture table", ctx, queue, owned_bytes(std::move(infos)), limits, bytes, keep);
  b.texels = upload("texel", ctx, queue, owned_bytes(std::move(texels)), limits, bytes, keep);
  b.lights = upload("light", ctx, queue, owned_bytes(std::move(lights)), limits, bytes, keep);
  b.colours = upload("vertex colour", ctx, queue, owned_bytes(std::move(colours)), limits, bytes, keep);
  b.instances = upload("instance", ctx, queue, owned_bytes(std::move(instance_words)), limits, bytes, keep);
  // Only update_geometry reads the flags again: a static scene does not keep them.
  if (scene.rig) tri_flags_ = tri_flags;
  bytes_in_context_ = bytes;
  upload_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - upload_start).count();
  per_device_.assign(devices.devices().size(), b);
}

std::vector<LightTriangle> DeviceScene::posed_light_buffer(const Scene& scene) {
  // An emitter posed edge-on to nothing (zero area) leaves the table for this frame.
  const auto table = make_light_table(scene);
  light_count_ = table.size();
  // Emitters that move keep the tree's topology (a refit: bounds, cones and power from the leaves
  // up) while the table holds the same lights; a table that changed gets a new tree.
  const auto two_sided = light_two_sidedness(scene, table);
  const bool same_lights = light_prims_.size() == table.size() &&
                           std::equal(table.begin(), table.end(), light_prims_.begin(),
                                      [](const LightTriangle& l, std::uint32_t prim) { return l.prim == prim; });
  if (!same_lights || !light_tree_.refit(table, two_sided)) {
    light_tree_ = LightTree::build(table, two_sided);
    light_prims_.resize(table.size());
    for (std::size_t i = 0; i < table.size(); ++i) light_prims_[i] = table[i].prim;
  }
  return light_buffer(table, light_tree_);
}

std::size_t DeviceScene::update_lights(DeviceSet& devices, const Scene& scene) {
  if (per_device_.empty()) throw std::logic_error("DeviceScene::update_lights before any upload");
  const auto lights = posed_light_buffer(scene);
  const AllocationLimits limits = allocation_limits(devices);
  DeviceSceneBuffers b = per_device_.front();
  std::size_t written = 0;
  rewrite("light", b.lights, capacity_.lights, shadows_.lights, devices.context(), devices.devices().front().queue,
          lights, limits, written);
  per_device_.assign(per_device_.size(), b);
  return written;
}

std::size_t DeviceScene::update_geometry(DeviceSet& devices, const Scene& scene, FlatBvh& bvh,
                                         const std::vector<SceneTriangle>* previous,
                                         const std::vector<glm::mat4>* previous_instances) {
  if (per_device_.empty()) throw std::logic_error("DeviceScene::update_geometry before any upload");
  if (scene.triangles.size() != tri_flags_.size())
    throw std::logic_error("DeviceScene::update_geometry: the scene has " + std::to_string(scene.triangles.size()) +
                           " triangles, not the " + std::to_string(tri_flags_.size()) + " uploaded");
  const bool instanced = instance_count_ > 0;
  if (instanced != !scene.instancing.empty() || scene.instancing.instances.size() != instance_count_ ||
      (instanced && mesh_words_.size() != scene.instancing.meshes.size()))
    throw std::logic_error("DeviceScene::update_geometry: the scene's instances are not those uploaded");
  std::vector<std::uint32_t> wide_words;
  std::vector<BvhTriangle> instanced_triangles;
  std::vector<std::uint32_t> instance_words;
  const bool has_world = !bvh.nodes.empty();
  if (has_world) {
    set_triangle_flags(bvh, tri_flags_);
    ensure_layout(bvh, layout_);
  }
  if (!instanced) {
    if (layout_ != BvhLayout::Binary) wide_words = device_wide_nodes(bvh, layout_);
  } else {
    const std::vector<MeshPlacement> placements =
        assemble_instanced(has_world ? &bvh : nullptr, wide_words, instanced_triangles);
    if (previous_instances && previous_instances->size() != instance_count_)
      throw std::logic_error("DeviceScene::update_geometry: previous matrices for another instance count");
    instance_words =
        instance_buffer_words(scene, placements, scene.instancing.world_triangles, nullptr, previous_instances);
  }
  const auto shading = make_triangle_shading(scene);
  const auto lights = posed_light_buffer(scene);
  std::vector<cl_float4> motion;
  if (previous) {
    if (previous->size() != scene.triangles.size())
      throw std::logic_error("DeviceScene::update_geometry: the previous frame has another triangle count");
    motion.resize(6 * scene.triangles.size());
    for (std::size_t t = 0; t < scene.triangles.size(); ++t)
      for (int c = 0; c < 3; ++c) {
        const glm::vec3& now = scene.triangles[t].p[c];
        const glm::vec3& before = (*previous)[t].p[c];
        motion[6 * t + std::size_t(c)] = {{now.x, now.y, now.z, 0.0f}};
        motion[6 * t + 3 + std::size_t(c)] = {{before.x, before.y, before.z, 0.0f}};
      }
  }
  const AllocationLimits limits = allocation_limits(devices);
  auto& queue = devices.devices().front().queue;
  const cl::Context& ctx = devices.context();
  DeviceSceneBuffers b = per_device_.front();
  std::size_t written = 0;
  Shadows& sh = shadows_;
  if (layout_ == BvhLayout::Binary && !instanced)
    rewrite("BVH node", b.nodes, capacity_.nodes, sh.nodes, ctx, queue, bvh.nodes, limits, written);
  else
    rewrite("BVH node", b.nodes, capacity_.nodes, sh.nodes, ctx, queue, wide_words, limits, written);
  rewrite("triangle", b.triangles, capacity_.triangles, sh.triangles, ctx, queue,
          instanced ? instanced_triangles : bvh.triangles, limits, written);
  if (instanced)
    rewrite("instance", b.instances, capacity_.instances, sh.instances, ctx, queue, instance_words, limits, written);
  rewrite("shading", b.shading, capacity_.shading, sh.shading, ctx, queue, shading, limits, written);
  rewrite("light", b.lights, capacity_.lights, sh.lights, ctx, queue, lights, limits, written);
  if (previous) rewrite("motion", b.motion, capacity_.motion, sh.motion, ctx, queue, motion, limits, written);
  per_device_.assign(per_device_.size(), b);
  return written;
}

}  // namespace px
