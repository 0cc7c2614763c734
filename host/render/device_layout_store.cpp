// DeviceScene's write of a static scene's layout to the device layout cache
// (device_layout_cache.h): at once, or on the start's cache-writing thread (background_writes.h).
#include "render/device_scene.h"

#include "io/progress_ticker.h"

#include <chrono>
#include <cstdio>
#include <string>
#include <utility>

namespace px {

void DeviceScene::store_layout(const DeviceLayoutStore& store, const DeviceLayoutParts& parts,
                               std::size_t scene_triangles, std::vector<std::shared_ptr<const void>> keep) {
  // The write itself, on this thread or the writer's: it returns its time.
  const auto write = [cache = *store.cache, key = store.content_key, options = store.options, quiet = store.quiet,
                      parts, scene_triangles] {
    const auto t = std::chrono::steady_clock::now();
    std::string why;
    const std::string path = cache.store(key, options, scene_triangles, parts, &why);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
    if (!quiet && !path.empty())
      std::fprintf(stderr, "[bvh] the %s device layout cached in %s for the next run (%.0f ms)\n",
                   to_string(parts.layout), path.c_str(), ms);
    if (!quiet && path.empty())
      std::fprintf(stderr, "[bvh] warning: could not cache the device layout (%s)\n", why.c_str());
    return ms;
  };
  if (store.background && !keep.empty()) {
    // The arrays stay alive for the write through `keep` (no copy: on CPU devices they are the
    // buffers themselves).
    store.background->submit([write, keep = std::move(keep)] { write(); }, BackgroundWrites::Start::AfterFirstFrame);
    return;
  }
  const ProgressTicker ticker(store.quiet ? "" : "[bvh] still writing the device layout cache");
  layout_store_ms_ = write();
}

}  // namespace px
