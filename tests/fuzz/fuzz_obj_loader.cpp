// libFuzzer target: the OBJ + MTL loader. The input is an OBJ, optionally followed by a line
// "#--mtl--" and the text of m.mtl (which the OBJ can name with "mtllib m.mtl"). The loader's
// contract is a Scene or a SceneError with a message: any other exception, a crash, a
// sanitizer report, a hang or a runaway allocation is a finding.
#include "fuzz_common.h"
#include "scene/scene_loader.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view marker = "\n#--mtl--\n";
  const std::size_t split = input.find(marker);
  const std::string_view obj = input.substr(0, split);
  const std::string_view mtl =
      split == std::string_view::npos ? std::string_view() : input.substr(split + marker.size());
  px::fuzz::write("m.mtl", mtl);
  const std::string path = px::fuzz::write("m.obj", obj);
  try {
    const px::Scene scene = px::load_obj(path);
    // What every loaded scene promises: triangles with finite positions and valid materials.
    if (scene.triangles.empty() || scene.materials.empty()) std::abort();
    for (const px::SceneTriangle& t : scene.triangles) {
      if (t.material >= scene.materials.size()) std::abort();
      for (const auto& p : t.p)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) std::abort();
    }
  } catch (const px::SceneError&) {}
  return 0;
}
