// Point and spot lights (punctual_light.h).
#include "scene/punctual_light.h"

#include <algorithm>
#include <cmath>

namespace px {

bool place_light_at_node(const glm::dmat4& world, PunctualLight& light) {
  const glm::dvec3 at(world * glm::dvec4(0.0, 0.0, 0.0, 1.0));
  const glm::dvec3 along(world * glm::dvec4(0.0, 0.0, -1.0, 0.0));
  const double len = glm::length(along);
  if (!(len > 0.0) || !std::isfinite(len) || !std::isfinite(at.x + at.y + at.z)) return false;
  light.position = glm::vec3(at);
  light.direction = glm::vec3(along / len);
  return true;
}

SpotRamp spot_ramp(const PunctualLight& light) {
  SpotRamp r;
  if (!light.spot) return r;
  const float cos_inner = std::cos(light.inner_cone_rad), cos_outer = std::cos(light.outer_cone_rad);
  r.scale = 1.0f / std::max(0.001f, cos_inner - cos_outer);
  r.offset = -cos_outer * r.scale;
  r.cos_outer = cos_outer;
  return r;
}

float spot_falloff(const PunctualLight& light, const glm::vec3& out) {
  const SpotRamp r = spot_ramp(light);
  const float a = std::clamp(glm::dot(light.direction, out) * r.scale + r.offset, 0.0f, 1.0f);
  return a * a;
}

double punctual_light_power(const PunctualLight& light) {
  const glm::vec3& c = light.intensity;
  const double lum = 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
  if (!light.spot) return 4.0 * lum;
  const double cos_mid = 0.5 * (std::cos(double(light.inner_cone_rad)) + std::cos(double(light.outer_cone_rad)));
  return 2.0 * (1.0 - cos_mid) * lum;
}

}  // namespace px
