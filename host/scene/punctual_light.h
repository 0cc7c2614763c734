// Point and spot lights (Scene::punctual_lights): where a glTF node puts one, how a spot light
// falls off about its axis (glTF KHR_lights_punctual's formula, the one the kernels evaluate), and
// the power next-event estimation weighs it by.
#pragma once

#include "scene/scene.h"

#include <glm/glm.hpp>

namespace px {

// Places `light` as a glTF light on a node with world matrix `world`: at the node's origin,
// shining along its local -z (normalised); false, `light` unchanged, when the matrix makes the
// direction degenerate or the position not finite.
bool place_light_at_node(const glm::dmat4& world, PunctualLight& light);

// glTF's spot falloff as a linear ramp in the cosine, squared: saturate(cos * scale + offset)^2,
// with scale = 1 / max(0.001, cos(inner) - cos(outer)) and offset = -cos(outer) * scale. A point
// light: scale 0, offset 1 (1 in every direction).
struct SpotRamp {
  float scale = 0.0f;
  float offset = 1.0f;
  float cos_outer = -1.0f;  // no light beyond this cosine to the axis (-1: none excluded)
};
SpotRamp spot_ramp(const PunctualLight& light);

// The falloff of `light` towards unit direction `out` (from the light): 1 for a point light.
float spot_falloff(const PunctualLight& light, const glm::vec3& out);

// The light's power in the units of the light table (watts / pi, as an emissive triangle's
// area x radiance): 4 pi I for a point light; for a spot light 2 pi (1 - (cos_inner + cos_outer)
// / 2) I, the solid angle of a cone halfway between the two (an approximation of the falloff's
// integral); I the luminance of the intensity.
double punctual_light_power(const PunctualLight& light);

}  // namespace px
