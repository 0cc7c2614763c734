// libFuzzer target: the glTF loader (load_gltf), on .gltf JSON and binary .glb alike (the
// loader tells them by content). A small external buffer sits next to it as "b.bin" (48 bytes:
// three float positions and three uint32 indices) so that external "uri"s are reached too.
// The contract: a Scene or a SceneError with a message; anything else is a finding.
#include "fuzz_common.h"
#include "scene/instancing.h"
#include "scene/scene_loader.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string bin = [] {
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const std::uint32_t idx[3] = {0, 1, 2};
    std::string b(sizeof pos + sizeof idx, '\0');
    std::memcpy(b.data(), pos, sizeof pos);
    std::memcpy(b.data() + sizeof pos, idx, sizeof idx);
    return px::fuzz::write("b.bin", b);
  }();
  (void)bin;
  const std::string path = px::fuzz::write("m.gltf", std::string_view(reinterpret_cast<const char*>(data), size));
  try {
    const px::Scene scene = px::load_gltf(path);
    if (scene.triangles.empty() || scene.materials.empty()) std::abort();
    for (const px::SceneTriangle& t : scene.triangles) {
      if (t.material >= scene.materials.size()) std::abort();
      for (const auto& p : t.p)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) std::abort();
    }
    // Instancing, when the file shares a mesh among nodes, describes the triangles it has.
    try {
      px::check_instancing(scene);
    } catch (const std::logic_error&) {
      std::abort();
    }
    if (!scene.vertex_colours.empty() && scene.vertex_colours.size() != scene.triangles.size()) std::abort();
    for (const px::Material& m : scene.materials)
      for (int tex : {m.diffuse_texture, m.specular_texture, m.normal_texture, m.alpha_texture})
        if (tex >= int(scene.textures.size())) std::abort();
  } catch (const px::SceneError&) {}
  return 0;
}
