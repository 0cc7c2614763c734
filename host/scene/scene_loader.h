// Entry points that turn user input into a Scene. All of them throw SceneError with a message
// that names the file (and line where there is one) on anything they cannot repair.
#pragma once

#include "scene/scene.h"

#include <nlohmann/json.hpp>
#include <string>

namespace px {

// `spec` is one of:
//   - a path to a scene JSON file (scenes/*.json; format documented in scenes/README.md),
//   - a path to an .obj file (camera framed on its bounding box, no sun/sky),
//   - the name of a built-in generator: "cornell", "cornell-glossy", "atrium".
Scene load_scene(const std::string& spec);

// Loads an OBJ (+MTL, textures through OpenImageIO) into triangles and materials.
// Repairs (with counts in scene.stats): drops degenerate and non-finite triangles,
// falls back to a default material for a missing MTL / unknown material (with a warning).
// Refuses (SceneError): unreadable file, out-of-range indices, no triangles left.
Scene load_obj(const std::string& path);

// Built-in scenes, written from their published dimensions / procedurally.
// `params` are generator options from the scene file ({} = defaults).
Scene make_builtin_scene(const std::string& name, const nlohmann::json& params = {});

// Names accepted by make_builtin_scene.
const std::vector<std::string>& builtin_scene_names();

}  // namespace px
