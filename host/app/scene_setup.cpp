#include "app/scene_setup.h"

#include "scene/scene_loader.h"

#include <chrono>
#include <cstdio>
#include <string>

namespace px {

LoadedScene load_and_build(const std::string& spec, bool quiet) {
  using clock = std::chrono::steady_clock;
  LoadedScene out;
  auto t0 = clock::now();
  if (!quiet) std::fprintf(stderr, "[scene] loading %s ...\n", spec.c_str());
  out.scene = load_scene(spec);
  const auto& st = out.scene.stats;
  auto t1 = clock::now();
  if (!quiet) {
    std::fprintf(stderr, "[scene] %s: %zu triangles, %zu materials, %zu textures (%.0f ms)\n",
                 out.scene.name.c_str(), out.scene.triangles.size(), out.scene.materials.size(),
                 out.scene.textures.size(), std::chrono::duration<double, std::milli>(t1 - t0).count());
    // Dropped triangles are reported once, by the loader's warnings (which name the file).
    for (const auto& w : st.warnings) std::fprintf(stderr, "[scene] warning: %s\n", w.c_str());
  }
  out.bvh = build_bvh(out.scene.triangles);
  const auto& bs = out.bvh.stats;
  if (!quiet)
    std::fprintf(stderr, "[bvh] %zu nodes, %zu leaf triangles, depth %d, SAH %.1f (%.0f ms)%s%s\n", bs.nodes,
                 bs.leaf_triangles, bs.depth, bs.sah_cost, bs.build_ms,
                 bvh_layout() == BvhLayout::Binary ? ""
                 : (std::string("; traversed as ") + to_string(bvh_layout()) + ", " +
                    std::to_string(bvh_layout() == BvhLayout::Wide4 ? out.bvh.nodes4.size() : out.bvh.nodes8.size()) +
                    " nodes").c_str(),
                 bs.split_budget_exceeded ? "; spatial splits stopped at their budget (heavily overlapping "
                                            "triangles): binned SAH instead"
                                          : "");
  auto check = validate_bvh(out.bvh, out.scene.triangles);
  if (!check.ok) {
    std::string msg = "internal error: BVH failed validation:";
    for (const auto& e : check.errors) msg += "\n  " + e;
    throw std::runtime_error(msg);
  }
  return out;
}

}  // namespace px
