// Name -> generator dispatch for the built-in scenes, and parameter checking shared by them.
#include "scene/builtin_scenes.h"
#include "scene/scene_loader.h"

#include <cmath>
#include <sstream>

namespace px {

const std::vector<std::string>& builtin_scene_names() {
  static const std::vector<std::string> names = {"cornell", "cornell-glossy", "atrium", "rooms"};
  return names;
}

Scene make_builtin_scene(const std::string& name, const nlohmann::json& params) {
  if (name == "cornell") return make_cornell_scene(params, false);
  if (name == "cornell-glossy") return make_cornell_scene(params, true);
  if (name == "atrium") return make_atrium_scene(params);
  if (name == "rooms") return make_rooms_scene(params);
  std::string list;
  for (const std::string& n : builtin_scene_names()) list += (list.empty() ? "" : ", ") + n;
  throw SceneError("unknown built-in scene '" + name + "' (built-in scenes: " + list + ")");
}

void check_generator_params(std::string_view generator, const nlohmann::json& params,
                            std::initializer_list<std::string_view> known) {
  if (params.is_null()) return;
  if (!params.is_object())
    throw SceneError("generator '" + std::string(generator) + "': parameters must be an object, got " +
                     params.type_name());
  for (const auto& [key, value] : params.items()) {
    bool ok = false;
    for (std::string_view k : known) ok |= key == k;
    if (ok) continue;
    std::string list;
    for (std::string_view k : known) list += (list.empty() ? "" : ", ") + std::string(k);
    throw SceneError("generator '" + std::string(generator) + "': unknown parameter '" + key +
                     "' (known: " + (list.empty() ? "none" : list) + ")");
  }
}

double generator_number(std::string_view generator, const nlohmann::json& params, std::string_view key, double fallback,
                        double min, double max) {
  if (!params.is_object()) return fallback;
  const auto it = params.find(key);
  if (it == params.end()) return fallback;
  const std::string where = "generator '" + std::string(generator) + "': parameter '" + std::string(key) + "'";
  if (!it->is_number()) throw SceneError(where + " must be a number, got " + it->type_name());
  const double v = it->get<double>();
  if (!std::isfinite(v) || v < min || v > max) {
    std::ostringstream msg;
    msg << where << " must be within [" << min << ", " << max << "], got " << v;
    throw SceneError(msg.str());
  }
  return v;
}

Material diffuse_material(const char* name, glm::vec3 albedo) {
  Material m;
  m.name = name;
  m.diffuse = albedo;
  m.roughness = 1.0f;
  return m;
}

}  // namespace px
