// libFuzzer target: JSON scene files (load_scene on a .json). A small OBJ sits next to it as
// "m.obj" so that "mesh" paths reach the OBJ loader too. The contract: a Scene that passed every
// check, or a SceneError with a message; anything else is a finding.
#include "fuzz_common.h"
#include "scene/scene_loader.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string mesh = px::fuzz::write("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n");
  (void)mesh;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  // The atrium generator makes 0.5-4 million triangles by design (its "detail" range): each
  // such input would take seconds, starving the rest of the search. It is tested elsewhere.
  if (input.find("atrium") != std::string_view::npos) return 0;
  const std::string path = px::fuzz::write("scene.json", input);
  try {
    const px::Scene scene = px::load_scene(path);
    if (scene.triangles.empty() || scene.materials.empty()) std::abort();
    if (!(std::abs(scene.camera.position.x) <= px::kMaxSceneCoordinate)) std::abort();
  } catch (const px::SceneError&) {}
  return 0;
}
