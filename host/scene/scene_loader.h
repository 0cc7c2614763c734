// Entry points that turn user input into a Scene. All of them throw SceneError with a message
// that names the file (and line where there is one) on anything they cannot repair.
#pragma once

#include "scene/scene.h"

#include <nlohmann/json.hpp>
#include <string>

namespace px {

// `spec` is one of:
//   - a path to a scene JSON file (scenes/*.json; format documented in scenes/README.md),
//   - a path to an .obj, .gltf or .glb file (camera: a glTF's first perspective camera, else
//     framed on the bounding box),
//   - the name of a built-in generator: "cornell", "cornell-glossy", "atrium", "rooms".
// Whatever the source, the scene's coordinates are then checked (check_coordinate_range), and
// light is seen to by `options.sky` (one warning line says what was done):
//   kAuto: a scene without any light (no emitter, sun or sky) gets default_sky();
//   kOn:   a scene without a sky of its own gets default_sky(), whatever else lights it;
//   kOff:  nothing is added (an unlit scene renders black, and the warning says so).
enum class SkyMode { kAuto, kOn, kOff };

// How a scene is loaded, whatever its source (the command line's --sky and --instancing).
struct SceneLoadOptions {
  SkyMode sky = SkyMode::kAuto;
  // A glTF mesh that several nodes draw (or, in a file that moves, a rigid mesh a clip moves)
  // is stored once with a matrix per node (Scene::instancing); false stores a world-space copy
  // per node instead (see load_gltf).
  bool instancing = true;
};

Scene load_scene(const std::string& spec, const SceneLoadOptions& options = {});

// Largest coordinate magnitude (vertices, camera, camera path) parallax traces. Rays are traced
// in 32-bit floats: intersection tests multiply up to three coordinates, so beyond ~1e12 they
// overflow (geometry at 1e13 vanished, at 1e19 the image was all NaN with exit 0); 1e11 keeps
// a factor of ten in hand. A scene of any shape fits by scaling or recentring.
inline constexpr float kMaxSceneCoordinate = 1e11f;

// Refuses (SceneError naming `source` and what is out of range) a scene with a vertex or
// camera coordinate beyond kMaxSceneCoordinate; warns (scene.stats.warnings) when the geometry
// lies so far from the origin relative to its size that floats resolve it coarsely.
void check_coordinate_range(Scene& scene, const std::string& source, bool warn = true);

// Loads an OBJ (+MTL, textures through the image codec, image/image_io.h) into triangles and materials.
// Repairs (with counts in scene.stats): drops degenerate and non-finite triangles,
// falls back to a default material for a missing MTL / unknown material (with a warning).
// Refuses (SceneError): unreadable file, out-of-range indices, no triangles left.
Scene load_obj(const std::string& path);

// Loads a glTF 2.0 file (.gltf with external / data-URI buffers, or binary .glb; the kind is
// told by the content) into triangles, materials and textures (mapping in gltf_loader.cpp).
// The default scene's node hierarchy is flattened into world space. When the file has a
// perspective camera on a node, the first one becomes scene.camera and *has_camera is set.
// Features it does not render are named in one warning line. Refuses (SceneError naming the
// file): unreadable or malformed files, missing buffers, accessors or buffer views out of
// bounds, indices out of range, unsupported required extensions, no triangles left.
// Of `options`, it reads `instancing` (the sky is load_scene's).
Scene load_gltf(const std::string& path, const SceneLoadOptions& options = {}, bool* has_camera = nullptr);

// The environment load_scene gives a scene without any light (no emitter, sun or sky): a
// soft grey-blue sky, bright enough to show the geometry at the default exposure.
Sky default_sky();

// Built-in scenes, written from their published dimensions / procedurally.
// `params` are generator options from the scene file ({} = defaults).
Scene make_builtin_scene(const std::string& name, const nlohmann::json& params = {});

// Names accepted by make_builtin_scene.
const std::vector<std::string>& builtin_scene_names();

}  // namespace px
