// The sun that moves: a scene file's sun keys and a glTF directional light on an animated node,
// both evaluated on the animation's one clock (SceneAnimator poses the scene's sun with the rest
// of the scene, so that `render`, `reference --frame`, `view` and every MPI rank light frame f
// with the same sun).
//
// A sun that moves may set: as its disk goes below the horizon (the plane y = 0 of the scene's
// +y up) its radiance fades to nothing, linearly over the disk's height, instead of lighting the
// scene from below. A sun that does not move stays as the scene gives it, wherever it points.
#pragma once

#include "scene/scene.h"

#include <glm/glm.hpp>

#include <string>
#include <vector>

namespace px {

// The direction towards the sun at `time_s` on `keys` (at least one, times strictly
// increasing): the key's own direction at a key time, held before the first and after the
// last, and in between along the great circle from one key's direction to the next at an even
// angular speed (slerp; a normalised lerp where the two are nearly the same). Keys with
// opposite directions are refused at load (check_sun_keys), where the great circle is not one.
glm::vec3 sun_path_direction(const std::vector<SunKey>& keys, double time_s);

// Whether `keys` can be a sun path: each direction finite and non-zero (normalised by the
// loader), times finite, non-negative and strictly increasing, no two consecutive directions
// opposite. When not: false, with `key` the offending key's name (`name` + "[2].time") and
// `what` what is wrong with it.
bool check_sun_keys(const std::vector<SunKey>& keys, const std::string& name, std::string& key, std::string& what);

// How much of a moving sun's disk is above the horizon, 0 to 1: 1 with its whole disk above
// y = 0, 0 with its whole disk below, linear in the elevation's sine in between.
float sun_above_horizon(const glm::vec3& towards, float angular_radius_deg);

// `base` moved to point towards `towards` (unit), its radiance faded by sun_above_horizon.
Sun moving_sun(const Sun& base, const glm::vec3& towards);

// The direction towards a glTF directional light on a node with world matrix `world` (the
// light shines along the node's local -z, so the sun is along +z); false when the matrix
// makes it degenerate.
bool sun_from_node(const glm::dmat4& world, glm::vec3& towards);

}  // namespace px
