// What every command does before it renders: load the scene, report what the loader repaired,
// build and validate the BVH, all with progress on stderr.
#pragma once

#include "bvh/flat_bvh.h"
#include "scene/scene.h"
#include "scene/scene_loader.h"

#include <string>

namespace px {

struct LoadedScene {
  Scene scene;
  FlatBvh bvh;
};

// Throws SceneError / std::runtime_error with a user-facing message on failure.
LoadedScene load_and_build(const std::string& spec, bool quiet = false, SkyMode sky = SkyMode::kAuto);

}  // namespace px
