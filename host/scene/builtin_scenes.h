// Internal to the scene module: the generators behind make_builtin_scene and the helpers they
// share for reading their parameters. Users go through scene_loader.h.
#pragma once

#include "scene/scene.h"

#include <nlohmann/json.hpp>

#include <initializer_list>
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

// Throws SceneError unless `params` is null or an object whose keys are all in `known`.
void check_generator_params(std::string_view generator, const nlohmann::json& params,
                            std::initializer_list<std::string_view> known);

// Number parameter `key` (or `fallback` when absent), which must be finite and within
// [min, max]; SceneError naming the generator and key otherwise.
double generator_number(std::string_view generator, const nlohmann::json& params, std::string_view key, double fallback,
                        double min, double max);

}  // namespace px
