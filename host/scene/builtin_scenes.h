// Internal to the scene module: the generators behind make_builtin_scene and the helpers they
// share for reading their parameters. Users go through scene_loader.h.
#pragma once

#include "scene/scene.h"

#include <nlohmann/json.hpp>

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <numbers>
#include <string>
#include <string_view>

namespace px {

// The Cornell box from the published measurements; `glossy` makes the tall block glossy and adds
// a mirror sphere.
Scene make_cornell_scene(const nlohmann::json& params, bool glossy);

// The procedural colonnaded courtyard.
Scene make_atrium_scene(const nlohmann::json& params);

// A grid of rooms joined by doorways, lit by many small ceiling lamps (the many-lights case).
Scene make_rooms_scene(const nlohmann::json& params);

// The generators' random numbers: splitmix64, tiny, fast and the same on every platform, so a
// seed always gives the same scene.
class GeneratorRng {
 public:
  explicit GeneratorRng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  float uniform() { return float(next() >> 40) * (1.0f / 16777216.0f); }  // [0, 1)
  float range(float lo, float hi) { return lo + (hi - lo) * uniform(); }
  glm::vec3 unit_vector() {
    const float z = range(-1.0f, 1.0f), phi = range(0.0f, 2.0f * std::numbers::pi_v<float>);
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
    return {r * std::cos(phi), r * std::sin(phi), z};
  }
  // Uniform in the unit ball (rejection: accepts ~52%).
  glm::vec3 in_unit_ball() {
    for (;;) {
      const glm::vec3 p(range(-1, 1), range(-1, 1), range(-1, 1));
      if (glm::dot(p, p) <= 1.0f) return p;
    }
  }

 private:
  std::uint64_t state_;
};

// A Lambertian material (roughness 1) named `name`.
Material diffuse_material(const char* name, glm::vec3 albedo);

// Throws SceneError unless `params` is null or an object whose keys are all in `known`.
void check_generator_params(std::string_view generator, const nlohmann::json& params,
                            std::initializer_list<std::string_view> known);

// Number parameter `key` (or `fallback` when absent), which must be finite and within
// [min, max]; SceneError naming the generator and key otherwise.
double generator_number(std::string_view generator, const nlohmann::json& params, std::string_view key, double fallback,
                        double min, double max);

}  // namespace px
