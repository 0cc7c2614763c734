#include "scene/sun_path.h"

#include <algorithm>
#include <cmath>

namespace px {

glm::vec3 sun_path_direction(const std::vector<SunKey>& keys, double time_s) {
  if (keys.empty()) return glm::vec3(0.0f, 1.0f, 0.0f);
  if (!(time_s > double(keys.front().time))) return keys.front().direction;
  if (time_s >= double(keys.back().time)) return keys.back().direction;
  const auto next =
      std::upper_bound(keys.begin(), keys.end(), time_s, [](double t, const SunKey& k) { return t < double(k.time); });
  const auto prev = next - 1;
  const double u = (time_s - double(prev->time)) / (double(next->time) - double(prev->time));
  const glm::dvec3 a(prev->direction), b(next->direction);
  const double cos_angle = std::clamp(glm::dot(a, b), -1.0, 1.0);
  const double angle = std::acos(cos_angle);
  glm::dvec3 d;
  // Below about a thousandth of a degree sin(angle) loses its digits: the lerp is as good there.
  if (angle < 1e-5) {
    d = glm::mix(a, b, u);
  } else {
    const double s = std::sin(angle);
    d = (std::sin((1.0 - u) * angle) / s) * a + (std::sin(u * angle) / s) * b;
  }
  return glm::vec3(glm::normalize(d));
}

bool check_sun_keys(const std::vector<SunKey>& keys, const std::string& name, std::string& key, std::string& what) {
  const auto fail = [&](const std::string& k, const std::string& w) {
    key = k;
    what = w;
    return false;
  };
  if (keys.empty()) return fail(name, "needs at least one key");
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const std::string at = name + "[" + std::to_string(i) + "]";
    const SunKey& k = keys[i];
    if (!std::isfinite(k.time) || k.time < 0.0f) return fail(at + ".time", "must be a finite number >= 0 (seconds)");
    if (i > 0 && !(k.time > keys[i - 1].time))
      return fail(at + ".time", "must be greater than the previous key's time");
    const float len = glm::length(k.direction);
    if (!(len > 0.0f) || !std::isfinite(len)) return fail(at + ".direction", "must be a finite, non-zero vector");
    if (i > 0 && glm::dot(k.direction / len, glm::normalize(keys[i - 1].direction)) < -0.9999f)
      return fail(at + ".direction",
                  "points opposite to the previous key's, so which way the sun turns between them is not defined: "
                  "add a key between them");
  }
  return true;
}

float sun_above_horizon(const glm::vec3& towards, float angular_radius_deg) {
  const float s = std::sin(glm::radians(angular_radius_deg));
  const float y = glm::normalize(towards).y;
  if (y >= s) return 1.0f;
  if (y <= -s) return 0.0f;
  return std::clamp(0.5f * (y / s + 1.0f), 0.0f, 1.0f);
}

Sun moving_sun(const Sun& base, const glm::vec3& towards) {
  Sun sun = base;
  sun.direction = towards;
  sun.radiance = base.radiance * sun_above_horizon(towards, base.angular_radius_deg);
  return sun;
}

bool sun_from_node(const glm::dmat4& world, glm::vec3& towards) {
  const glm::dvec3 travel(world * glm::dvec4(0.0, 0.0, -1.0, 0.0));
  const double len = glm::length(travel);
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  towards = glm::vec3(-travel / len);
  return true;
}

}  // namespace px
